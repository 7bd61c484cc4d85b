"""Stiff and extreme cases: each correct against a closed form or a converged run, or a
named error; never a silent wrong answer.

Reference values come from closed forms derived in the docstrings (here or in
`contactdiff.bench.extreme_cases`), from physical laws (energy of an elastic ball, static
equilibrium) or from finite differences (a flow Jacobian against the outcome of
a perturbed run). Zeno limits and most bad-input errors are in integration/test_hybrid.py
and model/test_inputs.py; this file extends them where the issue asks more.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

import contactdiff as cd
from contactdiff.bench import extreme_cases as studies
from contactdiff.errors import GrazingError
from contactdiff.integration.hybrid import simulate
from contactdiff.model.robot_files import ROBOTS_DIR
from contactdiff.ode import method_choice
from contactdiff.ode.factory import PinocchioGroup
from contactdiff.ode.method_choice import spectral_radius

TIGHT = dict(rtol=1e-12, atol=1e-14)


# ----------------------------------------------------------------------------------
# stiffness: method="auto" and the sweep
# ----------------------------------------------------------------------------------
def _rho(scene, mode, q, v):
    dyn = cd.ModeDynamics(scene)
    return spectral_radius(lambda t, q, v: dyn.solve(q, v, t, mode).ddq, q, v, 0.0, PinocchioGroup(scene.model))


def test_spectral_radius_closed_forms():
    """Arnoldi on difference quotients against hand-derived frequencies (1e-6 relative:
    forward differences of a linear field at sqrt(eps) steps).

    two_limb flight: body M = 1, limbs m = 0.1 on springs k = 10; the limbs moving
    together against the body have s'' = -(k/m + 2k/M) s: rho = sqrt(120); in stance
    (limbs held) the body rides both springs: rho = sqrt(2k/M) = sqrt(20).
    planar_trot_soft flight: feet (1) together against the body (1): 27 + 2 * 27 = 81."""
    two = cd.load_scene("two_limb")
    assert _rho(two, (), two.q0, two.v0) == pytest.approx(math.sqrt(120.0), rel=1e-6)
    q = two.q0.copy()
    q[0], q[1:] = 0.5, 0.0  # limbs on the ground, springs at rest length (linear: any state)
    assert _rho(two, (0, 1), q, two.v0) == pytest.approx(math.sqrt(20.0), rel=1e-6)
    trot = cd.load_scene("planar_trot_soft")
    assert _rho(trot, (), trot.q0, trot.v0) == pytest.approx(9.0, rel=1e-6)


def test_spectral_radius_matches_analytic_derivatives_on_solo12():
    """A free-flyer (with the -ad(v) block) in flight and on four feet: Arnoldi's largest
    Ritz value against the eigenvalues of the analytic Jacobian [[G, I], [da/dq, da/dv]]
    (1e-3 relative: 12 Arnoldi products of a 36-dimensional system)."""
    scene = cd.load_scene("solo12_drop")
    group = PinocchioGroup(scene.model)
    dyn = cd.ModeDynamics(scene)
    v = scene.v0 + 0.1
    for mode in [(), (0, 1, 2, 3)]:
        _, der = dyn.solve(scene.q0, v, 0.0, mode, derivatives=True)
        nv = scene.nv
        DF = np.zeros((2 * nv, 2 * nv))
        DF[:nv, :nv] = group.velocity_jacobian_q(scene.q0, v)
        DF[:nv, nv:] = np.eye(nv)
        DF[nv:, :nv], DF[nv:, nv:] = der.ddq_dq, der.ddq_dv
        exact = np.max(np.abs(np.linalg.eigvals(DF)))
        assert _rho(scene, mode, scene.q0, v) == pytest.approx(exact, rel=1e-3)


@pytest.mark.parametrize(
    "name,t_final",
    [("ball", 6.0), ("two_limb", 3.0), ("planar_trot_soft", 3.0), ("planar_trot_rigid", 2.0), ("solo12_drop", 0.5)],
)
def test_auto_stays_explicit_on_nominal_scenes(name, t_final):
    """The shipped scenes are not stiff at the default tolerances: auto takes the same
    DOP853 steps as method="DOP853" (same step count, same final state to rounding)."""
    scene = cd.load_scene(name)
    auto = simulate(scene, t_final)
    explicit = simulate(scene, t_final, method="DOP853")
    assert auto.stats.method == "auto" and auto.stats.method_switches == []
    assert set(auto.stats.steps_by_method) == {"DOP853"}
    assert auto.stats.steps == explicit.stats.steps
    np.testing.assert_allclose(auto.q, explicit.q, rtol=0, atol=1e-13)
    np.testing.assert_allclose(auto.v, explicit.v, rtol=0, atol=1e-13)


@pytest.fixture(scope="module")
def stiff_runs():
    """planar_trot_soft with legs 1e5 times stiffer and damping ratio 1, to t = 1.2:
    touchdown at 1, the feet bounce once and land again, the legs settle."""
    scene = studies.stiff_trot(1e5, 1.0)
    runs = {m: simulate(scene, 1.2, method=m) for m in ("auto", "DOP853", "Radau")}
    return scene, runs, simulate(scene, 1.2, method="Radau", rtol=1e-11, atol=1e-11)


def test_auto_chooses_radau_when_stiff(stiff_runs):
    scene, runs, _ = stiff_runs
    auto = runs["auto"]
    assert "Radau" in auto.stats.steps_by_method
    assert auto.stats.method_switches[0][1] == "Radau"
    assert any("method auto: Radau" in n for n in auto.notes)
    # stability-limited DOP853 needs ~ rho T / 6 steps (rho ~ 6e3 to 9e3 /s here, T = 1.2):
    # auto and Radau far fewer
    assert runs["DOP853"].stats.steps > 5 * auto.stats.steps
    assert runs["DOP853"].stats.steps > 2 * runs["Radau"].stats.steps


def test_stiff_runs_are_correct(stiff_runs):
    """Every method ends at the closed-form rest state (feet on the ground, each leg
    compressed by half the body weight: body height 0.5 - 1/(2 k)), up to the decay
    exp(-~960/s * 0.1 s) ~ 1e-42 and rounding; the event times agree with the tight Radau
    run to 1e3 rtol (they carry the transient)."""
    scene, runs, ref = stiff_runs
    q_rest, v_rest = studies.settled_stance(scene)
    k = scene.effort_specs[0].stiffness
    assert q_rest[1] == 0.5 - 1.0 / (2 * k)
    for method, traj in runs.items():
        assert studies.state_error(scene, traj, q_rest, v_rest) < 1e-9, method
        assert [e.kind for e in traj.events] == [e.kind for e in ref.events], method
        for e, e_ref in zip(traj.events, ref.events):
            assert abs(e.t - e_ref.t) < 1e-5, method
    assert [e.kind for e in ref.events] == ["touchdown", "lift-off", "touchdown"]


@pytest.mark.parametrize("dz,dv", [(0.0, 3.5e-13), (1e-11, 0.0), (5e-12, -3e-13)])
def test_radau_at_rest_on_stiff_legs_does_not_collapse(dz, dv):
    """Radau at rtol = atol = 1e-11 from the closed-form rest stance of the damped legs
    at k x 1e7 (`settled_stance`), its body nudged by dz (m) and dv (m/s), to 0.1 s: the
    spring forces carry a rounding noise of k ulp(q), so near rest Newton's increments
    stop contracting (rate ~ 1) at a few 1e-6 of newton_tol's scale. Taken for
    divergence, each halved the step until the run stopped at max_steps (the stiffness
    sweep's own reference, under one BLAS kernel, after its last touchdown). Now a few
    dozen steps, and the state ends at the rest state (the slowest stance mode decays at
    ~9.6e3 /s: exp(-960) over 0.1 s) to the 1e-9 of test_stiff_runs_are_correct."""
    scene = studies.stiff_trot(1e7, 1.0)
    q, v = studies.settled_stance(scene)
    z, vz = scene.robot.scalar_joint("body_z")
    q0, v0 = q.copy(), v.copy()
    q0[z] += dz
    v0[vz] += dv
    traj = simulate(scene.with_state(q0, v0), 0.1, method="Radau", rtol=1e-11, atol=1e-11, max_steps=3000)
    assert traj.stats.steps < 100
    assert studies.state_error(scene, traj, q, v) < 1e-9


def test_auto_keeps_explicit_while_a_stiff_spring_rings():
    """Undamped legs 1e4 times stiffer: the flight is stiff (springs at rest length, never
    excited), so auto switches to Radau; the touchdown rings the legs at
    omega = sqrt(2k) = 2.3e3 /s, which every accurate method must resolve, and auto
    returns to DOP853 (cheaper per resolved period) for the rest of the run."""
    scene = studies.stiff_trot(1e4, 0.0)
    auto = simulate(scene, 1.2)
    switches = auto.stats.method_switches
    assert [m for _, m in switches] == ["Radau", "DOP853"]
    assert switches[0][0] < 1.0 < switches[1][0]
    assert auto.stats.steps_by_method["DOP853"] > 10 * auto.stats.steps_by_method["Radau"]
    ref = simulate(scene, 1.2, method="DOP853", rtol=1e-11, atol=1e-11)
    assert studies.state_error(scene, auto, ref.q, ref.v) < 1e-5


def test_auto_with_jacobian_through_a_switch():
    """The flow Jacobian is carried across a method switch: against central differences
    of the final state in the initial body height (h = 1e-6, tolerance 1e-6 relative to
    the column's size; rtol 1e-10 so the runs' own error stays below)."""
    scene = studies.stiff_trot(1e4, 1.0)
    opts = dict(rtol=1e-10, atol=1e-10)
    traj = simulate(scene, 0.9, jacobian=True, **opts)  # flight only: Radau after the switch
    assert "Radau" in traj.stats.steps_by_method
    model, h = scene.model, 1e-6
    k = scene.robot.scalar_joint("body_z")[1]
    e = np.zeros(scene.nv)
    e[k] = h
    runs = [simulate(scene, 0.9, q0=pin.integrate(model, scene.q0, s * e), **opts) for s in (1, -1)]
    fd = np.concatenate([pin.difference(model, runs[1].q, runs[0].q), runs[0].v - runs[1].v]) / (2 * h)
    np.testing.assert_allclose(traj.jacobian[:, k], fd, rtol=0, atol=1e-6 * np.max(np.abs(fd)))


def _chooser_steps(chooser, steps):
    """Feed ``chooser`` accepted steps (s) with a constant ρ; return the switches it asks."""
    return [chooser.after_step(h, None, None, 0.0) for h in steps]


def test_auto_trial_returns_to_explicit_when_radau_steps_are_clearly_shorter():
    """The method chooser's trial (method_choice module doc), on a probe that always
    measures ρ = 1000 /s. Explicit steps of 4e-3 s (h ρ = 4 >= STIFF_RATIO) switch to
    Radau after SWITCH_COUNT of them; Radau steps of 1e-4 s (40 times shorter, below the
    1/TRIAL_MARGIN of the explicit steps) switch back after TRIAL_STEPS, and Radau is
    refused for the rest of the mode however many stiff-looking explicit steps follow; a
    new mode may switch again; Radau steps of 2e-3 s (half the explicit: within the margin)
    keep Radau."""
    rho = 1000.0
    chooser = method_choice.MethodChooser(lambda q, v, t: rho)
    n = method_choice.SWITCH_COUNT
    assert _chooser_steps(chooser, [4e-3] * n) == [None] * (n - 1) + ["Radau"]
    trial = _chooser_steps(chooser, [1e-4] * method_choice.TRIAL_STEPS)
    assert trial == [None] * (method_choice.TRIAL_STEPS - 1) + ["DOP853"]
    assert _chooser_steps(chooser, [4e-3] * 3 * method_choice.WINDOW) == [None] * 3 * method_choice.WINDOW
    chooser.new_mode(lambda q, v, t: rho)
    assert _chooser_steps(chooser, [4e-3] * n)[-1] == "Radau"
    assert _chooser_steps(chooser, [2e-3] * 3 * method_choice.WINDOW) == [None] * 3 * method_choice.WINDOW
    assert chooser.method == "Radau"
    # a trial that spans a new mode is judged on: the switch back then measures the new mode's ρ
    chooser = method_choice.MethodChooser(lambda q, v, t: rho)
    assert _chooser_steps(chooser, [4e-3] * n)[-1] == "Radau"
    chooser.new_mode(lambda q, v, t: 2 * rho)
    assert _chooser_steps(chooser, [1e-4] * method_choice.TRIAL_STEPS)[-1] == "DOP853"
    assert chooser.rho == 2 * rho


def test_auto_with_jacobian_does_not_stay_in_radau_with_shorter_steps():
    """solo12_drop rolled 0.03 and pitched 0.05 rad, raised 1 cm (the feet land one at a
    time; scripts/parameter_cost.py), with the flow Jacobian: in the flight the Jacobian's
    columns hold DOP853's steps at h ρ ≈ 4.5 (ρ ≈ 770 /s), limited by their accuracy, and
    Radau's own error control then takes steps 14 times shorter. Whether the explicit steps'
    count reaches a switch before the first touchdown is close (it did on every BLAS kernel
    tried, and the run then took 24 Radau steps); the trial ends such a switch after at most
    TRIAL_STEPS Radau steps. The events and the final state agree with method="DOP853"
    to the run's tolerance (rtol 1e-8: 1e-6 on the state, a 100x margin for the 33 events'
    sensitivity)."""
    from scipy.spatial.transform import Rotation

    scene = cd.load_scene("solo12_drop")
    q = scene.q0.copy()
    q[3:7] = Rotation.from_euler("xyz", [0.03, 0.05, 0.0]).as_quat()
    q[2] += 0.01
    scene = scene.with_state(q)
    auto = simulate(scene, 0.3, jacobian=True)
    explicit = simulate(scene, 0.3, jacobian=True, method="DOP853")
    assert auto.stats.steps_by_method.get("Radau", 0) <= method_choice.TRIAL_STEPS
    assert [(e.kind, e.contacts) for e in auto.events] == [(e.kind, e.contacts) for e in explicit.events]
    assert studies.state_error(scene, auto, explicit.q, explicit.v) < 1e-6


def test_stiffness_sweep_compares_modes_within_the_event_time_resolution():
    """The sweep's event comparison (`stiff_cases._event_time_error`) on runs made of
    segments (t0, t1, mode): the undamped legs at k x 1e7 land at t = 1 in the reference
    (one touchdown), and under some BLAS kernels at the default tolerances the feet land
    2e-9 s early, bounce off at 6.5e-10 m/s and touch again 4e-9 s later (a bounce and
    a grazing event). Within a resolution of 1e-5 s (1e3 rtol) the two are the same mode
    sequence, with the mode change 2e-9 s apart; with a resolution finer than the 4e-9 s
    flight they differ; a run that never lands differs at any resolution."""
    from types import SimpleNamespace

    from contactdiff.bench.stiff_cases import _event_time_error

    def run(*segments):
        return SimpleNamespace(segments=[SimpleNamespace(t0=a, t1=b, mode=m, sliding=()) for a, b, m in segments])

    feet = ("rear_foot", "front_foot")
    ref = run((0.0, 1.0, ()), (1.0, 1.0001352, feet), (1.0001352, 1.2, ()))
    bounced = run(
        (0.0, 0.999999998, ()), (0.999999998, 1.000000002, ()), (1.000000002, 1.0001352, feet), (1.0001352, 1.2, ())
    )
    assert _event_time_error(bounced, ref, 1e-5) == pytest.approx(2e-9, rel=1e-6)
    assert _event_time_error(bounced, ref, 1e-9) == pytest.approx(2e-9, rel=1e-6)  # same modes, merged
    split = run(
        (0.0, 0.999999998, ()),
        (0.999999998, 0.999999999, feet),
        (0.999999999, 1.000000002, ()),
        (1.000000002, 1.0001352, feet),
        (1.0001352, 1.2, ()),
    )
    assert _event_time_error(split, ref, 1e-5) == pytest.approx(2e-9, rel=1e-6)
    assert _event_time_error(split, ref, 1e-10) == math.inf
    assert _event_time_error(run((0.0, 1.2, ())), ref, 1e-5) == math.inf


def test_stiffness_sweep_rows():
    """The study's own verdicts at two stiffnesses (its bounds are in its docstring)."""
    rows = studies.stiffness_sweep(scales=(1, 1e3), methods=("auto", "Radau"))
    assert len(rows) == 4 and all(r.ok for r in rows), [(r.parameter, r.method, r.outcome) for r in rows]
    assert all(r.error < 1e-6 and r.steps > 0 for r in rows)


# ----------------------------------------------------------------------------------
# tiny limb masses
# ----------------------------------------------------------------------------------
def test_two_limb_closed_form_is_consistent():
    """The closed form itself: continuous at t = 1 and at lift-off, lift-off where the
    limb's load m g - k x vanishes, and in flight the energy (kinetic + 2 springs +
    gravity) constant, for a heavy and a light limb."""
    k, g = 10.0, 1.0
    for m in (0.1, 1e-6):
        *_, t_lo = studies.two_limb_closed_form(1.5, m)
        for t in (1.0, t_lo):
            a = np.array(studies.two_limb_closed_form(t - 1e-9, m)[:4])
            b = np.array(studies.two_limb_closed_form(t + 1e-9, m)[:4])
            assert np.max(np.abs(a[[0, 2]] - b[[0, 2]])) < 1e-8  # positions continuous
        zb, vb, zf, vf, _ = studies.two_limb_closed_form(t_lo, m)
        assert zb - 0.5 - zf == pytest.approx(m * g / k, rel=1e-9, abs=1e-15)

        def energy(t):
            zb, vb, zf, vf, _ = studies.two_limb_closed_form(t, m)
            s = zb - 0.5 - zf
            return 0.5 * vb**2 + m * vf**2 + k * s**2 + g * (zb + 2 * m * zf)

        e0 = energy(t_lo + 1e-6)
        for t in np.linspace(t_lo + 1e-3, t_lo + 0.3, 7):
            assert energy(t) == pytest.approx(e0, abs=1e-12)


def test_tiny_limb_mass():
    """Limbs of 1e-6 the body's mass: after lift-off they ring at sqrt(k/m) = 3.2e3 rad/s
    with 1 m/s amplitude. auto (and DOP853) resolve it: whole state and lift-off time
    within 1e3 rtol of the closed form (the lift-off time error, ~1e-9, times the
    ringing frequency sets the limb speed error)."""
    rows = studies.tiny_mass_study(masses=(1e-6,), methods=("auto",), t_final=1.85)
    (row,) = rows
    assert row.ok, row
    assert row.error < 1e-5
    assert row.details["stiffness_ratio"] == pytest.approx(math.sqrt((1e7 + 20) / 20))


# ----------------------------------------------------------------------------------
# near-grazing
# ----------------------------------------------------------------------------------
@pytest.mark.parametrize("u", [1e-3, 1e-8, 1e-9 * (1 + 1e-6), 1e-9, 1e-9 * (1 - 1e-6), 1e-10, 1e-12])
def test_slow_drop(u):
    """A plastic ball dropped from 1e-6 m under g = u^2 / 2e-6 lands at t = 2e-6/u with
    speed u: the event time is exact (a quadratic, to 1e-12 relative); a touchdown above
    grazing_speed = 1e-9 m/s, a grazing event below it, and GrazingError with
    on_grazing="raise". Either way the ball then rests on the ground.

    The fall is a quadratic, which the steppers integrate exactly: the touch speed carries
    round-off only, a few ulps (1e-15 relative), so 1e-6 relative either side of the
    threshold decides it; at u = grazing_speed itself the last bits decide (they differ
    between BLAS kernels), and the outcome must only be consistent: a grazing event
    exactly when on_grazing="raise" raises."""
    scene = studies.slow_drop(u)
    t_c = 2e-6 / u
    traj = simulate(scene, 1.5 * t_c, **TIGHT)
    (ev,) = traj.events
    assert ev.t == pytest.approx(t_c, rel=1e-12)
    assert ev.normal_speeds["ball"] == pytest.approx(-u, rel=1e-9)
    assert abs(traj.q[0]) < 1e-15 and traj.v[0] == 0.0
    if u == 1e-9:
        assert ev.kind in ("grazing", "touchdown")
        if ev.kind == "touchdown":
            simulate(scene, 1.5 * t_c, on_grazing="raise", **TIGHT)  # no GrazingError
            return
    if u <= 1e-9:
        assert ev.kind == "grazing" and not ev.differentiable
        with pytest.raises(GrazingError, match="grazing touchdown of ball"):
            simulate(scene, 1.5 * t_c, on_grazing="raise", **TIGHT)
    else:
        assert ev.kind == "touchdown"


def test_grazing_study_verdict_at_the_threshold():
    """The study's slow drop at u = grazing_speed (its docstring): ok whichever side of
    the threshold the touch speed's last bits fall (under OPENBLAS_CORETYPE=Haswell the
    default tolerances give a touchdown at 1.000000000000001e-9 m/s, which the study
    called NOT OK), and the run with on_grazing="raise" agrees with the event's kind."""
    (row,) = studies.grazing_study(speeds=(1e-9,), dips=())
    assert row.ok, row.outcome
    assert row.outcome in ("touchdown; on_grazing=raise: no error", "grazing; on_grazing=raise: GrazingError")


@pytest.mark.parametrize("dip", [1e-2, 1e-8, 1e-10, 1e-14, 0.0])
def test_tangent_approach_is_correct_or_named(dip):
    """A ball swinging down on a spring (amplitude 1, no gravity) whose free motion would
    dip `dip` below the ground: it touches with speed u = sqrt(2 dip - dip^2) and stops.
    At the default tolerances either the touch is found and the final state is within
    10 (rtol + atol)(1 + 1/u) of the closed form (the event time's condition number is
    1/u), or the run names a near-grazing miss (note, counter; GrazingError with
    on_grazing="raise") and its error is O(u) (the stopped speed)."""
    scene, t_c, u = studies.tangent_approach(dip)
    r = 1.0 - dip
    traj = simulate(scene, 4.0)
    err = max(abs(traj.q[0] - r * (1 - math.cos(4.0 - t_c))), abs(traj.v[0] - r * math.sin(4.0 - t_c)))
    found = [e for e in traj.events if e.t == pytest.approx(t_c, abs=1e-3)]
    if found:
        assert err <= 10 * (1e-8 + 1e-10) * (1 + 1 / u)
        assert traj.stats.near_grazing_misses == 0
    else:
        assert traj.stats.near_grazing_misses == 1
        assert any("near-grazing of ball" in n for n in traj.notes)
        assert err <= 2 * u + 1e-8
        with pytest.raises(GrazingError, match="near-grazing of ball"):
            simulate(scene, 4.0, on_grazing="raise")
    if dip <= 1e-10:  # below the default tolerances: cannot be resolved, must be named
        assert not found


def test_clear_miss_is_not_flagged():
    """The same swing passing 1e-4 m above the ground (far outside the default band of
    10 (atol + rtol |q|) ~ 2e-7 m): no event, no note; exact free motion z = r + cos t."""
    scene, _, _ = studies.tangent_approach(-1e-4)
    traj = simulate(scene, 4.0)
    assert traj.events == [] and traj.stats.near_grazing_misses == 0 and traj.notes == []
    assert traj.q[0] == pytest.approx(1.0 + 1e-4 + math.cos(4.0), abs=1e-7)


def test_grazing_gap_option():
    """grazing_gap sets the band: 0 accepts every miss (no note), a wide band flags the
    1e-4 m clear miss; bad values are refused."""
    scene, _, _ = studies.tangent_approach(1e-12)
    assert simulate(scene, 4.0, grazing_gap=0.0).stats.near_grazing_misses == 0
    wide, _, _ = studies.tangent_approach(-1e-4)
    assert simulate(wide, 4.0, grazing_gap=1e-3).stats.near_grazing_misses == 1
    for bad in (-1.0, math.nan, math.inf):
        with pytest.raises(cd.InvalidInputError, match="grazing_gap"):
            simulate(scene, 1.0, grazing_gap=bad)


# ----------------------------------------------------------------------------------
# near-simultaneous touchdowns
# ----------------------------------------------------------------------------------
def test_gap_time_formula():
    """The touchdown time difference from the free fall (g = 1) against the direct
    difference of the two landing times at a pitch where cancellation is harmless."""
    p = 0.1
    for model, c, d in (("soft", 1.0, 0.5), ("rigid", 2 / 3, 1 / 6)):
        h_r = c - 0.25 * math.sin(p) - d * math.cos(p)
        h_f = c + 0.25 * math.sin(p) - d * math.cos(p)
        assert studies.touchdown_gap_time(model, p) == pytest.approx(math.sqrt(2 * h_f) - math.sqrt(2 * h_r), rel=1e-12)
        assert studies.touchdown_gap_time(model, studies.pitch_for_gap_time(model, 1e-7)) == pytest.approx(
            1e-7, rel=1e-9
        )


@pytest.fixture(scope="module")
def soft_trot_at_zero():
    return simulate(cd.trot_touchdown("soft", 0.0), 1.5, jacobian=True, **TIGHT)


@pytest.mark.parametrize("dt", [1e-4, 1e-8, 1e-12])
def test_soft_trot_continuous_and_differentiable_into_simultaneous(soft_trot_at_zero, dt):
    """Decoupled model, feet landing dt apart (dt = 1e-8: two events; 1e-12: grouped as
    one simultaneous event within simultaneous_tol = 1e-9). With the initial offset
    d0 = x0(dt) - x0(0) (~dt): the outcome changes by J(0) d0 + O(dt^2), i.e. the flow
    Jacobian at the simultaneous touchdown is the derivative through it (a central
    finite-difference check: O(dt^2) + rounding 1e-14), its outcome is continuous
    (|dx| <= |J(0)| |d0|, here ~10 dt) and the Jacobian changes by O(dt)."""
    ref = soft_trot_at_zero
    scene = cd.trot_touchdown("soft", studies.pitch_for_gap_time("soft", dt))
    traj = simulate(scene, 1.5, jacobian=True, **TIGHT)
    n_touch = [e.kind for e in traj.events].count("touchdown")
    assert n_touch == (1 if dt < 1e-9 else 2)
    d0 = np.concatenate([pin.difference(scene.model, ref.q0, scene.q0), scene.v0 - ref.v0])
    dx = np.concatenate([pin.difference(scene.model, ref.q, traj.q), traj.v - ref.v])
    J = ref.jacobian
    assert np.max(np.abs(dx - J @ d0)) <= 1e3 * dt**2 + 1e-13
    assert np.max(np.abs(dx)) <= 1.01 * np.max(np.abs(J @ d0)) + 1e-13
    assert np.max(np.abs(traj.jacobian - J)) <= 1e3 * dt + 1e-9
    assert all(e.differentiable for e in traj.events)


def test_rigid_trot_jumps_at_every_small_dt():
    """The coupled model: landing one foot dt = 1e-6 s first changes the outcome by O(1)
    against the simultaneous landing (the contrast of the paper's Fig. 1); grouped
    (dt < simultaneous_tol) it is the simultaneous outcome."""
    rows = studies.simultaneous_study(gaps=(1e-6, 1e-12), rigid=True)
    rigid = [r for r in rows if r.case == "rigid trot"]
    assert rigid[0].error > 0.1 and "jump" in rigid[0].outcome
    assert rigid[1].error < 1e-12 and rigid[1].outcome == "grouped as simultaneous"
    assert all(r.ok for r in rows)


# ----------------------------------------------------------------------------------
# long elastic runs
# ----------------------------------------------------------------------------------
def _elastic(impacts):
    (row,) = studies.elastic_study(impacts)
    return row


def test_thousand_elastic_impacts():
    """e = 1: each impact is exact up to rounding; the drift comes from time stored as an
    absolute float (eps t ~ 6e-13 s at t = 2800 per impact, a random walk over the
    impacts): bounded by 1e-9 in energy (v^2/2 + z = 1), 1e-10 m in gap at the located
    impacts and in penetration over the flights, 1e-6 s in impact times
    (t_k = sqrt(2)(1 + 2k))."""
    row = _elastic(1000)
    d = row.details
    assert d["impacts"] == 1000
    assert d["energy_drift_events"] < 1e-9 and d["energy_drift_flights"] < 1e-9
    assert d["gap_at_impacts_max"] < 1e-10 and d["lowest_gap"] > -1e-10
    assert d["impact_time_drift"] < 1e-6
    assert row.ok


@pytest.mark.slow
def test_ten_thousand_elastic_impacts():
    """The same over 10,000 impacts (t up to 2.8e4 s: ten times the rounding per impact,
    ten times as many impacts): energy within 1e-7, gaps within 1e-9 m."""
    row = _elastic(10_000)
    d = row.details
    assert d["impacts"] == 10_000
    assert d["energy_drift_events"] < 1e-7 and d["energy_drift_flights"] < 1e-7
    assert d["gap_at_impacts_max"] < 1e-9 and d["lowest_gap"] > -1e-9


# ----------------------------------------------------------------------------------
# bad numbers, refused up front
# ----------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "option,value",
    [
        ("max_events", math.nan),
        ("max_events", math.inf),
        ("max_events", -1),
        ("max_events", 2.5),
        ("max_events", True),
        ("t0", math.nan),
        ("max_step", math.nan),
        ("zeno_speed", math.inf),
        ("simultaneous_tol", math.nan),
        ("grazing_speed", -math.inf),
        ("project_tol", math.nan),
        ("grazing_gap", math.inf),
    ],
)
def test_bad_simulate_numbers(option, value):
    with pytest.raises(cd.InvalidInputError, match=option) as info:
        simulate(cd.load_scene("ball"), 1.0, **{option: value})
    assert str(value) in str(info.value) or repr(value) in str(info.value)


@pytest.mark.parametrize(
    "entry,where",
    [
        ("[[contact]]\nframe = 'ball'\noffset = nan\n", "offset"),
        ("[[contact]]\nframe = 'ball'\nrestitution = inf\n", "restitution"),
        ("[[contact]]\nframe = 'ball'\nnormal = [0.0, 0.0, nan]\n", "normal"),
        ("[[joint_spring]]\njoint = 'z'\nstiffness = nan\n", "stiffness"),
        ("[[joint_spring]]\njoint = 'z'\nstiffness = 1.0\ndamping = inf\n", "damping"),
        ("gravity = [0.0, 0.0, -inf]\n", "gravity"),
        ("[initial]\nv = { z = -inf }\n", "finite"),
    ],
)
def test_non_finite_toml_values(tmp_path, entry, where):
    """TOML's own nan and inf literals, in every numeric field of a scene file."""
    (tmp_path / "b.urdf").write_text((ROBOTS_DIR / "ball.urdf").read_text())
    path = tmp_path / "s.toml"
    text = 'robot = "b.urdf"\n'
    text = (entry + text) if entry.startswith("gravity") else (text + entry)
    path.write_text(text + ("" if "[initial]" in entry else "[initial]\nq = { z = 1.0 }\n"))
    with pytest.raises(cd.InvalidInputError, match=where) as info:
        cd.load_scene(path)
    assert "nan" in str(info.value) or "inf" in str(info.value)


def test_nan_inertia_in_urdf_is_refused(tmp_path):
    """ixx = "nan": the parser silently drops the whole rotational inertia (iyy = 7 is
    lost too), a wrong model; it must be refused."""
    text = (ROBOTS_DIR / "two_limb.urdf").read_text()
    text = text.replace('ixx="0" ixy="0"', 'ixx="nan" ixy="0"', 1).replace('iyy="0"', 'iyy="7"', 1)
    path = tmp_path / "bad.urdf"
    path.write_text(text)
    with pytest.raises(cd.ModelLoadError, match="nan"):
        cd.load_robot(path)


def test_bad_input_study_all_refused():
    rows = studies.bad_input_study()
    assert rows and all(r.ok for r in rows), [(r.parameter, r.outcome) for r in rows if not r.ok]
