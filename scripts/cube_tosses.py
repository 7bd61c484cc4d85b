"""Identify the cube's contact parameters from measured tosses and evaluate them on held-out ones.

Splits the tosses into a training set and a held-out set (upstream's duplicated
recordings on one side), fits the cube's parameters on the training tosses by
least squares with exact derivatives (`contactdiff.fit.fit`, rollouts from three
samples before the cube can first touch), then runs every held-out toss at the
nominal and at the fitted parameters from both published starts and reports
the published metrics (time-averaged position error in % of the edge, rotation
error in degrees: mean ± std and median over tosses), beside the tuned
time-stepping simulators of Acosta, Yang and Posa (their numbers, quoted; fitted
on all tosses, no held-out set). Also: the fit's cost, the exact Jacobian's cost
against finite differences of the same residuals, the wall time per toss, the
tosses whose outcome is not differentiable, and the worst held-out tosses.

    python scripts/cube_tosses.py --tosses ../shared/data/cube_tosses/tosses.npz --train 100
    python scripts/cube_tosses.py --tosses ../shared/data/cube_tosses/tosses.npz --train 100 --window 15
    python scripts/cube_tosses.py --quick          # 2 shipped tosses to fit, 2 held out, 1 evaluation

``--window N`` fits on short windows (multiple shooting, `contactdiff.fit.windows`) instead of
whole tosses: N samples from a free-flight start before each touch, each window's start
velocity fitted with the parameters.
"""

from __future__ import annotations

import argparse
import functools
import json
import statistics
import sys
import time
from collections import Counter
from dataclasses import replace
from pathlib import Path

import numpy as np

import contactdiff as cd
from contactdiff.data.cube_recordings import (
    Start,
    split,
    toss_errors,
    toss_recording,
    toss_windows,
)
from contactdiff.data.cube_tosses import NOMINAL, load_tosses
from contactdiff.data.toss_checks import length_check
from contactdiff.data.toss_evaluation import evaluate_start, start_noise
from contactdiff.fit import Loss, ResidualWeights, Scaled, Windows, fit
from contactdiff.fit.evaluation import StateFit, Task, evaluate
from contactdiff.fit.parameters import FitPlan
from contactdiff.fit.rest import REST_SAMPLES, rest_height
from contactdiff.fit.rollouts import rollout

ANCHORS = {"Drake": (13.5, 8.2, 16.5, 20.0), "Bullet": (14.9, 8.9, 16.5, 20.2), "MuJoCo": (25.1, 10.8, 21.7, 21.4)}
"""Acosta, Yang, Posa (RA-L 2022), tuned on all tosses: position % (mean, std), rotation deg (mean, std)."""

STEPPING_COST = {"MuJoCo": (3.4e-3, 21.9), "Drake": (9e-3, 13.1)}
"""Quoted wall time per toss (s) at a 0.68 ms step and position error (%) of the time-stepping simulators."""


def unknowns(scene, gravity: bool = True, offset: bool = True, inertia: bool = True) -> list:
    """μ and e shared by the eight corners, (unless ``offset`` is False) the board height, (unless
    ``inertia`` is False) a scale of the three moments, and (unless ``gravity`` is False) gravity."""
    moments = {f"body:cube:i{a}{a}": NOMINAL.moment for a in "xyz"}
    return (
        ["group:cube:friction", "group:cube:restitution"]
        + (["group:cube:offset"] if offset else [])
        + ([Scaled("inertia_scale", moments)] if inertia else [])
        + (["scene:gravity_z"] if gravity else [])
    )


def training_recordings(tosses, names, args, scene) -> list:
    """Whole tosses from three samples before touch, or (``--window N``) each toss's windows
    that start in free flight ``--lead`` samples before a touch (`toss_windows`)."""
    if not args.window:
        return [toss_recording(tosses[n], Start.BEFORE_TOUCH) for n in names]
    base = base_parameters(args)
    return [
        w for n in names for w in toss_windows(tosses[n], Windows(args.window), base, lead=args.lead, model=scene.model)
    ]


def base_parameters(args):
    """The cube's parameters the fit starts from: the board at --ground, lengths and g scaled by --length-scale,
    μ, e and the moments from --friction, --restitution and --moment-scale."""
    return replace(
        NOMINAL,
        ground=args.ground,
        edge=NOMINAL.edge * args.length_scale,
        gravity=NOMINAL.gravity * args.length_scale,
        friction=args.friction,
        restitution=args.restitution,
        moment=NOMINAL.moment * args.moment_scale,
    )


def evaluate_held_out(tosses, names, values, jobs, label, options, source=cd.cube_scene) -> dict:
    """Both starts' rollouts of the held-out ``names`` at ``values`` (`evaluate_start`), each
    start's line on stderr as it ends."""
    out = {}
    for start in Start:
        out[start.value] = evaluate_start(tosses, names, values, start, jobs, options, source)
        print(f"{label}, start {start.value}: " + _line(out[start.value]), file=sys.stderr, flush=True)
    return out


def _line(s: dict) -> str:
    if not s.get("tosses"):
        return "no toss finished"
    return (
        f"{s['tosses']} tosses: position {s['position_mean']:.1f} ± {s['position_std']:.1f} % "
        f"(median {s['position_median']:.1f}), rotation {s['rotation_mean']:.1f} ± {s['rotation_std']:.1f} deg "
        f"(median {s['rotation_median']:.1f}); {len(s['failed'])} failed"
    )


def jacobian_cost(recordings, scene, options, parameters, state: StateFit = StateFit.NONE) -> dict:
    """One recording's residuals with their exact Jacobian against the plain run that finite differences
    repeat (forward: n + 1 runs, central: 2n, n the fitted parameters and initial-state offsets of a
    recording), medians over ``recordings`` (run in this process)."""
    plan = FitPlan(scene, parameters)
    values = plan.values(plan.start(scene))
    s = len(state.columns(scene.nv))
    exact, plain = [], []
    for rec in recordings:
        task = Task(0, rec, values, np.zeros(s), state, ResidualWeights(), options)
        t0 = time.perf_counter()
        evaluate(scene, plan.parameters, task)
        exact.append(time.perf_counter() - t0)
        plain.append(rollout(scene, rec, values, options).wall)
    k = len(plan.names) + s
    ratio = statistics.median(e / p for e, p in zip(exact, plain))
    return {
        "unknowns": k,
        "exact_over_plain": ratio,
        "forward_fd_over_plain": k + 1,
        "central_fd_over_plain": 2 * k,
        "exact_median": statistics.median(exact),
        "plain_median": statistics.median(plain),
    }


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tosses", help="a tosses .npz file (default: the 24 shipped with the package)")
    parser.add_argument("--train", type=int, default=100, help="tosses to fit on (default 100)")
    parser.add_argument("--test", type=int, default=None, help="held-out tosses evaluated (default: all the rest)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the split (default 0)")
    parser.add_argument("--max-evaluations", type=int, default=12, help="the fit's evaluations at most")
    parser.add_argument("--jobs", type=int, default=None, help="worker processes (default: one per core)")
    parser.add_argument(
        "--rtol",
        type=float,
        default=1e-6,
        help="the runs' relative tolerance (default 1e-6: the data's noise is ~1e-3 m on 0.1 m)",
    )
    parser.add_argument("--atol", type=float, default=1e-8, help="the runs' absolute tolerance (default 1e-8)")
    parser.add_argument(
        "--window",
        type=int,
        default=0,
        metavar="N",
        help="fit on windows of N samples that start in free flight before each touch, each "
        "window's start velocity fitted too (default 0: whole tosses)",
    )
    parser.add_argument(
        "--lead",
        type=int,
        default=4,
        help="with --window: start each window this many free-flight samples before the last "
        "one before a touch (default 4)",
    )
    parser.add_argument(
        "--policy",
        default="keep",
        choices=["keep", "exclude"],
        help="recordings not differentiable at the start: keep or exclude (default keep)",
    )
    parser.add_argument(
        "--loss",
        default="linear",
        choices=[loss.value for loss in Loss],
        help="the fit's loss (default linear: least squares; soft_l1, huber, cauchy: robust)",
    )
    parser.add_argument(
        "--f-scale",
        type=float,
        default=0.003,
        help="m: with a robust --loss, residual rows beyond this count less (default 0.003: three "
        "times the data's ~1 mm noise)",
    )
    parser.add_argument("--no-gravity", action="store_true", help="keep g at 9.81 m/s² (do not fit it)")
    parser.add_argument(
        "--ground",
        type=float,
        default=0.0,
        help="the board's height (m) the fit starts from, or keeps with --no-offset (default 0)",
    )
    parser.add_argument(
        "--length-scale",
        type=float,
        default=1.0,
        help="the model's edge and g times this (the data's lengths in units this much too "
        "small: 0.98 makes edge 0.1027 m and g 9.61 m/s²; default 1)",
    )
    parser.add_argument(
        "--friction", type=float, default=NOMINAL.friction, help=f"μ to start from (default {NOMINAL.friction})"
    )
    parser.add_argument(
        "--restitution",
        type=float,
        default=NOMINAL.restitution,
        help=f"e to start from (default {NOMINAL.restitution})",
    )
    parser.add_argument(
        "--moment-scale",
        type=float,
        default=1.0,
        help="the moments of inertia to start from, times the nominal (default 1)",
    )
    parser.add_argument(
        "--no-inertia", action="store_true", help="keep the moments of inertia nominal (do not fit their scale)"
    )
    parser.add_argument("--no-offset", action="store_true", help="keep the board's height at --ground (do not fit it)")
    parser.add_argument(
        "--rest-board",
        action="store_true",
        help="set the board's height from the training tosses' last --rest-samples samples at rest "
        "(contactdiff.fit.rest_height, closed form) and hold it in the fit (implies --no-offset)",
    )
    parser.add_argument(
        "--rest-samples", type=int, default=REST_SAMPLES, help=f"with --rest-board (default {REST_SAMPLES})"
    )
    parser.add_argument(
        "--length-check",
        action="store_true",
        help="only compare the data's free-flight g and rest height with the model's, and stop",
    )
    parser.add_argument(
        "--start-noise",
        type=int,
        default=0,
        metavar="K",
        help="also run each held-out toss from before touch K times from starts perturbed by the "
        "data's noise, at the fitted values (how much of the error is luck; default 0: not)",
    )
    parser.add_argument(
        "--no-nominal", action="store_true", help="do not evaluate the held-out tosses at the nominal values"
    )
    parser.add_argument("--quick", action="store_true", help="2 shipped tosses to fit, 2 held out, 1 evaluation")
    parser.add_argument("--plot-dir", help="write plots of held-out tosses and the error distribution here")
    parser.add_argument("--json", action="store_true", help="print the report as JSON")
    args = parser.parse_args(argv)
    tosses = load_tosses(args.tosses)
    if args.length_check:
        c = length_check(tosses)
        print(
            json.dumps(c, indent=2)
            if args.json
            else f"free-flight g: median {c['g_median']:.3f} m/s² over {c['flights']} first flights (quartiles "
            f"{c['g_quartiles'][0]:.3f}, {c['g_quartiles'][1]:.3f}), {c['g_ratio']:.4f} of 9.81; rest height: "
            f"median {c['rest_median']:.5f} m over {c['tosses']} tosses, {c['rest_ratio']:.4f} of edge / 2; "
            f"noise in free flight: position {c['position_noise_median'] * 1e3:.4f} mm, rotation "
            f"{c['rotation_noise_median']:.5f} rad (medians)"
        )
        return 0
    if args.quick:
        args.train, args.test, args.max_evaluations = 2, 2, 1
    jobs = args.jobs or 2
    train, held_out = split(tosses, args.train, args.seed)
    held_out = held_out[: args.test] if args.test else held_out
    rest = None
    if args.rest_board:  # the board from the training tosses at rest, held in the fit
        rest = rest_height(
            cd.cube_scene(base_parameters(args)),
            [toss_recording(tosses[n]) for n in train],
            group="cube",
            samples=args.rest_samples,
        )
        args.ground, args.no_offset = rest.offset, True
    base = base_parameters(args)
    build = functools.partial(cd.cube_scene, base)
    scene = build()
    report = {
        "train": len(train),
        "held_out": len(held_out),
        "seed": args.seed,
        "base": {"edge": base.edge, "gravity": base.gravity, "ground": base.ground},
    }
    if rest is not None:
        report["rest_board"] = {"offset": rest.offset, "standard_error": rest.standard_error, "points": rest.points}
        print(
            f"board from the training tosses at rest: {rest.offset * 1e3:.3f} ± {rest.standard_error * 1e3:.3f} mm "
            f"({rest.points} supporting corners)",
            file=sys.stderr,
            flush=True,
        )

    recs = training_recordings(tosses, train, args, scene)
    parameters = unknowns(scene, gravity=not args.no_gravity, offset=not args.no_offset, inertia=not args.no_inertia)
    state = StateFit.VELOCITY if args.window else StateFit.NONE
    report |= {"loss": args.loss, "f_scale": args.f_scale if args.loss != "linear" else None}
    report |= {"window": args.window, "lead": args.lead if args.window else None, "recordings": len(recs)}
    weights = ResidualWeights(position=1.0, orientation=NOMINAL.edge / 2)  # a radian counts as a corner's travel
    started = time.perf_counter()
    options = {"rtol": args.rtol, "atol": args.atol}
    result = fit(
        build if jobs > 1 else scene,
        recs,
        parameters,
        weights=weights,
        jobs=jobs,
        state=state,
        policy=args.policy,
        max_evaluations=args.max_evaluations,
        options=options,
        loss=args.loss,
        f_scale=args.f_scale,
    )
    report["fit"] = result.to_dict() | {"wall_time": time.perf_counter() - started}
    print(result.table(), file=sys.stderr, flush=True)
    fitted = {"group:cube:offset": args.ground} | FitPlan(scene, parameters).values(result.values)
    report["fitted_scene_values"] = fitted

    report["options"] = options
    if not args.no_nominal:
        report["nominal"] = evaluate_held_out(tosses, held_out, None, jobs, "nominal", options)
    report["fitted"] = evaluate_held_out(tosses, held_out, fitted, jobs, "fitted", options, build)
    if args.start_noise:
        report["start_noise"] = start_noise(tosses, held_out, fitted, jobs, options, build, args.start_noise)
        n = report["start_noise"]
        print(
            f"start noise, {args.start_noise} draws: means {np.round(n['draw_means'], 1).tolist()} (std "
            f"{n['draw_mean_std']:.1f}); per toss best {n['best_of_draws_mean']:.1f}, worst "
            f"{n['worst_of_draws_mean']:.1f}; spread median {n['spread_median']:.1f}, "
            f"{n['tosses_spread_over_10']} tosses spread > 10 points; {n['failed']} failed",
            file=sys.stderr,
            flush=True,
        )
    probe = recs[:5] if args.window else [toss_recording(tosses[n], Start.BEFORE_TOUCH) for n in train[:5]]
    report["jacobian_cost"] = jacobian_cost(probe, scene, options, parameters, state)
    report["anchors"] = ANCHORS
    report["stepping_cost"] = STEPPING_COST
    if args.plot_dir:
        plot_report(report, tosses, fitted, Path(args.plot_dir), build())
    print(json.dumps(report, indent=2) if args.json else format_report(report))
    return 0


def plot_report(report: dict, tosses, fitted: dict, folder: Path, scene) -> None:
    """``cube_toss_errors.png``: the held-out position errors (nominal and fitted, from before
    touch) with the anchors' means; ``cube_toss_rollouts.png``: measured against fitted
    centre positions of the two best and two worst held-out tosses."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder.mkdir(parents=True, exist_ok=True)
    start = Start.BEFORE_TOUCH.value
    fig, ax = plt.subplots(figsize=(7, 3.2))
    for label, color in (("nominal", "C7"), ("fitted", "C0")):
        if label not in report:
            continue
        errors = [row[1] for row in report[label][start]["per_toss"]]
        ax.hist(errors, bins=np.linspace(0, 100, 41), alpha=0.6, color=color, label=f"{label} parameters")
    for (name, values), color in zip(ANCHORS.items(), ("C1", "C2", "C3")):
        ax.axvline(values[0], color=color, linestyle="--", label=f"{name} (tuned on all) {values[0]} %")
    ax.set_xlabel("time-averaged position error (% of the edge), held-out tosses")
    ax.set_ylabel("tosses")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(folder / "cube_toss_errors.png", dpi=120)
    plt.close(fig)

    rows = report["fitted"][start]["per_toss"]  # sorted worst first
    chosen = [r[0] for r in rows[-2:][::-1]] + [r[0] for r in rows[:2]]
    fig, axes = plt.subplots(len(chosen), 1, figsize=(7, 2.3 * len(chosen)), squeeze=False)
    for ax, name in zip(axes[:, 0], chosen):
        rec = toss_recording(tosses[name], Start.BEFORE_TOUCH)
        run = rollout(scene, rec, fitted, report["options"])
        k = rec.compared[: len(run.q)]
        for j, axis in enumerate("xyz"):
            ax.plot(rec.t, rec.q[:, j], ".", color=f"C{j}", markersize=2.5, label=f"{axis} measured")
            ax.plot(rec.t[k], run.q[:, j], "-", color=f"C{j}", linewidth=1.2, label=f"{axis} simulated")
        pos, rot = toss_errors(rec, run.q) if run.complete else (float("nan"), float("nan"))
        ax.set_title(f"{name}: {pos:.1f} % of the edge, {rot:.1f} deg", fontsize=9)
        ax.set_ylabel("m")
    axes[0, 0].legend(fontsize=7, ncol=3)
    axes[-1, 0].set_xlabel("t (s)")
    fig.tight_layout()
    fig.savefig(folder / "cube_toss_rollouts.png", dpi=120)
    plt.close(fig)


def format_report(report: dict) -> str:
    fit_ = report["fit"]
    shape = (
        f"{report['recordings']} windows of {report['window']} samples, lead {report['lead']}"
        if report.get("window")
        else "whole tosses"
    )
    lines = [
        f"fit on {report['train']} tosses, {shape} ({fit_['iterations']} iterations, "
        f"{fit_['evaluations']} evaluations, "
        f"{fit_['wall_time']:.0f} s; not differentiable per evaluation: {fit_['nondifferentiable']}):"
    ]
    for name, p in fit_["parameters"].items():
        lines.append(f"  {name:<26} {p['start']:>10.5g} -> {p['value']:>10.5g} ± {p['standard_error']:.2g}")
    lines.append(f"held out: {report['held_out']} tosses")
    for label in ("nominal", "fitted"):
        for start, s in report.get(label, {}).items():
            lines.append(f"  {label:<8} from {start:<13} " + _line(s))
    lines.append(
        "anchors (tuned on all tosses, from before touch): "
        + "; ".join(f"{k} {v[0]} ± {v[1]} %, {v[2]} ± {v[3]} deg" for k, v in report["anchors"].items())
    )
    c = report["jacobian_cost"]
    lines.append(
        f"exact Jacobian of {c['unknowns']} unknowns: {c['exact_over_plain']:.2f} plain runs "
        f"(forward FD {c['forward_fd_over_plain']}, central {c['central_fd_over_plain']}); plain run "
        f"median {c['plain_median'] * 1e3:.0f} ms per fitted recording"
    )
    worst = report["fitted"][Start.BEFORE_TOUCH.value]["worst"]
    lines.append(
        "worst held-out tosses (fitted, from before touch): "
        + "; ".join(
            f"{w['toss']} {w['position']:.0f} % {w['rotation']:.0f} deg {dict(Counter(w['events']))}" for w in worst[:5]
        )
    )
    return "\n".join(lines)


if __name__ == "__main__":
    sys.exit(main())
