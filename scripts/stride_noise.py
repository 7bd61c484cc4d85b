"""How finely a stride map is resolved: the same stride computed several ways.

    python scripts/stride_noise.py [--scene solo12_trot] [--foot FL_FOOT] [--warmup 8]
                                   [--perturb 4] [--size 1e-11] [--rtol 1e-10] [--atol 1e-12]
                                   [--events] [--json]
    python scripts/stride_noise.py --quick   # no warm-up, one moved start, rtol 1e-8, --events: a smoke run

From the scene's initial state the script simulates ``--warmup`` seconds and runs
on to the foot's next touchdown after a flight (the start of
``contactdiff stride SCENE --foot F --warmup W``). There it computes the reduced
residual ``r = Bᵀ (x' ⊖ x)`` of the stride map (section coordinates, neutral
moves removed, clock phase included; ``B`` fixed at that start):

1. with the stride's Jacobian (as the Newton search does) and without it: the
   same state equations, evaluated in another order (the Jacobian run uses the
   fused dynamics-and-derivatives evaluation), so any difference is rounding;
2. without the Jacobian at ``rtol`` and ``atol`` divided by 10 and by 100;
3. without the Jacobian from ``--perturb`` starts moved by ``--size`` along
   random section coordinates (put back onto the guard); the largest linear
   change of ``r`` over such a move, ``‖A‖ size`` with ``A = Bᵀ J B - I``, is
   printed beside the spread.

It prints ``|r|`` of each run and the pairwise ``|Δr|`` (min, median, max):
differences far above the integration tolerance and the linear change are
the map's noise, the floor below which no Newton iteration can bring the
residual. ``--events`` lists, event by event, how far the runs with and
without the Jacobian have parted (event time, velocities before and after).
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import time

import numpy as np
import pinocchio as pin

import contactdiff as cd
from contactdiff.analysis.gait import (
    align,
    available_neutral,
    first_touchdown,
    onto_section,
    scene_period,
    section_basis,
    stride_map,
)
from contactdiff.integration.hybrid import simulate
from contactdiff.integration.trajectory import NonSmooth


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="solo12_trot")
    parser.add_argument("--foot", default="FL_FOOT")
    parser.add_argument("--warmup", type=float, default=8.0, help="seconds simulated first")
    parser.add_argument("--perturb", type=int, default=4, help="perturbed starts")
    parser.add_argument("--size", type=float, default=1e-11, help="size of each perturbation (section coordinates)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--rtol", type=float, default=1e-10)
    parser.add_argument("--atol", type=float, default=1e-12)
    parser.add_argument("--method", default="DOP853")
    parser.add_argument("--events", action="store_true", help="where the runs with and without the Jacobian part")
    parser.add_argument("--json", action="store_true")
    parser.add_argument(
        "--quick",
        action="store_true",
        help="a smoke run of seconds: no warm-up, one moved start, rtol 1e-8, atol 1e-10, --events",
    )
    args = parser.parse_args(argv)
    if args.quick:
        args.warmup, args.perturb, args.rtol, args.atol, args.events = 0.0, 1, 1e-8, 1e-10, True

    scene = cd.load_scene(args.scene)
    period = scene_period(scene)
    opts = dict(rtol=args.rtol, atol=args.atol, method=args.method)
    began = time.perf_counter()
    q, v, t = scene.q0, scene.v0, 0.0
    if args.warmup > 0:
        warm = simulate(scene, args.warmup, **opts)
        q, v, t = warm.q, warm.v, warm.t
    t, q, v = first_touchdown(scene, args.foot, q, v, t, **opts)
    q = onto_section(scene, args.foot, q)
    neutral = available_neutral(scene, q, v, t)
    B = section_basis(scene, args.foot, q, neutral, period)
    setup = time.perf_counter() - began

    def residual(s) -> np.ndarray:
        q_aligned, _ = align(scene, s.q, s.q0, neutral)
        delta = np.concatenate([pin.difference(scene.model, s.q0, q_aligned), s.v - s.v0])
        if period is not None:
            delta = np.append(delta, math.remainder(s.t - s.t0, period))
        return B.T @ delta

    runs, strides = {}, {}

    def run(name, q=q, v=v, t=t, jacobian=False, rtol=args.rtol, atol=args.atol):
        c = time.perf_counter()
        s = stride_map(scene, args.foot, q, v, t, jacobian=jacobian, rtol=rtol, atol=atol, method=args.method)
        strides[name] = s
        runs[name] = {
            "residual": residual(s),
            "seconds": time.perf_counter() - c,
            "events": len(s.trajectory.events),
            "stride_time": s.stride_time,
        }

    run("Jacobian", jacobian=True)
    run("no Jacobian")
    for k in (10, 100):
        run(f"tolerances / {k}", rtol=args.rtol / k, atol=args.atol / k)
    rng = np.random.default_rng(args.seed)
    nv = scene.nv
    for j in range(args.perturb):
        d = rng.standard_normal(B.shape[1])
        step = B @ (d * args.size / np.linalg.norm(d))
        q1 = onto_section(scene, args.foot, pin.integrate(scene.model, q, step[:nv]))
        run(f"moved #{j}", q1, v + step[nv : 2 * nv], t + (step[2 * nv] if period is not None else 0.0))

    names = list(runs)
    diffs = [
        float(np.linalg.norm(runs[a]["residual"] - runs[b]["residual"]))
        for i, a in enumerate(names)
        for b in names[i + 1 :]
    ]
    A = B.T @ strides["Jacobian"].extended_jacobian() @ B - np.eye(B.shape[1])
    linear = float(np.linalg.norm(A, 2)) * args.size
    result = {
        "scene": args.scene,
        "foot": args.foot,
        "warmup": args.warmup,
        "t": t,
        "rtol": args.rtol,
        "atol": args.atol,
        "setup_seconds": setup,
        "runs": {
            n: {
                "norm": float(np.linalg.norm(r["residual"])),
                "seconds": r["seconds"],
                "events": r["events"],
                "stride_time": r["stride_time"],
            }
            for n, r in runs.items()
        },
        "pairwise": {"min": min(diffs), "median": statistics.median(diffs), "max": max(diffs)},
        "A_norm": float(np.linalg.norm(A, 2)),
        "linear_change": linear,
        "perturbation": args.size,
    }
    if args.json:
        print(json.dumps(result, indent=2))
        return
    print(
        f"{args.scene}, stride map of {args.foot} from its touchdown at t = {t:.12g} s "
        f"(warm-up {args.warmup:g} s, {setup:.1f} s), rtol {args.rtol:g}, atol {args.atol:g}, {args.method}"
    )
    for n, r in result["runs"].items():
        print(
            f"  {n:<20} |r| = {r['norm']:.3e}   stride {r['stride_time']:.12f} s, "
            f"{r['events']} events, {r['seconds']:.1f} s"
        )
    p = result["pairwise"]
    print(f"  pairwise |Δr| over {len(diffs)} pairs: min {p['min']:.2e}, median {p['median']:.2e}, max {p['max']:.2e}")
    print(f"  ‖A‖ = {result['A_norm']:.3g}: a move of {args.size:g} changes r by at most {linear:.1e} (linear)")
    if args.events:
        print("  event by event, with against without the Jacobian:")
        for x, y in zip(strides["Jacobian"].trajectory.events, strides["no Jacobian"].trajectory.events):
            same = (
                ""
                if x.contacts == y.contacts and x.kind == y.kind
                else f"  (other run: {y.kind} {'+'.join(y.contacts)})"
            )
            print(
                f"    {x.t:.12f}  {x.kind:<9} {'+'.join(x.contacts):<24} Δt {abs(x.t - y.t):.1e} s  "
                f"|Δv-| {np.abs(x.v_minus - y.v_minus).max():.1e}  "
                f"|Δv+| {np.abs(x.v_plus - y.v_plus).max():.1e}{same}"
            )
        for event in strides["Jacobian"].trajectory.events:
            if NonSmooth.ZENO_CASCADE in event.nonsmooth:
                print(f"    {event.nonsmooth[NonSmooth.ZENO_CASCADE]}")


if __name__ == "__main__":
    main()
