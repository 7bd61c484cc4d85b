"""Record, or compare, the events and final states of real cube tosses: a check that a
change to the simulator leaves its runs as they were.

``record`` runs the first ``--limit`` tosses of a tosses file at the nominal friction
and restitution (`contactdiff.cube_scene`) and writes, per toss, each event's kind,
contacts and time (s) and the final time, configuration and velocity to a ``.npz``
file; ``compare`` reads two such files and reports, per toss, whether the event lists
agree (the same kinds and contacts in the same order, times within ``--time-tol``)
and the largest difference of the final states. Run the code before a change with
``PYTHONPATH`` set to an exported copy of it:

    mkdir ../base && git archive BASE | tar -x -C ../base
    PYTHONPATH=../base python scripts/toss_events.py record old.npz --tosses TOSSES --limit 20
    python scripts/toss_events.py record new.npz --tosses TOSSES --limit 20
    python scripts/toss_events.py compare old.npz new.npz

(``TOSSES``: a tosses file, such as ``../shared/data/cube_tosses/tosses.npz``.)
``compare`` exits 1 if any toss differs beyond the tolerances, 0 otherwise; their
defaults, 1e-9 s on event times and 1e-6 on final states, are loose bounds of the
integration's error at default tolerances (rtol 1e-8); ``--time-tol 0 --state-tol 0``
asks for the same runs bit for bit.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np


def record(path: str, tosses: str | None, limit: int) -> int:
    """Run the first ``limit`` tosses and write their events and final states to ``path``."""
    import contactdiff as cd
    from contactdiff.data.cube_tosses import load_tosses

    scene = cd.cube_scene()
    out: dict[str, np.ndarray] = {}
    names = list(load_tosses(tosses).items())[:limit]
    started = time.process_time()
    for name, toss in names:
        q0, v0 = toss.state(0)
        traj = cd.simulate(scene.with_state(q0, v0), float(toss.t[-1]), t0=float(toss.t[0]))
        events = [[str(e.kind), list(e.contacts), float(e.t)] for e in traj.events]
        out[f"{name}:events"] = np.array(json.dumps(events))
        out[f"{name}:final"] = np.concatenate([[traj.t], traj.q, traj.v])
    np.savez(path, **out)
    print(f"{len(names)} tosses recorded in {time.process_time() - started:.1f} s of CPU")
    return 0


def compare(old_path: str, new_path: str, time_tol: float, state_tol: float) -> int:
    """Compare two recordings (module doc); 1 if any toss differs beyond the tolerances."""
    with np.load(old_path) as old, np.load(new_path) as new:
        names = sorted({k.split(":")[0] for k in old.files} & {k.split(":")[0] for k in new.files})
        bad = 0
        events = 0
        worst_t = worst_x = 0.0
        for name in names:
            a = json.loads(str(old[f"{name}:events"]))
            b = json.loads(str(new[f"{name}:events"]))
            same = len(a) == len(b) and all(x[:2] == y[:2] for x, y in zip(a, b))
            dt = max((abs(x[2] - y[2]) for x, y in zip(a, b)), default=0.0) if same else np.inf
            fa, fb = old[f"{name}:final"], new[f"{name}:final"]
            dx = float(np.abs(fa - fb).max()) if fa.shape == fb.shape else np.inf
            events += len(a)
            worst_t, worst_x = max(worst_t, dt), max(worst_x, dx)
            ok = same and dt <= time_tol and dx <= state_tol
            bad += not ok
            if not ok:
                print(
                    f"{name}: {len(a)} vs {len(b)} events, same kinds and contacts {same}, "
                    f"time diff {dt:.3g} s, final state diff {dx:.3g}"
                )
    print(
        f"{len(names)} tosses, {events} events: {len(names) - bad} agree; largest event-time difference "
        f"{worst_t:.3g} s, largest final-state difference {worst_x:.3g}"
    )
    return 1 if bad else 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    rec = sub.add_parser("record", help="run tosses and write their events")
    rec.add_argument("output", help="the .npz file to write")
    rec.add_argument("--tosses", help="a tosses .npz file (default: the 24 shipped with the package)")
    rec.add_argument("--limit", type=int, default=20, help="the first N tosses (default 20)")
    cmp_ = sub.add_parser("compare", help="compare two recordings")
    cmp_.add_argument("old")
    cmp_.add_argument("new")
    cmp_.add_argument("--time-tol", type=float, default=1e-9, help="event times, s (default 1e-9)")
    cmp_.add_argument("--state-tol", type=float, default=1e-6, help="final states (default 1e-6)")
    args = parser.parse_args(argv)
    if args.command == "record":
        if args.limit < 1:
            parser.error(f"--limit must be at least 1; got {args.limit}")
        return record(args.output, args.tosses, args.limit)
    return compare(args.old, args.new, args.time_tol, args.state_tol)


if __name__ == "__main__":
    sys.exit(main())
