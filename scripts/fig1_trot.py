"""The paper's Fig. 1: trot touchdown outcomes against the initial pitch.

Sweeps the initial pitch θ0 through 0 for planar_trot_rigid (coupled legs) and
planar_trot_soft (legs decoupled by springs), simulates to a fixed time T and
plots the pitch rate and body height at T against θ0, with the derivative from
the flow Jacobian drawn as short tangent lines. Prints, at θ0 = 0, one-sided
finite-difference slopes for shrinking steps h. The pitch rate is odd in θ0, so
its right and left slopes agree; they converge for the soft model and grow
like 1/h for the rigid one (a jump). The body height is even in θ0: the gap
between its right and left slopes shrinks linearly with h for the soft model
(differentiable) and grows like 1/h for the rigid one.

    python scripts/fig1_trot.py [--out docs/fig1_trot.png] [--points 41] [--json]
    python scripts/fig1_trot.py --quick --out /tmp/fig1.png   # 5 points, 3 tangents, 2 steps h: seconds
"""

import argparse
import json

import numpy as np

import contactdiff as cd
from contactdiff.paper import TROT_MODELS

T = 1.25  # s: after the landing at t ≈ 1, during stance
SPAN = 0.05  # rad: θ0 in [-SPAN, SPAN]
TOL = dict(rtol=1e-11, atol=1e-12, max_step=0.01)
OUTCOMES = (("body_pitch", "v", "pitch rate at T (rad/s)"), ("body_z", "q", "body height at T"))


def initial_state_derivative(model: str, theta: float, h: float = 1e-6) -> np.ndarray:
    """d x0 / d θ0 in the tangent space (central difference of the initial-state geometry)."""
    plus, minus = cd.trot_touchdown(model, theta + h), cd.trot_touchdown(model, theta - h)
    robot = plus.robot
    return np.concatenate([robot.difference(minus.q0, plus.q0), plus.v0 - minus.v0]) / (2 * h)


def outcome(model: str, theta: float, jacobian: bool = False):
    """Outcomes at T (one per OUTCOMES entry) and, with ``jacobian``, their derivatives in θ0."""
    scene = cd.trot_touchdown(model, theta)
    traj = cd.simulate(scene, T, jacobian=jacobian, **TOL)
    robot, nv = scene.robot, scene.nv
    rows = []
    for joint, kind, _ in OUTCOMES:
        j = robot.model.joints[robot.joint_id(joint)]
        rows.append((j.idx_q if kind == "q" else None, j.idx_v + (nv if kind == "v" else 0)))
    values = np.array([traj.q[iq] if iq is not None else traj.v[iv - nv] for iq, iv in rows])
    if not jacobian:
        return values, None
    dx0 = initial_state_derivative(model, theta)
    slopes = np.array([traj.jacobian[iv] @ dx0 for _, iv in rows])
    return values, slopes


def one_sided_slopes(model: str, steps=(1e-2, 1e-3, 1e-4, 1e-5)) -> list[dict]:
    f0, _ = outcome(model, 0.0)
    rows = []
    for h in steps:
        fp, _ = outcome(model, h)
        fm, _ = outcome(model, -h)
        right, left = (fp - f0) / h, (f0 - fm) / h
        rows.append(
            {
                "step": h,
                "pitch_rate_right": right[0],
                "pitch_rate_left": left[0],
                "height_right": right[1],
                "height_left": left[1],
                "height_gap": abs(right[1] - left[1]),
            }
        )
    return rows


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="docs/fig1_trot.png")
    parser.add_argument("--points", type=int, default=41)
    parser.add_argument("--json", action="store_true")
    parser.add_argument(
        "--quick", action="store_true", help="a smoke run of seconds: 5 points, 3 tangents, steps h = 1e-2 and 1e-4"
    )
    args = parser.parse_args(argv)
    points, n_tangents, steps = (5, 3, (1e-2, 1e-4)) if args.quick else (args.points, 7, (1e-2, 1e-3, 1e-4, 1e-5))
    thetas = np.linspace(-SPAN, SPAN, points)
    tangents_at = np.linspace(-SPAN, SPAN, n_tangents)
    data = {}
    for model in TROT_MODELS:
        values = np.array([outcome(model, th)[0] for th in thetas])
        tangents = [(th, *outcome(model, th, jacobian=True)) for th in tangents_at if th != 0.0 or model == "soft"]
        data[model] = {
            "theta": thetas,
            "values": values,
            "tangents": tangents,
            "slopes": one_sided_slopes(model, steps),
        }
    report = {m: d["slopes"] for m, d in data.items()}
    if args.json:
        print(json.dumps(report, indent=2))
    else:
        print(f"one-sided finite-difference slopes at θ0 = 0 of the outcomes at T = {T} s")
        for model, rows in report.items():
            print(f"  {model}:")
            print(
                f"    {'step':>8}  {'pitch rate R':>14}  {'pitch rate L':>14}  "
                f"{'height R':>12}  {'height L':>12}  {'height gap':>11}"
            )
            for r in rows:
                print(
                    f"    {r['step']:8.0e}  {r['pitch_rate_right']:14.6g}  {r['pitch_rate_left']:14.6g}  "
                    f"{r['height_right']:12.5g}  {r['height_left']:12.5g}  {r['height_gap']:11.3e}"
                )
    plot(data, args.out)
    if not args.json:
        print(f"figure written to {args.out}")


def plot(data, path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(OUTCOMES), 2, figsize=(9, 6), sharex=True, constrained_layout=True)
    for col, model in enumerate(("rigid", "soft")):
        d = data[model]
        for row, (_, _, label) in enumerate(OUTCOMES):
            ax = axes[row, col]
            ax.plot(d["theta"], d["values"][:, row], ".", ms=4, color="tab:blue", label="simulated outcome")
            half = 0.006
            for k, (th, value, slope) in enumerate(d["tangents"]):
                xs = np.array([th - half, th + half])
                ax.plot(
                    xs,
                    value[row] + slope[row] * (xs - th),
                    color="tab:red",
                    lw=1.6,
                    label="flow-Jacobian tangent" if k == 0 else None,
                )
            ax.set_ylabel(label)
            if row == 0:
                ax.set_title(
                    f"planar_trot_{model}" + (" (coupled: jumps)" if model == "rigid" else " (decoupled: smooth)")
                )
            if row == len(OUTCOMES) - 1:
                ax.set_xlabel("initial pitch θ0 (rad)")
            ax.legend(fontsize=7, loc="best")
    fig.savefig(path, dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    main()
