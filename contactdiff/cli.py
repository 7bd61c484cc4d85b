"""The ``contactdiff`` command line.

    contactdiff check SOURCE [--samples N] [--seed S] [--armature X] [--tol T] [--json]
    contactdiff simulate SOURCE --t-final T [--q JOINT=VALUE ...] [--v JOINT=VALUE ...]
                        [--method M] [--rtol R] [--atol A] [--json] [--plot out.png]
    contactdiff stride SOURCE --foot NAME [--newton N] [--warmup SECONDS] [--t0 T] [--period T]
                        [--neutral x,y,yaw] [--min-flight S] [--json]

SOURCE is a scene (TOML path or a name of robots/) or a robot (URDF path or
example-robot-data name; its feet get ground contacts). Errors print one line
and exit with status 2.
"""

from __future__ import annotations

import argparse
import json
import sys

from .errors import ContactDiffError


def _positive_int(text: str) -> int:
    value = int(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {value}")
    return value


def _nonnegative_float(text: str) -> float:
    value = float(text)
    if not value >= 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"must be a finite number >= 0, got {text}")
    return value


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="contactdiff",
        description="Differentiability through contact: check robots for limb decoupling.")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    check = sub.add_parser(
        "check", help="decoupling / orthogonality report of a scene or robot",
        description="Measure how far a scene is from the paper's assumptions: inverse-mass "
                    "coupling of every contact pair, and limbs decoupled through the body.")
    check.add_argument("source", metavar="SOURCE",
                       help="scene (TOML path or robots/ name) or robot (URDF path or "
                            "example-robot-data name such as solo12)")
    check.add_argument("--samples", type=_positive_int, default=20,
                       help="random poses besides the reference (default 20)")
    check.add_argument("--seed", type=int, default=0, help="seed of the random poses (default 0)")
    check.add_argument("--armature", type=_nonnegative_float, default=0.0,
                       help="rotor inertia added to actuated joints, kg m^2; the report "
                            "is compared with the one without it")
    check.add_argument("--tol", type=float, default=1e-9,
                       help="relative size below which a coupling counts as zero (default 1e-9)")
    check.add_argument("--json", action="store_true", help="print the report as JSON")
    check.set_defaults(run=_run_check)

    from .steppers import METHODS

    sim = sub.add_parser(
        "simulate", help="event-driven simulation: events, final state",
        description="Integrate a scene event by event (touchdown, lift-off, bounce) and "
                    "print its events and final state.")
    sim.add_argument("source", metavar="SOURCE", help="scene or robot, as for check")
    sim.add_argument("--t-final", type=float, required=True, help="final time (s)")
    sim.add_argument("--q", action="append", default=[], metavar="JOINT=VALUE",
                     help="initial joint coordinate (repeatable); comma-separated for multi-dof joints")
    sim.add_argument("--v", action="append", default=[], metavar="JOINT=VALUE",
                     help="initial joint velocity (repeatable)")
    sim.add_argument("--method", default="auto", choices=("auto",) + tuple(METHODS),
                     help="stepper: auto (DOP853, switching to Radau while stiff; the default), "
                          "or one used throughout")
    sim.add_argument("--rtol", type=float, default=1e-8, help="relative tolerance (default 1e-8)")
    sim.add_argument("--atol", type=float, default=1e-10, help="absolute tolerance (default 1e-10)")
    sim.add_argument("--jacobian", action="store_true",
                     help="also compute the flow Jacobian d x(T)/d x0 and every saltation matrix")
    sim.add_argument("--json", action="store_true", help="print the trajectory summary as JSON")
    sim.add_argument("--plot", metavar="PNG",
                     help="draw contact gaps over time with events marked; for a floating base, "
                          "the contact timeline and the base height, roll and pitch")
    sim.set_defaults(run=_run_simulate)

    bench = sub.add_parser(
        "bench", help="error against run time of each method and baseline",
        description="Measure final-state and event-time error against run time for contactdiff "
                    "and its baselines (solve_ivp with events, impulse time stepping) on the "
                    "project's scenes, and the cost of flow Jacobians against finite differences.")
    bench.add_argument("--scenes", nargs="+", metavar="SCENE", help="scenes to run (default all)")
    bench.add_argument("--quick", action="store_true", help="a tiny sweep of a few seconds (tests, CI)")
    bench.add_argument("--repeats", type=int, default=3, help="timing repeats, median kept (default 3)")
    bench.add_argument("--json", action="store_true", help="print the results as JSON")
    bench.add_argument("--plot", metavar="PNG", help="write the log-log error vs run time plot")
    bench.add_argument("--studies", action="store_true",
                       help="also run the stiff and extreme-case studies and measure what a scene "
                            "costs beyond its needs (with --quick: seconds; without: minutes)")
    bench.set_defaults(run=_run_bench)

    stride = sub.add_parser(
        "stride", help="gait stability: stride map, periodic gait, Floquet multipliers",
        description="Stride map of a foot (the state just before one of its touchdowns to the state "
                    "just before the next) and its Jacobian; Newton iterations towards a periodic "
                    "gait; the Floquet multipliers (eigenvalues in section coordinates, neutral moves "
                    "removed). The start is the scene's initial state carried to the foot's first "
                    "touchdown.")
    stride.add_argument("source", metavar="SOURCE", help="scene or robot, as for check")
    stride.add_argument("--foot", required=True, help="contact whose touchdowns define the section")
    stride.add_argument("--newton", type=_positive_int, default=0, metavar="N",
                        help="Newton iterations towards a periodic gait (default 0: one stride)")
    stride.add_argument("--tol", type=_nonnegative_float, default=1e-9,
                        help="residual at which Newton stops (default 1e-9); it also stops where the "
                             "residual is within the map's resolution, twice its change when the stride "
                             "is computed again at 10 times tighter tolerances")
    stride.add_argument("--t0", type=float, default=0.0, help="start time (s, default 0)")
    stride.add_argument("--t-max", type=float, default=10.0, help="longest stride (s, default 10)")
    stride.add_argument("--min-stride", type=float, default=None,
                        help="shortest stride (s): earlier re-landings of the foot are skipped "
                             "(default: half the clock period of a clock-driven scene, else 0)")
    stride.add_argument("--min-flight", type=float, default=None,
                        help="shortest flight (s) before a touchdown that ends a stride: re-landings of "
                             "impact cascades are skipped (default: 5 %% of the clock period, else 0)")
    stride.add_argument("--warmup", type=float, default=0.0, metavar="SECONDS",
                        help="simulate this long before the search: a stable gait settles on its own "
                             "(default 0)")
    stride.add_argument("--period", type=float, default=None,
                        help="clock period (s) of a clock-driven scene (default: from its controller)")
    stride.add_argument("--neutral", default=None, metavar="MOVES",
                        help="neutral moves removed, comma-separated from x, y, yaw, or 'none' "
                             "(default: those the scene admits)")
    stride.add_argument("--q", action="append", default=[], metavar="JOINT=VALUE",
                        help="initial joint coordinate (repeatable)")
    stride.add_argument("--v", action="append", default=[], metavar="JOINT=VALUE",
                        help="initial joint velocity (repeatable)")
    stride.add_argument("--method", default="DOP853", choices=METHODS, help="stepper (default DOP853)")
    stride.add_argument("--rtol", type=float, default=1e-10, help="relative tolerance (default 1e-10)")
    stride.add_argument("--atol", type=float, default=1e-12, help="absolute tolerance (default 1e-12)")
    stride.add_argument("--json", action="store_true", help="print the result as JSON")
    stride.set_defaults(run=_run_stride)
    return parser


def _run_stride(args) -> int:
    from .stride import find_periodic_gait

    scene = _scene_from_args(args)
    neutral = args.neutral
    if neutral is not None and neutral.strip().lower() == "none":
        neutral = ""
    gait = find_periodic_gait(scene, args.foot, t=args.t0, iterations=args.newton, tol=args.tol,
                              neutral=neutral, period=args.period, t_max=args.t_max,
                              min_stride=args.min_stride, min_flight=args.min_flight, warmup=args.warmup,
                              method=args.method, rtol=args.rtol, atol=args.atol)
    print(json.dumps(gait.to_dict(), indent=2) if args.json else gait.format())
    return 0


def _run_bench(args) -> int:
    from .bench import run_bench

    result = run_bench(scenes=args.scenes, repeats=args.repeats, quick=args.quick, studies=args.studies)
    if args.plot:
        result.plot(args.plot)
    print(json.dumps(result.to_dict(), indent=2) if args.json else result.format())
    if args.plot and not args.json:
        print(f"plot written to {args.plot}")
    return 0


def _scene_from_args(args):
    """The scene of ``args.source`` with the initial state changed by ``--q`` / ``--v``."""
    from .scene import load_source

    scene = load_source(args.source)
    q0, v0 = _assignments(args.q, "--q"), _assignments(args.v, "--v")
    if q0 or v0:
        scene = scene.with_state(q0 or None, v0 or None)
    return scene


def _assignments(items: list[str], flag: str) -> dict:
    from .errors import InvalidInputError

    out = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep or not name:
            raise InvalidInputError(f"{flag} takes JOINT=VALUE, got {item!r}")
        try:
            numbers = [float(x) for x in value.split(",")]
        except ValueError:
            raise InvalidInputError(f"{flag} {name}: value must be numbers, got {value!r}") from None
        out[name] = numbers[0] if len(numbers) == 1 else numbers
    return out


def _run_simulate(args) -> int:
    from .integrator import simulate

    scene = _scene_from_args(args)
    traj = simulate(scene, args.t_final, method=args.method, rtol=args.rtol, atol=args.atol,
                    jacobian=args.jacobian)
    if args.plot:
        from .plotting import plot_gait, plot_gaps

        # floating base: contact timeline, base height and attitude; else contact gaps
        (plot_gait if scene.robot.floating_base else plot_gaps)(traj, scene, args.plot)
    if args.json:
        print(json.dumps(traj.summary(), indent=2))
        return 0
    print(_format_trajectory(traj, scene))
    if args.plot:
        print(f"plot written to {args.plot}")
    return 0


def _format_trajectory(traj, scene) -> str:
    lines = [f"simulation of {traj.scene_name} from t = {traj.t0:g} to {traj.t:g} s",
             f"{len(traj.events)} events", ""]
    if traj.events:
        lines.append(f"  {'t (s)':>18}  {'kind':<9}  {'contacts':<28}  {'simult.':<7}  mode after")
        for e in traj.events[:200]:
            lines.append(f"  {e.t:18.12f}  {e.kind:<9}  {', '.join(e.contacts):<28}  "
                         f"{'yes' if e.simultaneous else 'no':<7}  {', '.join(e.mode_after) or '(flight)'}")
        if len(traj.events) > 200:
            lines.append(f"  ... {len(traj.events) - 200} more (see --json)")
        lines.append("")
    lines.append("final state")
    names = scene.robot.tangent_names()
    for label, x in zip(scene.robot.configuration_names(), traj.q):
        lines.append(f"  q {label:<24} {x: .12g}")
    for label, x in zip(names, traj.v):
        lines.append(f"  v {label:<24} {x: .12g}")
    lines.append("")
    s = traj.stats
    lines.append(f"steps {s['steps']} (rejected {s['rejected_steps']}), dynamics evaluations "
                 f"{s['dynamics_evaluations']}, largest active-gap drift {traj.max_drift:.2e} m")
    if s.get("steps_by_method"):
        lines.append(f"method {s['method']}: " + ", ".join(f"{m} {n} steps" for m, n in s["steps_by_method"].items()))
    lines += [f"note: {n}" for n in traj.notes]
    if traj.jacobian is not None:
        lines += [""] + _format_jacobian(traj, scene)
    return "\n".join(lines)


def _format_jacobian(traj, scene) -> list[str]:
    import numpy as np

    J = traj.jacobian
    names = scene.robot.tangent_names()
    labels = [f"dq[{n}]" for n in names] + [f"dv[{n}]" for n in names]
    sv = np.linalg.svd(J, compute_uv=False)
    lines = [f"flow Jacobian d x({traj.t:g}) / d x({traj.t0:g}): {J.shape[0]} x {J.shape[1]}, tangent space",
             f"  2-norm {sv[0]:.6g}, condition number {sv[0] / sv[-1] if sv[-1] > 0 else float('inf'):.6g}",
             "  largest entries:"]
    order = np.argsort(-np.abs(J), axis=None)[:6]
    for flat in order:
        i, j = divmod(int(flat), J.shape[1])
        lines.append(f"    d {labels[i]:<28} / d {labels[j]:<28} = {J[i, j]: .6g}")
    lines.append("  events:")
    for e in traj.events:
        verdict = "differentiable" if e.differentiable else "NOT differentiable (piecewise-linear derivative)"
        lines.append(f"    t = {e.t:.12f}  {e.kind:<9} {', '.join(e.contacts):<24} {verdict}")
    lines.append("  the trajectory is " + ("differentiable" if traj.differentiable else
                                          "NOT differentiable at some event (see notes)"))
    return lines


def _run_check(args) -> int:
    from .checks import check_decoupling
    from .scene import load_source

    scene = load_source(args.source)
    options = dict(samples=args.samples, seed=args.seed, tol=args.tol)
    report = check_decoupling(scene, armature=args.armature, **options)
    baseline = check_decoupling(scene, **options) if args.armature else None
    if args.json:
        out = report.to_dict()
        if baseline is not None:
            out["without_armature"] = baseline.to_dict()
        print(json.dumps(out, indent=2))
        return 0
    print(report.format())
    if baseline is not None:
        print(f"\narmature {args.armature:g}: max coupling {baseline.max_coupling:.3e} -> "
              f"{report.max_coupling:.3e}; verdict {baseline.verdict} -> {report.verdict}")
    return 0


def main(argv: list[str] | None = None) -> int:
    """Run the command line; return the exit status (0 ok, 2 bad input or model)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.run(args)
    except ContactDiffError as exc:
        print(f"contactdiff {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
