"""Flow Jacobians, saltation matrices and event-time gradients (docs/design.md §2, §7).

References, never the code's own output:

* **Central finite differences of the simulator on the manifold.** Column k
  perturbs the initial state (``q0 ⊕ ±ε e_k`` for k < nv, ``v0 ± ε e_{k-nv}``),
  simulates to T with the same tolerances and takes
  ``[difference(q-, q+), v+ - v-] / 2ε``. Step: ε = 1e-5 at rtol = 1e-12,
  atol = 1e-13. The FD error has a truncation part ~ε² |x'''| (1e-10) and a
  noise part ~(steps × tol)/ε from the adaptive step sequence, which changes
  discretely with the perturbation; measured on the soft trot the total is
  4e-8 at ε = 1e-5, 1e-7 at 3e-6, 4e-7 at 1e-6 and 7e-7 at 3e-7 (noise
  dominated below 1e-5), so 1e-5 is the sweet spot. The comparison is
  ``max|J - FD| / max|FD|`` ≤ 1e-6 (`helpers.assert_fd`, docs/design.md §7).
  FD is only meaningful where the perturbations do not change the event
  sequence in a non-differentiable way: for every scene with separate events
  the perturbed runs are checked to have the nominal event sequence; at the
  *decoupled* simultaneous events (two_limb, soft trot at pitch 0) the
  perturbations split the event in both orders, which is exactly the paper's
  claim (the flow stays C¹), so FD still applies there.
* **Closed forms** for the ball (saltation matrix and event times).
* **The implicit-function theorem** for event-time gradients, evaluated here
  from a run stopped just before the event.

Models (docs/design.md §6, g = 1 except solo12): ball (e = 0.8), two_limb, the soft and
rigid planar trot (`trot_touchdown`), a rigid bar = the rigid trot with
restitution 0.5 on both feet, sticking-foot variants of the soft trot, and a
tilted solo12 drop (free-flyer, sticking plastic feet).
"""

from __future__ import annotations

import functools
import json
import math
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin
import pytest
from helpers import assert_fd
from scipy.spatial.transform import Rotation

import contactdiff as cd
from contactdiff.cli import main as cli_main
from contactdiff.dynamics.mode import ModeDynamics
from contactdiff.integration.hybrid import simulate
from contactdiff.integration.sensitivity import liftoff_saltation, saltation_matrices

TOL = dict(rtol=1e-12, atol=1e-13)
EPS = 1e-5
JAC_RTOL = 1e-6  # docs/design.md §7: flow Jacobians vs FD of the simulator


# ----------------------------------------------------------------------------------
# scenes
# ----------------------------------------------------------------------------------
def _trot_variant(model: str, pitch: float, v0=None, name=None, **contact) -> cd.Scene:
    """`trot_touchdown(model, pitch)` with every foot contact rebuilt with ``contact``
    (e.g. restitution=0.5, friction="stick") and an optional initial velocity."""
    base = cd.trot_touchdown(model, pitch)
    contacts = [cd.Contact(c.frame, **contact) for c in base.contact_specs]
    scene = cd.Scene(base.robot, contacts, base.effort_specs, None, base.q0, base.v0, name=name or f"{model}-{contact}")
    return scene.with_state(None, v0) if v0 else scene


def _solo_tilted() -> cd.Scene:
    """solo12_drop with the base rolled 0.03 and pitched 0.05 rad and raised 1 cm:
    the feet land one at a time (FR at t ≈ 0.0964, FL at ≈ 0.10678, FR again 8e-6 s
    later after the FL impact threw it off, HR at ≈ 0.1166)."""
    scene = cd.load_scene("solo12_drop")
    q = scene.q0.copy()
    q[3:7] = Rotation.from_euler("xyz", [0.03, 0.05, 0.0]).as_quat()  # (x, y, z, w) as pinocchio
    q[2] += 0.01
    return scene.with_state(q)


GLIDE = 0.3  # m/s: body and feet moving forward together before the landing


@dataclass(frozen=True)
class Case:
    """One FD study: scene, final time, simulator options and the expected events
    ``(kind, {contacts}, simultaneous)``."""

    build: object
    t_final: float
    events: tuple
    options: dict = field(default_factory=dict)

    def scene(self) -> cd.Scene:
        return self.build()


R, F = "rear_foot", "front_foot"
CASES = {
    # two bounces at t = sqrt2 and sqrt2 (1 + 2e)
    "ball": Case(lambda: cd.load_scene("ball"), 5.2, (("bounce", {"ball"}, False), ("bounce", {"ball"}, False))),
    # simultaneous touchdown at t = 1, simultaneous lift-off at t ≈ 1.81
    "two_limb": Case(
        lambda: cd.load_scene("two_limb"),
        2.0,
        (("touchdown", {"left_foot", "right_foot"}, True), ("lift-off", {"left_foot", "right_foot"}, True)),
    ),
    "soft_pitch0": Case(
        lambda: cd.trot_touchdown("soft", 0.0), 1.8, (("touchdown", {R, F}, True), ("lift-off", {R, F}, True))
    ),
    "soft_pitch0.05": Case(
        lambda: cd.trot_touchdown("soft", 0.05),
        1.8,
        (("touchdown", {R}, False), ("touchdown", {F}, False), ("lift-off", {F}, False), ("lift-off", {R}, False)),
    ),
    # rear lands, then the front, whose impact makes the rear leave
    "rigid_pitch0.05": Case(
        lambda: cd.trot_touchdown("rigid", 0.05), 1.6, (("touchdown", {R}, False), ("touchdown", {F}, False))
    ),
    # rigid bar bouncing (e = 0.5): rear bounce, then front bounce
    "bar_e0.5_pitch0.05": Case(
        lambda: _trot_variant("rigid", 0.05, restitution=0.5), 1.5, (("bounce", {R}, False), ("bounce", {F}, False))
    ),
    # sticking feet: separate touchdowns and lift-offs with tangential force left
    "soft_stick_pitch0.05": Case(
        lambda: _trot_variant("soft", 0.05, friction="stick"),
        1.8,
        (("touchdown", {R}, False), ("touchdown", {F}, False), ("lift-off", {F}, False), ("lift-off", {R}, False)),
    ),
    # sticking feet landing while gliding forward: the legs lean, and both sticking
    # feet lift off together with tangential force (regression: simultaneous lift-off)
    "soft_stick_glide": Case(
        lambda: _trot_variant(
            "soft", 0.0, {"body_x": GLIDE, "rear_foot_x": GLIDE, "front_foot_x": GLIDE}, friction="stick"
        ),
        1.8,
        (("touchdown", {R, F}, True), ("lift-off", {R, F}, True)),
    ),
    "solo12_one_touchdown": Case(_solo_tilted, 0.104, (("touchdown", {"FR_FOOT"}, False),)),
    # three touchdowns within 1e-5 s of each other amplify the FD noise: at rtol 1e-12
    # the FD error is 6.7e-7 (ε = 1e-5; 3.8e-6 at ε = 1e-6); one decade tighter it is
    # 1.7e-7, while the Jacobian itself moves by 7e-10 between the two tolerances
    "solo12_three_touchdowns": Case(
        _solo_tilted,
        0.112,
        (("touchdown", {"FR_FOOT"}, False), ("touchdown", {"FL_FOOT"}, False), ("touchdown", {"FR_FOOT"}, False)),
        dict(rtol=1e-13, atol=1e-14),
    ),
    "rigid_pitch0.05_radau": Case(
        lambda: cd.trot_touchdown("rigid", 0.05),
        1.6,
        (("touchdown", {R}, False), ("touchdown", {F}, False)),
        dict(method="Radau"),
    ),
}
SLOW_CASES = {
    "soft_pitch0.05_radau": Case(
        lambda: cd.trot_touchdown("soft", 0.05), 1.8, CASES["soft_pitch0.05"].events, dict(method="Radau")
    ),
    "soft_pitch0_second_landing": Case(
        lambda: cd.trot_touchdown("soft", 0.0), 2.5, CASES["soft_pitch0"].events + (("touchdown", {R, F}, True),)
    ),
    "two_limb_second_landing": Case(
        lambda: cd.load_scene("two_limb"),
        4.0,
        CASES["two_limb"].events + (("touchdown", {"left_foot", "right_foot"}, True),),
    ),
}


def _sequence(traj) -> list:
    return [(e.kind, set(e.contacts), e.simultaneous) for e in traj.events]


@dataclass
class Study:
    scene: cd.Scene
    traj: cd.Trajectory
    fd: np.ndarray
    plus: list
    minus: list


@functools.lru_cache(maxsize=None)
def _study(name: str) -> Study:
    """Nominal run with the Jacobian and the 4 nv perturbed runs of the central FD."""
    case = {**CASES, **SLOW_CASES}[name]
    options = {**TOL, **case.options}
    scene = case.scene()
    model, nv = scene.model, scene.nv
    traj = simulate(scene, case.t_final, jacobian=True, **options)
    plus, minus, cols = [], [], []
    for k in range(2 * nv):
        e = np.zeros(nv)
        e[k % nv] = EPS
        runs = []
        for sign in (1.0, -1.0):
            if k < nv:
                q, v = pin.integrate(model, scene.q0, sign * e), scene.v0
            else:
                q, v = scene.q0, scene.v0 + sign * e
            runs.append(simulate(scene.with_state(q, v), case.t_final, **options))
        p, m = runs
        plus.append(p)
        minus.append(m)
        cols.append(np.concatenate([pin.difference(model, m.q, p.q), p.v - m.v]) / (2 * EPS))
    return Study(scene, traj, np.array(cols).T, plus, minus)


def _rel(a, b) -> float:
    return float(np.abs(np.asarray(a) - np.asarray(b)).max() / max(np.abs(b).max(), 1e-300))


# ----------------------------------------------------------------------------------
# 1. flow Jacobian vs FD of the simulator, through every kind of event
# ----------------------------------------------------------------------------------
def _check_study(name: str) -> None:
    case = {**CASES, **SLOW_CASES}[name]
    s = _study(name)
    assert _sequence(s.traj) == list(case.events), _sequence(s.traj)
    nv = s.scene.nv
    assert s.traj.jacobian.shape == (2 * nv, 2 * nv)
    assert s.traj.differentiable, s.traj.notes
    if not any(e.simultaneous for e in s.traj.events):
        # FD is a derivative of one smooth branch only if no perturbation changes the events
        for run in s.plus + s.minus:
            assert [(e.kind, e.contacts) for e in run.events] == [(e.kind, e.contacts) for e in s.traj.events]
    assert_fd(f"flow jacobian {name}", s.traj.jacobian, s.fd, rtol=JAC_RTOL)


@pytest.mark.parametrize("name", list(CASES))
def test_flow_jacobian_matches_fd(name):
    _check_study(name)


@pytest.mark.slow
@pytest.mark.parametrize("name", list(SLOW_CASES))
def test_flow_jacobian_matches_fd_slow(name):
    _check_study(name)


def test_frictionless_liftoff_saltation_is_identity():
    """A frictionless contact's force is 0 at its lift-off and its vector field
    continuous: Ξ = I to round-off (separate lift-offs and decoupled simultaneous ones)."""
    n = 0
    for name in ("soft_pitch0.05", "soft_pitch0", "two_limb"):
        for ev in _study(name).traj.events:
            if ev.kind == "lift-off":
                n += 1
                np.testing.assert_allclose(ev.saltation, np.eye(len(ev.saltation)), rtol=0, atol=1e-13)
    assert n == 4


def test_sticking_liftoff_saltation_is_not_identity():
    """A sticking foot still carries tangential force when its normal force reaches 0:
    the acceleration jumps and Ξ ≠ I (the FD test of the same run validates it)."""
    s = _study("soft_stick_pitch0.05")
    lift = [ev for ev in s.traj.events if ev.kind == "lift-off"]
    assert len(lift) == 2
    for ev in lift:
        assert np.abs(ev.saltation - np.eye(len(ev.saltation))).max() > 0.05
        np.testing.assert_array_equal(ev.v_plus, ev.v_minus)  # no jump in the state


def test_simultaneous_sticking_liftoff_is_the_product_in_either_order():
    """Both sticking feet of the gliding soft trot release together with tangential
    force. The decoupled limbs make the two single lift-off saltations commute, and
    the event's matrix must be their product (it used to take only the first
    contact's guard with the whole jump of the vector field: 3e-2 off against FD)."""
    s = _study("soft_stick_glide")
    ev = s.traj.events[1]
    assert ev.kind == "lift-off" and ev.simultaneous
    dyn = ModeDynamics(s.scene)
    r, f = s.scene.contact_index(R), s.scene.contact_index(F)
    q, v = ev.q, ev.v_minus
    rear_first = liftoff_saltation(dyn, ev.t, q, v, (f,), f, ()) @ liftoff_saltation(dyn, ev.t, q, v, (r, f), r, (f,))
    front_first = liftoff_saltation(dyn, ev.t, q, v, (r,), r, ()) @ liftoff_saltation(dyn, ev.t, q, v, (r, f), f, (r,))
    assert np.abs(rear_first - np.eye(len(rear_first))).max() > 0.1
    assert _rel(rear_first, front_first) <= 1e-12
    assert _rel(ev.saltation, rear_first) <= 1e-12


# ----------------------------------------------------------------------------------
# 2. ball saltation matrix vs closed form
# ----------------------------------------------------------------------------------
def test_ball_saltation_closed_form():
    """State (z, v), guard h = z (Dh = [1, 0]), reset v+ = -e v- (DR = diag(1, -e)),
    F- = (v-, -g), F+ = (-e v-, -g). Then F+ - DR F- = -(1 + e)(v-, g), Dh F- = v-, and

        Ξ = DR + (F+ - DR F-) Dh / (Dh F-) = [[-e, 0], [-(1 + e) g / v-, -e]].

    Both bounces of the e = 0.8, g = 1 ball, to 1e-12 (the formula is evaluated at
    the event's own v-, which matches -e^k sqrt(2) to 1e-10)."""
    e, g = 0.8, 1.0
    traj = _study("ball").traj
    for k, ev in enumerate(traj.events):
        vm = float(ev.v_minus[0])
        assert vm == pytest.approx(-(e**k) * math.sqrt(2.0), abs=1e-10)
        expected = np.array([[-e, 0.0], [-(1 + e) * g / vm, -e]])
        assert _rel(ev.saltation, expected) <= 1e-12, (ev.saltation, expected)


# ----------------------------------------------------------------------------------
# 3. order (in)dependence at simultaneous touchdowns
# ----------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["two_limb", "soft_pitch0", "soft_stick_glide"])
def test_decoupled_simultaneous_touchdown_is_order_independent(name):
    traj = _study(name).traj
    ev = traj.events[0]
    assert ev.kind == "touchdown" and ev.simultaneous and ev.differentiable
    orders = ev.saltation_orders
    assert len(orders) == 2
    for m in orders.values():
        assert _rel(m, ev.saltation) <= 1e-12
    assert not any("not differentiable" in n for n in traj.notes)


def _coupled_event(traj):
    ev = traj.events[0]
    assert ev.simultaneous and not ev.differentiable
    assert not traj.differentiable
    assert any(n.startswith("not differentiable at t = 1") for n in traj.notes), traj.notes
    a, b = ev.saltation_orders.values()
    assert _rel(a, b) > 0.1  # O(1)
    return ev


def test_coupled_simultaneous_touchdown_rigid_trot():
    """Rigid trot at pitch 0 (plastic): rear-first and front-first differ at O(1);
    they are mirror images (x -> -x, pitch -> -pitch swaps the feet)."""
    traj = simulate(cd.trot_touchdown("rigid", 0.0), 1.5, jacobian=True, **TOL)
    ev = _coupled_event(traj)
    assert ev.kind == "touchdown" and set(ev.contacts) == {R, F}
    P = np.diag([-1.0, 1.0, -1.0, -1.0, 1.0, -1.0])
    rf, fr = ev.saltation_orders[(R, F)], ev.saltation_orders[(F, R)]
    assert _rel(P @ rf @ P, fr) <= 1e-12


def test_coupled_simultaneous_bounce_rigid_bar():
    traj = simulate(_trot_variant("rigid", 0.0, restitution=0.5), 1.5, jacobian=True, **TOL)
    ev = _coupled_event(traj)
    assert ev.kind == "bounce" and ev.mode_after == ()


def test_public_saltation_matrices_hand_built_states():
    """`saltation_matrices` at states built here: both feet at the ground, falling."""
    rng = np.random.default_rng(7)
    # decoupled: two_limb, any body velocity, both limbs approaching
    limb = cd.load_scene("two_limb")
    q = limb.with_state({"body_z": 0.5, "left_foot_z": 0.0, "right_foot_z": 0.0}).q0
    np.testing.assert_allclose(limb.gaps(q), 0.0, atol=1e-15)
    for _ in range(5):
        v = np.concatenate([rng.normal(size=1), -rng.uniform(0.2, 2.0, size=2)])
        sim = saltation_matrices(limb, q, v, ["left_foot", "right_foot"])
        assert sim.differentiable and sim.spread <= 1e-12
        for m in sim.orders.values():
            assert _rel(m, sim.paper) <= 1e-12
    # decoupled: soft trot at pitch 0, body and feet moving
    soft = cd.load_scene("planar_trot_soft")
    q = soft.with_state({"body_z": 0.5, "rear_foot_z": 0.0, "front_foot_z": 0.0}).q0
    np.testing.assert_allclose(soft.gaps(q), 0.0, atol=1e-15)
    for _ in range(5):
        v = rng.normal(size=7)
        v[[4, 6]] = -rng.uniform(0.2, 2.0, size=2)  # rear_foot_z, front_foot_z
        sim = saltation_matrices(soft, q, v, [R, F])
        assert sim.differentiable and sim.spread <= 1e-12
    # coupled: rigid trot (feet at body-frame z = -1/6), falling at speed 1
    rigid = cd.load_scene("planar_trot_rigid")
    q = np.array([0.0, 1 / 6, 0.0])
    np.testing.assert_allclose(rigid.gaps(q), 0.0, atol=1e-15)
    sim = saltation_matrices(rigid, q, np.array([0.0, -1.0, 0.0]), [R, F])
    assert not sim.differentiable and sim.spread > 0.1
    a, b = sim.orders.values()
    assert _rel(a, b) > 0.1


# ----------------------------------------------------------------------------------
# 4. event-time gradients
# ----------------------------------------------------------------------------------
def _ift_time_gradient(scene, options, traj, k, delta=1e-10) -> np.ndarray:
    """``-Dh Φ- / (Dh F-)`` from a run stopped ``delta`` before touchdown ``k``:
    Φ- its flow Jacobian, Dh = [A_i, 0] with A_i the vertical row of pinocchio's
    LOCAL_WORLD_ALIGNED frame Jacobian, F- = (v, ddq) of the mode before. Stopping
    δ early costs O(δ) (measured 5e-11..4e-10 relative at δ = 1e-10)."""
    ev = traj.events[k]
    pre = simulate(scene, ev.t - delta, jacobian=True, **options)
    assert len(pre.events) == k
    model, nv = scene.model, scene.nv
    data = model.createData()
    pin.computeJointJacobians(model, data, pre.q)
    pin.updateFramePlacements(model, data)
    i = scene.contact_index(ev.contacts[0])
    fid = model.getFrameId(scene.contact_specs[i].frame)
    A = np.reshape(pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED), (6, nv))[2]
    mode = tuple(scene.contact_index(n) for n in pre.segments[-1].mode)
    ddq = ModeDynamics(scene).solve(pre.q, pre.v, pre.t, mode).ddq
    Dh = np.concatenate([A, np.zeros(nv)])
    return -(Dh @ pre.jacobian) / float(Dh @ np.concatenate([pre.v, ddq]))


@pytest.mark.parametrize(
    "name",
    [
        "ball",
        "soft_pitch0.05",
        "rigid_pitch0.05",
        "bar_e0.5_pitch0.05",
        "soft_stick_pitch0.05",
        "solo12_three_touchdowns",
    ],
)
def test_time_gradient_implicit_function(name):
    case = CASES[name]
    s = _study(name)
    n = 0
    for k, ev in enumerate(s.traj.events):
        if ev.kind in ("touchdown", "bounce"):
            n += 1
            g = _ift_time_gradient(s.scene, {**TOL, **case.options}, s.traj, k)
            assert _rel(ev.time_gradient, g) <= 1e-8, (k, ev.time_gradient, g)
    assert n >= 1


@pytest.mark.parametrize(
    "name",
    [
        "ball",
        "soft_pitch0.05",
        "rigid_pitch0.05",
        "bar_e0.5_pitch0.05",
        "soft_stick_pitch0.05",
        "solo12_one_touchdown",
        "solo12_three_touchdowns",
        "rigid_pitch0.05_radau",
    ],
)
def test_time_gradient_matches_fd(name):
    """Every event (touchdowns, bounces, lift-offs of both kinds): central FD of the
    event time over the same perturbed runs as the Jacobian FD (same event sequence)."""
    s = _study(name)
    for run in s.plus + s.minus:
        assert [(e.kind, e.contacts) for e in run.events] == [(e.kind, e.contacts) for e in s.traj.events]
    for k, ev in enumerate(s.traj.events):
        fd = np.array([(p.events[k].t - m.events[k].t) / (2 * EPS) for p, m in zip(s.plus, s.minus)])
        assert _rel(ev.time_gradient, fd) <= 1e-6, (k, ev.kind, ev.time_gradient, fd)


def test_ball_time_gradient_closed_form():
    """Ball from z0 = 1 thrown up at v0 = 0.3 (g = 1, e = 0.8). With s = sqrt(v0² + 2 g z0)
    (the first impact speed): t1 = (v0 + s)/g, t2 = t1 + 2 e s/g, so
    dt1/dz0 = 1/s, dt1/dv0 = (1 + v0/s)/g, dt2/dz0 = (1 + 2e)/s,
    dt2/dv0 = (1 + (1 + 2e) v0/s)/g (at v0 = 0: dt1/dz0 = 1/sqrt(2 g z0))."""
    e, g, z0, v0 = 0.8, 1.0, 1.0, 0.3
    scene = cd.load_scene("ball").with_state({"z": z0}, {"z": v0})
    traj = simulate(scene, 5.0, jacobian=True, **TOL)
    s = math.sqrt(v0**2 + 2 * g * z0)
    t1, t2 = (v0 + s) / g, (v0 + s) / g + 2 * e * s / g
    assert [ev.t for ev in traj.events[:2]] == pytest.approx([t1, t2], abs=1e-10)
    np.testing.assert_allclose(traj.events[0].time_gradient, [1 / s, (1 + v0 / s) / g], rtol=1e-10)
    np.testing.assert_allclose(
        traj.events[1].time_gradient, [(1 + 2 * e) / s, (1 + (1 + 2 * e) * v0 / s) / g], rtol=1e-10
    )
    # the drop of the scene file: dt1/dz0 = 1/sqrt(2 g z0), dt1/dv0 = 1/g
    np.testing.assert_allclose(
        _study("ball").traj.events[0].time_gradient, [1 / math.sqrt(2 * g * z0), 1 / g], rtol=1e-10
    )


# ----------------------------------------------------------------------------------
# 5. the theorem, numerically: C¹ in the pitch for the soft trot, a jump for the rigid one
# ----------------------------------------------------------------------------------
def _pitch_study(model: str, t_final: float):
    """Final state at pitch 0, its Jacobian slope along the pitch of `trot_touchdown`,
    and the one-sided difference quotients ``(x(±h) ⊖ x(0)) / ±h``.

    The initial state's tangent ``d x0/dθ`` is pure geometry (sines and cosines of
    `trot_touchdown`); it is taken by a central difference with step 1e-6 (error ~1e-12).
    """
    base = cd.trot_touchdown(model, 0.0)
    traj = simulate(base, t_final, jacobian=True, **TOL)
    d = 1e-6
    dq0 = pin.difference(base.model, cd.trot_touchdown(model, -d).q0, cd.trot_touchdown(model, d).q0) / (2 * d)
    slope = traj.jacobian @ np.concatenate([dq0, np.zeros(base.nv)])
    quotients = {}
    for h in (1e-4, 1e-5):
        for sign in (1, -1):
            run = simulate(cd.trot_touchdown(model, sign * h), t_final, **TOL)
            dx = np.concatenate([pin.difference(base.model, traj.q, run.q), run.v - traj.v])
            quotients[sign * h] = dx / (sign * h)
    return traj, slope, quotients


def test_soft_trot_outcome_is_c1_in_pitch():
    """Pitch ±h sends the rear or the front down first, yet both one-sided quotients
    of the whole final state (body x, height, pitch, feet, velocities) tend to the
    Jacobian slope, at first order in h (measured: 2.6 h relative)."""
    traj, slope, quotients = _pitch_study("soft", 1.25)
    assert traj.differentiable and traj.events[0].simultaneous
    assert np.abs(slope).max() > 0.5  # a real slope (pitch, x, feet), not a symmetric zero
    for h, quotient in quotients.items():
        err = _rel(quotient, slope)
        assert err <= 10 * abs(h), (h, err)


def test_rigid_trot_outcome_jumps_at_zero_pitch():
    """The same quotients for the rigid trot blow up like 1/h: x(±h) ⊖ x(0) stays O(1)
    (rear-first, front-first and simultaneous landings end in different states)."""
    traj, slope, quotients = _pitch_study("rigid", 1.25)
    assert not traj.differentiable
    for h, quotient in quotients.items():
        jump = np.abs(quotient * h).max()
        assert jump > 0.01, (h, jump)
        assert _rel(quotient, slope) > 10.0


# ----------------------------------------------------------------------------------
# 6. command line
# ----------------------------------------------------------------------------------
def test_cli_simulate_json_jacobian(capsys):
    rc = cli_main(["simulate", "two_limb", "--t-final", "1.5", "--jacobian", "--json"])
    assert rc == 0
    out = json.loads(capsys.readouterr().out)
    scene = cd.load_scene("two_limb")
    nv = scene.nv
    J = np.array(out["jacobian"])
    assert J.shape == (2 * nv, 2 * nv)
    ref = simulate(scene, 1.5, jacobian=True)  # the command's default tolerances
    np.testing.assert_array_equal(J, ref.jacobian)
    assert len(out["events"]) == len(ref.events) == 1
    for got, ev in zip(out["events"], ref.events):
        assert np.array(got["saltation"]).shape == (2 * nv, 2 * nv)
        np.testing.assert_array_equal(np.array(got["saltation"]), ev.saltation)
        np.testing.assert_array_equal(np.array(got["time_gradient"]), ev.time_gradient)
        assert got["differentiable"] is True and got["simultaneous"] is True
        assert set(got["saltation_orders"]) == {"left_foot > right_foot", "right_foot > left_foot"}
    assert out["differentiable"] is True
