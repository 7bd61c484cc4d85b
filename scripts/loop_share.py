"""How much of a run is the loop, and how fast a loop could make it: ours and the
`solve_ivp` baseline on the same dynamics.

For each scene and tolerance: our run time and the baseline's (best of 5 x 5
runs each, interleaved in one process), their dynamics evaluations, the cost of
one `ModeDynamics.solve` in the scene's last mode (best of 5 x 2000 calls), the
share of the baseline's time spent in the dynamics (its evaluations times that
cost), and the largest speed-up over the baseline that a loop taking the
baseline's evaluations could reach with no overhead at all (baseline time over
the dynamics' time alone).

    python scripts/loop_share.py
    python scripts/loop_share.py --quick   # one scene, one tolerance, single timings: a smoke run of seconds
"""

from __future__ import annotations

import argparse
import timeit

import contactdiff as cd
from contactdiff.bench.baselines import solve_ivp_baseline
from contactdiff.dynamics.mode import ModeDynamics

SCENES = {"two_limb": 2.0, "planar_trot_soft": 1.8}  # the bench's horizons (s)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--quick", action="store_true", help="two_limb over 0.5 s at tol 1e-6 only, each time taken once: seconds"
    )
    args = parser.parse_args(argv)
    scenes = {"two_limb": 0.5} if args.quick else SCENES
    tols = (1e-6,) if args.quick else (1e-6, 1e-9)
    runs, repeats, calls = (1, 1, 20) if args.quick else (5, 5, 2000)
    print(
        "scene              tol     ours ms  evals  baseline ms  evals  solve us  dynamics share  zero-overhead bound"
    )
    for name, t_final in scenes.items():
        scene = cd.load_scene(name)
        dyn = ModeDynamics(scene)
        for tol in tols:

            def ours():
                return cd.simulate(scene, t_final, rtol=tol, atol=tol * 1e-2)

            def baseline():
                return solve_ivp_baseline(scene, t_final, rtol=tol, atol=tol * 1e-2)

            t_ours = min(timeit.repeat(ours, number=runs, repeat=repeats)) / runs
            t_base = min(timeit.repeat(baseline, number=runs, repeat=repeats)) / runs
            run, base = ours(), baseline()
            mode = tuple(scene.contact_index(c) for c in run.modes[-1])
            cost = (
                min(timeit.repeat(lambda: dyn.solve(run.q, run.v, run.t, mode), number=calls, repeat=repeats)) / calls
            )
            n_base = base.stats.dynamics_evaluations
            share = n_base * cost / t_base
            print(
                f"{name:<18} {tol:5.0e}  {1e3 * t_ours:7.2f}  {run.stats.dynamics_evaluations:5d}  "
                f"{1e3 * t_base:11.2f}  {n_base:5d}  {1e6 * cost:8.1f}  {share:14.2f}  {1 / share:19.2f}"
            )


if __name__ == "__main__":
    main()
