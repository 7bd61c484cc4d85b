"""A finger pushes a ball (robots/pushed_ball.toml): closed forms of the push, the roll,
the slip and the release.

Finger of mass M on a slide, driven by a spring k toward ``rest`` from x_f = 0; a ball
of mass m, radius r, inertia I = 2 m r²/5, on the ground with Coulomb friction μ,
pushed at its centre's height (no torque from the finger). Their contact closes at
x_b = x_f + r (ball centre x_b, tip x_f).

**Rolling** (the ground contact sticks): the ball's kinetic energy is
(m + I/r²) ẋ²/2 = (7m/5) ẋ²/2, so finger and ball move as one mass M + 7m/5:

    x_f(t) = rest (1 - cos Ωt),     Ω = sqrt(k / (M + 7m/5)),

the push is (7m/5) ẍ and the ground's friction I ẍ / r² = (2/5) m ẍ, inside the cone
while (2/5) rest Ω² <= μ g. The push vanishes at x_f = rest, t1 = π / (2Ω): the
finger lets go (a lift-off), the ball rolls on at V = rest Ω with spin V / r about
+y, and the spring's energy k rest²/2 is all in (M + 7m/5) V²/2. The finger, now alone,
swings about ``rest`` at sqrt(k/M) and never catches the ball again.

**Slipping** (μ below (2/5) rest Ω² / g): friction μ m g opposes the slip and spins
the ball up, so (M + m) ẍ = k (rest - x) - μ m g and I ω̇ = μ m g r:

    x_f = c (1 - cos Ω' t),  c = rest - μ m g / k,  Ω' = sqrt(k / (M + m)),  ω r = 5 μ g t / 2;

the ball sticks (and rolls) when ẋ = ω r, at the root t_s of c Ω' sin Ω't = 5 μ g t/2,
then rolls as above from (x_s, ẋ_s) until the push vanishes at x_f = rest:
t1 = t_s + atan((rest - x_s) Ω / ẋ_s) / Ω.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from scipy.optimize import brentq

import contactdiff as cd
from contactdiff.dynamics.mode import ModeDynamics
from contactdiff.dynamics.redundant import range_basis

M, MASS, R, K, REST, G, MU = 0.3, 0.2, 0.03, 20.0, 0.1, 9.81, 0.5  # the scene file's numbers (SI)
OMEGA = np.sqrt(K / (M + 1.4 * MASS))
T1 = np.pi / (2 * OMEGA)
V = REST * OMEGA
T_END = 0.6
TIGHT = dict(rtol=1e-10, atol=1e-12)
# a located event: the guard's zero to about atol + rtol |x| over its rate (O(1) here): ~1e-10 s;
# states: the integration error ~1e-10 relative, grown over the run's few time constants
EVENT_ATOL = 1e-8  # s
STATE_ATOL = 1e-8  # m, m/s, rad/s


@pytest.fixture(scope="module")
def scene():
    return cd.load_scene("pushed_ball")


def _ball_world_velocity(scene, q, v):
    """The ball's linear and angular velocity in world axes (m/s, rad/s): its free-flyer
    velocity is in its own frame."""
    joint = scene.model.joints[scene.robot.joint_id("ball")]
    rotation = pin.Quaternion(q[joint.idx_q + 3 : joint.idx_q + 7]).matrix()
    local = v[joint.idx_v : joint.idx_v + 6]
    return rotation @ local[:3], rotation @ local[3:]


def test_the_numbers_of_the_scene_file_are_those_of_the_closed_form(scene):
    ball = scene.robot.objects[0]
    assert (ball.mass, ball.radius) == (MASS, R)
    assert scene.model.inertias[scene.robot.joint_id("slide")].mass == M
    assert scene.contacts[0].spec.mu == MU and scene.effort_specs[0].stiffness == K
    assert 0.4 * REST * OMEGA**2 < MU * G  # it rolls: the friction stays inside the cone


def test_the_ball_rolls_with_the_finger_and_leaves_it_at_the_spring_rest(scene):
    traj = cd.simulate(scene, T_END, dense=True, **TIGHT)
    (release,) = traj.events
    assert release.kind == "lift-off" and release.contacts == ("push",)
    assert release.t == pytest.approx(T1, abs=EVENT_ATOL)
    slide = scene.robot.scalar_joint("slide")[0]
    ball_x = scene.model.joints[scene.robot.joint_id("ball")].idx_q
    for t in np.linspace(0.0, T1, 7)[1:-1]:  # pushing: one mass M + 7m/5 on the spring
        q, _ = traj.at(t)
        assert q[slide] == pytest.approx(REST * (1 - np.cos(OMEGA * t)), abs=STATE_ATOL)
        assert q[ball_x] == pytest.approx(q[slide] + R, abs=STATE_ATOL)  # touching, at the centre's height
    linear, angular = _ball_world_velocity(scene, traj.q, traj.v)
    np.testing.assert_allclose(linear, [V, 0.0, 0.0], atol=STATE_ATOL)
    np.testing.assert_allclose(angular, [0.0, V / R, 0.0], atol=STATE_ATOL / R)  # rolling: ω = V / r
    assert traj.q[ball_x] == pytest.approx(REST + R + V * (T_END - T1), abs=STATE_ATOL)
    omega_f = np.sqrt(K / M)  # the finger alone, from (rest, V) at t1
    assert traj.q[slide] == pytest.approx(REST + V / omega_f * np.sin(omega_f * (T_END - T1)), abs=STATE_ATOL)


def test_energy_the_spring_gives_is_the_rolling_pair_s(scene):
    traj = cd.simulate(scene, T1 - 1e-6, **TIGHT)  # just before the release: no dissipation so far
    slide = scene.robot.scalar_joint("slide")
    x, xdot = traj.q[slide[0]], traj.v[slide[1]]
    spring = 0.5 * K * (REST - x) ** 2
    kinetic = 0.5 * (M + 1.4 * MASS) * xdot**2
    assert spring + kinetic == pytest.approx(0.5 * K * REST**2, abs=1e-9 * K * REST**2)


def test_the_ground_holds_the_weight_and_the_rolling_friction(scene):
    """At t = 0 the ground pushes m g up and (2/5) m ẍ back along x (ẍ = rest Ω²)."""
    dyn = cd.ModeDynamics(scene)
    sol = dyn.solve(scene.q0, scene.v0, 0.0, (0, 1))
    ground, push = sol.row_forces()
    tangents = scene.contacts[0].directions[1:]
    friction = tangents.T @ ground[1:]
    assert ground[0] == pytest.approx(MASS * G, rel=1e-12)
    np.testing.assert_allclose(friction, [-0.4 * MASS * REST * OMEGA**2, 0.0, 0.0], atol=1e-12)
    assert push[0] == pytest.approx(1.4 * MASS * REST * OMEGA**2, rel=1e-12)


def test_with_little_friction_the_ball_slips_then_rolls(scene):
    mu = 0.1  # below (2/5) rest Ω² / g = 0.14: it slips from the start
    assert mu < 0.4 * REST * OMEGA**2 / G
    slippery = scene.with_friction(mu, contacts=["ground"])
    traj = cd.simulate(slippery, T_END, **TIGHT)
    c, omega_s = REST - mu * MASS * G / K, np.sqrt(K / (M + MASS))
    t_s = brentq(lambda t: c * omega_s * np.sin(omega_s * t) - 2.5 * mu * G * t, 1e-3, np.pi / (2 * omega_s))
    x_s, xdot_s = c * (1 - np.cos(omega_s * t_s)), c * omega_s * np.sin(omega_s * t_s)
    t_release = t_s + np.arctan((REST - x_s) * OMEGA / xdot_s) / OMEGA
    assert [(e.kind, e.contacts) for e in traj.events] == [("stick", ("ground",)), ("lift-off", ("push",))]
    assert traj.events[0].t == pytest.approx(t_s, abs=EVENT_ATOL)
    assert traj.events[1].t == pytest.approx(t_release, abs=EVENT_ATOL)
    linear, angular = _ball_world_velocity(slippery, traj.q, traj.v)
    assert angular[1] * R == pytest.approx(linear[0], abs=STATE_ATOL)  # rolling at the end


def test_the_checker_finds_the_push_and_the_ground_orthogonal(scene):
    """The two normals (x, z) pass through the sphere's centre: G_12 = x·z / m = 0."""
    report = cd.check_decoupling(scene, samples=4)
    (pair,) = report.pairs
    assert pair.max < 1e-15  # products of O(1/m) numbers that cancel exactly in exact arithmetic
    assert report.verdict == "orthogonal only"  # each gap moves with the ball, the body


def test_friction_on_the_finger_too_shares_the_load_by_compatible_deflection(scene):
    """A Coulomb finger holds the ball's vertical motion through its tangential row, as
    the ground's normal does: four rows of rank 3, so the vertical load's split between
    them is the principle's (`contactdiff.dynamics.redundant`): the forces lie in
    ``range(A)``, the ball neither sinks nor rises, and the run goes on."""
    both = scene.with_friction(0.1)
    traj = cd.simulate(both, T_END)
    assert traj.t == pytest.approx(T_END)
    dyn = ModeDynamics(both)
    push, ground = both.contact_names.index("push"), both.contact_names.index("ground")
    mode = tuple(sorted((push, ground)))
    assert dyn.redundant(mode)
    sol = dyn.solve(both.q0, both.v0, 0.0, mode)
    dyn.kin.update(both.q0, both.v0)
    A = np.vstack([dyn.contact(k).rows(dyn.kin) for k in mode])
    U = range_basis(A)
    scale = MASS * G  # N: the forces' size; round-off ~1e-15 of it
    np.testing.assert_allclose(sol.forces - U @ (U.T @ sol.forces), 0.0, atol=1e-12 * scale)
    np.testing.assert_allclose(
        A @ sol.ddq + np.concatenate([dyn.contact(k).drift(dyn.kin) for k in mode]), 0.0, atol=1e-12 * G
    )
    assert sol.normal_forces()[mode.index(ground)] > 0.0
