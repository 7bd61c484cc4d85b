"""The solo12 and ANYmal trots with sticking feet against Coulomb feet of coefficient μ.

Each trot scene (``solo12_trot``, ``anymal_trot``) is run as it is (feet ``friction="stick"``,
infinite friction) and with every foot contact replaced by the same contact with
``friction=μ`` (each μ given), with the run settings of ``contactdiff bench --speed``
(``simulate(scene, t_final)``, default options, 3 s). Prints, per robot and friction:
events by kind, impact-cascade bounces (``bounce`` events, and events whose
``nonsmooth`` holds ``ZENO_CASCADE``), slip events and the time feet spend slipping
(foot-seconds: segment durations times the number of sliding contacts, from
``traj.segments``), the run's wall time (median of ``--repeats``), accepted and
rejected steps, the final base height over the start's and the base tilt; upright:
the base ends at least half its start height, tilted less than 45 deg.
A run that raises is reported with its counts up to there, traceback, time reached and last events.

    python scripts/friction_trots.py                 # μ = 0.7 and 0.8, 3 s
    python scripts/friction_trots.py --mu 0.5 --repeats 3 --json
    python scripts/friction_trots.py --profile       # and where the Coulomb runs' time goes
    python scripts/friction_trots.py --mu 0.8 --scenes solo12_trot --jacobian --profile  # with the flow Jacobian
    python scripts/friction_trots.py --mu 0.8 --scenes solo12_trot --jacobian-cost --reference
        # the flow Jacobian's cost and accuracy under each jacobian_error
    python scripts/friction_trots.py --quick         # solo12, μ = 0.7, 0.2 s, profiled: a smoke run
"""

from __future__ import annotations

import argparse
import bisect
import json
import math
import statistics
import sys
import time
import traceback
from collections import Counter
from contextlib import contextmanager

import numpy as np
import pinocchio as pin

import contactdiff as cd
from contactdiff.integration.options import JacobianError
from contactdiff.integration.trajectory import EVENT_KINDS

TROTS = ("solo12_trot", "anymal_trot")


def counts(events, segments) -> dict:
    """Events by kind, bounces, Zeno-cascade cut-offs, slips and foot-seconds slipping."""
    kinds = Counter(e.kind for e in events)
    return {
        "events": len(events),
        "kinds": {k: kinds.get(k, 0) for k in EVENT_KINDS},
        "bounces": kinds.get("bounce", 0),
        "slips": kinds.get("slip", 0),
        "zeno_cascades": sum(cd.NonSmooth.ZENO_CASCADE in e.nonsmooth for e in events),
        "slip_time": sum((s.t1 - s.t0) * len(s.sliding) for s in segments),
    }


@contextmanager
def where_time_goes(record: list):
    """Record each accepted step of the steppers as ``(t_old, t, rejected attempts, wall s, evaluations)``
    (evaluations: the stepper's ``accel`` calls in the step and its rejected attempts) and each
    impact as ``("impact", wall s)`` into ``record``, for this run only (timers wrapped around
    ``step`` and the loop's ``resolve_impact``)."""
    from contactdiff.integration import event_resets
    from contactdiff.ode.explicit_rk import ExplicitRK
    from contactdiff.ode.radau import Radau

    steps = {cls: cls.step for cls in (ExplicitRK, Radau)}
    impact = event_resets.resolve_impact

    def timed_step(original):
        def step(self):
            t_old, rejected, evals, start = self.t, self.n_rejected, self.n_accel, time.perf_counter()
            original(self)
            record.append(
                (t_old, self.t, self.n_rejected - rejected, time.perf_counter() - start, self.n_accel - evals)
            )

        return step

    def timed_impact(*args, **kwargs):
        start = time.perf_counter()
        try:
            return impact(*args, **kwargs)
        finally:
            record.append(("impact", time.perf_counter() - start))

    try:
        for cls, original in steps.items():
            cls.step = timed_step(original)
        event_resets.resolve_impact = timed_impact
        yield record
    finally:
        for cls, original in steps.items():
            cls.step = original
        event_resets.resolve_impact = impact


def _decade(seconds: float) -> str:
    """``"1e-6"`` for a time from 1e-6 to 1e-5 s."""
    return f"1e{math.floor(math.log10(max(seconds, 1e-300)))}"


def time_shares(record: list, segments, wall: float, events=()) -> dict:
    """Wall time of steps inside segments with a slipping contact, of the other steps and of
    impacts, with the steps' counts, their evaluations of the field, the simulated time (s: a step
    that crossed an event, which the loop cut back to it, counts up to the segment's end) and
    the evaluations per simulated second; ``slip_to_other``: the ratio of the two parts' rates.
    ``one_step_floor``: the ratio if each slipping segment took a single step of the other steps'
    mean cost (a floor for any method that steps through each slip).
    ``stops``: of the slipping segments, those that end in a ``stick`` event (of ``events``): their
    count, evaluations, and evaluations by decade of the time left to the stop at the step's start
    (``"1e-6"``: from 1e-6 to 1e-5 s); ``onsets``: the others that begin with a ``slip`` event (a
    contact leaving its cone), by decade of the time since the onset at the step's end."""
    starts = [seg.t0 for seg in segments]
    stop_times = {e.t for e in events if e.kind == "stick"}
    onset_times = {e.t for e in events if e.kind == "slip"}
    out = {
        part: {"wall": 0.0, "steps": 0, "rejected": 0, "evaluations": 0, "sim_time": 0.0}
        for part in ("slipping", "other")
    }
    stops = {
        "segments": sum(bool(seg.sliding) and seg.t1 in stop_times for seg in segments),
        "evaluations": 0,
        "by_time_left": Counter(),
    }
    onsets = {
        "segments": sum(bool(seg.sliding) and seg.t1 not in stop_times and seg.t0 in onset_times for seg in segments),
        "evaluations": 0,
        "by_time_since": Counter(),
    }
    impacts = 0.0
    for item in record:
        if item[0] == "impact":
            impacts += item[1]
            continue
        t_old, t, rejected, seconds, evaluations = item
        seg = segments[max(0, bisect.bisect_right(starts, t_old) - 1)]
        part = out["slipping" if seg.sliding else "other"]
        part["wall"] += seconds
        part["steps"] += 1
        part["rejected"] += rejected
        part["evaluations"] += evaluations
        part["sim_time"] += min(t, seg.t1) - t_old  # a step that crossed an event counts up to it
        if seg.sliding and seg.t1 in stop_times:
            stops["evaluations"] += evaluations
            stops["by_time_left"][_decade(seg.t1 - t_old)] += evaluations
        elif seg.sliding and seg.t0 in onset_times:
            onsets["evaluations"] += evaluations
            onsets["by_time_since"][_decade(min(t, seg.t1) - seg.t0)] += evaluations
    for part in out.values():
        part["evaluations_per_s"] = part["evaluations"] / part["sim_time"] if part["sim_time"] > 0 else 0.0
    rates = out["slipping"]["evaluations_per_s"], out["other"]["evaluations_per_s"]
    out["slipping"]["segments"] = sum(bool(seg.sliding) for seg in segments)
    per_step = out["other"]["evaluations"] / max(1, out["other"]["steps"])
    slip_time = out["slipping"]["sim_time"]
    floor = out["slipping"]["segments"] * per_step / slip_time if slip_time > 0 else 0.0
    for part, key in ((stops, "by_time_left"), (onsets, "by_time_since")):
        part[key] = dict(sorted(part[key].items(), key=lambda kv: float(kv[0])))
    return out | {
        "slip_to_other": rates[0] / rates[1] if rates[1] > 0 else float("nan"),
        "stops": stops,
        "one_step_floor": floor / rates[1] if rates[1] > 0 else float("nan"),
        "onsets": onsets,
        "impacts": {"wall": impacts},
        "rest": {"wall": wall - impacts - out["slipping"]["wall"] - out["other"]["wall"]},
    }


def run(
    scene: cd.Scene,
    t_final: float,
    repeats: int,
    profile: bool = False,
    jacobian: bool = False,
    jacobian_error: str = JacobianError.CONTROL,
) -> dict:
    """One scene's row: counts of the last run, median wall time; on an exception, the diagnosis;
    with ``profile`` one more run with `where_time_goes`."""
    walls, reached = [], [0.0, 0, 0]
    # what simulate(scene, t_final) runs; progress only records (t, events, accepted steps)
    options = cd.SimulateOptions(
        progress=lambda *p: reached.__setitem__(slice(None), p), jacobian=jacobian, jacobian_error=jacobian_error
    )
    for _ in range(repeats):
        loop = cd.HybridLoop(scene, 0.0, t_final, options=options)
        start = time.perf_counter()
        try:
            traj = loop.run()
        except Exception as exc:  # reported, not fixed
            last = loop.segments[-1] if loop.segments else None
            return counts(loop.events, loop.segments) | {
                "error": f"{type(exc).__name__}: {exc}",
                "traceback": traceback.format_exc(),
                "wall": time.perf_counter() - start,
                "t_reached": last.t1 if last else 0.0,
                "steps": reached[2],
                "last_events": [
                    dict(
                        t=e.t,
                        kind=e.kind,
                        contacts=list(e.contacts),
                        mode_after=list(e.mode_after),
                        sliding=list(e.sliding),
                        nonsmooth=[r.name for r in e.nonsmooth],
                    )
                    for e in loop.events[-8:]
                ],
                "last_mode": list(last.mode) if last else [],
                "last_sliding": list(last.sliding) if last else [],
            }
        walls.append(time.perf_counter() - start)
    up = pin.Quaternion(traj.q[6], *traj.q[3:6]).toRotationMatrix()[:, 2]
    tilt = float(np.degrees(np.arccos(np.clip(up[2], -1.0, 1.0))))
    height, start_height = float(traj.q[2]), float(scene.q0[2])
    return (
        counts(traj.events, traj.segments)
        | {
            "wall": statistics.median(walls),
            "walls": walls,
            "steps": traj.stats.steps,
            "rejected_steps": traj.stats.rejected_steps,
            "termination": str(traj.termination),
            "base_height": height,
            "start_height": start_height,
            "tilt_deg": tilt,
            "upright": height >= 0.5 * start_height and tilt < 45.0,
        }
        | (_profiled(scene, t_final, jacobian, jacobian_error) if profile else {})
    )


def _profiled(
    scene: cd.Scene, t_final: float, jacobian: bool = False, jacobian_error: str = JacobianError.CONTROL
) -> dict:
    record = []
    with where_time_goes(record):
        start = time.perf_counter()
        traj = cd.simulate(scene, t_final, jacobian=jacobian, jacobian_error=jacobian_error)
        wall = time.perf_counter() - start
    return {"profile": time_shares(record, traj.segments, wall, traj.events) | {"total": {"wall": wall}}}


def _column_error(J: np.ndarray, ref: np.ndarray) -> tuple[float, float]:
    """Largest and median over the columns of ``max |J - ref|`` over the column's ``max |ref|``."""
    err = np.abs(J - ref).max(axis=0) / np.abs(ref).max(axis=0)
    return float(err.max()), float(np.median(err))


def jacobian_costs(scene: cd.Scene, t_final: float, reference: bool = False) -> dict:
    """The flow Jacobian's cost in plain runs under each `JacobianError`, in one process: a plain
    run, then one with ``jacobian=True`` per setting (counts, wall, wall over the plain run's),
    and the largest difference between the settings' Jacobians per column, relative to the
    column's largest entry under ``"control"``; with ``reference`` each setting's column errors
    against a run at rtol 1e-11, atol 1e-13 under ``"control"`` (and whether its events match)."""
    out: dict = {}
    start = time.perf_counter()
    plain = cd.simulate(scene, t_final)
    out["plain"] = {
        "wall": time.perf_counter() - start,
        "steps": plain.stats.steps,
        "rejected": plain.stats.rejected_steps,
        "evaluations": plain.stats.stepper_evaluations,
    }
    jacobians = {}
    for setting in JacobianError:
        start = time.perf_counter()
        traj = cd.simulate(scene, t_final, jacobian=True, jacobian_error=setting)
        wall = time.perf_counter() - start
        jacobians[setting] = traj.jacobian
        out[setting.value] = {
            "wall": wall,
            "ratio": wall / out["plain"]["wall"],
            "steps": traj.stats.steps,
            "rejected": traj.stats.rejected_steps,
            "evaluations": traj.stats.stepper_evaluations,
            "jacobian_evaluations": traj.stats.jacobian_evaluations,
            "events": len(traj.events),
            "same_state": bool(np.array_equal(traj.q, plain.q) and np.array_equal(traj.v, plain.v)),
        }
    out["state_vs_control_column_rel"] = _column_error(
        jacobians[JacobianError.STATE], jacobians[JacobianError.CONTROL]
    )[0]
    if reference:
        ref = cd.simulate(scene, t_final, jacobian=True, rtol=1e-11, atol=1e-13)
        out["reference"] = {"events": len(ref.events)} | {
            setting.value: _column_error(J, ref.jacobian) for setting, J in jacobians.items()
        }
    return out


def table(rows: list[dict], t_final: float) -> str:
    """The rows as a table, then the failures' diagnoses."""
    short = {
        "touchdown": "td",
        "lift-off": "lo",
        "slip": "slip",
        "stick": "stick",
        "bounce": "bnc",
        "grazing": "graz",
        "zeno": "zeno",
        "bear": "bear",
    }
    head = " ".join(f"{short[k]:>5}" for k in EVENT_KINDS)
    lines = [f"scene        friction events {head}  zenoC  slip s  wall s  steps  rej   base m (start)  tilt  upright"]
    fails = []
    for r in rows:
        if "jacobian_costs" in r:  # no table row: its lines follow
            continue
        cells = (
            f"{r['scene']:<12} {r['friction']:>8} {r['events']:6d} "
            + " ".join(f"{r['kinds'][k]:5d}" for k in EVENT_KINDS)
            + f"  {r['zeno_cascades']:5d}  {r['slip_time']:6.3f}  {r['wall']:6.2f}  {r['steps']:5d}  "
        )
        if "error" in r:
            lines.append(cells + f"FAILED at t = {r['t_reached']:.6g} s: {r['error'].split(':')[0]} (below)")
            fails.append(r)
        else:
            lines.append(
                cells + f"{r['rejected_steps']:4d}  {r['base_height']:.3f} ({r['start_height']:.3f})  "
                f"{r['tilt_deg']:4.1f}  {r['upright']}"
            )
    lines.append(
        f"{t_final:g} s each; td touchdown, lo lift-off, bnc bounce, graz grazing; zenoC: events with "
        "NonSmooth.ZENO_CASCADE; slip s: foot-seconds slipping; wall: median; rej: rejected steps; "
        "tilt: base z axis from vertical (deg); a FAILED row counts up to the failure"
    )
    if all("jacobian_costs" in r for r in rows):  # --jacobian-cost: no table rows
        lines = []
    for r in rows:
        if "profile" in r:
            p = r["profile"]
            lines.append(
                f"\n{r['scene']} friction={r['friction']}: where the time goes (one more run, "
                f"{p['total']['wall']:.2f} s with timers)"
            )
            for part in ("slipping", "other"):
                q = p[part]
                lines.append(
                    f"  steps in {part:>8} segments: {q['wall']:6.2f} s wall, {q['steps']:5d} steps "
                    f"({q['rejected']} rejected), {q['evaluations']} evaluations, {q['sim_time']:.4f} s "
                    f"simulated: {q['evaluations_per_s']:.4g} evaluations per simulated s"
                )
            lines.append(
                f"  evaluations per simulated s, slipping over other: {p['slip_to_other']:.3g} "
                f"({p['slipping']['segments']} slipping segments; one step each would give "
                f"{p['one_step_floor']:.3g})"
            )
            st = p["stops"]
            lines.append(
                f"  of the slipping steps, in the {st['segments']} segments that end in a stop: "
                f"{st['evaluations']} evaluations; by the time left to the stop (s): "
                + ", ".join(f"{k}: {n}" for k, n in st["by_time_left"].items())
            )
            on = p["onsets"]
            lines.append(
                f"  in the {on['segments']} others that begin with a slip from sticking: {on['evaluations']} "
                "evaluations; by the time since the onset (s): "
                + ", ".join(f"{k}: {n}" for k, n in on["by_time_since"].items())
            )
            lines.append(
                f"  impacts: {p['impacts']['wall']:.2f} s; events, guards, the rest: {p['rest']['wall']:.2f} s"
            )
    for r in rows:
        if "jacobian_costs" in r:
            c = r["jacobian_costs"]
            lines.append(
                f"{r['scene']} friction={r['friction']}: the flow Jacobian's cost (one process); plain run "
                f"{c['plain']['wall']:.2f} s wall, {c['plain']['steps']} steps ({c['plain']['rejected']} rejected), "
                f"{c['plain']['evaluations']} evaluations"
            )
            for setting in JacobianError:
                q = c[setting.value]
                lines.append(
                    f"  jacobian_error={setting.value:<8} {q['wall']:7.2f} s wall = {q['ratio']:5.2f} plain runs, "
                    f"{q['steps']} steps ({q['rejected']} rejected), {q['evaluations']} evaluations, "
                    f"{q['jacobian_evaluations']} Jacobian evaluations, {q['events']} events, "
                    f"state bit for bit the plain run's: {q['same_state']}"
                )
            lines.append(
                "  largest difference of a column of the Jacobian, state against control, relative to the "
                f"column's largest entry: {c['state_vs_control_column_rel']:.3g}"
            )
            if "reference" in c:
                ref = c["reference"]
                lines.append(
                    f"  against the run at rtol 1e-11, atol 1e-13 ({ref['events']} events), largest (median) "
                    "column error relative to the column's largest entry: "
                    + ", ".join(f"{k} {ref[k][0]:.3g} ({ref[k][1]:.3g})" for k in ("control", "state"))
                )
    for r in fails:
        lines += [
            f"\n--- {r['scene']} friction={r['friction']}: {r['error']}",
            r["traceback"].rstrip(),
            f"time reached {r['t_reached']!r} s; mode {r['last_mode']}, sliding {r['last_sliding']}; last events:",
        ]
        lines += [f"  {e}" for e in r["last_events"]]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--mu",
        type=float,
        nargs="+",
        default=[0.7, 0.8],
        help="Coulomb coefficients of the feet, one run each (default 0.7 0.8)",
    )
    parser.add_argument("--t-final", type=float, default=3.0, help="simulated time of each run (s)")
    parser.add_argument("--repeats", type=int, default=1, help="timed runs per case (median kept)")
    parser.add_argument("--scenes", nargs="+", default=list(TROTS))
    parser.add_argument(
        "--profile",
        action="store_true",
        help="also time, in one more run of each Coulomb case, the steps in segments with a "
        "slipping foot, the other steps and the impacts",
    )
    parser.add_argument(
        "--jacobian", action="store_true", help="carry the flow Jacobian in every run (simulate(..., jacobian=True))"
    )
    parser.add_argument(
        "--jacobian-error",
        choices=[m.value for m in JacobianError],
        default=JacobianError.CONTROL.value,
        help="with --jacobian: which errors choose the steps (SimulateOptions.jacobian_error)",
    )
    parser.add_argument(
        "--jacobian-cost",
        action="store_true",
        help="instead of the table's runs, for each Coulomb case: a plain run and one with the flow "
        "Jacobian under each jacobian_error, their counts and wall in plain runs, and how far apart "
        "the two Jacobians are",
    )
    parser.add_argument(
        "--reference",
        action="store_true",
        help="with --jacobian-cost: also each setting's Jacobian error against a run at rtol 1e-11, "
        "atol 1e-13 with jacobian_error=control",
    )
    parser.add_argument("--json", action="store_true")
    parser.add_argument(
        "--quick",
        action="store_true",
        help="a smoke run of seconds: solo12_trot, μ = 0.7, 0.2 s, one repeat, --profile",
    )
    args = parser.parse_args(argv)
    if args.quick:
        args.scenes, args.mu, args.t_final, args.repeats, args.profile = ["solo12_trot"], [0.7], 0.2, 1, True
    rows = []
    for name in args.scenes:
        stick = cd.load_scene(name)
        for friction, scene in [("stick", stick)] + [(mu, stick.with_friction(mu)) for mu in args.mu]:
            print(
                f"running {name} friction={friction} for {args.t_final:g} s x {args.repeats} ...",
                file=sys.stderr,
                flush=True,
            )
            if args.jacobian_cost:
                costs = jacobian_costs(scene, args.t_final, args.reference)
                print(f"  done: {costs['plain']['wall']:.2f} s plain", file=sys.stderr, flush=True)
                rows.append({"scene": name, "friction": friction, "jacobian_costs": costs})
                continue
            profile = args.profile and friction != "stick"
            row = {"scene": name, "friction": friction} | run(
                scene, args.t_final, args.repeats, profile, args.jacobian, args.jacobian_error
            )
            done = row.get("error") or f"{row['events']} events, {row['wall']:.2f} s wall"
            print(f"  done: {done}", file=sys.stderr, flush=True)
            rows.append(row)
    print(json.dumps(rows, indent=2) if args.json else table(rows, args.t_final))


if __name__ == "__main__":
    main()
