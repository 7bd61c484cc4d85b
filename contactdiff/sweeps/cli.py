"""``contactdiff sweep SCENE ...``: the command line of `contactdiff.sweep`.

    contactdiff sweep SCENE (--grid NAME=VALUES ... | --list NAME=V,V,... ... |
                             --random NAME=DIST ... --samples N [--seed S] | --points FILE)
                      [--set NAME=VALUE ...] [--job JOB] [--t-final T] [--rtol R] [--atol A]
                      [--backend loky|dask|ray] [--jobs N] [--scheduler ADDRESS]
                      [--out results.jsonl] [--plot out.png] [--json]

`add_parser` adds the subcommand to the ``contactdiff`` parser; `run` is its action.
"""

from __future__ import annotations

import argparse
import json
import sys
import warnings
from collections.abc import Collection
from pathlib import Path
from typing import TYPE_CHECKING

from ..cli_args import (
    COUNT,
    FINITE,
    SEED,
    Number,
    add_plot,
    assignment,
    check_plot_path,
    print_flushed,
    raise_failures,
    write_output,
)
from ..errors import InvalidInputError, ModelLoadError, OutputFileError

if TYPE_CHECKING:
    from .rows import SweepResult

TABLE_ROWS = 200
"""Rows printed as text (every row is in --json and --out)."""


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Add ``sweep`` to the ``contactdiff`` subcommands ``sub``."""
    from .engines import Backend
    from .jobs import JobKind
    from .points import DISTRIBUTIONS, MAX_POINTS
    from .quantities import OPTIONS

    parser = sub.add_parser(
        "sweep",
        help="one scene over many points (grid, list, random), one row per point, on many cores",
        description="Run a job (a simulation, its Jacobians, the order gap, a stride search, or your own "
        "module:function) at every point of a grid, a list or seeded random samples of initial "
        "coordinates (q:JOINT), velocities (v:JOINT), scene parameters (kind:target:field), run "
        f"options ({', '.join(OPTIONS)}) or a scene factory's arguments (arg:NAME); one row "
        "per point, on local processes, a Dask cluster or Ray.",
    )
    parser.add_argument(
        "scene", metavar="SCENE", help="scene name or TOML path, robot name, or module:function returning a Scene"
    )
    points = parser.add_argument_group("points (one kind per sweep; names are quantities, see docs/sweep.md)")
    points.add_argument(
        "--grid",
        action="append",
        default=[],
        metavar="NAME=VALUES",
        help="a grid axis: values a,b,c or a range lo:hi:n, n a positive integer (repeatable: "
        f"every combination, at most {MAX_POINTS:,} points in all)",
    )
    points.add_argument(
        "--list",
        action="append",
        default=[],
        metavar="NAME=V,V,...",
        help="explicit points: the lists of all --list are zipped (equal lengths)",
    )
    points.add_argument(
        "--random",
        action="append",
        default=[],
        metavar="NAME=DIST",
        help=f"random samples, DIST {' or '.join(f'{d}:A:B' for d in DISTRIBUTIONS)} "
        "(uniform low:high, normal mean:std)",
    )
    points.add_argument("--samples", type=Number(int, 1), default=None, help="number of random samples")
    points.add_argument("--seed", type=SEED, default=0, help="seed of the random samples (default 0)")
    points.add_argument("--points", metavar="FILE", help="explicit points from a JSON list of objects or JSON Lines")
    points.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="a quantity fixed at one value for every point, a number where the text is one (repeatable)",
    )
    job = parser.add_argument_group("job")
    job.add_argument(
        "--job",
        default=JobKind.SIMULATE.value,
        metavar="JOB",
        help=f"{', '.join(JobKind)}, or module:function taking (scene, point) and returning a dict (default simulate)",
    )
    job.add_argument("--t-final", type=FINITE, default=None, help="final time (s) of every run, unless swept")
    job.add_argument("--rtol", type=FINITE, default=None, help="relative tolerance (default: the job's)")
    job.add_argument("--atol", type=FINITE, default=None, help="absolute tolerance (m, rad, m/s; default: the job's)")
    job.add_argument("--method", default=None, help="stepper (default: the job's)")
    job.add_argument("--max-steps", type=COUNT, default=None, help="step budget of each run")
    job.add_argument(
        "--param",
        action="append",
        default=[],
        metavar="NAME",
        help="jacobian job: also differentiate in this scene parameter (repeatable; 'all')",
    )
    job.add_argument("--contacts", metavar="A,B", help="order-gap job: only this pair of contacts")
    job.add_argument("--foot", help="stride job: the contact whose touchdowns define the stride")
    job.add_argument("--newton", type=COUNT, default=None, metavar="N", help="stride job: Newton iterations")
    engine = parser.add_argument_group("engine")
    engine.add_argument(
        "--backend", default=Backend.LOKY.value, help=f"{', '.join(Backend)} (default loky: local processes, no server)"
    )
    engine.add_argument(
        "--jobs",
        type=Number(int, 1),
        default=None,
        metavar="N",
        help="worker processes (default: one per core; 1 runs in this process)",
    )
    engine.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="dask: scheduler address (tcp://host:8786); ray: cluster address (auto); default: a local cluster",
    )
    output = parser.add_argument_group("output")
    output.add_argument(
        "--out",
        metavar="FILE",
        help="results file, .jsonl or .csv, written as runs finish; run again with the same "
        "file to skip the points already done",
    )
    output.add_argument("--retry-failed", action="store_true", help="with --out: run failed points again")
    add_plot(output, "draw one output over a 1-D (line) or 2-D (heatmap) sweep")
    output.add_argument("--plot-output", metavar="NAME", help="the output to plot (default: the job's)")
    output.add_argument("--json", action="store_true", help="print every row as JSON")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Run ``contactdiff sweep`` from parsed ``args``; return the exit status."""
    from .runner import DamagedRowsWarning, sweep

    if args.plot:
        check_plot_path(args.plot)
    options = {
        k: v
        for k, v in (("rtol", args.rtol), ("atol", args.atol), ("method", args.method), ("max_steps", args.max_steps))
        if v is not None
    }
    job_options = {
        k: v
        for k, v in (
            ("parameters", args.param or None),
            ("contacts", args.contacts),
            ("foot", args.foot),
            ("iterations", args.newton),
        )
        if v is not None
    }
    # option: its file's failed write, reported once the rows are printed
    failures: dict[str, OutputFileError | None] = {}
    with warnings.catch_warnings():
        warnings.simplefilter("always", DamagedRowsWarning)
        warnings.showwarning = _warning_line
        try:
            result = sweep(
                args.scene,
                _points(args),
                args.job,
                t_final=args.t_final,
                options=options,
                job_options=job_options,
                fixed=_fixed(args.set),
                backend=args.backend,
                n_jobs=args.jobs,
                scheduler=args.scheduler,
                out=args.out,
                retry_failed=args.retry_failed,
            )
        except OutputFileError as exc:
            if exc.result is None:
                raise
            result = exc.result  # every point ran; the results file failed on the way
            failures["--out"] = exc
    if args.plot:
        failures["--plot"] = write_output("--plot", args.plot, lambda: result.plot(args.plot, args.plot_output))
    if args.json:
        print_flushed(
            json.dumps(
                {
                    "names": list(result.names),
                    "points": len(result),
                    "skipped": result.skipped,
                    "failed": len(result.failed),
                    "wall_time": result.wall_time,
                    "rows": result.to_dicts(),
                },
                indent=2,
            )
        )
    else:
        print_flushed(format_result(result, args, failed={k for k, v in failures.items() if v}))
    raise_failures(failures.values())
    return 0


def _warning_line(message, category, *_args, **_kwargs) -> None:
    """Print a warning of the sweep (damaged lines of a results file) as one line on stderr."""
    print(f"contactdiff sweep: warning: {message}", file=sys.stderr, flush=True)


def _points(args):
    from .points import point_list, random_points

    kinds = [
        flag
        for flag, given in (
            ("--grid", args.grid),
            ("--list", args.list),
            ("--random", args.random),
            ("--points", args.points),
        )
        if given
    ]
    if len(kinds) != 1:
        raise InvalidInputError(
            "sweep: give the points one way: --grid, --list, --random or --points"
            + (f" (got {' and '.join(kinds)})" if kinds else "")
        )
    if (args.samples is not None) != bool(args.random):
        raise InvalidInputError("sweep: --random and --samples N go together")
    if args.grid:
        return _assignments(args.grid, "--grid")
    if args.list:
        return point_list(_assignments(args.list, "--list"))
    if args.random:
        return random_points(_assignments(args.random, "--random"), args.samples, args.seed)
    return point_list(_read_points(args.points))


def _assignments(items: list[str], flag: str) -> dict[str, str]:
    """``NAME=TEXT`` items as ``{name: text}`` (the text is parsed by the points module)."""
    out = {}
    for item in items:
        name, text = assignment(item, flag, "NAME=VALUES")
        if name in out:
            raise InvalidInputError(f"{flag} names {name!r} twice")
        out[name] = text
    return out


def _fixed(items: list[str]) -> dict:
    """``--set NAME=VALUE`` items as ``{name: value}``, the text read as a number where it is one."""
    from .points import parse_value

    return {name: parse_value(name, text) for name, text in _assignments(items, "--set").items()}


def _read_points(path: str) -> list:
    try:
        text = Path(path).read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise ModelLoadError(f"cannot read --points {path!r}: {exc}") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError:
        try:
            data = [json.loads(line) for line in text.splitlines() if line.strip()]
        except json.JSONDecodeError as exc:
            raise ModelLoadError(f"--points {path!r} is neither a JSON list nor JSON Lines: {exc}") from None
    if not isinstance(data, list):
        raise InvalidInputError(
            f"--points {path!r} must hold a list of objects (name: value), got {type(data).__name__}"
        )
    return data


def format_result(result: SweepResult, args: argparse.Namespace, failed: Collection[str] = frozenset()) -> str:
    """The rows as a text table: the point's values, the plotted (or job's) output, the
    error; and the files written (but those of the options in ``failed``)."""
    output = args.plot_output or result.default_output
    columns = list(result.names) + ([output] if output and any(output in r.outputs for r in result) else [])
    cells = [[_cell(r.to_dict().get(c)) for c in columns] + [r.error.kind if r.error else ""] for r in result]
    header = columns + ["error"]
    widths = [max(len(h), *(len(c[k]) for c in cells)) for k, h in enumerate(header)]
    lines = [
        f"sweep of {args.scene}: {len(result)} points, {len(result.failed)} failed"
        + (f", {result.skipped} read back from {args.out}" if result.skipped else "")
        + f", {result.wall_time:.2f} s",
        "",
        "  " + "  ".join(h.ljust(w) for h, w in zip(header, widths)),
    ]
    lines += ["  " + "  ".join(c.ljust(w) for c, w in zip(row, widths)) for row in cells[:TABLE_ROWS]]
    if len(cells) > TABLE_ROWS:
        lines.append(f"  ... {len(cells) - TABLE_ROWS} more rows (--json, --out)")
    for r in result.failed[:3]:
        assert r.error is not None  # a failed row has its error
        lines.append(f"point #{r.index} failed: {r.error.kind}: {r.error.message}")
    if args.out and "--out" not in failed:
        lines.append(f"rows written to {args.out}")
    if args.plot and "--plot" not in failed:
        lines.append(f"plot written to {args.plot}")
    return "\n".join(lines)


def _cell(value) -> str:
    if isinstance(value, float):
        return f"{value:.6g}"
    return "-" if value is None else str(value)


__all__ = ["add_parser", "run", "format_result"]
