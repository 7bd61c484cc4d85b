"""Gradients through contact: contactdiff against MuJoCo (and MJX) on five tasks.

    python scripts/gradient_bench.py [--quick] [--json out.json] [--plots DIR] [--no-mjx] [--repeats N]

For each task (`contactdiff.bench.gradients`) and method, the gradient's relative
error against the exact one (Frobenius norm of the difference over that of the
exact gradient) and the wall and CPU time of computing it, measured in this one
run: contactdiff's as the median of ``--repeats`` runs (of every point on task 4),
MuJoCo's once (on task 4 the median over its 20 points);
task 2's gradient descent (iterations, reached distance); task 4's verdicts;
one work-precision plot per task (error against CPU time, log-log) in ``--plots``
(default docs/gradients/). ``--quick``: one MuJoCo variant and one tolerance per
task, no MJX, seconds. Needs the ``mujoco`` extra; MJX needs ``jax`` and
``mujoco-mjx`` (left out, with a note, when absent).
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

from contactdiff.bench import gradients as g
from contactdiff.bench import gradients_cube as cube
from contactdiff.bench import gradients_mujoco as mj
from contactdiff.errors import ContactDiffError

ROOT = Path(__file__).resolve().parents[1]
TOLERANCES = (1e-6, 1e-9, 1e-12)
QUICK_TOLERANCES = (1e-12,)
VARIANTS = [mj.Variant(dt, tau) for tau in (0.02, 0.005) for dt in (1e-3, 1e-4, 1e-5)]
QUICK_VARIANTS = [mj.Variant(1e-3, 0.02)]
FD_STEPS = (1e-2, 1e-5)
TRANSITION_MIN_DT = 1e-4  # the product of 1/dt Jacobians in a Python loop: slower below
TARGET = 1e-3
"""A baseline's relative gradient error that counts as reaching the target."""
OWN_TARGET = 1e-8
"""contactdiff's: its cost is that of its cheapest tolerance within it."""
REPEATS = 5


def relative(gradient, exact) -> float:
    return float(np.linalg.norm(np.asarray(gradient) - exact) / np.linalg.norm(exact))


def row(task, method, variant, error, cost: g.Cost, **extra) -> dict:
    return {
        "task": task,
        "method": method,
        "variant": variant,
        "error": error,
        "seconds": cost.wall,
        "cpu_seconds": cost.cpu,
        **extra,
    }


def repeated(run, repeats: int):
    """``run()`` (a `g.Run`) ``repeats`` times: the last run, with the median `g.Cost`."""
    runs = [run() for _ in range(repeats)]
    last = runs[-1]
    last.cost = g.median_cost(r.cost for r in runs)
    return last


def contactdiff_rows(task: str, exact, run, tolerances, repeats: int) -> list[dict]:
    rows = []
    for rtol in tolerances:
        r = repeated(lambda: run(rtol, rtol / 10), repeats)
        rows.append(
            row(
                task,
                "contactdiff",
                f"rtol {rtol:g}",
                relative(r.gradient, exact),
                r.cost,
                differentiable=r.differentiable,
            )
        )
    return rows


def mujoco_rows(task: str, exact, gradient, variants, quick: bool) -> list[dict]:
    """``gradient(variant, method, h) -> (G, seconds)``: FD at each step, the transition product."""
    rows = []
    for v in variants:
        if v.timeconst < 4 * v.timestep:
            continue
        for h in FD_STEPS[-1:] if quick else FD_STEPS:
            G, s = gradient(v, "fd", h)
            rows.append(row(task, "mujoco fd", f"{v.label}, h {h:g}", relative(G, exact), s))
        if v.timestep >= TRANSITION_MIN_DT:
            G, s = gradient(v, "transition", None)
            rows.append(row(task, "mujoco transitionFD", v.label, relative(G, exact), s))
    return rows


def mjx_row(task: str, exact, model, qpos, qvel, steps, rows_, columns, label) -> list[dict]:
    try:
        G, first, second = mj.mjx_gradient(model, qpos, qvel, steps, rows_, columns)
    except ContactDiffError as exc:
        return [row(task, "mjx jacfwd", f"left out: {exc}", math.nan, g.Cost(math.nan, math.nan))]
    return [row(task, "mjx jacfwd", label, relative(G, exact), second, compile_seconds=first)]


def ball_task(name: str, task: g.BallTask, variants, tolerances, quick: bool, mjx: bool, repeats: int) -> list[dict]:
    exact = g.ball_gradient(task)
    rows = contactdiff_rows(name, exact, lambda rt, at: g.contactdiff_ball(task, rtol=rt, atol=at), tolerances, repeats)
    rows += mujoco_rows(name, exact, lambda v, m, h: mj.mujoco_ball(task, v, m, h=h or mj.FD_STEP), variants, quick)
    if mjx:
        v = mj.Variant(1e-3, 0.02)
        qpos = np.array([task.position[0], 0.0, task.position[1], 1.0, 0.0, 0.0, 0.0])
        qvel = np.array([task.velocity[0], 0.0, task.velocity[1], 0.0, 0.0, 0.0])
        rows += mjx_row(
            name,
            exact,
            mj.ball_model(task, v),
            qpos,
            qvel,
            mj.steps_of(task.horizon, v.timestep),
            (0, 2),
            (7, 9),
            v.label,
        )
    return rows


def descend(task: g.BallTask, gradient_at, position_at, iterations: int, tol: float = 1e-6) -> dict:
    """Gradient descent on ``L = |p(T) - target|²/2`` over (vx, vz), step ``1/σ_max(J0)²`` of the
    exact Jacobian at the start (the same for every method)."""
    v = np.array(task.velocity, dtype=float)
    target = np.array(task.target)
    lr = 1.0 / np.linalg.norm(g.ball_gradient(task, v), 2) ** 2
    for k in range(iterations):
        p = position_at(v)
        if np.linalg.norm(p - target) < tol:
            break
        v = v - lr * gradient_at(v).T @ (p - target)
    exact_p = g.ball_outcome(task, v)[:2].real
    return {
        "iterations": k,
        "own_distance": float(np.linalg.norm(position_at(v) - target)),
        "exact_distance": float(np.linalg.norm(exact_p - target)),
        "velocity": v.tolist(),
    }


def descent_rows(name: str, task: g.BallTask, variant: mj.Variant, h: float, iterations: int) -> list[dict]:
    out = []
    methods = {
        "exact": (lambda v: g.ball_gradient(task, v), lambda v: g.ball_outcome(task, v)[:2].real),
        "contactdiff": (lambda v: g.contactdiff_ball(task, v).gradient, lambda v: g.contactdiff_ball(task, v).outcome),
        f"mujoco fd ({variant.label}, h {h:g})": (
            lambda v: mj.mujoco_ball(task, variant, "fd", velocity=v, h=h)[0],
            lambda v: mj.mujoco_ball_position(task, variant, v),
        ),
    }
    for method, (grad, pos) in methods.items():
        out.append({"task": name, "method": method, **descend(task, grad, pos, iterations)})
    return out


def brax_rows(quick: bool, variants, tolerances, repeats: int) -> tuple[list[dict], list[dict]]:
    """Task 4: a row per method and variant (error: the largest over the differentiable
    points; cost: the median over the points, each contactdiff point's the median of
    ``repeats`` runs), and the verdicts of the runs at the tightest tolerance."""
    task = g.BRAX
    points = [task.kink + 0.05 * k for k in range(-10, 11, 5 if quick else 1)]
    verdicts, rows = [], []
    for rtol in tolerances:
        runs = [
            (z0, repeated(lambda: g.contactdiff_brax(task, z0, rtol, rtol / 10), repeats), g.brax_outcome(task, z0))
            for z0 in points
        ]
        errors = [abs(r.gradient[0, 0] - d) for _, r, (_, d) in runs if d is not None]
        rows.append(
            row("4 brax", "contactdiff", f"rtol {rtol:g}", max(errors), g.median_cost(r.cost for _, r, _ in runs))
        )
    for z0, r, (z_exact, d_exact) in runs:
        verdicts.append(
            {
                "z0": z0,
                "z_T": float(r.outcome[0]),
                "z_T_exact": z_exact,
                "gradient": float(r.gradient[0, 0]),
                "exact": d_exact,
                "differentiable": r.differentiable,
                "notes": r.notes,
            }
        )
    smooth = [(z0, d) for z0, _, (_, d) in runs if d is not None]
    for v in variants:
        if v.timeconst < 4 * v.timestep:
            continue
        for method, h in [("fd", FD_STEPS[-1]), ("transition", None)]:
            if method == "transition" and v.timestep < TRANSITION_MIN_DT:
                continue
            results = [mj.mujoco_brax(task, v, z0, method, h or mj.FD_STEP) for z0, _ in smooth]
            rows.append(
                row(
                    "4 brax",
                    f"mujoco {'fd' if h else 'transitionFD'}",
                    v.label,
                    max(abs(G[0, 0] - d) for (G, _, _), (_, d) in zip(results, smooth)),
                    g.median_cost(s for _, s, _ in results),
                )
            )
    return rows, verdicts


def cube_rows(variants, tolerances, quick: bool, repeats: int) -> tuple[list[dict], dict]:
    steps = cube.REFERENCE_STEPS
    coarse, fine = (cube.cube_reference(h) for h in steps)
    exact = cube.extrapolated(coarse[0], fine[0], steps[0] / steps[1])
    info = {
        "horizon": cube.HORIZON,
        "reference_steps": list(steps),
        "fine_vs_extrapolated": relative(fine[0], exact),
        "coarse_vs_extrapolated": relative(coarse[0], exact),
        "reference_seconds": coarse[1].wall + fine[1].wall,
        "gradient": exact.tolist(),
    }
    rows = contactdiff_rows(
        "5 cube", exact, lambda rt, at: cube.contactdiff_cube(rtol=rt, atol=at), tolerances, repeats
    )
    rows.append(
        row(
            "5 cube", "contactdiff central FD", f"rtol 1e-12, h {steps[0]:g}", info["coarse_vs_extrapolated"], coarse[1]
        )
    )
    rows.append(
        row("5 cube", "contactdiff central FD", f"rtol 1e-12, h {steps[1]:g}", info["fine_vs_extrapolated"], fine[1])
    )
    cube_variants = variants if quick else [mj.Variant(dt, tau) for tau in (0.02, 0.005, 0.002) for dt in (1e-3, 1e-4)]
    for v in cube_variants:
        if v.timeconst < 4 * v.timestep:
            continue
        for h in (1e-4,) if quick else (1e-2, 1e-4):
            G, s = mj.mujoco_cube(v, h)
            rows.append(row("5 cube", "mujoco fd", f"{v.label}, h {h:g}", relative(G, exact), s))
    return rows, info


def cube_study(horizons, json_path) -> None:
    """Print (and with ``--json`` write) `cube.horizon_study` over ``horizons``."""
    study = cube.horizon_study(horizons)
    steps = [f"h {h:g}" for h in cube.REFERENCE_STEPS] + ["extrapolated"]
    print(
        f"{'T (s)':>6} {'events':>6} {'differentiable':<14} {'|J|':>9}  "
        + "  ".join(f"{s:>12}" for s in steps)
        + "  reasons"
    )
    for r in study:
        print(
            f"{r['horizon']:>6g} {r['events']:>6} {str(r['differentiable']):<14} {r['jacobian_norm']:>9.3g}  "
            + "  ".join(f"{e:>12.2g}" for e in r["errors"].values())
            + "  "
            + ", ".join(r["reasons"])
        )
    if json_path:
        Path(json_path).write_text(json.dumps(study, indent=2))


def summary(rows: list[dict]) -> list[str]:
    """Per task: contactdiff's cheapest (CPU) tolerance within `OWN_TARGET` (else its best),
    and the cheapest (CPU) MuJoCo variant within `TARGET` with the time ratios (CPU, wall),
    or the best variant where none reaches it."""
    lines = []
    for task in dict.fromkeys(r["task"] for r in rows):
        mine = [r for r in rows if r["task"] == task and r["method"] == "contactdiff"]
        within = [r for r in mine if r["error"] <= OWN_TARGET]
        best = min(within, key=lambda r: r["cpu_seconds"]) if within else min(mine, key=lambda r: r["error"])
        others = [r for r in rows if r["task"] == task and r["method"].startswith("mujoco") and np.isfinite(r["error"])]
        reaching = [r for r in others if r["error"] <= TARGET]
        line = (
            f"{task}: contactdiff {best['error']:.2g} in {best['cpu_seconds']:.3g} s CPU, "
            f"{best['seconds']:.3g} s wall ({best['variant']})"
        )
        if reaching:
            cheap = min(reaching, key=lambda r: r["cpu_seconds"])
            line += (
                f"; cheapest MuJoCo at <= {TARGET:g}: {cheap['method']} {cheap['variant']} "
                f"({cheap['error']:.2g}), {cheap['cpu_seconds']:.3g} s CPU, {cheap['seconds']:.3g} s wall: "
                f"ratio {cheap['cpu_seconds'] / best['cpu_seconds']:.3g} (CPU), "
                f"{cheap['seconds'] / best['seconds']:.3g} (wall)"
            )
        elif others:
            top = min(others, key=lambda r: r["error"])
            line += (
                f"; no MuJoCo variant reaches {TARGET:g}: best {top['error']:.2g} "
                f"({top['method']} {top['variant']}, {top['cpu_seconds']:.3g} s CPU, "
                f"{top['seconds']:.3g} s wall)"
            )
        lines.append(line)
    return lines


def plot(rows: list[dict], folder: Path) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder.mkdir(parents=True, exist_ok=True)
    written = []
    markers = {
        "contactdiff": "o",
        "mujoco fd": "s",
        "mujoco transitionFD": "^",
        "mjx jacfwd": "D",
        "contactdiff central FD": "x",
    }
    for task in dict.fromkeys(r["task"] for r in rows):
        fig, ax = plt.subplots(figsize=(5.5, 4))
        for method, marker in markers.items():
            pts = [
                (r["cpu_seconds"], max(r["error"], 1e-17))
                for r in rows
                if r["task"] == task and r["method"] == method and np.isfinite(r["error"])
            ]
            if pts:
                ax.loglog(*zip(*pts), marker, label=method, alpha=0.8)
        ax.axhline(TARGET, color="grey", lw=0.8, ls="--")
        ax.set_xlabel("CPU time of one gradient (s)")
        ax.set_ylabel("relative error of the gradient")
        ax.set_title(f"task {task}")
        ax.legend(fontsize=7)
        fig.tight_layout()
        path = folder / f"task_{task.replace(' ', '_').replace('+', '_')}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        written.append(path)
    return written


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one MuJoCo variant and tolerance, no MJX: seconds")
    parser.add_argument("--json", metavar="PATH", help="also write every row as JSON")
    parser.add_argument("--plots", type=Path, default=ROOT / "docs" / "gradients", help="folder of the plots")
    parser.add_argument("--no-mjx", action="store_true", help="leave MJX out")
    parser.add_argument(
        "--cube-horizons",
        type=float,
        nargs="+",
        metavar="T",
        help="only the cube's study over horizons T (s): verdict, Jacobian against central FD",
    )
    parser.add_argument(
        "--repeats",
        type=int,
        default=None,
        help=f"runs of each contactdiff gradient whose median time is taken (default {REPEATS}; --quick: 1)",
    )
    args = parser.parse_args(argv)
    repeats = args.repeats if args.repeats is not None else 1 if args.quick else REPEATS
    if repeats < 1:
        parser.error(f"--repeats must be >= 1, got {repeats}")
    if args.cube_horizons:
        if min(args.cube_horizons) <= 0:
            parser.error(f"--cube-horizons must be positive, got {args.cube_horizons}")
        cube_study(args.cube_horizons, args.json)
        return
    variants = QUICK_VARIANTS if args.quick else VARIANTS
    tolerances = QUICK_TOLERANCES if args.quick else TOLERANCES
    mjx = not (args.quick or args.no_mjx)
    rows = ball_task("1 bounce", g.BOUNCE, variants, tolerances, args.quick, mjx, repeats)
    rows += ball_task("2 wall", g.WALL, variants, tolerances, args.quick, mjx, repeats)
    rows += ball_task("2 wall+friction", g.WALL_FRICTION, variants, tolerances, args.quick, False, repeats)
    exact = g.two_ball_gradient()
    rows += contactdiff_rows(
        "3 two balls", exact, lambda rt, at: g.contactdiff_two_balls(rtol=rt, atol=at), tolerances, repeats
    )
    rows += mujoco_rows(
        "3 two balls", exact, lambda v, m, h: mj.mujoco_two_balls(g.NIMBLE, v, m, h or mj.FD_STEP), variants, args.quick
    )
    if mjx:
        v, t = mj.Variant(1e-3, 0.02), g.NIMBLE
        qpos = np.array([t.x1, 0, 0, 1, 0, 0, 0, t.x2, 0, 0, 1, 0, 0, 0], dtype=float)
        qvel = np.zeros(12)
        qvel[0], qvel[6] = t.v1, t.v2
        rows += mjx_row(
            "3 two balls", exact, mj.two_ball_model(t, v), qpos, qvel, 1000, (0, 7), (0, 7, 14, 20), v.label
        )
    brax, verdicts = brax_rows(args.quick, variants, tolerances, repeats)
    rows += brax
    cube_part, cube_info = cube_rows(variants, tolerances, args.quick, repeats)
    rows += cube_part
    best = max(variants, key=lambda v: v.timestep) if args.quick else mj.Variant(1e-4, 0.005)
    descent = []
    for name, task in (("2 wall", g.WALL), ("2 wall+friction", g.WALL_FRICTION)):
        descent += descent_rows(name, task, best, 1e-2, 20 if args.quick else 200)

    print(f"{'task':<16} {'method':<24} {'variant':<34} {'rel. error':>10} {'CPU s':>9} {'wall s':>9}")
    for r in rows:
        print(
            f"{r['task']:<16} {r['method']:<24} {r['variant'][:34]:<34} {r['error']:>10.2g} "
            f"{r['cpu_seconds']:>9.3g} {r['seconds']:>9.3g}"
        )
    print("\ngradient descent to the target (exact: the closed form's distance at the final velocity):")
    for d in descent:
        print(
            f"  {d['task']:<16} {d['method']:<44} iterations {d['iterations']:>4}  own distance "
            f"{d['own_distance']:.2g} m  exact distance {d['exact_distance']:.2g} m"
        )
    print("\ntask 4 verdicts (z0, z(T), dz/dz0, exact, differentiable):")
    for v in verdicts:
        print(f"  {v['z0']:.3f}  {v['z_T']:.6f}  {v['gradient']:+.1f}  {v['exact']}  {v['differentiable']}")
    wrong = [v for v in verdicts if v["differentiable"] != (v["exact"] is not None)]
    print(f"  verdicts wrong: {len(wrong)} of {len(verdicts)}")
    print(
        f"\ntask 5 (T = {cube.HORIZON:g} s) reference: central FD at h {cube.REFERENCE_STEPS[0]:g}, "
        f"{cube.REFERENCE_STEPS[1]:g} vs extrapolated {cube_info['coarse_vs_extrapolated']:.2g}, "
        f"{cube_info['fine_vs_extrapolated']:.2g}"
    )
    print("\ntargets (times measured in this one run):")
    for line in summary(rows):
        print("  " + line)
    written = plot(rows, args.plots)
    print(f"\nplots written to {args.plots} ({len(written)} files)")
    if args.json:
        Path(args.json).write_text(
            json.dumps({"rows": rows, "descent": descent, "verdicts": verdicts, "cube": cube_info}, indent=2)
        )


if __name__ == "__main__":
    main()
