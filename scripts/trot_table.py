"""The trots of the six quadrupeds over 3 s: events, stances, base motion, run time.

Regenerates the table of docs/results/trot.md. For each robot, one run of
``cd.simulate(trot_scene(name), T)`` is timed (``time.perf_counter``) with its
dense output off (as a user's run is), then run again with ``dense=True`` to
sample the base (3,000 points). Prints, per robot: events and their kinds,
touchdowns per foot (stances of `stance_intervals` that begin after the start), lift-offs that start as slips, base
height range, largest |roll| and |pitch|, steps, rejected over accepted steps,
and the run time.

    python scripts/trot_table.py            # all six, 3 s each
    python scripts/trot_table.py --robots solo12 anymal --json
    python scripts/trot_table.py --quick    # solo12 over 0.2 s: a smoke run
"""

from __future__ import annotations

import argparse
import json
import time
from collections import Counter

import numpy as np
import pinocchio as pin

import contactdiff as cd
from contactdiff.analysis.gait.stances import stance_intervals
from contactdiff.control.trot_scenes import trot_scene


def row(name: str, t_final: float) -> dict:
    """One robot's row (module doc)."""
    scene = trot_scene(name)
    start = time.perf_counter()
    traj = cd.simulate(scene, t_final)
    wall = time.perf_counter() - start
    dense = cd.simulate(scene, t_final, dense=True)
    qs, _ = dense.sample(np.linspace(0.0, t_final, 3000))
    rpy = np.array([pin.rpy.matrixToRpy(pin.Quaternion(q[6], *q[3:6]).toRotationMatrix()) for q in qs])
    # touchdowns: stances that begin after the start (pair A starts on the ground)
    touchdowns = [sum(1 for t0, _ in stance_intervals(traj, c.name) if t0 > 0.0) for c in scene.contacts]
    kinds = Counter(e.kind for e in traj.events)
    return {
        "robot": name,
        "events": len(traj.events),
        "kinds": dict(kinds),
        "same_events_dense": [(e.kind, e.contacts) for e in dense.events]
        == [(e.kind, e.contacts) for e in traj.events],
        "touchdowns_per_foot": [min(touchdowns), max(touchdowns)],
        "slips": kinds.get("slip", 0),
        "lift_offs": kinds.get("lift-off", 0),
        "base_height": [float(qs[:, 2].min()), float(qs[:, 2].max())],
        "start_height": float(scene.q0[2]),
        "max_roll": float(np.abs(rpy[:, 0]).max()),
        "max_pitch": float(np.abs(rpy[:, 1]).max()),
        "steps": traj.stats.steps,
        "rejected_over_accepted": traj.stats.rejected_steps / traj.stats.steps,
        "run_time": wall,
    }


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", nargs="+", default=list(cd.QUADRUPEDS))
    parser.add_argument("--t-final", type=float, default=3.0)
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--quick", action="store_true", help="solo12 over 0.2 s: a smoke run")
    args = parser.parse_args(argv)
    if args.quick:
        args.robots, args.t_final = ["solo12"], 0.2
    rows = [row(name, args.t_final) for name in args.robots]
    if args.json:
        print(json.dumps(rows, indent=2))
        return
    print(
        "robot    events  touchdowns/foot  slips/lift-offs  base height (m)        max|roll| max|pitch|  steps  "
        "rejected  run time (s)"
    )
    for r in rows:
        lo, hi = r["base_height"]
        print(
            f"{r['robot']:<8} {r['events']:6d}  {r['touchdowns_per_foot'][0]}-{r['touchdowns_per_foot'][1]:<13} "
            f"{r['slips']:5d}/{r['lift_offs']:<9d}  {lo:.3f}-{hi:.3f} ({r['start_height']:.3f})  "
            f"{r['max_roll']:8.3f} {r['max_pitch']:9.3f}  {r['steps']:5d}  {r['rejected_over_accepted']:7.1%}  "
            f"{r['run_time']:8.2f}"
        )
        print(f"         kinds: {r['kinds']}; same events with dense output: {r['same_events_dense']}")


if __name__ == "__main__":
    main()
