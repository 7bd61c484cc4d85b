"""Stiff cases: leg springs scaled up to 1e7 and limb masses down to 1e-6 of the body's.

See `contactdiff.bench.extreme_cases` for what each study measures.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from ..errors import ContactDiffError, IntegrationError
from ..model.efforts import Spring
from ..model.scene import Scene
from ..scenes.scene_file import load_scene
from .study_rows import DEFAULT_TOL, StudyRow, _counts, _failed, _run, _skipped, state_error


# -- stiffness ------------------------------------------------------------------------
def stiff_trot(scale: float, damping_ratio: float = 0.0) -> Scene:
    """planar_trot_soft (pitch 0) with both leg springs ``scale`` times stiffer.

    Each leg gets the damping ``c = 2 ζ sqrt(k m_f)`` (N s/m), ``ζ = damping_ratio``
    relative to the foot mass m_f = 1 on its leg; 0 keeps the shipped, undamped legs.
    The fastest motion has ``ω ≈ sqrt(2 k)`` (body on two legs, or foot against body).
    """
    base = load_scene("planar_trot_soft")
    efforts = [
        Spring(
            s.frame_a,
            s.frame_b,
            s.stiffness * scale,
            2.0 * damping_ratio * math.sqrt(s.stiffness * scale),
            s.rest_length,
        )
        for s in base.effort_specs
    ]
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


def _mode_sequence(traj, resolution: float) -> list[tuple[tuple, float]]:
    """The run's contact modes (active and sliding contacts) with their start times (s),
    leaving out segments no longer than ``resolution`` (s) and merging neighbours of the
    same mode."""
    modes: list[tuple[tuple, float]] = []
    for segment in traj.segments:
        if segment.t1 - segment.t0 <= resolution:
            continue
        key = (segment.mode, segment.sliding)
        if not modes or modes[-1][0] != key:
            modes.append((key, segment.t0))
    return modes


def _event_time_error(traj, ref, resolution: float) -> float:
    """Largest difference between the times at which the two runs change contact mode,
    matched by order, within the resolution of event times ``resolution`` (s); inf if
    the modes differ.

    Modes, not event kinds: a run whose touchdown comes out as an impact that lifts
    the feet by a hair (``bounce``) and a grazing re-touch nanoseconds later has the
    same outcome, within the tolerance, as one touchdown, and which of the two a run
    gives turns on the last bits of its arithmetic (the undamped legs at k x 1e7:
    feet that land at 1 m/s bounce off at 6.5e-10 m/s under one BLAS kernel).
    Segments no longer than ``resolution`` are left out (a time interval the event
    times cannot resolve), so such a pair compares as the single event it resolves to.
    """
    modes, ref_modes = _mode_sequence(traj, resolution), _mode_sequence(ref, resolution)
    if [m for m, _ in modes] != [m for m, _ in ref_modes]:
        return math.inf
    return max((abs(a - b) for (_, a), (_, b) in zip(modes[1:], ref_modes[1:])), default=0.0)


def stiffness_sweep(
    scales=(1, 10, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7),
    damping_ratio: float = 1.0,
    methods=("auto", "DOP853", "Radau"),
    t_final: float | None = None,
    tol: dict | None = None,
    reference_method: str | None = None,
    reference_tol: dict | None = None,
    skip=None,
) -> list[StudyRow]:
    """planar_trot_soft with stiffer legs: the cost of each method and its error.

    Error: the larger of the final-state error and the largest error in the times the
    contact mode changes (modes matched by order, segments shorter than the event-time
    bound ``1e3 rtol`` left out: `_event_time_error`; a different mode sequence is an
    error of inf)
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
        t_final: end time of every run (s; default 1.2).
        tol: ``rtol``/``atol`` of the timed runs (default rtol 1e-8, atol 1e-10).
        reference_method: method of the reference run (default Radau for damped
            legs, DOP853 for undamped ones).
        reference_tol: ``rtol``/``atol`` of the reference run (default 1e-11 both).
        skip: ``skip(scale, method) -> reason or None``: runs not made (too slow).

    A run is ok when its mode sequence is the reference's and its error is at
    most ``1e3 rtol`` (the global error of these hybrid runs: ~1e-6 relative
    event-time sensitivity through the bounces) plus ten times the spread; with
    undamped legs plus ``ω p``, ``p = atol + rtol |q|_inf`` the position
    tolerance: the touchdown is located within ``p`` (in time within ``p / u``
    at touch speed ``u``), so the feet stop up to ``p`` off and the legs ring
    about a rest point moved by that much, an error of up to ``ω p`` in
    velocity, which no decay removes (k x 1e7: ``ω p`` = 1.2e-4; a touchdown
    2e-9 s early, within ``p / u`` = 5e-9 s, gave 6.2e-5 under one BLAS kernel
    and 5.1e-6 under another).
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
            raise IntegrationError(f"reference of {scene.name} failed: {ref if isinstance(ref, Exception) else chk}")
        spread = max(state_error(scene, chk, ref.q, ref.v), _event_time_error(chk, ref, 1e3 * check_tol["rtol"]))
        k = scene.effort_specs[0].stiffness
        omega = math.sqrt(2.0 * k)
        # undamped legs: a touchdown located within the position tolerance p (its time within
        # p / u at touch speed u) stops the foot up to p off, and the leg then rings about a
        # rest point moved by up to p: a final-state error up to omega p (docstring)
        ringing = 0.0 if damping_ratio > 0 else omega * (tol["atol"] + tol["rtol"] * float(np.max(np.abs(ref.q))))
        rest = None
        if damping_ratio > 0:
            # slowest stance motion: body on two legs, omega_b = sqrt(2k), damping 2c
            zeta_b = 2.0 * damping_ratio * math.sqrt(k) / math.sqrt(2.0 * k)
            slow = omega * (zeta_b - math.sqrt(zeta_b**2 - 1.0)) if zeta_b >= 1 else omega * zeta_b
            if math.exp(-slow * (t_final - 1.1)) < 1e-12:
                rest = settled_stance(scene)
        for method in methods:
            reason = skip(scale, method) if skip else None
            base = dict(
                study="stiffness",
                case=case,
                parameter=f"k x {scale:g}",
                method=method,
                reference=f"{reference_method} rtol = atol = {reference_tol['rtol']:g} (final state and event times)",
            )
            if reason:
                rows.append(_skipped(base, reason, {"omega": omega}))
                continue
            traj, elapsed = _run(scene, t_final, method=method, max_events=1000, **tol)
            if isinstance(traj, ContactDiffError):
                rows.append(_failed(base, traj, elapsed))
                continue
            steps, evals = _counts(traj)
            state_err = state_error(scene, traj, ref.q, ref.v)
            events_err = _event_time_error(traj, ref, 1e3 * tol["rtol"])
            err = max(state_err, events_err)
            details = {
                "omega": omega,
                "reference_spread": spread,
                "state_error": state_err,
                "event_time_error": events_err,
                "steps_by_method": traj.stats.steps_by_method,
                "events": [e.kind for e in traj.events],
                "rejected_steps": traj.stats.rejected_steps,
            }
            if rest is not None:
                details["error_vs_rest"] = state_error(scene, traj, *rest)
            ok = err <= 1e3 * tol["rtol"] + ringing + 10 * spread
            outcome = "ok" if ok else ("mode sequence differs" if math.isinf(events_err) else "error above bound")
            rows.append(
                StudyRow(
                    **base,
                    error=err,
                    time=elapsed,
                    steps=steps,
                    evaluations=evals,
                    outcome=outcome,
                    ok=ok,
                    details=details,
                )
            )
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
    return Scene(
        robot, base.contact_specs, base.effort_specs, None, base.q0, base.v0, name=f"two_limb limb mass {mass:g}"
    )


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
        return (g / w**2) * (math.cos(w * tau) - 1.0) - math.sin(w * tau) / w

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


def tiny_mass_study(
    masses=(1e-1, 1e-3, 1e-6),
    t_final: float = 1.9,
    methods=("auto", "DOP853", "Radau"),
    tol: dict | None = None,
    skip=None,
) -> list[StudyRow]:
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
            base = dict(
                study="tiny-mass",
                case="two_limb",
                parameter=f"limb mass {m:g}",
                method=method,
                reference="closed form (stance, lift-off at m g/k, ringing flight)",
            )
            reason = skip(m, method) if skip else None
            if reason:
                rows.append(_skipped(base, reason, {"stiffness_ratio": ratio}))
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
            rows.append(
                StudyRow(
                    **base,
                    error=err,
                    time=elapsed,
                    steps=steps,
                    evaluations=evals,
                    outcome="ok" if ok else f"events {kinds}" if len(kinds) != 2 else "error above bound",
                    ok=ok,
                    details={
                        "body_error": body_err,
                        "limb_error": limb_err,
                        "liftoff_error": lift - t_lo,
                        "stiffness_ratio": ratio,
                        "steps_by_method": traj.stats.steps_by_method,
                    },
                )
            )
    return rows
