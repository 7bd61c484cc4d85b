"""Approach a periodic trot of a quadruped and print its Floquet multipliers.

    python scripts/trot_floquet.py [--robot solo12] [--foot FL_FOOT] [--warmup 20]
                                   [--newton 4] [--rtol 1e-10] [--atol 1e-12] [--json]
    python scripts/trot_floquet.py --quick   # no warm-up, one Newton iteration, rtol 1e-8: a smoke run

The trot scene (`contactdiff.control.trot_scenes.trot_scene`: a clock-driven PD trot, sticking
plastic feet) starts standing at phase 0. The script

1. simulates ``--warmup`` clock periods without sensitivities (a stable gait
   settles towards its limit cycle by about its largest multiplier's modulus
   per period), then runs on to the next touchdown of ``--foot`` after a swing
   (a point of the section: the state just before that foot's impact; the
   re-landings of impact cascades are skipped, see `stride_map`'s min_flight);
2. runs ``--newton`` damped Newton iterations on the stride map of that foot
   (`contactdiff.analysis.gait.find_periodic_gait`: state and clock phase, with the
   neutral moves x, y, yaw removed), each stride with its Jacobian;
3. prints the residual of every iterate, the stride time, the drift per stride
   along the neutral moves, the multipliers (and their moduli) and the run
   times; then, as a check, the eigenvalues of the stroboscopic map over one
   clock period from mid-stride (`contactdiff.analysis.gait.period_map`), whose
   nonzero ones are the same multipliers.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from contactdiff.analysis.gait import find_periodic_gait, first_touchdown, period_map
from contactdiff.control.trot_scenes import trot_scene
from contactdiff.errors import ContactDiffError
from contactdiff.integration.hybrid import simulate


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default="solo12")
    parser.add_argument("--foot", default=None, help="section foot (default: the scene's first contact)")
    parser.add_argument("--warmup", type=int, default=20, help="clock periods simulated before the search")
    parser.add_argument("--newton", type=int, default=4, help="Newton iterations")
    parser.add_argument("--tol", type=float, default=1e-8, help="residual at which Newton stops")
    parser.add_argument("--rtol", type=float, default=1e-10)
    parser.add_argument("--atol", type=float, default=1e-12)
    parser.add_argument("--method", default="DOP853")
    parser.add_argument("--no-period-map", action="store_true", help="skip the stroboscopic check")
    parser.add_argument("--json", action="store_true")
    parser.add_argument(
        "--quick",
        action="store_true",
        help="a smoke run of seconds: no warm-up, one Newton iteration, rtol 1e-8, atol 1e-10",
    )
    args = parser.parse_args(argv)
    if args.quick:
        args.warmup, args.newton, args.rtol, args.atol = 0, 1, 1e-8, 1e-10

    options = dict(rtol=args.rtol, atol=args.atol, method=args.method)
    scene = trot_scene(args.robot)
    foot = args.foot or scene.contact_names[0]
    period = scene.effort_specs[0].period
    started = time.perf_counter()
    q, v, t = scene.q0, scene.v0, 0.0
    if args.warmup > 0:
        warm = simulate(scene, args.warmup * period, **options)
        q, v, t = warm.q, warm.v, warm.t
    t, q, v = first_touchdown(scene, foot, q, v, t, t_max=4 * period, **options)
    warmup_time = time.perf_counter() - started

    gait = find_periodic_gait(scene, foot, q, v, t, iterations=args.newton, tol=args.tol, t_max=4 * period, **options)
    result = gait.to_dict() | {
        "robot": args.robot,
        "warmup_periods": args.warmup,
        "warmup_run_time": warmup_time,
        **options,
    }
    if not args.no_period_map:
        began = time.perf_counter()
        mid = gait.t + 0.5 * gait.stride.stride_time
        halfway = simulate(scene, mid, gait.q, gait.v, t0=gait.t, **options)  # the fixed point, half a stride on
        qm, vm = halfway.q, halfway.v
        try:
            pm = period_map(scene, qm, vm, mid, **options)
        except ContactDiffError as exc:  # e.g. the mid-stride state is not a consistent start
            result["period_map"] = {"t0": mid, "error": str(exc)}
        else:
            lam = pm.multipliers
            result["period_map"] = {
                "t0": mid,
                "multipliers": [[float(x.real), float(x.imag)] for x in lam],
                "moduli": [float(abs(x)) for x in lam],
                "run_time": time.perf_counter() - began,
            }
    if args.json:
        print(json.dumps(result, indent=2))
        return
    print(
        f"{args.robot} trot, clock period {period:g} s, warm-up {args.warmup} periods "
        f"({warmup_time:.2f} s), rtol {args.rtol:g}, atol {args.atol:g}, {args.method}"
    )
    print(gait.format())
    if "period_map" in result and "error" in result["period_map"]:
        print(f"\nstroboscopic map: {result['period_map']['error']}")
    elif "period_map" in result:
        pmr = result["period_map"]
        nonzero = [m for m in pmr["moduli"] if m > 1e-6]
        print(
            f"\nstroboscopic map over one period from t = {pmr['t0']:.6g} s ({pmr['run_time']:.2f} s): "
            f"{len(nonzero)} multipliers with |λ| > 1e-6; largest moduli " + ", ".join(f"{m:.6g}" for m in nonzero[:8])
        )
        ours = np.sort([abs(m) for m in gait.multipliers if abs(m) > 1e-6])[::-1]
        print("stride-map moduli > 1e-6: " + ", ".join(f"{m:.6g}" for m in ours[:8]))


if __name__ == "__main__":
    main()
