"""A design gradient on a real robot: the largest Floquet-multiplier modulus of the solo12
trot against its PD gains and its base's mass, checked against finite differences,
and a few gradient steps that lower it.

    python scripts/trot_design_gradient.py [--steps 3] [--rate 0.1] [--plot docs/trot_design_gradient.png] [--json]
    python scripts/trot_design_gradient.py --quick   # kp only, loose tolerances, one step: a smoke run

1. The periodic trot as `scripts/trot_floquet.py` finds it (20 clock periods of
   warm-up, then Newton on the stride map of the first foot; rtol 1e-10).
2. `gait_sensitivity` gives ``d|λ_max|/dp`` for ``p`` = the trot's ``kp`` (N m/rad),
   ``kd`` (N m s/rad) and the base's mass (kg): eigenvalue perturbation of the
   stride Jacobian between gaits re-converged at ``p ± 1e-4 |p|``
   (`contactdiff.analysis.gait.sensitivity`).
3. Check: the same derivative by central differences of ``|λ_max|`` itself, each
   gait found anew by Newton (``h = 1e-3 |p|``).
4. Steps: each moves the parameters by ``rate`` in relative terms against the
   gradient of ``|λ_max|`` in ``log p`` (``Δ log p = -rate g / |g|``, ``g_i = p_i
   d|λ|/dp_i``), re-converges the gait from the last one and recomputes the
   gradient (the largest multiplier is re-chosen each time: where two moduli cross,
   the largest is not differentiable and the gradient is that of the new largest).
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from contactdiff.analysis.gait import find_periodic_gait, first_touchdown, gait_sensitivity
from contactdiff.control.trot_scenes import trot_scene
from contactdiff.integration.hybrid import simulate

PARAMETERS = ["trot:kp", "trot:kd", "body:base_link:mass"]
OPTIONS = dict(rtol=1e-10, atol=1e-12, method="DOP853")
GAIT_TOL = 1e-8  # residual at which a gait counts as converged
WARMUP = 20  # clock periods simulated before the first search
# --quick: a smoke run of the same steps, its numbers meaningless (loose tolerances, kp only, a shorter warm-up)
QUICK = dict(parameters=PARAMETERS[:1], options=dict(rtol=1e-7, atol=1e-9, method="DOP853"), gait_tol=1e-4, warmup=10)


def _gait(scene, q, v, t, period):
    gait = find_periodic_gait(
        scene, scene.contact_names[0], q, v, t, iterations=6, tol=GAIT_TOL, t_max=4 * period, **OPTIONS
    )
    if not gait.converged:
        raise SystemExit(f"the gait did not converge (residual {gait.residuals[-1]:.3g})")
    return gait


def _largest(gait) -> float:
    return float(abs(gait.multipliers[0]))


def main(argv: list[str] | None = None) -> None:
    global PARAMETERS, OPTIONS, GAIT_TOL, WARMUP
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--steps", type=int, default=3, help="gradient steps")
    parser.add_argument("--rate", type=float, default=0.1, help="relative change of the parameters per step")
    parser.add_argument("--plot", default=None, help="write the plot (PNG) here")
    parser.add_argument("--no-check", action="store_true", help="skip the finite-difference check")
    parser.add_argument("--json", action="store_true")
    parser.add_argument(
        "--quick",
        action="store_true",
        help="a smoke run: kp only, 10 periods of warm-up, loose tolerances, no step (the check kept)",
    )
    args = parser.parse_args(argv)
    if args.quick:
        PARAMETERS, OPTIONS, GAIT_TOL, WARMUP = (QUICK[k] for k in ("parameters", "options", "gait_tol", "warmup"))
        args.steps = 0

    started = time.perf_counter()
    scene = trot_scene("solo12")
    period = scene.effort_specs[0].period
    foot = scene.contact_names[0]
    warm = simulate(scene, WARMUP * period, **OPTIONS) if WARMUP else None
    q, v, t = (warm.q, warm.v, warm.t) if warm else (scene.q0, scene.v0, 0.0)
    t, q, v = first_touchdown(scene, foot, q, v, t, t_max=4 * period, **OPTIONS)
    gait = _gait(scene, q, v, t, period)
    history = []
    check = None
    for step in range(args.steps + 1):
        values = scene.parameter_values(PARAMETERS)
        sens = gait_sensitivity(scene, gait, PARAMETERS, which=(0,), t_max=4 * period, tol=1e-2 * GAIT_TOL, **OPTIONS)
        grad = sens.modulus_gradient(0)
        history.append(
            {
                "step": step,
                "values": values.tolist(),
                "largest_modulus": _largest(gait),
                "multiplier": [float(gait.multipliers[0].real), float(gait.multipliers[0].imag)],
                "gradient": grad.tolist(),
                "run_time": time.perf_counter() - started,
            }
        )
        if step == 0 and not args.no_check:
            fd = []
            for name, value in zip(PARAMETERS, values):
                h = 1e-3 * abs(value)
                moduli = [
                    _largest(_gait(scene.with_parameters({name: value + s * h}), gait.q, gait.v, gait.t, period))
                    for s in (1, -1)
                ]
                fd.append((moduli[0] - moduli[1]) / (2 * h))
            check = {
                "finite_differences": fd,
                "relative_error": [abs(a - b) / max(abs(b), 1e-12) for a, b in zip(grad, fd)],
            }
        if step == args.steps:
            break
        g_log = values * grad
        new = values * np.exp(-args.rate * g_log / np.linalg.norm(g_log))
        scene = scene.with_parameters(dict(zip(PARAMETERS, new.tolist())))
        gait = _gait(scene, gait.q, gait.v, gait.t, period)

    out = {
        "parameters": PARAMETERS,
        "history": history,
        "check": check,
        "options": OPTIONS,
        "run_time": time.perf_counter() - started,
    }
    if args.plot:
        _plot(out, args.plot)
    if args.json:
        print(json.dumps(out, indent=2))
        return
    print(f"solo12 trot: largest Floquet-multiplier modulus against {', '.join(PARAMETERS)}")
    for row in history:
        vals = ", ".join(f"{v:.6g}" for v in row["values"])
        grads = ", ".join(f"{g:.4g}" for g in row["gradient"])
        print(
            f"  step {row['step']}: p = ({vals})  |λ_max| = {row['largest_modulus']:.6f}  "
            f"d|λ|/dp = ({grads})  [{row['run_time']:.0f} s]"
        )
    if check:
        print(
            "check at step 0, central differences of |λ_max| of re-converged gaits (h = 1e-3 |p|): "
            + ", ".join(
                f"{n}: {fd:.4g} (relative error {e:.1e})"
                for n, fd, e in zip(PARAMETERS, check["finite_differences"], check["relative_error"])
            )
        )
    print(f"total {out['run_time']:.0f} s" + (f"; plot written to {args.plot}" if args.plot else ""))


def _plot(out: dict, path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    history = out["history"]
    steps = [r["step"] for r in history]
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 3.8))
    a.plot(steps, [r["largest_modulus"] for r in history], "o-")
    a.set_xlabel("gradient step")
    a.set_ylabel("largest Floquet-multiplier modulus")
    a.set_title("solo12 trot: |λ_max| along the gradient")
    first = np.array(history[0]["values"])
    for k, name in enumerate(out["parameters"]):
        b.plot(steps, [r["values"][k] / first[k] for r in history], "o-", label=name)
    b.set_xlabel("gradient step")
    b.set_ylabel("parameter / its start value")
    b.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    main()
