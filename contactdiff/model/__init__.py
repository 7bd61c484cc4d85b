"""Models of what is simulated: robots, contacts, efforts and scenes.

Robots as Pinocchio models with their frames, joints and Lie-group helpers
(`robot`) and loading them from URDF and MJCF files or names (`robot_files`),
choosing a legged robot's feet (`feet`) and rounding them (`round_feet`),
unilateral contacts with their gaps, Jacobian rows, drifts and derivatives
(`contacts`), the generalised forces of a scene and their derivatives
(`efforts`), the per-state kinematics cache they share (`kinematics`),
series-compliant feet (`compliance`), and scenes built in Python (`scene`; read from TOML files by
`contactdiff.scenes.scene_file`).
"""
