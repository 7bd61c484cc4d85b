"""Stiff and extreme cases: each a check of correctness and a row of cost.

Every study returns `StudyRow` objects: the case, its parameter, the method,
the error against a closed form or a converged tight-tolerance run (and which),
the run time (one run, s), the steps, the dynamics evaluations and the outcome
(a named error counts as an outcome, not a failure). `run_studies` collects
them in a `StudyResult` with ``format()`` and ``to_dict()``; `contactdiff bench
--studies` prints them and ``scripts/stiff_study.py`` draws the stiffness sweep.

Units follow the scenes (g = 1 in the paper's models): m, s, m/s.

The studies:

* `stiffness_sweep`: both leg springs of planar_trot_soft scaled by 1 … 1e7,
  undamped (as shipped: the touchdown rings the legs, which every accurate
  method must resolve) or with a leg damping ratio (the fast motion decays:
  a stiff problem); DOP853, Radau and ``method="auto"``.
* `tiny_mass_study`: two_limb with limb masses down to 1e-6 of the body's,
  against its closed form.
* `grazing_study`: touchdown speeds 1e-3 … 1e-12 of a slow drop (transversal),
  and a tangential approach whose dip below the ground shrinks to nothing.
* `simultaneous_study`: the soft (decoupled) and rigid trot landing Δt apart,
  Δt = 1e-2 … 1e-14 and 0.
* `zeno_study`: balls with e = 0.5, 0.9, 0.99 against the limit time.
* `elastic_study`: a ball with e = 1 over many impacts: energy and constraint drift.
* `bad_input_study`: non-finite numbers in the state and the parameters.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, field

import numpy as np
import pinocchio as pin

from .runner import state_error as bench_state_error
from ..model.contacts import Contact
from ..model.efforts import JointSpring, Spring
from ..errors import ContactDiffError
from ..integration.hybrid import simulate
from ..paper import trot_touchdown
from ..model.scene import Scene, load_scene

SQ2 = math.sqrt(2.0)
DEFAULT_TOL = dict(rtol=1e-8, atol=1e-10)
TIGHT_TOL = dict(rtol=1e-12, atol=1e-14)


@dataclass
class StudyRow:
    """One run of a study.

    Attributes:
        study: the study (``stiffness``, ``tiny-mass``, ...).
        case: the scene or variant.
        parameter: the swept value, as text (``k x 1e5``, ``u = 1e-9 m/s``, ...).
        method: ``simulate``'s method (``auto``, ``DOP853``, ``Radau``) or ``-``.
        error: error against ``reference`` (None where there is none).
        reference: what the error is measured against.
        time: run time of one run (s).
        steps, evaluations: accepted steps and dynamics evaluations.
        outcome: what happened (``ok``, an event kind, a named error, ``refused``...).
        ok: whether the outcome is the right one (correct within the stated bound,
            or a named error where one is due).
        details: further numbers of the row.
    """

    study: str
    case: str
    parameter: str
    method: str
    error: float | None
    reference: str
    time: float
    steps: int
    evaluations: int
    outcome: str
    ok: bool
    details: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        return _clean(asdict(self))


@dataclass
class StudyResult:
    """The rows of several studies."""

    rows: list[StudyRow] = field(default_factory=list)

    def to_dict(self) -> dict:
        return {"rows": [r.to_dict() for r in self.rows],
                "all_ok": all(r.ok for r in self.rows)}

    def format(self) -> str:
        out = []
        for study in dict.fromkeys(r.study for r in self.rows):
            rows = [r for r in self.rows if r.study == study]
            out.append(f"== study: {study}")
            out.append(f"  {'case':<30} {'parameter':<24} {'method':<7} {'error':>9} {'time (ms)':>10} "
                       f"{'steps':>7} {'evals':>8}  outcome")
            for r in rows:
                err = "-" if r.error is None else f"{r.error:.2e}"
                mark = "" if r.ok else "  <-- NOT OK"
                out.append(f"  {r.case[:30]:<30} {r.parameter[:24]:<24} {r.method:<7} {err:>9} "
                           f"{1e3 * r.time:>10.1f} {r.steps:>7d} {r.evaluations:>8d}  {r.outcome}{mark}")
            refs = sorted({r.reference for r in rows if r.reference})
            out.append("  error against: " + "; ".join(refs))
            out.append("")
        return "\n".join(out)


def _clean(d):
    if isinstance(d, dict):
        return {k: _clean(x) for k, x in d.items()}
    if isinstance(d, (list, tuple)):
        return [_clean(x) for x in d]
    if isinstance(d, np.ndarray):
        return _clean(d.tolist())
    if isinstance(d, (float, np.floating)):
        return float(d) if math.isfinite(d) else None
    if isinstance(d, np.integer):
        return int(d)
    if isinstance(d, np.bool_):
        return bool(d)
    return d


def _run(scene, t_final, **options):
    """simulate() timed once; returns (trajectory or the named error, seconds)."""
    start = time.perf_counter()
    try:
        out = simulate(scene, t_final, **options)
    except ContactDiffError as exc:
        out = exc
    return out, time.perf_counter() - start


def _failed(base: dict, error: ContactDiffError, elapsed: float) -> StudyRow:
    """The row of a run that ended in a named error."""
    return StudyRow(**base, error=None, time=elapsed, steps=0, evaluations=0,
                    outcome=f"{type(error).__name__}: {error}", ok=False)


def _error_name(out) -> str:
    """Name of the error a `_run` returned, or ``"no error"``."""
    return type(out).__name__ if isinstance(out, Exception) else "no error"


def _counts(traj) -> tuple[int, int]:
    return int(traj.stats["steps"]), int(traj.stats["dynamics_evaluations"])


def state_error(scene: Scene, traj, q_ref, v_ref) -> float:
    """``max(|q ⊖ q_ref|_inf, |v - v_ref|_inf)`` of a trajectory's final state (`bench.state_error`)."""
    return bench_state_error(scene, traj.q, traj.v, np.asarray(q_ref, dtype=float), np.asarray(v_ref))


# -- stiffness ------------------------------------------------------------------------
def stiff_trot(scale: float, damping_ratio: float = 0.0) -> Scene:
    """planar_trot_soft (pitch 0) with both leg springs ``scale`` times stiffer.

    Each leg gets the damping ``c = 2 ζ sqrt(k m_f)`` (N s/m), ``ζ = damping_ratio``
    relative to the foot mass m_f = 1 on its leg; 0 keeps the shipped, undamped legs.
    The fastest motion has ``ω ≈ sqrt(2 k)`` (body on two legs, or foot against body).
    """
    base = load_scene("planar_trot_soft")
    efforts = [Spring(s.frame_a, s.frame_b, s.stiffness * scale,
                      2.0 * damping_ratio * math.sqrt(s.stiffness * scale), s.rest_length)
               for s in base.effort_specs]
    name = f"planar_trot_soft k x {scale:g}" + (f", zeta {damping_ratio:g}" if damping_ratio else "")
    return Scene(base.robot, base.contact_specs, efforts, None, base.q0, base.v0, name=name)


def settled_stance(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """Closed-form rest state of `stiff_trot` standing on both feet: feet on the ground
    under the hips, each leg compressed by half the body's weight, m_b g / (2 k)."""
    k = scene.effort_specs[0].stiffness
    g = -float(scene.model.gravity.linear[2])
    q = scene.q0.copy()
    robot = scene.robot
    q[robot.scalar_joint("body_z")[0]] = 0.5 - 1.0 * g / (2.0 * k)  # body mass 1
    for side in ("rear", "front"):
        q[robot.scalar_joint(f"{side}_foot_z")[0]] = 0.0
    return q, np.zeros(scene.nv)


def _event_time_error(traj, ref) -> float:
    """Largest difference of event times matched by order; inf if the kinds differ."""
    kinds, ref_kinds = [e.kind for e in traj.events], [e.kind for e in ref.events]
    if kinds != ref_kinds:
        return math.inf
    return max((abs(a.t - b.t) for a, b in zip(traj.events, ref.events)), default=0.0)


def stiffness_sweep(scales=(1, 10, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7), damping_ratio: float = 1.0,
                    methods=("auto", "DOP853", "Radau"), t_final: float | None = None,
                    tol: dict | None = None, reference_method: str | None = None,
                    reference_tol: dict | None = None, skip=None) -> list[StudyRow]:
    """planar_trot_soft with stiffer legs: the cost of each method and its error.

    Error: the larger of the final-state error and the largest event-time error
    (events matched by order; a different event sequence is an error of inf)
    against a reference run with ``reference_method`` at ``reference_tol``
    (default rtol = atol = 1e-11: with very stiff springs the accelerations carry
    a rounding noise of k ulp(q), up to ~1e-9 m/s² at k x 1e7, which a smaller
    atol cannot resolve). The reference's own error is bounded by its difference
    from the same method at ten times the tolerances (``details["reference_spread"]``).

    Damped legs (``damping_ratio > 0``; default Radau reference, ``t_final`` 1.2):
    the touchdown at t = 1 rings the legs, the feet bounce off and land again,
    and the legs settle; the run is stiff once the fast motion has decayed.
    Where the slowest stance motion has decayed below 1e-12 by ``t_final`` the
    final state is also compared with the closed-form rest state
    (`settled_stance`, ``details["error_vs_rest"]``).

    Undamped legs (default DOP853 reference, ``t_final`` 1.2): the flight is
    stiff (the springs at rest length, never excited) and the stance after the
    touchdown is a fast undamped oscillation, ``ω = sqrt(2k)``, that every
    accurate method must resolve: its cost grows like sqrt(k) whatever the method.

    Args:
        scales: stiffness multipliers.
        damping_ratio: leg damping ratio ζ (0: undamped).
        methods: methods timed at ``tol`` (default rtol 1e-8, atol 1e-10).
        skip: ``skip(scale, method) -> reason or None``: runs not made (too slow).

    A run is ok when its event sequence is the reference's and its error is at
    most ``1e3 rtol`` (the global error of these hybrid runs: ~1e-6 relative
    event-time sensitivity through the bounces) plus ten times the spread.
    """
    tol = dict(DEFAULT_TOL if tol is None else tol)
    reference_tol = dict(rtol=1e-11, atol=1e-11) if reference_tol is None else dict(reference_tol)
    reference_method = reference_method or ("Radau" if damping_ratio > 0 else "DOP853")
    t_final = 1.2 if t_final is None else t_final
    check_tol = {k: 10 * x for k, x in reference_tol.items()}
    rows = []
    case = "planar_trot_soft " + (f"legs zeta {damping_ratio:g}" if damping_ratio else "undamped legs")
    for scale in scales:
        scene = stiff_trot(scale, damping_ratio)
        ref, _ = _run(scene, t_final, method=reference_method, max_events=1000, **reference_tol)
        chk, _ = _run(scene, t_final, method=reference_method, max_events=1000, **check_tol)
        if isinstance(ref, ContactDiffError) or isinstance(chk, ContactDiffError):
            raise RuntimeError(f"reference of {scene.name} failed: {ref if isinstance(ref, Exception) else chk}")
        spread = max(state_error(scene, chk, ref.q, ref.v), _event_time_error(chk, ref))
        k = scene.effort_specs[0].stiffness
        omega = math.sqrt(2.0 * k)
        rest = None
        if damping_ratio > 0:
            # slowest stance motion: body on two legs, omega_b = sqrt(2k), damping 2c
            zeta_b = 2.0 * damping_ratio * math.sqrt(k) / math.sqrt(2.0 * k)
            slow = omega * (zeta_b - math.sqrt(zeta_b ** 2 - 1.0)) if zeta_b >= 1 else omega * zeta_b
            if math.exp(-slow * (t_final - 1.1)) < 1e-12:
                rest = settled_stance(scene)
        for method in methods:
            reason = skip(scale, method) if skip else None
            base = dict(study="stiffness", case=case, parameter=f"k x {scale:g}", method=method,
                        reference=f"{reference_method} rtol = atol = {reference_tol['rtol']:g} "
                                  "(final state and event times)")
            if reason:
                rows.append(StudyRow(**base, error=None, time=math.nan, steps=0, evaluations=0,
                                     outcome=f"skipped: {reason}", ok=True, details={"omega": omega}))
                continue
            traj, elapsed = _run(scene, t_final, method=method, max_events=1000, **tol)
            if isinstance(traj, ContactDiffError):
                rows.append(_failed(base, traj, elapsed))
                continue
            steps, evals = _counts(traj)
            state_err = state_error(scene, traj, ref.q, ref.v)
            events_err = _event_time_error(traj, ref)
            err = max(state_err, events_err)
            details = {"omega": omega, "reference_spread": spread, "state_error": state_err,
                       "event_time_error": events_err,
                       "steps_by_method": traj.stats["steps_by_method"],
                       "events": [e.kind for e in traj.events], "rejected_steps": traj.stats["rejected_steps"]}
            if rest is not None:
                details["error_vs_rest"] = state_error(scene, traj, *rest)
            ok = err <= 1e3 * tol["rtol"] + 10 * spread
            outcome = "ok" if ok else ("event sequence differs" if math.isinf(events_err) else "error above bound")
            rows.append(StudyRow(**base, error=err, time=elapsed, steps=steps, evaluations=evals,
                                 outcome=outcome, ok=ok, details=details))
    return rows


# -- tiny limb masses -----------------------------------------------------------------
def two_limb_with_mass(mass: float) -> Scene:
    """two_limb with both limbs of mass ``mass`` (kg; the body's is 1)."""
    base = load_scene("two_limb")
    robot = base.robot.copy()
    for name in ("left_foot_z", "right_foot_z"):
        j = robot.model.getJointId(name)
        inertia = robot.model.inertias[j]
        robot.model.inertias[j] = pin.Inertia(float(mass), inertia.lever, inertia.inertia)
    return Scene(robot, base.contact_specs, base.effort_specs, None, base.q0, base.v0,
                 name=f"two_limb limb mass {mass:g}")


def two_limb_closed_form(t: float, mass: float, k: float = 10.0, g: float = 1.0, body: float = 1.0):
    """Exact state of `two_limb_with_mass` dropped from body height 1 (limbs hanging at
    the springs' rest length 0.5), at time ``t`` (s), up to the limbs' next touchdown.

    Free fall: the limbs land at t = 1 with speed 1 and stop (plastic; the springs
    are at rest length, so the body keeps its speed). Stance: the limbs rest on
    the ground and the body (mass M) rides the two springs, ``x'' = -ω² x - g``
    with ``ω² = 2k/M``, ``x = z_b - 0.5``, from ``x = 0, x' = -1``; each limb is
    pressed down by ``m g - k x`` and leaves when that reaches 0, at the first
    ``x = m g / k`` with ``x' > 0``. Flight: the centre of mass
    ``Z = (M z_b + 2 m z_f)/(M + 2m)`` falls freely and the stretch
    ``s = z_b - 0.5 - z_f`` (both limbs alike) rings, ``s'' = -(k/m + 2k/M) s``,
    from ``s = m g/k``, ``s' = x'``: a fast limb oscillation at ``sqrt(k/m)``.

    Returns:
        ``(z_body, v_body, z_limb, v_limb, t_liftoff)``.
    """
    from scipy.optimize import brentq

    w = math.sqrt(2.0 * k / body)

    def x(tau):
        return (g / w ** 2) * (math.cos(w * tau) - 1.0) - math.sin(w * tau) / w

    def xd(tau):
        return -(g / w) * math.sin(w * tau) - math.cos(w * tau)
    s0 = mass * g / k
    tau0 = (2.0 * math.pi - 2.0 * math.atan(w / g)) / w  # x = 0 again, rising
    tau1 = tau0 + 0.5 * math.pi / w
    while x(tau1) < s0:
        tau1 += 0.25 * math.pi / w
    tau_lo = brentq(lambda tau: x(tau) - s0, tau0, tau1, xtol=1e-15, rtol=1e-15)
    t_lo = 1.0 + tau_lo
    if t <= 1.0:
        return 1.0 - g * t * t / 2, -g * t, 0.5 - g * t * t / 2, -g * t, t_lo
    if t <= t_lo:
        return 0.5 + x(t - 1.0), xd(t - 1.0), 0.0, 0.0, t_lo
    tau = t - t_lo
    zb0, vb0 = 0.5 + s0, xd(tau_lo)
    total = body + 2.0 * mass
    Z0, V0 = zb0 - 2.0 * mass * (0.5 + s0) / total, body * vb0 / total
    Z, V = Z0 + V0 * tau - g * tau * tau / 2, V0 - g * tau
    om = math.sqrt(k / mass + 2.0 * k / body)
    s = s0 * math.cos(om * tau) + vb0 / om * math.sin(om * tau)
    sd = -s0 * om * math.sin(om * tau) + vb0 * math.cos(om * tau)
    zb, vb = Z + 2.0 * mass * (0.5 + s) / total, V + 2.0 * mass * sd / total
    return zb, vb, zb - 0.5 - s, vb - sd, t_lo


def tiny_mass_study(masses=(1e-1, 1e-3, 1e-6), t_final: float = 1.9,
                    methods=("auto", "DOP853", "Radau"), tol: dict | None = None,
                    skip=None) -> list[StudyRow]:
    """two_limb with light limbs against its exact solution (`two_limb_closed_form`).

    After lift-off (t ≈ 1.80) each limb rings against the body at ``sqrt(k/m)``
    (3.2e3 rad/s for m = 1e-6) with a speed amplitude of 1 m/s, which every
    accurate method must resolve; before the touchdown the flight is stiff but
    unexcited. The error is that of the whole final state (body and limbs) and
    the lift-off time; ok within ``1e3 rtol`` (global error of the ringing limb
    over ~100 periods). ``details["stiffness_ratio"]`` is the fastest over the
    slowest frequency of the flight, ``sqrt((k/m + 2k/M) / (2k/M))``.
    """
    tol = dict(DEFAULT_TOL if tol is None else tol)
    rows = []
    for m in masses:
        scene = two_limb_with_mass(m)
        zb, vb, zf, vf, t_lo = two_limb_closed_form(t_final, m)
        ratio = math.sqrt((10.0 / m + 20.0) / 20.0)
        for method in methods:
            base = dict(study="tiny-mass", case="two_limb", parameter=f"limb mass {m:g}", method=method,
                        reference="closed form (stance, lift-off at m g/k, ringing flight)")
            reason = skip(m, method) if skip else None
            if reason:
                rows.append(StudyRow(**base, error=None, time=math.nan, steps=0, evaluations=0,
                                     outcome=f"skipped: {reason}", ok=True, details={"stiffness_ratio": ratio}))
                continue
            traj, elapsed = _run(scene, t_final, method=method, **tol)
            if isinstance(traj, ContactDiffError):
                rows.append(_failed(base, traj, elapsed))
                continue
            steps, evals = _counts(traj)
            kinds = [e.kind for e in traj.events]
            lift = traj.events[1].t if len(traj.events) > 1 else math.nan
            body_err = max(abs(traj.q[0] - zb), abs(traj.v[0] - vb))
            limb_err = max(abs(traj.q[1] - zf), abs(traj.v[1] - vf), abs(traj.q[2] - zf), abs(traj.v[2] - vf))
            err = max(body_err, limb_err, abs(lift - t_lo))
            ok = kinds == ["touchdown", "lift-off"] and err <= 1e3 * tol["rtol"]
            rows.append(StudyRow(**base, error=err, time=elapsed, steps=steps, evaluations=evals,
                                 outcome="ok" if ok else f"events {kinds}" if len(kinds) != 2 else "error above bound",
                                 ok=ok, details={"body_error": body_err, "limb_error": limb_err,
                                                 "liftoff_error": lift - t_lo, "stiffness_ratio": ratio,
                                                 "steps_by_method": traj.stats["steps_by_method"]}))
    return rows


# -- grazing ---------------------------------------------------------------------------
def slow_drop(speed: float, height: float = 1e-6) -> Scene:
    """A plastic ball dropped from ``height`` (m) under the gravity that makes it land at
    ``speed`` (m/s): g = speed² / (2 height); it lands at t = 2 height / speed."""
    robot = load_scene("ball").robot
    g = speed * speed / (2.0 * height)
    return Scene(robot, [Contact("ball", restitution=0.0)], gravity=[0, 0, -g], q0={"z": height},
                 name=f"ball drop u={speed:g}")


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
    scene = Scene(robot, [Contact("ball")], [JointSpring("z", 1.0, 0.0, r)], gravity=[0, 0, 0],
                  q0={"z": r + amplitude}, name=f"tangent approach dip={dip:g}")
    if r > amplitude:  # a clear miss
        return scene, math.nan, math.nan
    return scene, math.acos(-r / amplitude), math.sqrt(max(amplitude ** 2 - r * r, 0.0))


def grazing_study(speeds=(1e-3, 1e-5, 1e-7, 1e-9, 1e-10, 1e-12),
                  dips=(1e-2, 1e-6, 1e-8, 1e-10, 1e-12, 1e-14, 0.0),
                  tol: dict | None = None) -> list[StudyRow]:
    """Near-grazing touchdowns: correct, or a named grazing event / error; never silent.

    Slow drop (transversal, `slow_drop`): the event time against 2h/u (relative
    error), kind ``touchdown`` above ``grazing_speed`` (1e-9 m/s) and
    ``grazing`` at or below, and with ``on_grazing="raise"`` a `GrazingError`
    for those.

    Tangent approach (`tangent_approach`, O(1) swing): the final state (t = 4)
    against the closed form with the touch. The touch speed is u ≈ sqrt(2 dip);
    the event time's condition number is 1/u, so a found touchdown is correct
    when its error is within ``10 (rtol + atol)(1 + 1/u)``. A dip below the
    integration error cannot be resolved: the run must say so (a near-grazing
    note, ``stats["near_grazing_misses"]``, or `GrazingError` with
    ``on_grazing="raise"``); its error is then O(u).
    """
    tol = dict(DEFAULT_TOL if tol is None else tol)
    rows = []
    for u in speeds:
        scene = slow_drop(u)
        t_c = 2e-6 / u
        traj, elapsed = _run(scene, 1.5 * t_c, **tol)
        raised, _ = _run(scene, 1.5 * t_c, on_grazing="raise", **tol)
        grazing = u <= 1e-9
        base = dict(study="grazing", case="slow drop from 1e-6 m", parameter=f"u = {u:g} m/s",
                    method="auto", reference="event time 2h/u (relative)")
        if isinstance(traj, ContactDiffError):
            rows.append(_failed(base, traj, elapsed))
            continue
        ev = traj.events[0] if traj.events else None
        err = abs(ev.t - t_c) / t_c if ev else None
        kind = ev.kind if ev else "no event"
        raise_outcome = _error_name(raised)
        ok = (ev is not None and err <= 1e-9 and kind == ("grazing" if grazing else "touchdown")
              and raise_outcome == ("GrazingError" if grazing else "no error"))
        steps, evals = _counts(traj)
        rows.append(StudyRow(**base, error=err, time=elapsed, steps=steps, evaluations=evals,
                             outcome=f"{kind}; on_grazing=raise: {raise_outcome}", ok=ok))
    for dip in dips:
        scene, t_c, u = tangent_approach(dip)
        t_final = 4.0
        r = 1.0 - dip
        z_ref, v_ref = r * (1 - math.cos(t_final - t_c)), r * math.sin(t_final - t_c)
        traj, elapsed = _run(scene, t_final, **tol)
        raised, _ = _run(scene, t_final, on_grazing="raise", **tol)
        base = dict(study="grazing", case="tangent approach, swing 1 m", parameter=f"dip {dip:g} m",
                    method="auto", reference="closed form with the touch")
        if isinstance(traj, ContactDiffError):
            rows.append(_failed(base, traj, elapsed))
            continue
        err = max(abs(traj.q[0] - z_ref), abs(traj.v[0] - v_ref))
        misses = traj.stats["near_grazing_misses"]
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
        rows.append(StudyRow(**base, error=err, time=elapsed, steps=steps, evaluations=evals,
                             outcome=f"{outcome}; on_grazing=raise: {raise_outcome}", ok=ok,
                             details={"touch_speed": u, "bound_if_found": bound, "near_grazing_misses": misses}))
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


def simultaneous_study(gaps=(1e-2, 1e-4, 1e-6, 1e-8, 1e-10, 1e-12, 1e-14), t_final: float = 1.5,
                       tol: dict | None = None, rigid: bool = True) -> list[StudyRow]:
    """Feet landing Δt apart versus together.

    Soft (decoupled) trot: the final state x(Δt) and the flow Jacobian J(Δt)
    against the simultaneous run (Δt = 0): ``error = |x(Δt) - x(0)|``; continuity
    means it scales like Δt (``details["per_dt"]`` = error / Δt stays bounded)
    and differentiability that ``|x(Δt) - x(0) - J(0) δx0|`` scales like Δt²
    (down to rounding). Rigid (coupled) trot: the same error stays O(1) however
    small Δt (until the runs group the touchdowns as simultaneous at
    ``simultaneous_tol`` = 1e-9 s): the outcome jumps.
    """
    tol = dict(TIGHT_TOL if tol is None else tol)
    rows = []
    models = ("soft", "rigid") if rigid else ("soft",)
    for model in models:
        jac = model == "soft"
        ref_scene = trot_touchdown(model, 0.0)
        ref, _ = _run(ref_scene, t_final, jacobian=jac, **tol)
        for dt in gaps:
            pitch = pitch_for_gap_time(model, dt)
            scene = trot_touchdown(model, pitch)
            traj, elapsed = _run(scene, t_final, jacobian=jac, **tol)
            dx = np.concatenate([pin.difference(scene.model, ref.q, traj.q), traj.v - ref.v])
            err = float(np.max(np.abs(dx)))
            touch = [e for e in traj.events if e.kind == "touchdown"]
            details = {"pitch": pitch, "per_dt": err / dt,
                       "events": [("simultaneous " if e.simultaneous else "") + e.kind for e in touch]}
            if jac:
                d0 = np.concatenate([pin.difference(scene.model, ref.q0, scene.q0), scene.v0 - ref.v0])
                details["linearisation_error"] = float(np.max(np.abs(dx - ref.jacobian @ d0)))
                details["jacobian_change"] = float(np.max(np.abs(traj.jacobian - ref.jacobian)))
                details["jacobian_change_per_dt"] = details["jacobian_change"] / dt
                ok = err <= 20 * dt + 1e-10 and details["jacobian_change"] <= 400 * dt + 1e-8
                outcome = f"continuous (|dx|/dt {err / dt:.3g}, |dJ|/dt {details['jacobian_change_per_dt']:.3g})"
            else:
                grouped = len(touch) == 1 and touch[0].simultaneous
                ok = grouped or err > 1e-2
                outcome = "grouped as simultaneous" if grouped else f"jump of {err:.3g} (order changes outcome)"
            steps, evals = _counts(traj)
            rows.append(StudyRow("near-simultaneous", f"{model} trot", f"dt = {dt:g} s", "auto", err,
                                 "the simultaneous run (dt = 0)", elapsed, steps, evals, outcome, ok, details))
    return rows


# -- Zeno ---------------------------------------------------------------------------------
def zeno_study(restitutions=(0.5, 0.9, 0.99), zeno_speed: float = 1e-6,
               tol: dict | None = None) -> list[StudyRow]:
    """Balls dropped from 1 (g = 1) end their bounces cleanly at the limit time.

    First impact at t1 = sqrt(2); the flights form a geometric series that
    accumulates at ``t_inf = t1 (1 + e)/(1 - e)``. The run stops bouncing at the
    first impact slower than ``zeno_speed`` (event ``zeno``, then at rest in
    contact), so ``t_inf - t_zeno`` lies in ``[2 e² z/(1-e), 2 e z/(1-e)]``,
    z = zeno_speed (derived in tests/test_integrator.py). ``error`` is
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
        ok = last.kind == "zeno" and lo <= gap <= hi and at_rest and \
            all(ev.kind == "bounce" for ev in traj.events[:-1])
        steps, evals = _counts(traj)
        rows.append(StudyRow("zeno", "ball dropped from 1", f"e = {e:g}", "auto", abs(gap),
                             "limit time sqrt(2)(1+e)/(1-e)", elapsed, steps, evals,
                             f"zeno after {len(traj.events)} impacts, then at rest" if ok else "NOT clean",
                             ok, {"t_inf": t_inf, "t_zeno": last.t, "bound": [lo, hi]}))
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
    traj, elapsed = _run(scene, t_final, max_events=impacts + 10, **tol)
    energy_events = max(max(abs(0.5 * ev.v_minus[0] ** 2 + ev.q[0] - 1.0),
                            abs(0.5 * ev.v_plus[0] ** 2 + ev.q[0] - 1.0)) for ev in traj.events)
    gaps_at_impacts = [float(traj.at(ev.t, side="left")[0][0]) for ev in traj.events]
    times = np.concatenate([np.linspace(s.t0, s.t1, samples_per_flight + 2)[1:-1] for s in traj.segments])
    qs, vs = traj.sample(times)
    energy_flow = float(np.max(np.abs(0.5 * vs[:, 0] ** 2 + qs[:, 0] - 1.0)))
    t_ref = SQ2 * (1 + 2 * np.arange(len(traj.events)))
    time_drift = float(np.max(np.abs(np.array([ev.t for ev in traj.events]) - t_ref)))
    energy = max(energy_events, energy_flow)
    details = {"energy_drift_events": energy_events, "energy_drift_flights": energy_flow,
               "gap_at_impacts_max": float(np.max(np.abs(gaps_at_impacts))),
               "lowest_gap": float(min(0.0, qs[:, 0].min())), "impact_time_drift": time_drift,
               "impacts": len(traj.events), "final_time": traj.t}
    # bounds: energy and gaps a few 1e3 rounding units of t ~ 3 impacts (eps t v g per impact,
    # random-walk growth), impact times drift by the energy error over the flights
    ok = (len(traj.events) == impacts and energy <= 1e-8 and details["gap_at_impacts_max"] <= 1e-10
          and details["lowest_gap"] >= -1e-10)
    steps, evals = _counts(traj)
    return [StudyRow("elastic", "ball e = 1", f"{impacts} impacts", "auto", energy,
                     "energy 1 (exact); gap 0 at impacts", elapsed, steps, evals,
                     f"energy drift {energy:.1e}, gap at impacts {details['gap_at_impacts_max']:.1e}, "
                     f"time drift {time_drift:.1e}", ok, details)]


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
        rows.append(StudyRow("bad-input", "ball", label, "-", None, "refused up front: a named error showing the value",
                             time.perf_counter() - start, 0, 0, outcome, ok))
    return rows


# -- all ------------------------------------------------------------------------------------
def _skip_radau_ringing(scale, method):
    return "ringing: ~10x DOP853 cost" if method == "Radau" and scale > 1e4 else None


def run_studies(quick: bool = True) -> StudyResult:
    """Every study; ``quick`` keeps each short (seconds in all), the full run takes minutes.

    Full: stiffness 1 … 1e7 with damped legs (all methods) and 1 … 1e5 undamped
    (Radau up to 1e4), tiny masses down to 1e-6, all grazing cases, Δt down to
    1e-14, Zeno e = 0.5, 0.9, 0.99 and 10,000 elastic impacts.
    """
    result = StudyResult()
    if quick:
        result.rows += stiffness_sweep(scales=(1, 1e2, 1e4), damping_ratio=1.0)
        result.rows += stiffness_sweep(scales=(1, 1e2), damping_ratio=0.0, methods=("auto", "DOP853"))
        result.rows += tiny_mass_study(masses=(1e-3,), methods=("auto", "DOP853"), t_final=1.85)
        result.rows += grazing_study(speeds=(1e-3, 1e-9, 1e-12), dips=(1e-4, 1e-12, 0.0))
        result.rows += simultaneous_study(gaps=(1e-4, 1e-8, 1e-12), rigid=True)
        result.rows += zeno_study(restitutions=(0.5, 0.9))
        result.rows += elastic_study(impacts=200)
    else:
        result.rows += stiffness_sweep(damping_ratio=1.0)
        result.rows += stiffness_sweep(scales=(1, 10, 1e2, 1e3, 1e4, 1e5), damping_ratio=0.0,
                                       skip=_skip_radau_ringing)
        result.rows += tiny_mass_study()
        result.rows += grazing_study()
        result.rows += simultaneous_study()
        result.rows += zeno_study()
        result.rows += elastic_study(impacts=10_000)
    result.rows += bad_input_study()
    return result


__all__ = ["StudyRow", "StudyResult", "run_studies", "stiffness_sweep", "tiny_mass_study", "grazing_study",
           "simultaneous_study", "zeno_study", "elastic_study", "bad_input_study", "stiff_trot",
           "settled_stance", "two_limb_with_mass", "two_limb_closed_form", "slow_drop",
           "tangent_approach", "touchdown_gap_time", "pitch_for_gap_time"]
