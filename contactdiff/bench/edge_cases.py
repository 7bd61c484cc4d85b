"""Edge cases: grazing, near-simultaneous touchdowns, Zeno sequences, thousands of
elastic impacts and bad numbers.

See `contactdiff.bench.extreme_cases` for what each study measures.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np
import pinocchio as pin

from ..errors import ContactDiffError
from ..integration.hybrid import simulate
from ..integration.options import SimulateOptions
from ..model.contacts import Contact
from ..model.efforts import JointSpring, Spring
from ..model.scene import Scene
from ..paper import trot_touchdown
from ..scenes.scene_file import load_scene
from .study_rows import DEFAULT_TOL, SQ2, TIGHT_TOL, StudyRow, _counts, _error_name, _failed, _run

GRAZING_SPEED = SimulateOptions().grazing_speed  # m/s, the default the studies run with


# -- grazing ---------------------------------------------------------------------------
def slow_drop(speed: float, height: float = 1e-6) -> Scene:
    """A plastic ball dropped from ``height`` (m) under the gravity that makes it land at
    ``speed`` (m/s): g = speed² / (2 height); it lands at t = 2 height / speed."""
    robot = load_scene("ball").robot
    g = speed * speed / (2.0 * height)
    return Scene(
        robot, [Contact("ball", restitution=0.0)], gravity=[0, 0, -g], q0={"z": height}, name=f"ball drop u={speed:g}"
    )


def tangent_approach(dip: float, amplitude: float = 1.0) -> tuple[Scene, float, float]:
    """A plastic ball on a joint spring (k = 1, no gravity), swinging down from
    ``z0 = rest + amplitude`` at rest: ``z = r + a cos t`` with ``r = a - dip``, so the
    free motion would dip ``dip`` below the ground (m). It touches at
    ``cos t_c = -r/a`` with speed ``u = sqrt(a² - r²)`` and stops; the spring then
    lifts it: ``z = r (1 - cos(t - t_c))``.

    Returns:
        ``(scene, t_c, u)`` (``dip = 0``: tangent, u = 0; ``dip < 0``: it passes ``-dip``
        above the ground, t_c and u are nan).
    """
    robot = load_scene("ball").robot
    r = amplitude - dip
    scene = Scene(
        robot,
        [Contact("ball")],
        [JointSpring("z", 1.0, 0.0, r)],
        gravity=[0, 0, 0],
        q0={"z": r + amplitude},
        name=f"tangent approach dip={dip:g}",
    )
    if r > amplitude:  # a clear miss
        return scene, math.nan, math.nan
    return scene, math.acos(-r / amplitude), math.sqrt(max(amplitude**2 - r * r, 0.0))


def grazing_study(
    speeds=(1e-3, 1e-5, 1e-7, 1e-9, 1e-10, 1e-12),
    dips=(1e-2, 1e-6, 1e-8, 1e-10, 1e-12, 1e-14, 0.0),
    tol: dict | None = None,
) -> list[StudyRow]:
    """Near-grazing touchdowns: correct, or a named grazing event / error; never silent.

    Slow drop (transversal, `slow_drop`): the event time against 2h/u (relative
    error), kind ``touchdown`` above ``grazing_speed`` (1e-9 m/s) and
    ``grazing`` below, and with ``on_grazing="raise"`` a `GrazingError`
    for those. At ``u = grazing_speed`` itself the touch speed is the threshold up
    to round-off (the fall, a quadratic, is integrated exactly; its speed carries a
    few ulps, which fall on either side of the threshold with the CPU's BLAS
    kernel): either kind is right there, provided the run with
    ``on_grazing="raise"`` agrees (`GrazingError` exactly when ``grazing``).

    Tangent approach (`tangent_approach`, O(1) swing): the final state (t = 4)
    against the closed form with the touch. The touch speed is u ≈ sqrt(2 dip);
    the event time's condition number is 1/u, so a found touchdown is correct
    when its error is within ``10 (rtol + atol)(1 + 1/u)``. A dip below the
    integration error cannot be resolved: the run must say so (a near-grazing
    note, ``stats.near_grazing_misses``, or `GrazingError` with
    ``on_grazing="raise"``); its error is then O(u).
    """
    tol = dict(DEFAULT_TOL if tol is None else tol)
    rows = []
    for u in speeds:
        scene = slow_drop(u)
        t_c = 2e-6 / u
        traj, elapsed = _run(scene, 1.5 * t_c, **tol)
        raised, _ = _run(scene, 1.5 * t_c, on_grazing="raise", **tol)
        outcomes = {False: ("touchdown", "no error"), True: ("grazing", "GrazingError")}
        if math.isclose(u, GRAZING_SPEED, rel_tol=1e-12):  # at the threshold: either (docstring)
            expected = set(outcomes.values())
        else:
            expected = {outcomes[u < GRAZING_SPEED]}
        base: dict[str, Any] = dict(
            study="grazing",
            case="slow drop from 1e-6 m",
            parameter=f"u = {u:g} m/s",
            method="auto",
            reference="event time 2h/u (relative)",
        )
        if isinstance(traj, ContactDiffError):
            rows.append(_failed(base, traj, elapsed))
            continue
        ev = traj.events[0] if traj.events else None
        err = abs(ev.t - t_c) / t_c if ev else None
        kind = ev.kind if ev else "no event"
        raise_outcome = _error_name(raised)
        ok = ev is not None and err is not None and err <= 1e-9 and (kind, raise_outcome) in expected
        steps, evals = _counts(traj)
        rows.append(
            StudyRow(
                **base,
                error=err,
                time=elapsed,
                steps=steps,
                evaluations=evals,
                outcome=f"{kind}; on_grazing=raise: {raise_outcome}",
                ok=ok,
            )
        )
    for dip in dips:
        scene, t_c, u = tangent_approach(dip)
        t_final = 4.0
        r = 1.0 - dip
        z_ref, v_ref = r * (1 - math.cos(t_final - t_c)), r * math.sin(t_final - t_c)
        traj, elapsed = _run(scene, t_final, **tol)
        raised, _ = _run(scene, t_final, on_grazing="raise", **tol)
        base = dict(
            study="grazing",
            case="tangent approach, swing 1 m",
            parameter=f"dip {dip:g} m",
            method="auto",
            reference="closed form with the touch",
        )
        if isinstance(traj, ContactDiffError):
            rows.append(_failed(base, traj, elapsed))
            continue
        err = max(abs(traj.q[0] - z_ref), abs(traj.v[0] - v_ref))
        misses = traj.stats.near_grazing_misses
        bound = 10 * (tol["rtol"] + tol["atol"]) * (1 + 1 / max(u, 1e-300))
        found = [e for e in traj.events if e.kind in ("touchdown", "bounce", "grazing")]
        flagged = misses > 0 or any(e.kind == "grazing" for e in found)
        raise_outcome = _error_name(raised)
        if found:
            outcome = f"{found[0].kind} at t_c {found[0].t - t_c:+.1e}"
        elif misses:
            outcome = "near-grazing miss noted"
        else:
            outcome = "no event"
        ok = (err <= bound) or (flagged and raise_outcome == "GrazingError")
        steps, evals = _counts(traj)
        rows.append(
            StudyRow(
                **base,
                error=err,
                time=elapsed,
                steps=steps,
                evaluations=evals,
                outcome=f"{outcome}; on_grazing=raise: {raise_outcome}",
                ok=ok,
                details={"touch_speed": u, "bound_if_found": bound, "near_grazing_misses": misses},
            )
        )
    return rows


# -- near-simultaneous touchdowns --------------------------------------------------------
def touchdown_gap_time(model: str, pitch: float) -> float:
    """Time between the rear and the front foot's touchdowns of `trot_touchdown` (s),
    from the free fall of the whole robot at rest (g = 1): foot heights
    ``h = c ∓ l sin θ - d cos θ`` (soft: c = 1, l = 0.25, d = 0.5; rigid: c = 2/3,
    l = 0.25, d = 1/6), ``Δt = sqrt(2 h_f) - sqrt(2 h_r)`` written without cancellation."""
    c, d = (1.0, 0.5) if model == "soft" else (2.0 / 3.0, 1.0 / 6.0)
    h_r = c - 0.25 * math.sin(pitch) - d * math.cos(pitch)
    h_f = h_r + 0.5 * math.sin(pitch)
    return 2.0 * (h_f - h_r) / (math.sqrt(2.0 * h_f) + math.sqrt(2.0 * h_r))


def pitch_for_gap_time(model: str, dt: float) -> float:
    """Initial pitch (rad) at which the feet of `trot_touchdown` land ``dt`` apart."""
    from scipy.optimize import brentq

    if dt == 0:
        return 0.0
    return float(brentq(lambda p: touchdown_gap_time(model, p) - dt, 0.0, 0.5, xtol=1e-300, rtol=1e-15))


def simultaneous_study(
    gaps=(1e-2, 1e-4, 1e-6, 1e-8, 1e-10, 1e-12, 1e-14),
    t_final: float = 1.5,
    tol: dict | None = None,
    rigid: bool = True,
    n_jobs: int | None = None,
) -> list[StudyRow]:
    """Feet landing Δt apart versus together.

    Soft (decoupled) trot: the final state x(Δt) and the flow Jacobian J(Δt)
    against the simultaneous run (Δt = 0): ``error = |x(Δt) - x(0)|``; continuity
    means it scales like Δt (``details["per_dt"]`` = error / Δt stays bounded)
    and differentiability that ``|x(Δt) - x(0) - J(0) δx0|`` scales like Δt²
    (down to rounding). Rigid (coupled) trot: the same error stays O(1) however
    small Δt (until the runs group the touchdowns as simultaneous at
    ``simultaneous_tol`` = 1e-9 s): the outcome jumps.

    The runs are one sweep of `trot_touchdown` over the model and the pitch
    (`contactdiff.sweeps`, ``n_jobs`` worker processes, default one per core).
    """
    from ..sweeps import point_list, sweep

    tol = dict(TIGHT_TOL if tol is None else tol)
    models = ("soft", "rigid") if rigid else ("soft",)
    cases = [(model, dt) for model in models for dt in (0.0,) + tuple(gaps)]
    points = point_list(
        [{"arg:model": model, "arg:pitch": pitch_for_gap_time(model, dt) if dt else 0.0} for model, dt in cases]
    )
    result = sweep(trot_touchdown, points, job=gap_run, t_final=t_final, options=tol, n_jobs=n_jobs, progress=False)
    runs: dict[tuple[str, float], dict[str, Any]] = {
        case: {k: np.asarray(v) if isinstance(v, list) else v for k, v in row.outputs.items()}
        for case, row in zip(cases, result.raise_failure())
    }
    rows = []
    for model in models:
        jac, ref, robot = model == "soft", runs[model, 0.0], trot_touchdown(model, 0.0).model
        for dt in gaps:
            run = runs[model, dt]
            dx = np.concatenate([pin.difference(robot, ref["q"], run["q"]), run["v"] - ref["v"]])
            err = float(np.max(np.abs(dx)))
            details = {"pitch": run["pitch"], "per_dt": err / dt, "events": list(run["touchdowns"])}
            if jac:
                d0 = np.concatenate([pin.difference(robot, ref["q0"], run["q0"]), run["v0"] - ref["v0"]])
                details["linearisation_error"] = float(np.max(np.abs(dx - ref["jacobian"] @ d0)))
                details["jacobian_change"] = float(np.max(np.abs(run["jacobian"] - ref["jacobian"])))
                details["jacobian_change_per_dt"] = details["jacobian_change"] / dt
                ok = err <= 20 * dt + 1e-10 and details["jacobian_change"] <= 400 * dt + 1e-8
                outcome = f"continuous (|dx|/dt {err / dt:.3g}, |dJ|/dt {details['jacobian_change_per_dt']:.3g})"
            else:
                grouped = details["events"] == ["simultaneous touchdown"]
                ok = grouped or err > 1e-2
                outcome = "grouped as simultaneous" if grouped else f"jump of {err:.3g} (order changes outcome)"
            rows.append(
                StudyRow(
                    "near-simultaneous",
                    f"{model} trot",
                    f"dt = {dt:g} s",
                    "auto",
                    err,
                    "the simultaneous run (dt = 0)",
                    run["time"],
                    run["steps"],
                    run["evaluations"],
                    outcome,
                    ok,
                    details,
                )
            )
    return rows


def gap_run(scene: Scene, point: dict) -> dict:
    """The sweep job of `simultaneous_study`: one touchdown scene run to ``t_final``, its
    initial and final state, flow Jacobian (soft model), touchdowns, counts and time (s)."""
    jac = point["arg:model"] == "soft"
    options = {k: point[k] for k in ("rtol", "atol") if k in point}
    traj, elapsed = _run(scene, point["t_final"], jacobian=jac, **options)
    if isinstance(traj, ContactDiffError):
        raise traj
    steps, evals = _counts(traj)
    return {
        "pitch": point["arg:pitch"],
        "q0": scene.q0,
        "v0": scene.v0,
        "q": traj.q,
        "v": traj.v,
        "jacobian": traj.jacobian if jac else None,
        "time": elapsed,
        "steps": steps,
        "evaluations": evals,
        "touchdowns": [
            ("simultaneous " if e.simultaneous else "") + e.kind for e in traj.events if e.kind == "touchdown"
        ],
    }


# -- Zeno ---------------------------------------------------------------------------------
def zeno_study(restitutions=(0.5, 0.9, 0.99), zeno_speed: float = 1e-6, tol: dict | None = None) -> list[StudyRow]:
    """Balls dropped from 1 (g = 1) end their bounces cleanly at the limit time.

    First impact at t1 = sqrt(2); the flights form a geometric series that
    accumulates at ``t_inf = t1 (1 + e)/(1 - e)``. The run stops bouncing at the
    first impact slower than ``zeno_speed`` (event ``zeno``, then at rest in
    contact), so ``t_inf - t_zeno`` lies in ``[2 e² z/(1-e), 2 e z/(1-e)]``,
    z = zeno_speed (derived in tests/integration/test_hybrid.py). ``error`` is
    ``|t_zeno - t_inf|``; ok when inside that interval, the last event is the
    only ``zeno`` one and the ball rests on the ground after it.
    """
    tol = dict(TIGHT_TOL if tol is None else tol)
    robot = load_scene("ball").robot
    rows = []
    for e in restitutions:
        scene = Scene(robot, [Contact("ball", restitution=e)], gravity=[0, 0, -1], q0={"z": 1.0})
        t_inf = SQ2 * (1 + e) / (1 - e)
        traj, elapsed = _run(scene, t_inf + 1.0, zeno_speed=zeno_speed, max_events=100_000, **tol)
        last = traj.events[-1]
        gap = t_inf - last.t
        lo, hi = 2 * e * e * zeno_speed / (1 - e) - 1e-9, 2 * e * zeno_speed / (1 - e) + 1e-9
        at_rest = abs(traj.q[0]) <= 1e-12 and abs(traj.v[0]) <= 1e-12
        ok = last.kind == "zeno" and lo <= gap <= hi and at_rest and all(ev.kind == "bounce" for ev in traj.events[:-1])
        steps, evals = _counts(traj)
        rows.append(
            StudyRow(
                "zeno",
                "ball dropped from 1",
                f"e = {e:g}",
                "auto",
                abs(gap),
                "limit time sqrt(2)(1+e)/(1-e)",
                elapsed,
                steps,
                evals,
                f"zeno after {len(traj.events)} impacts, then at rest" if ok else "NOT clean",
                ok,
                {"t_inf": t_inf, "t_zeno": last.t, "bound": [lo, hi]},
            )
        )
    return rows


# -- long elastic runs ----------------------------------------------------------------------
def elastic_study(impacts: int = 1000, tol: dict | None = None, samples_per_flight: int = 4) -> list[StudyRow]:
    """A ball with e = 1 dropped from 1 (g = 1): ``impacts`` impacts at t_k = sqrt(2)(1 + 2k).

    Reports the energy drift ``max |v²/2 + z - 1|`` over the impacts (both
    sides) and over ``samples_per_flight`` dense-output samples per flight, the
    constraint drift (the gap at each located impact, before the state is put
    on the ground, and the lowest gap over the samples: penetration), and the
    drift of the impact times from the closed form. ``error`` is the energy drift.
    """
    tol = dict(DEFAULT_TOL if tol is None else tol)
    robot = load_scene("ball").robot
    scene = Scene(robot, [Contact("ball", restitution=1.0)], gravity=[0, 0, -1], q0={"z": 1.0})
    t_final = SQ2 * (2 * impacts - 1) + SQ2  # up to the top after the last impact
    traj, elapsed = _run(scene, t_final, max_events=impacts + 10, dense=True, **tol)
    energy_events = max(
        max(abs(0.5 * ev.v_minus[0] ** 2 + ev.q[0] - 1.0), abs(0.5 * ev.v_plus[0] ** 2 + ev.q[0] - 1.0))
        for ev in traj.events
    )
    gaps_at_impacts = [float(traj.at(ev.t, side="left")[0][0]) for ev in traj.events]
    times = np.concatenate([np.linspace(s.t0, s.t1, samples_per_flight + 2)[1:-1] for s in traj.segments])
    qs, vs = traj.sample(times)
    energy_flow = float(np.max(np.abs(0.5 * vs[:, 0] ** 2 + qs[:, 0] - 1.0)))
    t_ref = SQ2 * (1 + 2 * np.arange(len(traj.events)))
    time_drift = float(np.max(np.abs(np.array([ev.t for ev in traj.events]) - t_ref)))
    energy = max(energy_events, energy_flow)
    details = {
        "energy_drift_events": energy_events,
        "energy_drift_flights": energy_flow,
        "gap_at_impacts_max": float(np.max(np.abs(gaps_at_impacts))),
        "lowest_gap": float(min(0.0, qs[:, 0].min())),
        "impact_time_drift": time_drift,
        "impacts": len(traj.events),
        "final_time": traj.t,
    }
    # bounds: energy and gaps a few 1e3 rounding units of t ~ 3 impacts (eps t v g per impact,
    # random-walk growth), impact times drift by the energy error over the flights
    ok = (
        len(traj.events) == impacts
        and energy <= 1e-8
        and details["gap_at_impacts_max"] <= 1e-10
        and details["lowest_gap"] >= -1e-10
    )
    steps, evals = _counts(traj)
    return [
        StudyRow(
            "elastic",
            "ball e = 1",
            f"{impacts} impacts",
            "auto",
            energy,
            "energy 1 (exact); gap 0 at impacts",
            elapsed,
            steps,
            evals,
            f"energy drift {energy:.1e}, gap at impacts {details['gap_at_impacts_max']:.1e}, "
            f"time drift {time_drift:.1e}",
            ok,
            details,
        )
    ]


# -- bad numbers ---------------------------------------------------------------------------------
def _bad_input_cases():
    ball = load_scene("ball")
    nan, inf = math.nan, math.inf
    cases = [
        ("q0 = nan", lambda: simulate(ball, 1.0, q0=[nan])),
        ("v0 = -inf", lambda: simulate(ball, 1.0, v0=[-inf])),
        ("t_final = nan", lambda: simulate(ball, nan)),
        ("t_final = inf", lambda: simulate(ball, inf)),
        ("rtol = nan", lambda: simulate(ball, 1.0, rtol=nan)),
        ("atol = inf", lambda: simulate(ball, 1.0, atol=inf)),
        ("max_step = nan", lambda: simulate(ball, 1.0, max_step=nan)),
        ("max_events = inf", lambda: simulate(ball, 1.0, max_events=inf)),
        ("grazing_gap = nan", lambda: simulate(ball, 1.0, grazing_gap=nan)),
        ("gravity = nan", lambda: Scene(ball.robot, ball.contact_specs, gravity=[0, 0, nan])),
        ("contact offset = nan", lambda: Contact("ball", offset=nan)),
        ("contact normal = inf", lambda: Contact("ball", normal=(0, 0, inf))),
        ("restitution = nan", lambda: Contact("ball", restitution=nan)),
        ("spring stiffness = inf", lambda: Spring("a", "b", inf)),
        ("joint spring rest = nan", lambda: JointSpring("z", 1.0, 0.0, nan)),
        ("armature = nan", lambda: ball.with_armature(nan)),
    ]
    return cases


def bad_input_study() -> list[StudyRow]:
    """Non-finite numbers in the state and the parameters: each refused up front with a
    named error (a `ContactDiffError`) whose message shows the bad value."""
    rows = []
    for label, call in _bad_input_cases():
        start = time.perf_counter()
        try:
            call()
            outcome, ok = "accepted", False
        except ContactDiffError as exc:
            text = str(exc)
            ok = any(s in text for s in ("nan", "inf"))
            outcome = f"{type(exc).__name__}: {text[:60]}"
        except Exception as exc:  # noqa: BLE001 - an unnamed error is what this study looks for
            outcome, ok = f"unnamed {type(exc).__name__}: {exc}", False
        rows.append(
            StudyRow(
                "bad-input",
                "ball",
                label,
                "-",
                None,
                "refused up front: a named error showing the value",
                time.perf_counter() - start,
                0,
                0,
                outcome,
                ok,
            )
        )
    return rows
