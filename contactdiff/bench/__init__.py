"""Benchmarks and studies: error against run time, stiff and extreme cases.

The benchmark runner, comparing methods per scene against a reference
(`runner`, its error measures in `metrics`) and against hand-written baselines
on the same dynamics (`baselines`); the stiff and extreme-case studies, each a
check of correctness and a row of cost (`extreme_cases`, `stiff_cases`,
`edge_cases`, `study_rows`); the measured footprint of a scene (`footprint`); and
gradients through contact against MuJoCo's on five tasks (`gradients`, `gradients_cube`,
`gradients_mujoco`, which imports ``mujoco`` only when called).
"""
