"""Gradients through contact: contactdiff against MuJoCo (and MJX) on five tasks.

    python scripts/gradient_bench.py [--quick] [--json out.json] [--plots DIR] [--no-mjx]

For each task (`contactdiff.bench.gradients`) and method, the gradient's relative
error against the exact one (Frobenius norm of the difference over that of the
exact gradient) and the wall time of computing it, measured in this one run;
task 2's gradient descent (iterations, reached distance); task 4's verdicts;
one work-precision plot per task (error against wall time, log-log) in ``--plots``
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


def relative(gradient, exact) -> float:
    return float(np.linalg.norm(np.asarray(gradient) - exact) / np.linalg.norm(exact))


def row(task, method, variant, error, seconds, **extra) -> dict:
    return {"task": task, "method": method, "variant": variant, "error": error, "seconds": seconds, **extra}


def contactdiff_rows(task: str, exact, run, tolerances) -> list[dict]:
    rows = []
    for rtol in tolerances:
        r = run(rtol, rtol / 10)
        rows.append(row(task, "contactdiff", f"rtol {rtol:g}", relative(r.gradient, exact), r.seconds,
                        differentiable=r.differentiable))
    return rows


def mujoco_rows(task: str, exact, gradient, variants, quick: bool) -> list[dict]:
    """``gradient(variant, method, h) -> (G, seconds)``: FD at each step, the transition product."""
    rows = []
    for v in variants:
        if v.timeconst < 4 * v.timestep:
            continue
        for h in (FD_STEPS[-1:] if quick else FD_STEPS):
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
        return [row(task, "mjx jacfwd", f"left out: {exc}", math.nan, math.nan)]
    return [row(task, "mjx jacfwd", label, relative(G, exact), second, compile_seconds=first)]


def ball_task(name: str, task: g.BallTask, variants, tolerances, quick: bool, mjx: bool) -> list[dict]:
    exact = g.ball_gradient(task)
    rows = contactdiff_rows(name, exact, lambda rt, at: g.contactdiff_ball(task, rtol=rt, atol=at), tolerances)
    rows += mujoco_rows(name, exact, lambda v, m, h: mj.mujoco_ball(task, v, m, h=h or mj.FD_STEP), variants, quick)
    if mjx:
        v = mj.Variant(1e-3, 0.02)
        qpos = np.array([task.position[0], 0.0, task.position[1], 1.0, 0.0, 0.0, 0.0])
        qvel = np.array([task.velocity[0], 0.0, task.velocity[1], 0.0, 0.0, 0.0])
        rows += mjx_row(name, exact, mj.ball_model(task, v), qpos, qvel, mj.steps_of(task.horizon, v.timestep),
                        (0, 2), (7, 9), v.label)
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
    return {"iterations": k, "own_distance": float(np.linalg.norm(position_at(v) - target)),
            "exact_distance": float(np.linalg.norm(exact_p - target)), "velocity": v.tolist()}


def descent_rows(name: str, task: g.BallTask, variant: mj.Variant, h: float, iterations: int) -> list[dict]:
    out = []
    methods = {
        "exact": (lambda v: g.ball_gradient(task, v), lambda v: g.ball_outcome(task, v)[:2].real),
        "contactdiff": (lambda v: g.contactdiff_ball(task, v).gradient, lambda v: g.contactdiff_ball(task, v).outcome),
        f"mujoco fd ({variant.label}, h {h:g})": (
            lambda v: mj.mujoco_ball(task, variant, "fd", velocity=v, h=h)[0],
            lambda v: mj.mujoco_ball_position(task, variant, v)),
    }
    for method, (grad, pos) in methods.items():
        out.append({"task": name, "method": method, **descend(task, grad, pos, iterations)})
    return out


def brax_rows(quick: bool, variants) -> tuple[list[dict], list[dict]]:
    task = g.BRAX
    points = [task.kink + 0.05 * k for k in range(-10, 11, 5 if quick else 1)]
    verdicts, rows = [], []
    runs = [(z0, g.contactdiff_brax(task, z0), g.brax_outcome(task, z0)) for z0 in points]
    for z0, r, (z_exact, d_exact) in runs:
        verdicts.append({"z0": z0, "z_T": float(r.outcome[0]), "z_T_exact": z_exact,
                         "gradient": float(r.gradient[0, 0]), "exact": d_exact,
                         "differentiable": r.differentiable, "notes": r.notes})
    smooth = [(z0, d) for z0, _, (_, d) in runs if d is not None]
    errors = [abs(r.gradient[0, 0] - d) for _, r, (_, d) in runs if d is not None]
    rows.append(row("4 brax", "contactdiff", "rtol 1e-12", max(errors),
                    float(np.mean([r.seconds for _, r, _ in runs]))))
    for v in variants:
        if v.timeconst < 4 * v.timestep:
            continue
        for method, h in [("fd", FD_STEPS[-1]), ("transition", None)]:
            if method == "transition" and v.timestep < TRANSITION_MIN_DT:
                continue
            results = [mj.mujoco_brax(task, v, z0, method, h or mj.FD_STEP) for z0, _ in smooth]
            rows.append(row("4 brax", f"mujoco {'fd' if h else 'transitionFD'}", v.label,
                            max(abs(G[0, 0] - d) for (G, _, _), (_, d) in zip(results, smooth)),
                            float(np.mean([s for _, s, _ in results]))))
    return rows, verdicts


def cube_rows(variants, tolerances, quick: bool) -> tuple[list[dict], dict]:
    coarse, fine = cube.cube_reference(1e-4), cube.cube_reference(1e-5)
    exact = (100.0 * fine[0] - coarse[0]) / 99.0       # Richardson: the O(h²) terms cancel
    info = {"reference_steps": [1e-4, 1e-5], "fd_1e-5_vs_extrapolated": relative(fine[0], exact),
            "reference_seconds": coarse[1] + fine[1], "gradient": exact.tolist()}
    rows = contactdiff_rows("5 cube", exact, lambda rt, at: cube.contactdiff_cube(rtol=rt, atol=at), tolerances)
    rows.append(row("5 cube", "contactdiff central FD", "rtol 1e-12, h 1e-5", info["fd_1e-5_vs_extrapolated"],
                    fine[1]))
    cube_variants = variants if quick else [mj.Variant(dt, tau) for tau in (0.02, 0.005, 0.002) for dt in (1e-3, 1e-4)]
    for v in cube_variants:
        if v.timeconst < 4 * v.timestep:
            continue
        for h in ((1e-4,) if quick else (1e-2, 1e-4)):
            G, s = mj.mujoco_cube(v, h)
            rows.append(row("5 cube", "mujoco fd", f"{v.label}, h {h:g}", relative(G, exact), s))
    return rows, info


def summary(rows: list[dict]) -> list[str]:
    lines = []
    for task in dict.fromkeys(r["task"] for r in rows):
        mine = [r for r in rows if r["task"] == task and r["method"] == "contactdiff"]
        best = min(mine, key=lambda r: r["error"])
        others = [r for r in rows if r["task"] == task and r["method"].startswith("mujoco") and
                  np.isfinite(r["error"])]
        reaching = [r for r in others if r["error"] <= TARGET]
        line = f"{task}: contactdiff {best['error']:.2g} in {best['seconds']:.3g} s ({best['variant']})"
        if reaching:
            cheap = min(reaching, key=lambda r: r["seconds"])
            line += (f"; cheapest MuJoCo at <= {TARGET:g}: {cheap['method']} {cheap['variant']}, "
                     f"{cheap['seconds']:.3g} s, ratio {cheap['seconds'] / best['seconds']:.3g}")
        elif others:
            top = min(others, key=lambda r: r["error"])
            line += (f"; no MuJoCo variant reaches {TARGET:g}: best {top['error']:.2g} "
                     f"({top['method']} {top['variant']}, {top['seconds']:.3g} s)")
        lines.append(line)
    return lines


def plot(rows: list[dict], folder: Path) -> list[Path]:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    markers = {"contactdiff": "o", "mujoco fd": "s", "mujoco transitionFD": "^", "mjx jacfwd": "D",
               "contactdiff central FD": "x"}
    for task in dict.fromkeys(r["task"] for r in rows):
        fig, ax = plt.subplots(figsize=(5.5, 4))
        for method, marker in markers.items():
            pts = [(r["seconds"], max(r["error"], 1e-17)) for r in rows
                   if r["task"] == task and r["method"] == method and np.isfinite(r["error"])]
            if pts:
                ax.loglog(*zip(*pts), marker, label=method, alpha=0.8)
        ax.axhline(TARGET, color="grey", lw=0.8, ls="--")
        ax.set_xlabel("wall time of one gradient (s)")
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
    args = parser.parse_args(argv)
    variants = QUICK_VARIANTS if args.quick else VARIANTS
    tolerances = QUICK_TOLERANCES if args.quick else TOLERANCES
    mjx = not (args.quick or args.no_mjx)
    rows = ball_task("1 bounce", g.BOUNCE, variants, tolerances, args.quick, mjx)
    rows += ball_task("2 wall", g.WALL, variants, tolerances, args.quick, mjx)
    rows += ball_task("2 wall+friction", g.WALL_FRICTION, variants, tolerances, args.quick, False)
    exact = g.two_ball_gradient()
    rows += contactdiff_rows("3 two balls", exact, lambda rt, at: g.contactdiff_two_balls(rtol=rt, atol=at),
                             tolerances)
    rows += mujoco_rows("3 two balls", exact, lambda v, m, h: mj.mujoco_two_balls(g.NIMBLE, v, m, h or mj.FD_STEP),
                        variants, args.quick)
    if mjx:
        v, t = mj.Variant(1e-3, 0.02), g.NIMBLE
        qpos = np.array([t.x1, 0, 0, 1, 0, 0, 0, t.x2, 0, 0, 1, 0, 0, 0], dtype=float)
        qvel = np.zeros(12)
        qvel[0], qvel[6] = t.v1, t.v2
        rows += mjx_row("3 two balls", exact, mj.two_ball_model(t, v), qpos, qvel, 1000, (0, 7), (0, 7, 14, 20),
                        v.label)
    brax, verdicts = brax_rows(args.quick, variants)
    rows += brax
    cube_part, cube_info = cube_rows(variants, tolerances, args.quick)
    rows += cube_part
    best = max(variants, key=lambda v: v.timestep) if args.quick else mj.Variant(1e-4, 0.005)
    descent = []
    for name, task in (("2 wall", g.WALL), ("2 wall+friction", g.WALL_FRICTION)):
        descent += descent_rows(name, task, best, 1e-2, 20 if args.quick else 200)

    print(f"{'task':<16} {'method':<24} {'variant':<34} {'rel. error':>10} {'wall s':>9}")
    for r in rows:
        print(f"{r['task']:<16} {r['method']:<24} {r['variant'][:34]:<34} {r['error']:>10.2g} {r['seconds']:>9.3g}")
    print("\ngradient descent to the target (exact: the closed form's distance at the final velocity):")
    for d in descent:
        print(f"  {d['task']:<16} {d['method']:<44} iterations {d['iterations']:>4}  own distance "
              f"{d['own_distance']:.2g} m  exact distance {d['exact_distance']:.2g} m")
    print("\ntask 4 verdicts (z0, z(T), dz/dz0, exact, differentiable):")
    for v in verdicts:
        print(f"  {v['z0']:.3f}  {v['z_T']:.6f}  {v['gradient']:+.1f}  {v['exact']}  {v['differentiable']}")
    wrong = [v for v in verdicts if v["differentiable"] != (v["exact"] is not None)]
    print(f"  verdicts wrong: {len(wrong)} of {len(verdicts)}")
    print(f"\ntask 5 reference: central FD at h 1e-5 vs extrapolated {cube_info['fd_1e-5_vs_extrapolated']:.2g}")
    print("\ntargets (times measured in this one run):")
    for line in summary(rows):
        print("  " + line)
    written = plot(rows, args.plots)
    print(f"\nplots written to {args.plots} ({len(written)} files)")
    if args.json:
        Path(args.json).write_text(json.dumps({"rows": rows, "descent": descent, "verdicts": verdicts,
                                               "cube": cube_info}, indent=2))


if __name__ == "__main__":
    main()
