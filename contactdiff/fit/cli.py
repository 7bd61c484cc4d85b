"""``contactdiff fit SCENE DATA ... --param NAME ...``: the command line of `contactdiff.fit.fit`.

    contactdiff fit SCENE DATA [DATA ...] --param NAME [--param NAME ...]
                    [--scale NAME=PARAM,PARAM,...] [--bound NAME=LO:HI] [--fit-state none|velocity|full]
                    [--policy keep|exclude] [--loss linear|soft_l1|huber|cauchy [--f-scale F]]
                    [--position-weight W] [--orientation-weight W]
                    [--window N [--window-stride S]] [--joint-weight W] [--rtol R] [--atol A] [--max-evaluations N]
                    [--jobs N] [--backend loky|dask|ray] [--json] [--plot out.png]

Each DATA file is one measured trajectory of SCENE (docs/observations.md: CSV or
``.npz``); its rollout starts at its first sample. `add_parser` adds the
subcommand; `run` is its action.
"""

from __future__ import annotations

import argparse
import json
from typing import TYPE_CHECKING

from ..cli_args import (
    COUNT,
    FINITE,
    Number,
    add_plot,
    assignment,
    check_plot_path,
    print_flushed,
    raise_failures,
    write_output,
)
from ..errors import InvalidInputError

if TYPE_CHECKING:
    from .problem import FitResult


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Add ``fit`` to the ``contactdiff`` subcommands ``sub``."""
    from .evaluation import StateFit
    from .loss import Loss
    from .problem import NonDifferentiablePolicy

    parser = sub.add_parser(
        "fit",
        help="fit scene parameters to measured trajectories with exact derivatives",
        description="Fit named scene parameters (and, if asked, each trajectory's initial state) to measured "
        "trajectories by nonlinear least squares, with the residuals' exact Jacobian from one run "
        "per trajectory; prints the fitted values with standard errors, each trajectory's residual "
        "and whether its outcome is differentiable.",
    )
    parser.add_argument("scene", metavar="SCENE", help="scene name or TOML path, or module:function returning a Scene")
    parser.add_argument("data", metavar="DATA", nargs="+", help="observation files (CSV or .npz), one trajectory each")
    parser.add_argument(
        "--param",
        action="append",
        default=[],
        metavar="NAME",
        help="a scene parameter to fit (repeatable; `contactdiff simulate SCENE --param list` lists them)",
    )
    parser.add_argument(
        "--scale",
        action="append",
        default=[],
        metavar="NAME=PARAM,PARAM,...",
        help="fit one scale NAME of several parameters at once (each = scale x its value in the scene; repeatable)",
    )
    parser.add_argument(
        "--bound",
        action="append",
        default=[],
        metavar="NAME=LO:HI",
        help="bounds of a fitted unknown (default: mu, e, masses, ... >= 0, e <= 1)",
    )
    parser.add_argument(
        "--fit-state",
        default=StateFit.NONE.value,
        choices=[s.value for s in StateFit],
        help="also fit each trajectory's initial velocity or whole state (default none)",
    )
    parser.add_argument(
        "--window",
        type=int,
        default=None,
        metavar="N",
        help="fit on windows of N samples cut from each trajectory (multiple shooting: each "
        "window starts from the data; docs/fit.md), not on whole trajectories",
    )
    parser.add_argument(
        "--window-stride",
        type=int,
        default=None,
        metavar="S",
        help="with --window: samples between window starts (default N)",
    )
    parser.add_argument(
        "--policy",
        default=NonDifferentiablePolicy.KEEP.value,
        choices=[p.value for p in NonDifferentiablePolicy],
        help="trajectories whose outcome is not differentiable: keep (count, warn) or exclude "
        "those not differentiable at the start (default keep)",
    )
    parser.add_argument(
        "--loss",
        default=Loss.LINEAR.value,
        choices=[loss.value for loss in Loss],
        help="the cost: linear (least squares, default) or a robust loss that counts rows beyond "
        "--f-scale less (soft_l1, huber, cauchy; start near the answer)",
    )
    parser.add_argument(
        "--f-scale",
        type=Number(float, 0.0),
        default=1.0,
        help="with a robust --loss: the weighted residual beyond which a row counts less (m for positions; default 1)",
    )
    parser.add_argument(
        "--position-weight",
        type=Number(float, 0.0),
        default=1.0,
        help="weight per m of a free body's position error (default 1)",
    )
    parser.add_argument(
        "--orientation-weight",
        type=Number(float, 0.0),
        default=1.0,
        help="weight per rad of a free body's orientation error (default 1)",
    )
    parser.add_argument(
        "--joint-weight",
        type=Number(float, 0.0),
        default=1.0,
        help="weight per rad (or m) of another joint's error (default 1)",
    )
    parser.add_argument("--rtol", type=FINITE, default=None, help="relative tolerance of the runs")
    parser.add_argument("--atol", type=FINITE, default=None, help="absolute tolerance of the runs")
    parser.add_argument(
        "--max-evaluations",
        type=COUNT,
        default=30,
        help="residual evaluations at most, each one run per trajectory (default 30)",
    )
    parser.add_argument(
        "--jobs", type=Number(int, 1), default=1, metavar="N", help="worker processes (default 1: this process)"
    )
    parser.add_argument("--backend", default="loky", help="the sweep engine's backend: loky, dask or ray")
    add_plot(parser, "draw each trajectory's measured and fitted positions over time")
    parser.add_argument("--json", action="store_true", help="print the result as JSON")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Run ``contactdiff fit`` from parsed ``args``; return the exit status."""
    from ..scenes.scene_file import load_source
    from .observation_files import load_observations
    from .problem import fit
    from .recordings import Recording
    from .residuals import ResidualWeights

    if args.plot:
        check_plot_path(args.plot)
    if not args.param and not args.scale:
        raise InvalidInputError("fit: name the parameters to fit with --param NAME (or --scale NAME=PARAMS)")
    scene = load_source(args.scene)
    recordings = [Recording.from_observations(load_observations(path, scene), name=path) for path in args.data]
    if args.window is not None or args.window_stride is not None:
        from .windows import Windows, cut

        if args.window is None:
            raise InvalidInputError("fit: --window-stride needs --window N (the windows' length in samples)")
        windows = Windows(args.window, args.window_stride)
        recordings = [w for rec in recordings for w in cut(rec, windows, scene.model)]
    unknowns = list(args.param) + [_scaled(item, scene) for item in args.scale]
    options = {k: v for k, v in (("rtol", args.rtol), ("atol", args.atol)) if v is not None}
    source = scene if args.jobs == 1 else args.scene
    result = fit(
        source,
        recordings,
        unknowns,
        bounds=_bounds(args.bound),
        state=args.fit_state,
        weights=ResidualWeights(args.position_weight, args.orientation_weight, args.joint_weight),
        policy=args.policy,
        jobs=args.jobs,
        backend=args.backend,
        options=options,
        max_evaluations=args.max_evaluations,
        loss=args.loss,
        f_scale=args.f_scale,
    )
    failed = None
    if args.plot:
        from .plot import plot_fit

        failed = write_output("--plot", args.plot, lambda: plot_fit(result, recordings, args.plot))
    print_flushed(json.dumps(result.to_dict(), indent=2) if args.json else format_result(result))
    raise_failures([failed])
    return 0


def _scaled(item: str, scene):
    from .parameters import Scaled

    name, members = assignment(item, "--scale", "NAME=PARAM,PARAM,...")
    names = [m.strip() for m in members.split(",") if m.strip()]
    values = scene.parameter_values(names)
    return Scaled(name, dict(zip(names, (float(v) for v in values))))


def _bounds(items: list[str]) -> dict:
    out = {}
    for item in items:
        name, text = assignment(item, "--bound", "NAME=LO:HI")
        try:
            lo, hi = (float(x) for x in text.split(":"))
        except ValueError:
            raise InvalidInputError(f"--bound {name}: give LO:HI as two numbers, got {text!r}") from None
        out[name] = (lo, hi)
    return out


def format_result(result: FitResult) -> str:
    """The fitted values, the cost, the iterations and each trajectory's residual and verdict."""
    lines = [
        result.table(),
        "",
        f"cost {result.start_cost:.6g} -> {result.cost:.6g} in {result.iterations} iterations "
        f"({result.evaluations} evaluations, {result.wall_time:.1f} s): {result.message}",
    ]
    if result.rank_deficient:
        lines.append("some unknowns are not identifiable from these data (standard error inf)")
    if result.failed_trials:
        lines.append(
            f"{len(result.failed_trials)} trial values rejected because a run failed; the first: "
            f"{result.failed_trials[0]}"
        )
    lines.append("")
    for r in result.recordings:
        verdict = (
            "differentiable"
            if r.differentiable
            else "NOT differentiable (" + ", ".join(f"{k} x{v}" for k, v in r.nonsmooth.items()) + ")"
        )
        lines.append(
            f"{r.name}: rms residual {r.rms:.4g}, {r.events} events, {verdict}" + (", excluded" if r.excluded else "")
        )
    return "\n".join(lines)


__all__ = ["add_parser", "run", "format_result"]
