"""Every measured cube toss simulated from its first sample to its last.

Runs the cube scene (`contactdiff.cube_scene`: eight Coulomb corners, nominal edge,
mass and inertia) from each toss's first sample to its last, through the sweep
engine on every core, at the nominal friction and restitution (μ 0.18, e 0.125)
and at μ in {0.1, 0.3, 0.5} with e in {0, 0.3}. Reports per setting: tosses that
finish (reach their last sample's time without an error), events by kind,
non-differentiable events by reason, and the median and worst wall time of one
toss (the run alone, in its worker); then the errors, if any.

    python scripts/cube_toss_runs.py --tosses ../shared/data/cube_tosses/tosses.npz
    python scripts/cube_toss_runs.py --nominal-only --json       # the shipped 24, nominal
    python scripts/cube_toss_runs.py --quick                     # 3 shipped tosses, nominal
    python scripts/cube_toss_runs.py --setting 0.5 0.3 --limit 40  # one setting, 40 tosses
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from collections import Counter

import contactdiff as cd
from contactdiff.data.cube_tosses import NOMINAL, load_tosses
from contactdiff.integration.trajectory import EVENT_KINDS, NonSmooth

SETTINGS = [(NOMINAL.friction, NOMINAL.restitution)] + [(mu, e) for mu in (0.1, 0.3, 0.5) for e in (0.0, 0.3)]


def summarise(rows) -> dict:
    """The counts of one setting's rows (module doc)."""
    done = [r for r in rows if r.error is None and abs(r.outputs["t_end"] - r.outputs["t_data"]) <= 1e-9]
    walls = [r.outputs["wall"] for r in done]
    events = Counter()
    reasons = Counter()
    for r in done:
        events.update({k: r.outputs[f"events:{k}"] for k in EVENT_KINDS})
        reasons.update({n.name: r.outputs[f"nonsmooth:{n.name}"] for n in NonSmooth})
    return {
        "tosses": len(rows),
        "finished": len(done),
        "events": dict(events),
        "nonsmooth": dict(reasons),
        "tosses_not_differentiable": sum(r.outputs["not_differentiable"] > 0 for r in done),
        "wall_median": statistics.median(walls) if walls else None,
        "wall_max": max(walls, default=None),
        "slowest": sorted(((r.outputs["wall"], r.point["job:toss"]) for r in done), reverse=True)[:3],
        "errors": [f"{r.point['job:toss']}: {r.error.kind}: {r.error.message}" for r in rows if r.error],
    }


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tosses", help="a tosses .npz file (default: the 24 shipped with the package)")
    parser.add_argument("--nominal-only", action="store_true", help="only the nominal friction and restitution")
    parser.add_argument("--quick", action="store_true", help="three shipped tosses at the nominal setting")
    parser.add_argument(
        "--setting",
        nargs=2,
        type=float,
        action="append",
        metavar=("MU", "E"),
        help="run this friction coefficient and restitution instead of the seven settings (repeatable)",
    )
    parser.add_argument("--limit", type=int, default=None, help="only the first N tosses of the file")
    parser.add_argument("--jobs", type=int, default=None, help="worker processes (default: one per core)")
    parser.add_argument("--json", action="store_true", help="print the summary as JSON")
    args = parser.parse_args(argv)
    names = list(load_tosses(args.tosses))
    if args.setting and (args.nominal_only or args.quick):
        parser.error("--setting chooses the settings: give it without --nominal-only and --quick")
    settings = [(mu, e) for mu, e in args.setting] if args.setting else SETTINGS
    if args.nominal_only or args.quick:
        settings = SETTINGS[:1]
    if args.quick:
        names = names[:3]
    if args.limit is not None:
        names = names[: args.limit]
    fixed = {"job:tosses": args.tosses} if args.tosses else {}
    points = [{"arg:friction": mu, "arg:restitution": e, "job:toss": name} for mu, e in settings for name in names]
    started = time.perf_counter()
    result = cd.sweep(
        "contactdiff.data.cube_tosses:cube_scene",
        points,
        job="contactdiff.data.cube_tosses:run_toss",
        fixed=fixed,
        n_jobs=args.jobs,
    )
    wall = time.perf_counter() - started
    summary = {"wall_total": wall, "settings": []}
    for mu, e in settings:
        rows = [r for r in result if r.point["arg:friction"] == mu and r.point["arg:restitution"] == e]
        summary["settings"].append({"friction": mu, "restitution": e, **summarise(rows)})
    if args.json:
        print(json.dumps(summary, indent=1))
        return 0
    print(f"{len(names)} tosses x {len(settings)} settings in {wall:.1f} s wall")
    print(
        f"{'mu':>5} {'e':>5} {'done':>9} {'events by kind':<60} {'not diff. (tosses)':>18} "
        f"{'wall median / max (s)':>22}"
    )
    for s in summary["settings"]:
        kinds = " ".join(f"{k} {n}" for k, n in s["events"].items() if n)
        median = "-" if s["wall_median"] is None else f"{s['wall_median']:.3f} / {s['wall_max']:.3f}"
        print(
            f"{s['friction']:>5g} {s['restitution']:>5g} {s['finished']:>4}/{s['tosses']:<4} {kinds:<60} "
            f"{s['tosses_not_differentiable']:>18} {median:>22}"
        )
        reasons = ", ".join(f"{k} {n}" for k, n in s["nonsmooth"].items() if n)
        print(f"{'':>11} slowest: " + ", ".join(f"{name} {wall:.2f} s" for wall, name in s["slowest"]))
        print(f"{'':>11} non-differentiable events: {reasons or 'none'}")
        for line in s["errors"]:
            print(f"{'':>11} {line}")
    return 0 if all(s["finished"] == s["tosses"] for s in summary["settings"]) else 1


if __name__ == "__main__":
    sys.exit(main())
