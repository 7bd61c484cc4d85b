"""The ``contactdiff`` command line.

    contactdiff check SOURCE [--samples N] [--seed S] [--armature X] [--tol T] [--json]
    contactdiff simulate SOURCE --t-final T [--q JOINT=VALUE ...] [--v JOINT=VALUE ...]
                        [--method M] [--rtol R] [--atol A] [--json] [--plot out.png] [--html out.html]
    contactdiff stride SOURCE --foot NAME [--newton N] [--warmup SECONDS] [--t0 T] [--period T]
                        [--neutral x,y,yaw] [--min-flight S] [--json]
    contactdiff sweep SCENE --grid NAME=lo:hi:n ... [--job JOB] [--t-final T] [--backend B] [--out FILE]
                        (contactdiff.sweeps.cli)
    contactdiff fit SCENE DATA ... --param NAME ... [--jobs N] [--json] [--plot out.png]
                        (contactdiff.fit.cli)

SOURCE is a scene (TOML path or a name of robots/) or a robot (URDF path or
example-robot-data name; its feet get ground contacts, chosen automatically or
with --feet; --floating-base gives a URDF path a free-flyer base). Errors print
one line and exit with status 2; Ctrl-C exits with 130; a closed output pipe
ends the command quietly. Long runs draw a progress bar on stderr (a terminal,
`contactdiff.progress_bar`). What each command runs is in `contactdiff.cli_commands`.
"""

from __future__ import annotations

import argparse
import os
import sys

from .cli_args import (
    COUNT,
    FINITE,
    NONNEGATIVE,
    POSITIVE,
    SEED,
    Number,
    add_plot,
)
from .cli_commands import run_bench, run_check, run_simulate, run_stride
from .errors import ContactDiffError


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors: the message and where to read more, no usage block."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _add_source(parser: argparse.ArgumentParser) -> None:
    """SOURCE and the options that say how a robot stands on its feet."""
    parser.add_argument(
        "source",
        metavar="SOURCE",
        help="scene (TOML path or robots/ name) or robot (URDF path or example-robot-data name such as solo12)",
    )
    parser.add_argument(
        "--feet",
        metavar="FRAME,FRAME,...",
        help="a robot's foot frames, chosen by hand (default: the lowest end frames at its reference pose)",
    )
    parser.add_argument(
        "--floating-base",
        action="store_true",
        default=None,
        help="load a URDF path with a free-flyer base (its feet are then found)",
    )


def build_parser() -> argparse.ArgumentParser:
    """The ``contactdiff`` argument parser: subcommands check, simulate, bench, stride and sweep."""
    parser = _Parser(
        prog="contactdiff", description="Differentiability through contact: check robots for limb decoupling."
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    check = sub.add_parser(
        "check",
        help="decoupling / orthogonality report of a scene or robot",
        description="Measure how far a scene is from the paper's assumptions: inverse-mass "
        "coupling of every contact pair, and limbs decoupled through the body.",
    )
    _add_source(check)
    check.add_argument("--samples", type=COUNT, default=20, help="random poses besides the reference (default 20)")
    check.add_argument("--seed", type=SEED, default=0, help="seed of the random poses, >= 0 (default 0)")
    check.add_argument(
        "--armature",
        type=NONNEGATIVE,
        default=0.0,
        help="rotor inertia added to actuated joints, kg m^2; the report is compared with the one without it",
    )
    check.add_argument(
        "--tol", type=POSITIVE, default=1e-9, help="relative size below which a coupling counts as zero (default 1e-9)"
    )
    check.add_argument("--json", action="store_true", help="print the report as JSON")
    check.set_defaults(run=run_check)

    from .analysis.gait.stride import STRIDE_ATOL, STRIDE_METHOD, STRIDE_RTOL
    from .integration.options import (
        ATOL_MAX,
        AUTO,
        RTOL_MAX,
        RTOL_MIN,
        SIMULATE_METHODS,
        JacobianError,
        OnGrazing,
        SimulateOptions,
    )
    from .ode.factory import METHODS
    from .replay import DEFAULT_FPS

    sim = sub.add_parser(
        "simulate",
        help="event-driven simulation: events, final state",
        description="Integrate a scene event by event (touchdown, lift-off, bounce) and "
        "print its events and final state.",
    )
    _add_source(sim)
    sim.add_argument("--t-final", type=FINITE, required=True, help="final time (s)")
    sim.add_argument(
        "--q",
        action="append",
        default=[],
        metavar="JOINT=VALUE",
        help="initial joint coordinate (repeatable); comma-separated for multi-dof joints",
    )
    sim.add_argument(
        "--v", action="append", default=[], metavar="JOINT=VALUE", help="initial joint velocity (repeatable)"
    )
    defaults = SimulateOptions()  # every default below is the options' own
    sim.add_argument(
        "--method",
        default=defaults.method,
        choices=SIMULATE_METHODS,
        help=f"stepper: {AUTO} (DOP853, switching to Radau while stiff; the default), or one used throughout",
    )
    sim.add_argument(
        "--rtol",
        type=FINITE,
        default=defaults.rtol,
        help=f"relative tolerance in [{RTOL_MIN:.3g}, {RTOL_MAX:g}] (default {defaults.rtol:g})",
    )
    sim.add_argument(
        "--atol",
        type=FINITE,
        default=defaults.atol,
        help=f"absolute tolerance in (0, {ATOL_MAX:g}] (m, rad, m/s; default {defaults.atol:g})",
    )
    sim.add_argument(
        "--max-steps",
        type=COUNT,
        default=defaults.max_steps,
        help="step budget: a run needing more accepted steps stops with an error "
        f"(default {defaults.max_steps}, at least 1)",
    )
    sim.add_argument(
        "--max-events",
        type=COUNT,
        default=defaults.max_events,
        help=f"event budget: a run with more events stops with an error (default {defaults.max_events})",
    )
    sim.add_argument(
        "--zeno-speed",
        type=FINITE,
        default=defaults.zeno_speed,
        help="a contact closing slower than this (m/s, >= 0) does not bounce: a bounce "
        f"sequence ends there and the contact stays closed (default {defaults.zeno_speed:g})",
    )
    sim.add_argument(
        "--grazing-speed",
        type=FINITE,
        default=defaults.grazing_speed,
        help=f"a touchdown slower than this (m/s, >= 0) is grazing (default {defaults.grazing_speed:g})",
    )
    sim.add_argument(
        "--grazing-gap",
        type=FINITE,
        default=None,
        help="a gap that comes down to within this distance (m, >= 0) of the ground and turns back "
        "up is a near-grazing miss (default 10 (atol + rtol |q|))",
    )
    sim.add_argument(
        "--on-grazing",
        choices=[m.value for m in OnGrazing],
        default=defaults.on_grazing.value,
        help="event: a grazing touchdown is an event, a near-grazing miss a note (the default); "
        "raise: both stop the run with an error",
    )
    sim.add_argument(
        "--jacobian", action="store_true", help="also compute the flow Jacobian d x(T)/d x0 and every saltation matrix"
    )
    sim.add_argument(
        "--jacobian-error",
        choices=[m.value for m in JacobianError],
        default=defaults.jacobian_error.value,
        help="with --jacobian or --param: control: steps chosen from the state's and the Jacobian's "
        "errors (the default); state: from the state's alone (the plain run's steps, cheaper)",
    )
    sim.add_argument(
        "--param",
        action="append",
        default=[],
        metavar="NAME",
        help="differentiate the final state with respect to this scene parameter "
        "(kind:name:field, e.g. body:base_link:mass, contact:FL_FOOT:restitution, "
        "scene:gravity_z; repeatable; 'all' for every parameter of the scene; "
        "'list' prints the names); with --jacobian also the state's flow Jacobian",
    )
    sim.add_argument("--json", action="store_true", help="print the trajectory summary as JSON")
    add_plot(
        sim,
        "draw contact gaps over time with events marked; for a floating base, "
        "the contact timeline and the base height, roll and pitch",
    )
    sim.add_argument(
        "--html",
        metavar="FILE",
        help="write a self-contained HTML page that replays the run in 3-D in a browser, "
        "offline: the robot, its closed contacts, the events on a timeline "
        "(needs meshcat: pip install 'contactdiff[viz]')",
    )
    sim.add_argument(
        "--package-dir",
        action="append",
        default=[],
        metavar="DIR",
        help="with --html: a folder in which the URDF's package://NAME/... meshes are found as "
        "DIR/NAME/... (repeatable; the folders above the URDF are searched too)",
    )
    sim.add_argument(
        "--fps",
        type=POSITIVE,
        default=DEFAULT_FPS,
        help=f"with --html: frames per second of simulated time (default {DEFAULT_FPS:g}; events are frames too)",
    )
    sim.set_defaults(run=run_simulate)

    bench = sub.add_parser(
        "bench",
        help="error against run time of each method and baseline",
        description="Measure final-state and event-time error against run time for contactdiff "
        "and its baselines (solve_ivp with events, impulse time stepping) on the "
        "project's scenes, and the cost of flow Jacobians against finite differences.",
    )
    bench.add_argument(
        "--scenes",
        nargs="+",
        metavar="SCENE",
        help="scenes to run (default all; with --quick: ball and planar_trot_rigid)",
    )
    bench.add_argument(
        "--quick",
        action="store_true",
        help="a tiny sweep of a few seconds (tests, CI): fewer tolerances, and the scenes "
        "ball and planar_trot_rigid unless --scenes names others",
    )
    bench.add_argument("--repeats", type=Number(int, 1), default=3, help="timing repeats, median kept (default 3)")
    bench.add_argument("--json", action="store_true", help="print the results as JSON")
    add_plot(bench, "write the log-log error vs run time plot")
    bench.add_argument(
        "--studies",
        action="store_true",
        help="also run the stiff and extreme-case studies and measure what a scene "
        "costs beyond its needs (with --quick: seconds; without: minutes)",
    )
    bench.add_argument(
        "--speed",
        action="store_true",
        help="instead: time the quadruped trots against real time and against Pinocchio's "
        "own calls (--scenes chooses the trots)",
    )
    bench.add_argument(
        "--t-final",
        type=Number(float, 0.0, strict=True),
        default=3.0,
        help="with --speed: simulated time of each timed run, s (default 3)",
    )
    bench.add_argument(
        "--memory",
        type=Number(float, 0.0, strict=True),
        metavar="SECONDS",
        help="with --speed: also the peak memory of a solo12 trot this long keeping events only",
    )
    bench.set_defaults(run=run_bench)

    stride = sub.add_parser(
        "stride",
        help="gait stability: stride map, periodic gait, Floquet multipliers",
        description="Stride map of a foot (the state just before one of its touchdowns to the state "
        "just before the next) and its Jacobian; Newton iterations towards a periodic "
        "gait; the Floquet multipliers (eigenvalues in section coordinates, neutral moves "
        "removed). The start is the scene's initial state carried to the foot's first "
        "touchdown.",
    )
    _add_source(stride)
    stride.add_argument("--foot", required=True, help="contact whose touchdowns define the section")
    stride.add_argument(
        "--newton",
        type=COUNT,
        default=0,
        metavar="N",
        help="Newton iterations towards a periodic gait (default 0: one stride)",
    )
    stride.add_argument(
        "--tol",
        type=NONNEGATIVE,
        default=1e-9,
        help="residual at which Newton stops (default 1e-9); it also stops where the "
        "residual is within the map's resolution, twice its change when the stride "
        "is computed again at 10 times tighter tolerances",
    )
    stride.add_argument("--t0", type=FINITE, default=0.0, help="start time (s, default 0)")
    stride.add_argument("--t-max", type=FINITE, default=10.0, help="longest stride (s, default 10)")
    stride.add_argument(
        "--min-stride",
        type=FINITE,
        default=None,
        help="shortest stride (s): earlier re-landings of the foot are skipped "
        "(default: half the clock period of a clock-driven scene, else 0)",
    )
    stride.add_argument(
        "--min-flight",
        type=FINITE,
        default=None,
        help="shortest flight (s) before a touchdown that ends a stride: re-landings of "
        "impact cascades are skipped (default: 5 %% of the clock period, else 0)",
    )
    stride.add_argument(
        "--warmup",
        type=FINITE,
        default=0.0,
        metavar="SECONDS",
        help="simulate this long before the search: a stable gait settles on its own (default 0)",
    )
    stride.add_argument(
        "--period",
        type=FINITE,
        default=None,
        help="clock period (s) of a clock-driven scene (default: from its controller)",
    )
    stride.add_argument(
        "--neutral",
        default=None,
        metavar="MOVES",
        help="neutral moves removed, comma-separated from x, y, yaw, or 'none' (default: those the scene admits)",
    )
    stride.add_argument(
        "--q", action="append", default=[], metavar="JOINT=VALUE", help="initial joint coordinate (repeatable)"
    )
    stride.add_argument(
        "--v", action="append", default=[], metavar="JOINT=VALUE", help="initial joint velocity (repeatable)"
    )
    stride.add_argument("--method", default=STRIDE_METHOD, choices=METHODS, help=f"stepper (default {STRIDE_METHOD})")
    stride.add_argument(
        "--rtol", type=FINITE, default=STRIDE_RTOL, help=f"relative tolerance (default {STRIDE_RTOL:g})"
    )
    stride.add_argument(
        "--atol", type=FINITE, default=STRIDE_ATOL, help=f"absolute tolerance (default {STRIDE_ATOL:g})"
    )
    stride.add_argument("--json", action="store_true", help="print the result as JSON")
    stride.set_defaults(run=run_stride)

    from .sweeps.cli import add_parser as add_sweep

    add_sweep(sub)
    from .fit.cli import add_parser as add_fit

    add_fit(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the command line; return the exit status (0 ok, 2 bad input or model,
    130 interrupted, 141 output pipe closed)."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help, or a bad argument (its line is printed)
        return exc.code if isinstance(exc.code, int) else int(exc.code is not None)  # sys.exit's own rule
    try:
        return args.run(args)
    except ContactDiffError as exc:
        print(f"contactdiff {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"\ncontactdiff {args.command}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # the reader went away (| head): say nothing, and keep Python's own flush at
        # exit from raising again on the closed stdout
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
        return 141


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
