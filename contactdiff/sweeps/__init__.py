"""Sweeps and Monte Carlo: one scene over many points, on every core or a cluster.

``contactdiff.sweep(scene, points, job=..., t_final=...)`` (`runner.sweep`) runs
a job at every point of a grid, a list or a seeded random sample and returns
one row per point; ``contactdiff sweep SCENE ...`` is the command line. The
modules, one concept each:

    points      grid, point_list, random_points (Uniform, Normal), "lo:hi:n" ranges
    quantities  what a point may change: q:/v: initial state, scene parameters,
                run options, arg: factory arguments, job: job arguments
    sources     the scene as workers rebuild it (name, file or factory), kept per process
    callables   "module:function" references
    jobs        simulate, jacobian, order-gap, stride, or a user function; a row's outputs
    rows        Row, RunError, SweepResult (to_pandas, plot)
    files       results files (JSON Lines, CSV) written as runs finish, read to resume
    engines     joblib backends: loky (local processes), dask, ray
    runner      sweep() and run_point()
    plot        a line (1-D) or a heatmap (2-D) of one output
    cli         the ``contactdiff sweep`` subcommand

``contactdiff.sweep`` is the function; this package (``contactdiff.sweeps``) holds it
and the rest (``from contactdiff.sweeps import grid, random_points``).
"""

from .engines import Backend
from .jobs import JobKind
from .points import Normal, PointSet, Uniform, grid, point_list, random_points
from .rows import Row, RunError, SweepResult
from .runner import DamagedRowsWarning, sweep

__all__ = [
    "sweep",
    "grid",
    "point_list",
    "random_points",
    "Uniform",
    "Normal",
    "PointSet",
    "Row",
    "RunError",
    "SweepResult",
    "Backend",
    "JobKind",
    "DamagedRowsWarning",
]
