"""The solo12 and ANYmal trots with sticking feet against Coulomb feet of coefficient μ.

Each trot scene (``solo12_trot``, ``anymal_trot``) is run as it is (feet ``friction="stick"``,
infinite friction) and with every foot contact replaced by the same contact with
``friction=μ``, with the run settings of ``contactdiff bench --speed``
(``simulate(scene, t_final)``, default options, 3 s). Prints, per robot and friction:
events by kind, impact-cascade bounces (``bounce`` events, and events whose
``nonsmooth`` holds ``ZENO_CASCADE``), slip events and the time feet spend slipping
(foot-seconds: segment durations times the number of sliding contacts, from
``traj.segments``), the run's wall time (median of ``--repeats``), accepted and
rejected steps, the final base height over the start's and the base tilt; upright:
the base ends at least half its start height, tilted less than 45 deg.
A run that raises is reported with its counts up to there, traceback, time reached and last events.

    python scripts/friction_trots.py                 # μ = 0.8, 3 s
    python scripts/friction_trots.py --mu 0.5 --repeats 3 --json
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import statistics
import sys
import time
import traceback
from collections import Counter

import numpy as np
import pinocchio as pin

import contactdiff as cd
from contactdiff.integration.trajectory import EVENT_KINDS

TROTS = ("solo12_trot", "anymal_trot")


def with_friction(scene: cd.Scene, mu: float) -> cd.Scene:
    """The scene with every contact's friction set to ``mu`` (as `Scene.with_robot` rebuilds a scene:
    the robot already carries the scene's gravity, so ``gravity=None`` keeps it)."""
    contacts = [dataclasses.replace(c.spec, friction=mu) for c in scene.contacts]
    out = cd.Scene(scene.robot, contacts, scene.effort_specs, None, scene.q0, scene.v0, scene.name)
    out.foot_choice = scene.foot_choice
    return out


def counts(events, segments) -> dict:
    """Events by kind, bounces, Zeno-cascade cut-offs, slips and foot-seconds slipping."""
    kinds = Counter(e.kind for e in events)
    return {"events": len(events), "kinds": {k: kinds.get(k, 0) for k in EVENT_KINDS},
            "bounces": kinds.get("bounce", 0), "slips": kinds.get("slip", 0),
            "zeno_cascades": sum(cd.NonSmooth.ZENO_CASCADE in e.nonsmooth for e in events),
            "slip_time": sum((s.t1 - s.t0) * len(s.sliding) for s in segments)}


def run(scene: cd.Scene, t_final: float, repeats: int) -> dict:
    """One scene's row: counts of the last run, median wall time; on an exception, the diagnosis."""
    walls, reached = [], [0.0, 0, 0]
    # what simulate(scene, t_final) runs; progress only records (t, events, accepted steps)
    options = cd.SimulateOptions(progress=lambda *p: reached.__setitem__(slice(None), p))
    for _ in range(repeats):
        loop = cd.HybridLoop(scene, 0.0, t_final, options=options)
        start = time.perf_counter()
        try:
            traj = loop.run()
        except Exception as exc:  # reported, not fixed
            last = loop.segments[-1] if loop.segments else None
            return counts(loop.events, loop.segments) | {
                "error": f"{type(exc).__name__}: {exc}", "traceback": traceback.format_exc(),
                "wall": time.perf_counter() - start, "t_reached": last.t1 if last else 0.0, "steps": reached[2],
                "last_events": [dict(t=e.t, kind=e.kind, contacts=list(e.contacts), mode_after=list(e.mode_after),
                                     sliding=list(e.sliding), nonsmooth=[r.name for r in e.nonsmooth])
                                for e in loop.events[-8:]],
                "last_mode": list(last.mode) if last else [], "last_sliding": list(last.sliding) if last else []}
        walls.append(time.perf_counter() - start)
    up = pin.Quaternion(traj.q[6], *traj.q[3:6]).toRotationMatrix()[:, 2]
    tilt = float(np.degrees(np.arccos(np.clip(up[2], -1.0, 1.0))))
    height, start_height = float(traj.q[2]), float(scene.q0[2])
    return counts(traj.events, traj.segments) | {
        "wall": statistics.median(walls), "walls": walls, "steps": traj.stats.steps,
        "rejected_steps": traj.stats.rejected_steps, "termination": str(traj.termination),
        "base_height": height, "start_height": start_height, "tilt_deg": tilt,
        "upright": height >= 0.5 * start_height and tilt < 45.0}


def table(rows: list[dict], t_final: float) -> str:
    """The rows as a table, then the failures' diagnoses."""
    short = {"touchdown": "td", "lift-off": "lo", "slip": "slip", "stick": "stick", "bounce": "bnc",
             "grazing": "graz", "zeno": "zeno"}
    head = " ".join(f"{short[k]:>5}" for k in EVENT_KINDS)
    lines = [f"scene        friction events {head}  zenoC  slip s  wall s  steps  rej   base m (start)  "
             f"tilt  upright"]
    fails = []
    for r in rows:
        cells = (f"{r['scene']:<12} {r['friction']:>8} {r['events']:6d} "
                 + " ".join(f"{r['kinds'][k]:5d}" for k in EVENT_KINDS)
                 + f"  {r['zeno_cascades']:5d}  {r['slip_time']:6.3f}  {r['wall']:6.2f}  {r['steps']:5d}  ")
        if "error" in r:
            lines.append(cells + f"FAILED at t = {r['t_reached']:.6g} s: {r['error'].split(':')[0]} (below)")
            fails.append(r)
        else:
            lines.append(cells + f"{r['rejected_steps']:4d}  {r['base_height']:.3f} ({r['start_height']:.3f})  "
                         f"{r['tilt_deg']:4.1f}  {r['upright']}")
    lines.append(f"{t_final:g} s each; td touchdown, lo lift-off, bnc bounce, graz grazing; zenoC: events with "
                 "NonSmooth.ZENO_CASCADE; slip s: foot-seconds slipping; wall: median; rej: rejected steps; "
                 "tilt: base z axis from vertical (deg); a FAILED row counts up to the failure")
    for r in fails:
        lines += [f"\n--- {r['scene']} friction={r['friction']}: {r['error']}", r["traceback"].rstrip(),
                  f"time reached {r['t_reached']!r} s; mode {r['last_mode']}, sliding {r['last_sliding']}; "
                  "last events:"]
        lines += [f"  {e}" for e in r["last_events"]]
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mu", type=float, default=0.8, help="Coulomb coefficient of the feet")
    parser.add_argument("--t-final", type=float, default=3.0, help="simulated time of each run (s)")
    parser.add_argument("--repeats", type=int, default=1, help="timed runs per case (median kept)")
    parser.add_argument("--scenes", nargs="+", default=list(TROTS))
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    rows = []
    for name in args.scenes:
        stick = cd.load_scene(name)
        for friction, scene in (("stick", stick), (args.mu, with_friction(stick, args.mu))):
            print(f"running {name} friction={friction} for {args.t_final:g} s x {args.repeats} ...",
                  file=sys.stderr, flush=True)
            row = {"scene": name, "friction": friction} | run(scene, args.t_final, args.repeats)
            done = row.get("error") or f"{row['events']} events, {row['wall']:.2f} s wall"
            print(f"  done: {done}", file=sys.stderr, flush=True)
            rows.append(row)
    print(json.dumps(rows, indent=2) if args.json else table(rows, args.t_final))


if __name__ == "__main__":
    main()
