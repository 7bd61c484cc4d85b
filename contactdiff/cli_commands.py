"""What the ``contactdiff`` commands check, simulate, bench and stride run once their
arguments are parsed (`contactdiff.cli` builds the parser and maps each command to
one of these): each takes the parsed arguments and returns the exit status."""

from __future__ import annotations

import json

from .cli_args import assignment, check_plot_path, raise_failures, write_output
from .cli_args import print_flushed as _print
from .errors import InvalidInputError, check_output_file
from .progress_bar import ProgressBar


def run_stride(args) -> int:
    """``contactdiff stride``: a periodic gait's search from the parsed arguments; its report or JSON."""
    from .analysis.gait import find_periodic_gait

    scene = _scene_from_args(args)
    neutral = args.neutral
    if neutral is not None and neutral.strip().lower() == "none":
        neutral = ""
    with ProgressBar("stride search", None) as bar:
        gait = find_periodic_gait(
            scene,
            args.foot,
            t=args.t0,
            iterations=args.newton,
            tol=args.tol,
            neutral=neutral,
            period=args.period,
            t_max=args.t_max,
            min_stride=args.min_stride,
            min_flight=args.min_flight,
            warmup=args.warmup,
            method=args.method,
            rtol=args.rtol,
            atol=args.atol,
            progress=bar,
        )
    _print(json.dumps(gait.to_dict(), indent=2) if args.json else gait.format())
    return 0


def run_bench(args) -> int:
    """``contactdiff bench``: the benchmark from the parsed arguments."""
    from .bench.runner import run_bench

    if args.speed:
        from .bench.speed import run_speed

        report = run_speed(args.scenes, t_final=args.t_final, repeats=args.repeats, memory_seconds=args.memory)
        _print(json.dumps(report.to_dict(), indent=2) if args.json else report.format())
        return 0

    if args.plot:
        check_plot_path(args.plot)
    result = run_bench(scenes=args.scenes, repeats=args.repeats, quick=args.quick, studies=args.studies)
    failed = None
    if args.plot:
        from .plotting import plot_bench

        failed = write_output("--plot", args.plot, lambda: plot_bench(result, args.plot))
    _print(json.dumps(result.to_dict(), indent=2) if args.json else result.format())
    if args.plot and not args.json and not failed:
        _print(f"plot written to {args.plot}")
    raise_failures([failed])
    return 0


def _check_html_path(path: str) -> None:
    """Refuse a replay that cannot be written, before any work is done: no meshcat,
    a folder that does not exist or a folder as the file."""
    from .replay import require_meshcat

    require_meshcat()
    check_output_file("--html", path, "replay.html")


def _scene_from_args(args):
    """The scene of ``args.source`` (with ``--feet``, ``--floating-base``) with the
    initial state changed by ``--q`` / ``--v``."""
    from .scenes.scene_file import load_source

    scene = load_source(args.source, floating_base=args.floating_base, feet=args.feet)
    q0, v0 = _assignments(getattr(args, "q", []), "--q"), _assignments(getattr(args, "v", []), "--v")
    if q0 or v0:
        scene = scene.with_state(q0 or None, v0 or None)
    return scene


def _assignments(items: list[str], flag: str) -> dict:
    out = {}
    for item in items:
        name, value = assignment(item, flag, "JOINT=VALUE")
        try:
            numbers = [float(x) for x in value.split(",")]
        except ValueError:
            raise InvalidInputError(f"{flag} {name}: value must be numbers, got {value!r}") from None
        out[name] = numbers[0] if len(numbers) == 1 else numbers
    return out


def run_simulate(args) -> int:
    """``contactdiff simulate``: one run from the parsed arguments; its text, JSON, plot or replay."""
    from .integration.hybrid import simulate

    if args.plot:
        check_plot_path(args.plot)
    if args.html:
        _check_html_path(args.html)
    scene = _scene_from_args(args)
    if args.html:  # a bad package folder or a mesh found nowhere is refused before the run
        import warnings

        from .model.mjcf import MJCFWarning
        from .replay_geometry import visual_model

        with warnings.catch_warnings():  # the replay itself says what it draws, once
            warnings.simplefilter("ignore", MJCFWarning)
            visual_model(scene.robot, args.package_dir)
    if "list" in args.param:
        if args.json:
            from .jsonable import to_jsonable
            from .model.parameters import parameter_table

            _print(json.dumps(to_jsonable(parameter_table(scene)), indent=2))
        else:
            _print("\n".join(scene.parameter_names()))
        return 0
    parameters = scene.parameter_names() if "all" in args.param else list(args.param)
    with ProgressBar(f"simulate {scene.name}", (0.0, args.t_final)) as bar:
        traj = simulate(
            scene,
            args.t_final,
            method=args.method,
            rtol=args.rtol,
            atol=args.atol,
            jacobian=args.jacobian,
            jacobian_error=args.jacobian_error,
            max_steps=args.max_steps,
            max_events=args.max_events,
            zeno_speed=args.zeno_speed,
            grazing_speed=args.grazing_speed,
            grazing_gap=args.grazing_gap,
            on_grazing=args.on_grazing,
            progress=bar,
            dense=bool(args.plot or args.html),  # plot and replay sample states between events
            parameters=parameters,
        )
    plotted = replayed = None  # a failed write, reported once the run is printed
    if args.plot:
        from .plotting import plot_gait, plot_gaps

        # floating base: contact timeline, base height and attitude; else contact gaps
        plot = plot_gait if scene.robot.floating_base else plot_gaps
        plotted = write_output("--plot", args.plot, lambda: plot(traj, scene, args.plot))
    if args.html:
        replayed = write_output(
            "--html", args.html, lambda: traj.to_html(args.html, scene, fps=args.fps, package_dirs=args.package_dir)
        )
    if args.json:
        _print(json.dumps(traj.summary(), indent=2))
    else:
        _print(traj.format(scene))
        if args.plot and not plotted:
            _print(f"plot written to {args.plot}")
        if args.html and not replayed:
            _print(f"replay written to {args.html}")
    raise_failures([plotted, replayed])
    return 0


def run_check(args) -> int:
    """``contactdiff check``: the limb-decoupling check from the parsed arguments (with
    ``--armature``, beside the check without)."""
    from .analysis.decoupling import check_decoupling

    scene = _scene_from_args(args)
    options = dict(samples=args.samples, seed=args.seed, tol=args.tol)
    report = check_decoupling(scene, armature=args.armature, **options)
    baseline = check_decoupling(scene, **options) if args.armature else None
    if args.json:
        out = report.to_dict()
        if baseline is not None:
            out["without_armature"] = baseline.to_dict()
        _print(json.dumps(out, indent=2))
        return 0
    _print(report.format())
    if baseline is not None and report.verdict is not None:
        _print(
            f"\narmature {args.armature:g}: max coupling {baseline.max_coupling:.3e} -> "
            f"{report.max_coupling:.3e}; verdict {baseline.verdict} -> {report.verdict}"
        )
    return 0
