"""The floor of a pure-Python stage loop over Pinocchio: how close to Pinocchio's own call
an evaluation inside a Runge-Kutta step can get, one ingredient at a time.

On a trot scene in stance (all four feet closed, the mode the trot spends most time in),
each line times one DOP853 attempt (11 stage evaluations; the first stage is the last
step's FSAL stage) built from less or more of what a step of the hybrid loop must do,
and divides its time per evaluation by Pinocchio's own ``constraintDynamics`` with the
same four 3-D contacts, all timed in this process (batches of each taken in turn,
median of 9 rounds):

1. bare: the stage combination (one numpy product), ``pinocchio.integrate`` of the
   chart coordinates, ``constraintDynamics`` with constant torques, the result stored;
   nothing else (no controller, the chart's velocity taken as ``v``, no error estimate);
2. + the controller (the scene's torques from its table at the stage's time);
3. + the chart's velocity (``Jlog6`` of the base's chart coordinates, what makes the
   step exact on SE(3));
4. + the mode's accelerator as the loop calls it (the kinematics' cache, the finiteness
   check and the forces kept for the guards), instead of the bare Pinocchio call;
5. the project's own stage loop (`ExplicitRK._stages`), which is line 4;
6. a whole `simulate` run of the scene (guards, events, error control), from
   ``contactdiff bench --speed``, and where its time goes: accepted and rejected steps
   (`ExplicitRK.step`), the guards after each step with the location of crossings
   (`GuardFinder.crossings`), the events themselves (impacts, mode choices: `HybridLoop._event`),
   and the rest of the loop (timers wrapped around those methods for this run only).

    python scripts/loop_floor.py [--scene solo12_trot] [--json]
    python scripts/loop_floor.py --quick   # solo12_trot, one round of few calls, 0.2-s run: a smoke run
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from contextlib import contextmanager

import numpy as np
import pinocchio as pin

import contactdiff as cd
from contactdiff.bench.speed import trot_speed
from contactdiff.dynamics.mode import ModeDynamics
from contactdiff.integration.guards import GuardFinder
from contactdiff.integration.hybrid import HybridLoop
from contactdiff.ode import tableaus
from contactdiff.ode.explicit_rk import DOP853, ExplicitRK
from contactdiff.ode.lie import PinocchioGroup

STAGES = tableaus.N_STAGES
A = tableaus.A[:STAGES, :STAGES]
C = tableaus.C[:STAGES]
H = 2e-3  # a typical accepted step of the trot (s)
SETTINGS = pin.ProximalSettings(1e-12, 0.0, 1)  # exact: one factorisation, as the loop uses


def _interleaved(fns: list, calls: list[int], rounds: int = 9) -> list[float]:
    """Median time of one call (s) of each function, batches of all of them taken in turn
    round after round, so that a change of the shared machine's load hits them all."""
    times: list[list[float]] = [[] for _ in fns]
    for _ in range(rounds):
        for k, (fn, n) in enumerate(zip(fns, calls)):
            start = time.perf_counter()
            for _ in range(n):
                fn()
            times[k].append((time.perf_counter() - start) / n)
    return [statistics.median(t) for t in times]


@contextmanager
def _timed(parts: dict[str, float], **methods):
    """Accumulate the wall time (s) of each ``name=(cls, attribute)`` into ``parts[name]``."""
    originals = {name: getattr(cls, attr) for name, (cls, attr) in methods.items()}

    def wrap(name, fn):
        def timed(*args, **kwargs):
            start = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                parts[name] += time.perf_counter() - start

        return timed

    try:
        for name, (cls, attr) in methods.items():
            parts[name] = 0.0
            setattr(cls, attr, wrap(name, originals[name]))
        yield parts
    finally:
        for name, (cls, attr) in methods.items():
            setattr(cls, attr, originals[name])


def breakdown(name: str, t_final: float = 3.0) -> dict[str, float]:
    """Shares of a whole run's wall time: steps, guards (with location), events, the rest."""
    scene = cd.load_scene(name)
    parts: dict[str, float] = {}
    with _timed(parts, steps=(ExplicitRK, "step"), guards=(GuardFinder, "crossings"), events=(HybridLoop, "_event")):
        start = time.perf_counter()
        cd.simulate(scene, t_final)
        wall = time.perf_counter() - start
    shares = {k: v / wall for k, v in parts.items()}
    shares["rest"] = 1.0 - sum(shares.values())
    return shares


def measure(name: str, quick: bool = False) -> dict:
    """The rows of the module doc for trot scene ``name``; ``quick``: one round of few calls
    and 0.2-s runs instead of nine rounds and 3-s runs (a smoke run, its numbers meaningless)."""
    scene = cd.load_scene(name)
    model, nv = scene.model, scene.nv
    q0, v0 = scene.q0.copy(), scene.v0.copy()
    mode = tuple(range(len(scene.contacts)))
    dyn = ModeDynamics(scene)
    accel = dyn.accelerator(mode)
    rigid = accel.rigid
    if rigid is None:
        raise SystemExit(f"{name}: its all-feet mode is not one of Pinocchio's 3-D contact modes")
    group = PinocchioGroup(model)
    kin = dyn.kin  # the scene's kinematics cache, which the controller reads
    tau0 = np.zeros(nv)
    t0 = 0.05
    y0 = np.concatenate([np.zeros(nv), v0])
    K = np.zeros((STAGES, 2 * nv))
    K[0, :nv] = v0
    K[0, nv:] = accel(q0, v0, t0)
    hA = H * A

    def attempt(torques: bool, chart: bool, accelerator: bool):
        def run():
            for s in range(1, STAGES):
                ys = y0 + hA[s, :s].dot(K[:s])
                xi, v = ys[:nv], ys[nv:]
                q = pin.integrate(model, q0, xi)
                t = t0 + C[s] * H
                K[s, :nv] = group.chart_velocity(q0, xi, v) if chart else v
                if accelerator:
                    K[s, nv:] = accel(q, v, t)
                else:
                    if torques:
                        kin.update(q, v)
                    tau = scene.tau(kin, t) if torques else tau0
                    K[s, nv:] = pin.constraintDynamics(
                        model, rigid.data, q, v, tau, rigid.models, rigid.datas, SETTINGS
                    )

        return run

    def pin_call():
        pin.constraintDynamics(model, rigid.data, q0, v0, tau0, rigid.models, rigid.datas, SETTINGS)

    stepper = DOP853(lambda t, q, v: accel(q, v, t), group, t0, q0, v0)
    stepper._K[0] = K[0]

    def ours():
        stepper._stages(t0, y0, H, q0)

    rows = [
        ("bare: combination, integrate, constraintDynamics", attempt(False, False, False), STAGES - 1),
        ("+ the controller's table", attempt(True, False, False), STAGES - 1),
        ("+ the chart's velocity", attempt(True, True, False), STAGES - 1),
        ("+ the mode's accelerator (cache, checks, forces)", attempt(True, True, True), STAGES - 1),
        ("the project's stage loop (ExplicitRK._stages)", ours, STAGES),  # its FSAL stage too
    ]
    calls, batch, rounds, t_final = (5, 2, 1, 0.2) if quick else (1000, 100, 9, 3.0)
    per_call = _interleaved([pin_call] + [fn for _, fn, _ in rows], [calls] + [batch] * len(rows), rounds)
    reference = per_call[0]
    out = {"scene": name, "pinocchio_us": 1e6 * reference, "rows": []}
    for (label, _, evals), t in zip(rows, per_call[1:]):
        out["rows"].append({"what": label, "us_per_eval": 1e6 * t / evals, "ratio": t / evals / reference})
    run = trot_speed(name, t_final, 1)
    # bench --speed's own reference: the run's modes weighted by time, timed after the run
    out["rows"].append(
        {
            "what": f"a whole simulate run, {t_final:g} s (bench --speed)",
            "us_per_eval": 1e6 * run.per_evaluation,
            "ratio": run.overhead_ratio,
        }
    )
    out["whole_run_shares"] = breakdown(name, t_final)
    return out


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scene", action="append", help="trot scene (repeatable; default both trots)")
    parser.add_argument("--json", action="store_true", help="print the rows as JSON")
    parser.add_argument(
        "--quick", action="store_true", help="a smoke run of seconds: solo12_trot unless --scene, one round, 0.2-s runs"
    )
    args = parser.parse_args(argv)
    default = ["solo12_trot"] if args.quick else ["solo12_trot", "anymal_trot"]
    results = [measure(name, args.quick) for name in (args.scene or default)]
    if args.json:
        print(json.dumps(results, indent=2))
        return
    for r in results:
        print(f"{r['scene']}: Pinocchio's constraintDynamics, four 3-D contacts: {r['pinocchio_us']:.1f} us")
        for row in r["rows"]:
            print(f"  {row['what']:<52} {row['us_per_eval']:6.1f} us/eval  {row['ratio']:5.2f} x Pinocchio")
        shares = ", ".join(f"{k} {v:.0%}" for k, v in r["whole_run_shares"].items())
        print(f"  the whole run's time: {shares}")


if __name__ == "__main__":
    main()
