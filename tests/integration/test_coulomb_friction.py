"""Coulomb friction in `simulate`, against closed forms derived here and central finite differences.

Models (URDFs in strings below):

* ``block3``: a point mass m = 2 kg on three prismatic joints x, y, z (q = position, v = velocity);
* ``block2``: the same mass on x and z only (a planar model: one tangent row);
* ``ball``: a free-flying solid sphere, m = 2 kg, radius R = 0.1 m, I = 2/5 m R² about every axis;
  its contact has ``radius=R`` on the centre frame, so its tangent rows hold the lowest material point.

Closed forms (each test's docstring derives its own). The recurring one: a point mass sliding on a
plane with normal force N = m g cos α (α the tilt) feels the friction force ``-μ N ŝ``, ŝ the unit
slip velocity; on flat ground, with no other horizontal force, ``v(t) = v0 - μ g t v̂0`` (ŝ is
constant because the deceleration is along the velocity).

Conventions checked on the way: the Jacobian is in the tangent space, columns (q0, v0) and rows
(q, v) at t_final; directions off the contact manifold (the normal position and velocity of a
closed contact) are those of the index-reduced mode flow: a closed contact's normal velocity is
conserved by ``A ddq + drift = 0`` (flat ground: drift = 0) and the ``stick`` reset, which holds the
contact's rows, zeroes it (so d q_z / d v_z0 = t_stop). Finite differences only perturb along the
manifold (a perturbation off it starts open or penetrating).

Tolerances. Runs use rtol = atol = 1e-12 (`TOL`). A run's error is then at most ~1e-12 per unit of
the state over its O(10²) steps, so closed-form values of O(1) are compared at 1e-10 relative (a
100x margin over ~1e-12 per step, while any wrong term in a closed form is O(1)); Jacobians
propagated by the variational equation carry the same relative error and are compared at 1e-8
(their own step error is not controlled, only the state's). Central differences (ε = 1e-6): the
truncation ε² |x'''| / 6 ~ 1e-13 for the O(1)..O(10) third derivatives here, and the noise of two
runs each within ~rtol |x| + atol ≈ 2e-12 is ≤ 2 · 2e-12 / (2 ε) = 2e-6 absolute at worst; the
Jacobians here have max-abs entry ≥ 1 (d q / d q0 = I), so `FD_RTOL` = 1e-5 relative to that scale
keeps a 5x margin over that worst case while an O(1e-2..1) error in a saltation term cannot pass.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
from helpers import assert_fd
from hypothesis import HealthCheck, assume, event, given, settings
from hypothesis import strategies as st

import contactdiff as cd
from contactdiff.dynamics.mode import ModeDynamics

G = 9.81  # m/s²
MASS = 2.0  # kg (block and ball)
MU = 0.5
RADIUS = 0.1  # m (ball)
INERTIA = 0.4 * MASS * RADIUS**2  # solid sphere, kg m²
TOL = dict(rtol=1e-12, atol=1e-12)
EPS = 1e-6  # central-difference step (module doc)
FD_RTOL = 1e-5  # module doc: worst-case FD noise 2e-6 relative to a Jacobian of scale >= 1, 5x margin
REL = 1e-10  # closed-form values of O(1) (module doc)
JAC_REL = 1e-8  # closed-form Jacobians and event time gradients (module doc)

_JOINT = ('<joint name="{n}" type="prismatic"><parent link="{p}"/><child link="{c}"/><axis xyz="{a}"/>'
          '<limit lower="-100" upper="100" effort="0" velocity="100"/></joint>')
_MASS_LINK = ('<link name="block"><inertial><mass value="{m}"/>'
              '<inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>')
BLOCK3_URDF = (f'<?xml version="1.0"?><robot name="block3"><link name="world"/><link name="sx"/><link name="sy"/>'
               f'{_MASS_LINK.format(m=MASS)}'
               f'{_JOINT.format(n="x", p="world", c="sx", a="1 0 0")}'
               f'{_JOINT.format(n="y", p="sx", c="sy", a="0 1 0")}'
               f'{_JOINT.format(n="z", p="sy", c="block", a="0 0 1")}</robot>')
BLOCK2_URDF = (f'<?xml version="1.0"?><robot name="block2"><link name="world"/><link name="sx"/>'
               f'{_MASS_LINK.format(m=MASS)}'
               f'{_JOINT.format(n="x", p="world", c="sx", a="1 0 0")}'
               f'{_JOINT.format(n="z", p="sx", c="block", a="0 0 1")}</robot>')
BALL_URDF = (f'<?xml version="1.0"?><robot name="ball"><link name="ball"><inertial><origin xyz="0 0 0"/>'
             f'<mass value="{MASS}"/><inertia ixx="{INERTIA}" iyy="{INERTIA}" izz="{INERTIA}" ixy="0" ixz="0" '
             f'iyz="0"/></inertial></link></robot>')


def _load(tmp_path_factory, name, text, **kwargs):
    path = tmp_path_factory.mktemp("coulomb") / f"{name}.urdf"
    path.write_text(text)
    return cd.load_robot(str(path), **kwargs)


@pytest.fixture(scope="module")
def block3(tmp_path_factory):
    return _load(tmp_path_factory, "block3", BLOCK3_URDF)


@pytest.fixture(scope="module")
def block2(tmp_path_factory):
    return _load(tmp_path_factory, "block2", BLOCK2_URDF)


@pytest.fixture(scope="module")
def ball(tmp_path_factory):
    return _load(tmp_path_factory, "ball", BALL_URDF, floating_base=True)


def _constant_force(force):
    """A constant generalised force (N on the prismatic joints) with its exact (zero) derivatives."""
    force = np.asarray(force, dtype=float)
    n = force.size
    return cd.UserEffort(lambda q, v, t: force, lambda q, v, t: (np.zeros((n, n)), np.zeros((n, n))),
                         name="push", time_derivative=lambda q, v, t: np.zeros(n))


def _kinds(traj):
    return [(e.kind, e.contacts) for e in traj.events]


def _fd(scene, t_final, directions, kinds):
    """Central differences of the final state (tangent space) and of every event time, along the
    initial-state tangent directions ``directions`` (each 2nv: dq then dv). Every perturbed run must
    have the nominal event sequence ``kinds`` (else the difference straddles a mode change)."""
    robot, nv = scene.robot, scene.nv
    cols, times = [], []
    for d in directions:
        d = np.asarray(d, dtype=float)
        runs = []
        for sign in (1.0, -1.0):
            q0 = robot.integrate(scene.q0, sign * EPS * d[:nv])
            run = cd.simulate(scene.with_state(q0, scene.v0 + sign * EPS * d[nv:]), t_final, **TOL)
            assert _kinds(run) == kinds, (d, _kinds(run))
            runs.append(run)
        plus, minus = runs
        cols.append(np.concatenate([robot.difference(minus.q, plus.q), plus.v - minus.v]) / (2 * EPS))
        times.append([(a.t - b.t) / (2 * EPS) for a, b in zip(plus.events, minus.events)])
    return np.array(cols).T, np.array(times).T


def _unit(k, n):
    e = np.zeros(n)
    e[k] = 1.0
    return e


# ==============================================================================================
# 1. a block sliding on flat ground in an arbitrary horizontal direction
# ==============================================================================================
V0_CASES = {"oblique": (1.2, -0.9), "diagonal": (1.1, 1.1), "axis-y": (0.0, -1.7), "second-quadrant": (-0.5, 0.35)}
PARALLEL_FORCES = {"none": 0.0, "pushed-along": 0.4, "braked": -0.5}  # f / (μ m g), along v̂0


def _block_on_ground(block3, v0_xy, force_xy=(0.0, 0.0), mu=MU):
    efforts = [_constant_force([*force_xy, 0.0])] if np.any(force_xy) else []
    return cd.Scene(block3, [cd.Contact("block", friction=mu)], efforts, gravity=[0, 0, -G],
                    q0=np.zeros(3), v0=np.array([*v0_xy, 0.0]))


@pytest.mark.parametrize("force", PARALLEL_FORCES, ids=list(PARALLEL_FORCES))
@pytest.mark.parametrize("case", V0_CASES, ids=list(V0_CASES))
def test_block_slides_to_a_stop(block3, case, force):
    """Closed form, with an optional constant horizontal force F = f v̂0 along the initial velocity
    (|f| < μ m g; f = 0 is the plain block).

    The normal force is m g (flat ground, no vertical effort), so while slipping
    m v̇ = f v̂0 - μ m g ŝ. With ŝ = v̂0 the right side is along v̂0, so ŝ stays v̂0 and the speed
    falls at a = μ g - f/m > 0: the stop is at t_s = V / a (V = |v0|) at q_s = q0 + v0 V / (2a), and
    the block then sticks (the force it needs, -F, is in the cone since |f| < μ m g).

    Jacobian, with P = v̂0 v̂0ᵀ and P⊥ = I - P (horizontal 2x2 blocks):

    * along v0: q_s = V² / (2a) v̂0, so d q_s / dV = V / a;
    * across: linearise in a transverse velocity w (|w| ≪ V): v̇∥ = f/m - μ g + O(w²) and
      ẇ = -μ g w / |v| ≈ -μ g w / (V - a t), so w(t) = w0 (1 - a t / V)^(μ g / a), which vanishes at
      t_s too (the stop time moves at second order only), and the transverse displacement is
      ∫0^t_s w dt = w0 (V / a) / (μ g / a + 1) = w0 V / (μ g + a);

      d q_xy(T) / d v0_xy = P V / a + P⊥ V / (μ g + a),   d q_xy / d q0_xy = I,   d v(T) / d · = 0,
      d t_s / d v0_xy = v̂0ᵀ / a,   d t_s / d q0 = 0.

    With f = 0 (a = μ g) this is (V I + v0 v0ᵀ / V) / (2 μ g). The normal columns (module doc):
    λ_N = m g whatever v_z, so they do not reach the horizontal rows, and d q_z / d v_z0 = t_s."""
    v0 = np.array(V0_CASES[case])
    speed = np.linalg.norm(v0)
    v_hat = v0 / speed
    f = PARALLEL_FORCES[force] * MU * MASS * G
    a = MU * G - f / MASS
    t_s = speed / a
    t_final = t_s + 0.2
    scene = _block_on_ground(block3, v0, f * v_hat)
    traj = cd.simulate(scene, t_final, jacobian=True, **TOL)

    assert _kinds(traj) == [("stick", ("block",))]
    (stop,) = traj.events
    assert stop.sliding == () and stop.mode_after == ("block",) and stop.differentiable
    assert [s.sliding for s in traj.segments] == [("block",), ()]
    assert stop.t == pytest.approx(t_s, rel=REL)
    q_s = v0 * speed / (2 * a)
    np.testing.assert_allclose(stop.q, [*q_s, 0.0], rtol=0, atol=REL * speed * t_s)
    np.testing.assert_allclose(traj.q, [*q_s, 0.0], rtol=0, atol=REL * speed * t_s)
    np.testing.assert_allclose(traj.v, 0.0, rtol=0, atol=REL * speed)
    np.testing.assert_allclose(stop.v_plus, 0.0, rtol=0, atol=REL * speed)

    # the event's time gradient
    grad = np.zeros(6)
    grad[3:5] = v_hat / a
    np.testing.assert_allclose(stop.time_gradient, grad, rtol=0, atol=JAC_REL * t_s / speed)

    # the flow Jacobian through slip -> stick: closed form
    P = np.outer(v_hat, v_hat)
    J = np.zeros((6, 6))
    J[:3, :3] = np.eye(3)
    J[:2, 3:5] = P * speed / a + (np.eye(2) - P) * speed / (MU * G + a)
    J[2, 5] = t_s  # off the manifold: the index-reduced convention (module doc)
    np.testing.assert_allclose(traj.jacobian, J, rtol=0, atol=JAC_REL * np.abs(J).max())

    # and central differences along the ground (q_x, q_y, v_x, v_y)
    directions = [_unit(k, 6) for k in (0, 1, 3, 4)]
    fd, fd_times = _fd(scene, t_final, directions, _kinds(traj))
    assert_fd(f"coulomb block {case} {force}", traj.jacobian[:, [0, 1, 3, 4]], fd, traj.q, rtol=FD_RTOL)
    assert_fd(f"coulomb block stop time {case} {force}", stop.time_gradient[[0, 1, 3, 4]], fd_times[0],
              t_s, rtol=FD_RTOL)


OBLIQUE_FORCES = {"perpendicular": (90.0, 0.6), "backward-oblique": (135.0, 0.8), "forward-oblique": (-40.0, 0.7)}


def _curved_slide(v0, a, c):
    """Closed form of the slide under a constant horizontal acceleration a (= F/m) and friction
    deceleration c = μ g (|a| < c), from v0 (2-vectors) to the stop.

    While slipping v̇ = a - c ŝ with ŝ = v̂, so d|v|/dt = a·v̂ - c and d(a·v)/dt = |a|² - c a·v̂:
    W = c |v| + a · v has Ẇ = |a|² - c², constant. At the stop v = 0, so with D = c² - |a|² > 0 and
    W0 = c V + a · v0 (V = |v0|):   t_s = W0 / D.

    Position: d/dt(v W) = (a - c v̂) W - D v = a W - c² v - c (a·v̂) v - D v and
    d/dt(|v| v) = (a·v̂) v - 2 c v + |v| a; so d/dt(v W + c |v| v) = a (W + c |v|) - (4c² - |a|²) v
    = 2 a W - M v with M = (4c² - |a|²) I + a aᵀ (using c |v| = W - a · v). Integrating from 0 to t_s
    (v = 0 at t_s, ∫ W dt = W0 t_s / 2):   M Δq = a W0 t_s + v0 (W0 + c V).

    Derivatives in v0 (dV = v̂0ᵀ dv0, dW0 = (c v̂0 + a)ᵀ dv0, a W0 t_s = a W0² / D):
    d t_s / d v0 = (c v̂0 + a)ᵀ / D,
    d Δq / d v0 = M⁻¹ [2 W0 a (c v̂0 + a)ᵀ / D + (W0 + c V) I + v0 (2 c v̂0 + a)ᵀ].
    Checks: a = 0 gives Δq = v0 V / (2c) and (V I + v0 v0ᵀ / V) / (2c) (test 1); a = α v̂0 gives
    t_s = V / (c - α), Δq = V² v̂0 / (2 (c - α)) and a transverse V / (2c - α) (test 1's braked and
    pushed blocks). Returns (t_s, Δq, d t_s / d v0, d Δq / d v0)."""
    V = np.linalg.norm(v0)
    v_hat = v0 / V
    D = c * c - a @ a
    W0 = c * V + a @ v0
    t_s = W0 / D
    M = (4 * c * c - a @ a) * np.eye(2) + np.outer(a, a)
    dq = np.linalg.solve(M, a * W0 * t_s + v0 * (W0 + c * V))
    K = np.linalg.solve(M, 2 * W0 * np.outer(a, c * v_hat + a) / D + (W0 + c * V) * np.eye(2)
                        + np.outer(v0, 2 * c * v_hat + a))
    return t_s, dq, (c * v_hat + a) / D, K


def test_curved_slide_closed_form_limits():
    """`_curved_slide` against its own limits (docstring): no force, and a force along v0."""
    v0, c = np.array([1.2, -0.9]), MU * G
    V, v_hat = 1.5, np.array([0.8, -0.6])
    t_s, dq, grad, K = _curved_slide(v0, np.zeros(2), c)
    assert t_s == pytest.approx(V / c, rel=1e-15)
    np.testing.assert_allclose(dq, v0 * V / (2 * c), rtol=1e-15)
    np.testing.assert_allclose(grad, v_hat / c, rtol=1e-15)
    np.testing.assert_allclose(K, (V * np.eye(2) + np.outer(v0, v0) / V) / (2 * c), rtol=1e-14)
    alpha = -0.5 * c
    t_s, dq, grad, K = _curved_slide(v0, alpha * v_hat, c)
    P = np.outer(v_hat, v_hat)
    assert t_s == pytest.approx(V / (c - alpha), rel=1e-15)
    np.testing.assert_allclose(dq, V**2 * v_hat / (2 * (c - alpha)), rtol=1e-14)
    np.testing.assert_allclose(K, P * V / (c - alpha) + (np.eye(2) - P) * V / (2 * c - alpha), rtol=0, atol=1e-15)


@pytest.mark.parametrize("force", OBLIQUE_FORCES, ids=list(OBLIQUE_FORCES))
def test_block_with_oblique_force_curves_and_sticks(block3, force):
    """A constant horizontal force F at an angle to v0 (|F| < μ m g): the friction -μ m g ŝ is then
    not along the net deceleration and the slip direction curves (it turns towards F̂: dv̂/dt =
    (I - v̂ v̂ᵀ) a / |v|). λ_N = m g throughout. Closed forms: `_curved_slide` (stop time and place,
    their derivatives, so the flow Jacobian: d q_xy / d q0_xy = I, d q_xy / d v0_xy = d Δq / d v0,
    normal columns as in test 1). And the physics, independently of it:

    * speed: d|v|/dt = F·v̂/m - μ g lies in [-(μ g + |F|/m), -(μ g - |F|/m)], so
      V / (μ g + |F|/m) <= t_s <= V / (μ g - |F|/m);
    * momentum: m (0 - v0) = F t_s - μ m g ∫ ŝ dt, and |∫ ŝ dt| <= t_s with equality only for a
      straight slide, so |m v0 + F t_s| < μ m g t_s;
    * energy: 0 - ½ m V² = F · Δq - μ m g L with the path length L >= |Δq| (strictly, the path
      curves), so ½ m V² + F · Δq > μ m g |Δq|;
    * after the stop it sticks: v = 0, q constant, and the sticking force balances F and gravity,
      λ = (λ_N, λ_T) = (m g, -F) in the contact's basis (n = z, t1 = x, t2 = n × t1 = y), inside the
      cone since |F| <= μ m g;
    * the flow Jacobian and the stop time's gradient against central differences too."""
    angle, fraction = OBLIQUE_FORCES[force]
    v0 = np.array(V0_CASES["oblique"])
    speed = np.linalg.norm(v0)
    c, s = math.cos(math.radians(angle)), math.sin(math.radians(angle))
    F = fraction * MU * MASS * G * np.array([[c, -s], [s, c]]) @ (v0 / speed)
    a_F = np.linalg.norm(F) / MASS
    t_s, dq_s, grad_s, K = _curved_slide(v0, F / MASS, MU * G)
    t_final = t_s + 0.1
    scene = _block_on_ground(block3, v0, F)
    traj = cd.simulate(scene, t_final, jacobian=True, **TOL)

    assert _kinds(traj) == [("stick", ("block",))]
    (stop,) = traj.events
    assert stop.sliding == () and stop.mode_after == ("block",) and stop.differentiable
    assert stop.t == pytest.approx(t_s, rel=REL)
    np.testing.assert_allclose(stop.q, [*dq_s, 0.0], rtol=0, atol=REL * speed * t_s)
    grad = np.zeros(6)
    grad[3:5] = grad_s
    np.testing.assert_allclose(stop.time_gradient, grad, rtol=0, atol=JAC_REL * np.abs(grad).max())
    J = np.zeros((6, 6))
    J[:3, :3] = np.eye(3)
    J[:2, 3:5] = K
    J[2, 5] = t_s  # off the manifold (module doc)
    np.testing.assert_allclose(traj.jacobian, J, rtol=0, atol=JAC_REL * np.abs(J).max())

    # the physics, without the closed form
    t_s = stop.t
    assert speed / (MU * G + a_F) < t_s < speed / (MU * G - a_F)
    dq = stop.q[:2]
    friction_impulse = np.linalg.norm(MASS * v0 + F * t_s)
    # the path curves: margins 1 - |∫ŝ dt| / t_s of 0.02 .. 0.38 and L / |Δq| - 1 of 0.02 .. 0.13 here
    assert friction_impulse < MU * MASS * G * t_s * (1 - 1e-3)
    assert 0.5 * MASS * speed**2 + F @ dq > MU * MASS * G * np.linalg.norm(dq) * (1 + 1e-3)
    assert abs(stop.q[2]) < REL
    np.testing.assert_allclose(traj.q, stop.q, rtol=0, atol=REL * speed * t_s)
    np.testing.assert_allclose(traj.v, 0.0, rtol=0, atol=REL * speed)

    # the sticking force at the end, from the mode's Newton-Euler solve
    forces = ModeDynamics(scene).solve(traj.q, traj.v, traj.t, (0,)).forces
    np.testing.assert_allclose(forces, [MASS * G, -F[0], -F[1]], rtol=0, atol=REL * MASS * G)
    assert np.linalg.norm(forces[1:]) <= MU * forces[0]

    directions = [_unit(k, 6) for k in (0, 1, 3, 4)]
    fd, fd_times = _fd(scene, t_final, directions, _kinds(traj))
    assert_fd(f"coulomb block oblique force {force}", traj.jacobian[:, [0, 1, 3, 4]], fd, traj.q, rtol=FD_RTOL)
    assert_fd(f"coulomb block oblique stop time {force}", stop.time_gradient[[0, 1, 3, 4]], fd_times[0], t_s,
              rtol=FD_RTOL)


# ==============================================================================================
# 2. the planar block (x, z): one tangent row
# ==============================================================================================
@pytest.mark.parametrize("vx", [1.3, -0.8])
def test_planar_block_slides_to_a_stop(block2, vx):
    """x and z only: the slip is along ±x, v_x(t) = v0 - μ g t sign(v0), stop at t_s = |v0| / (μ g),
    q_x = v0 |v0| / (2 μ g) (so d q_x / d v0 = |v0| / (μ g), d t_s / d v0 = sign(v0) / (μ g));
    the normal columns as in 3-D (module doc)."""
    t_s = abs(vx) / (MU * G)
    t_final = t_s + 0.2
    scene = cd.Scene(block2, [cd.Contact("block", friction=MU)], gravity=[0, 0, -G], q0=np.zeros(2),
                     v0=np.array([vx, 0.0]))
    traj = cd.simulate(scene, t_final, jacobian=True, **TOL)
    assert _kinds(traj) == [("stick", ("block",))]
    (stop,) = traj.events
    assert stop.sliding == () and stop.mode_after == ("block",)
    assert stop.t == pytest.approx(t_s, rel=REL)
    np.testing.assert_allclose(traj.q, [vx * abs(vx) / (2 * MU * G), 0.0], rtol=0, atol=REL * abs(vx) * t_s)
    np.testing.assert_allclose(traj.v, 0.0, rtol=0, atol=REL * abs(vx))
    np.testing.assert_allclose(stop.time_gradient, [0, 0, math.copysign(1, vx) / (MU * G), 0], rtol=0,
                               atol=JAC_REL * t_s / abs(vx))
    J = np.zeros((4, 4))
    J[0, 0] = J[1, 1] = 1.0
    J[0, 2] = abs(vx) / (MU * G)
    J[1, 3] = t_s  # off the manifold (module doc)
    np.testing.assert_allclose(traj.jacobian, J, rtol=0, atol=JAC_REL * np.abs(J).max())
    fd, _ = _fd(scene, t_final, [_unit(0, 4), _unit(2, 4)], _kinds(traj))
    assert_fd("coulomb planar block", traj.jacobian[:, [0, 2]], fd, traj.q, rtol=FD_RTOL)


# ==============================================================================================
# 3. a block on an incline
# ==============================================================================================
def _incline(ratio):
    """Tilt α with tan α = ratio μ, the normal n = (sin α, 0, cos α) and the downhill direction
    d = (cos α, 0, -sin α) (the plane n · p = 0 descends towards +x: (1, 0, -tan α) is on it)."""
    alpha = math.atan(ratio * MU)
    return alpha, (math.sin(alpha), 0.0, math.cos(alpha)), np.array([math.cos(alpha), 0.0, -math.sin(alpha)])


@pytest.mark.parametrize("ratio", [0.8, 1.2])
def test_block_at_rest_on_an_incline(block3, ratio):
    """Gravity splits into -g cos α along n (so λ_N = m g cos α) and g sin α along d. At rest the
    block can stick iff the force it needs, m g sin α, is in the cone μ m g cos α: tan α <= μ.
    Then nothing happens (no event, q and v stay 0). Otherwise it slides from t = 0 (a contact
    closed at the start that cannot stick slips from there: no event) down d with acceleration
    a = g (sin α - μ cos α): q(T) = ½ a T² d, v(T) = a T d."""
    alpha, normal, d = _incline(ratio)
    T = 0.5
    scene = cd.Scene(block3, [cd.Contact("block", normal=normal, friction=MU)], gravity=[0, 0, -G],
                     q0=np.zeros(3), v0=np.zeros(3))
    traj = cd.simulate(scene, T, **TOL)
    assert _kinds(traj) == []
    if ratio <= 1.0:
        assert [s.sliding for s in traj.segments] == [()]
        np.testing.assert_allclose(np.r_[traj.q, traj.v], 0.0, rtol=0, atol=1e-13)  # m, m/s: round-off
    else:
        assert [s.sliding for s in traj.segments] == [("block",)]
        a = G * (math.sin(alpha) - MU * math.cos(alpha))
        np.testing.assert_allclose(traj.q, 0.5 * a * T**2 * d, rtol=0, atol=REL * a * T**2)
        np.testing.assert_allclose(traj.v, a * T * d, rtol=0, atol=REL * a * T)


@pytest.mark.parametrize("ratio", [0.8, 1.2])
def test_block_launched_uphill(block3, ratio):
    """Launched up the incline, v0 = -w d: gravity and friction both decelerate it,
    a_up = g (sin α + μ cos α), so it stops at t_s = w / a_up, s_s = -w² / (2 a_up) along d. There
    it sticks if tan α <= μ (event ``stick``) or, the sticking force outside the cone, slips back
    down d (event ``slip``, sliding after) at a_dn = g (sin α - μ cos α):
    s(T) = s_s + ½ a_dn (T - t_s)², v(T) = a_dn (T - t_s) d.

    Jacobian (directional, in-plane directions only; the plane is y and d):

    * q0 along d or y: a translation: J (δq, 0) = (δq, 0);
    * w (v0 along -d): d s / d w = -w / a_up - a_dn (T - t_s) / a_up, d v_s / d w = -a_dn / a_up (a_dn
      terms only when it slides back), d t_s / d w = 1 / a_up;
    * v0 along y: as for the braked block of test 1, with μ g cos α for the friction and a_up for
      the deceleration, the transverse velocity decays as (1 - a_up t / w)^(μ g cos α / a_up): the
      displacement is w / (μ g cos α + a_up) along y and the velocity and the stop time do not
      change at first order. After the stop the sticking force (or the slide back) is along d
      whatever the y-offset, so the offset stays."""
    alpha, normal, d = _incline(ratio)
    w, y = 2.0, np.array([0.0, 1.0, 0.0])
    a_up = G * (math.sin(alpha) + MU * math.cos(alpha))
    a_dn = G * (math.sin(alpha) - MU * math.cos(alpha))
    t_s = w / a_up
    T = t_s + 0.3
    slides_back = ratio > 1.0
    scene = cd.Scene(block3, [cd.Contact("block", normal=normal, friction=MU)], gravity=[0, 0, -G],
                     q0=np.zeros(3), v0=-w * d)
    traj = cd.simulate(scene, T, jacobian=True, **TOL)

    (stop,) = traj.events
    assert stop.kind == ("slip" if slides_back else "stick") and stop.contacts == ("block",)
    assert stop.sliding == (("block",) if slides_back else ()) and stop.mode_after == ("block",)
    assert stop.differentiable
    assert stop.t == pytest.approx(t_s, rel=REL)
    s_T = -w**2 / (2 * a_up) + (0.5 * a_dn * (T - t_s) ** 2 if slides_back else 0.0)
    v_T = a_dn * (T - t_s) if slides_back else 0.0
    np.testing.assert_allclose(traj.q, s_T * d, rtol=0, atol=REL * w * T)
    np.testing.assert_allclose(traj.v, v_T * d, rtol=0, atol=REL * w)

    zero = np.zeros(3)
    directions = [np.r_[d, zero], np.r_[y, zero], np.r_[zero, -d], np.r_[zero, y]]
    expected = np.array([
        np.r_[d, zero],
        np.r_[y, zero],
        np.r_[(-w / a_up - (a_dn * (T - t_s) / a_up if slides_back else 0.0)) * d,
              (-a_dn / a_up if slides_back else 0.0) * d],
        np.r_[w / (MU * G * math.cos(alpha) + a_up) * y, zero],
    ]).T
    analytic = traj.jacobian @ np.array(directions).T
    np.testing.assert_allclose(analytic, expected, rtol=0, atol=JAC_REL * np.abs(expected).max())
    np.testing.assert_allclose(stop.time_gradient @ np.array(directions).T, [0, 0, 1 / a_up, 0], rtol=0,
                               atol=JAC_REL * t_s / w)
    fd, fd_times = _fd(scene, T, directions, _kinds(traj))
    assert_fd(f"coulomb incline uphill {ratio}", analytic, fd, traj.q, rtol=FD_RTOL)
    assert_fd(f"coulomb incline stop time {ratio}", stop.time_gradient @ np.array(directions).T, fd_times[0],
              t_s, rtol=FD_RTOL)


# ==============================================================================================
# 4. oblique impact of a point mass
# ==============================================================================================
def _impact_closed_form(v_t, v_n, e, mu):
    """Post-impact velocity of a point mass hitting flat ground at (v_t, -v_n), v_n > 0.

    Rows (n, t1, t2), G = I/m: the normal row is decoupled, Λ_N = m (1 + e) v_n (Newton: v_z+ = e v_n).
    Sticking needs Λ_T = -m v_t, in the cone iff |v_t| <= μ (1 + e) v_n: then v_T+ = 0. Otherwise
    the impulse is on the cone's boundary opposite the post-impact slip, Λ_T = -μ Λ_N ŝ with
    v_T+ = v_t - μ (1 + e) v_n ŝ along ŝ, so ŝ = v̂_t and v_T+ = v_t (1 - μ (1 + e) v_n / |v_t|).
    Returns (v_plus (3,), sticks)."""
    limit = mu * (1 + e) * v_n
    speed = np.linalg.norm(v_t)
    sticks = speed <= limit
    v_tp = np.zeros(2) if sticks else v_t * (1 - limit / speed)
    return np.array([*v_tp, e * v_n]), sticks


def _fall(h, w):
    """From height h with downward speed w under g: lands at t = (sqrt(w² + 2 g h) - w) / g with
    speed V = sqrt(w² + 2 g h); dt/dh = 1/V, dt/dv_z0 = t/V (v_z0 = -w)."""
    V = math.sqrt(w * w + 2 * G * h)
    return (V - w) / G, V


def _check_impact(landing, v_t, V, e, mu):
    """The touchdown against the closed form; impulse in the cone; kinetic energy not increased.
    The net impulse is m (v+ - v-): gravity's impulse over a zero-length impact is zero."""
    v_plus, sticks = _impact_closed_form(v_t, V, e, mu)
    scale = np.linalg.norm(landing.v_minus)
    np.testing.assert_allclose(landing.v_minus, [*v_t, -V], rtol=0, atol=REL * scale)
    np.testing.assert_allclose(landing.v_plus, v_plus, rtol=0, atol=REL * scale)
    impulse = MASS * (landing.v_plus - landing.v_minus)
    assert impulse[2] == pytest.approx(MASS * (1 + e) * V, rel=REL)
    assert landing.impulses["block"] == pytest.approx(impulse[2], rel=REL)
    assert np.linalg.norm(impulse[:2]) <= mu * impulse[2] * (1 + REL)
    assert landing.v_plus @ landing.v_plus <= landing.v_minus @ landing.v_minus * (1 + REL)
    return sticks


IMPACTS = {"stick": 0.5, "slide": 2.0}  # |v_t| / (μ (1 + e) V)


@pytest.mark.parametrize("e", [0.0, 0.6])
@pytest.mark.parametrize("case", IMPACTS, ids=list(IMPACTS))
def test_oblique_impact(block3, case, e):
    """A block falling from h = 0.05 m with v0 = (v_t, -1) m/s lands at t_td = _fall(h, 1) with normal
    speed V; `_impact_closed_form` gives v+. After it, with e = 0 the block stays on the ground:
    sticking (at rest) or slipping from v_T+ to a stop at t_td + |v_T+| / (μ g), q_xy moving on by
    v_T+ |v_T+| / (2 μ g) (test 1). With e > 0 it leaves at e V (event ``bounce``) and flies until
    t_td + 2 e V / g; the run ends at the apex, t_td + e V / g, at height (e V)² / (2 g), with the
    horizontal velocity v_T+. Then the flow Jacobian through the frictional impact against central
    differences in all six directions (the start is in flight, so all are admissible)."""
    h, w = 0.05, 1.0
    t_td, V = _fall(h, w)
    limit = MU * (1 + e) * V
    v_t = IMPACTS[case] * limit * np.array([0.8, -0.6])
    v_plus, sticks = _impact_closed_form(v_t, V, e, MU)
    assert sticks == (case == "stick")
    slip_speed = np.linalg.norm(v_plus[:2])
    t_stop = t_td + slip_speed / (MU * G)
    T = t_td + e * V / G if e > 0 else t_stop + 0.1
    scene = cd.Scene(block3, [cd.Contact("block", restitution=e, friction=MU)], gravity=[0, 0, -G],
                     q0=np.array([0.0, 0.0, h]), v0=np.array([*v_t, -w]))
    traj = cd.simulate(scene, T, jacobian=True, **TOL)
    landing = traj.events[0]
    assert landing.kind == ("bounce" if e > 0 else "touchdown") and landing.contacts == ("block",)
    assert landing.t == pytest.approx(t_td, rel=REL)
    _check_impact(landing, v_t, V, e, MU)
    q_td = np.array([*(v_t * t_td), 0.0])
    if e > 0:
        assert _kinds(traj) == [("bounce", ("block",))] and landing.mode_after == ()
        np.testing.assert_allclose(traj.q, q_td + [*(v_plus[:2] * (T - t_td)), (e * V) ** 2 / (2 * G)], rtol=0,
                                   atol=REL * np.linalg.norm(v_t) * T)
        np.testing.assert_allclose(traj.v, [*v_plus[:2], 0.0], rtol=0, atol=REL * V)
    elif sticks:
        assert _kinds(traj) == [("touchdown", ("block",))]
        assert landing.mode_after == ("block",) and landing.sliding == ()
        np.testing.assert_allclose(traj.q, q_td, rtol=0, atol=REL * np.linalg.norm(v_t) * T)
        np.testing.assert_allclose(traj.v, 0.0, rtol=0, atol=REL * V)
    else:
        assert _kinds(traj) == [("touchdown", ("block",)), ("stick", ("block",))]
        assert landing.mode_after == ("block",) and landing.sliding == ("block",)
        assert traj.events[1].t == pytest.approx(t_stop, rel=REL)
        np.testing.assert_allclose(traj.q, q_td + [*(v_plus[:2] * slip_speed / (2 * MU * G)), 0.0], rtol=0,
                                   atol=REL * np.linalg.norm(v_t) * T)
        np.testing.assert_allclose(traj.v, 0.0, rtol=0, atol=REL * V)
    fd, fd_times = _fd(scene, T, np.eye(6), _kinds(traj))
    assert_fd(f"coulomb oblique impact {case} e={e}", traj.jacobian, fd, traj.q, rtol=FD_RTOL)
    assert_fd(f"coulomb oblique impact time {case} e={e}", landing.time_gradient, fd_times[0], t_td, rtol=FD_RTOL)


# ==============================================================================================
# 5. a sphere thrown sliding with spin
# ==============================================================================================
SPINS = {  # v0 (world = local at the identity orientation), ω0 (rad/s)
    "backspin": ((2.0, 0.0, 0.0), (0.0, -10.0, 0.0)),
    "topspin": ((1.0, 0.0, 0.0), (0.0, 30.0, 0.0)),
    "no-spin-along-y": ((0.0, 1.5, 0.0), (0.0, 0.0, 0.0)),
    "sidespin": ((2.0, 0.5, 0.0), (4.0, -10.0, 0.0)),
    "sidespin-and-twist": ((2.0, 0.5, 0.0), (4.0, -10.0, 3.0)),
}


def _ball_scene(ball, case, mu=MU):
    v0, w0 = SPINS[case]
    q0 = np.array([0.0, 0.0, RADIUS, 0.0, 0.0, 0.0, 1.0])  # touching, identity orientation
    return cd.Scene(ball, [cd.Contact("ball", radius=RADIUS, friction=mu)], gravity=[0, 0, -G], q0=q0,
                    v0=np.r_[v0, w0])


def _world(q, v):
    """World linear and angular velocity from a free-flyer state (v is LOCAL)."""
    R = pin.XYZQUATToSE3(q).rotation
    return R @ v[:3], R @ v[3:]


def _sphere_closed_form(v0, w0, mu):
    """The sliding sphere. Contact point r = -R e_z from the centre; its velocity
    u = v + ω × r = (v_x - R ω_y, v_y + R ω_x, v_z) (ω × (0, 0, -R) = (-R ω_y, R ω_x, 0)).
    Friction f = -μ m g ŝ (ŝ = û, λ_N = m g) acts at r: v̇ = f / m, ω̇ = (r × f) / I with
    r × f = (R f_y, -R f_x, 0). So u̇_x = f_x / m - R ω̇_y = f_x (1/m + R²/I), u̇_y = f_y / m + R ω̇_x =
    f_y (1/m + R²/I): u̇ = -μ g (1 + m R² / I) ŝ = -(7/2) μ g ŝ for a solid sphere. The slip keeps its
    direction and reaches zero at t_r = 2 |u0| / (7 μ g); then the ball rolls (u = 0, no force needed
    on flat ground: constant v and ω). ω_z gets no torque. With ŝ = û0:
    v_r = v0 - μ g t_r ŝ, ω_r = ω0 + t_r (r × f) / I, centre at v0 t_r - ½ μ g t_r² ŝ at t_r.
    Along x only (ω about y): v_r = v0 - (2/7)(v0 - R ω0) = (5 v0 + 2 R ω0) / 7."""
    v0, w0 = np.asarray(v0, dtype=float), np.asarray(w0, dtype=float)
    u0 = v0[:2] + RADIUS * np.array([-w0[1], w0[0]])
    s = u0 / np.linalg.norm(u0)
    t_r = 2 * np.linalg.norm(u0) / (7 * mu * G)
    f = -mu * MASS * G * np.array([s[0], s[1], 0.0])
    v_r = v0 + f / MASS * t_r
    w_r = w0 + t_r * RADIUS * np.array([f[1], -f[0], 0.0]) / INERTIA
    p_r = v0 * t_r + 0.5 * f / MASS * t_r**2
    return u0, t_r, v_r, w_r, p_r


@pytest.mark.parametrize("case", SPINS, ids=list(SPINS))
def test_sphere_slides_then_rolls(ball, case):
    """`_sphere_closed_form`: one ``stick`` event at t_r, then rolling at constant speed with
    v_x = R ω_y and v_y = -R ω_x (world frame), the centre at height R and ω_z unchanged."""
    v0, w0 = SPINS[case]
    u0, t_r, v_r, w_r, p_r = _sphere_closed_form(v0, w0, MU)
    if case in ("backspin", "topspin"):  # the textbook formula, independently of the vector form
        assert v_r[0] == pytest.approx((5 * v0[0] + 2 * RADIUS * w0[1]) / 7, rel=1e-14)
    T = t_r + 0.2
    traj = cd.simulate(_ball_scene(ball, case), T, **TOL)
    assert _kinds(traj) == [("stick", ("ball",))]
    (stop,) = traj.events
    assert stop.sliding == () and stop.mode_after == ("ball",)
    assert [s.sliding for s in traj.segments] == [("ball",), ()]
    # error scale: velocities up to |v| + R |ω| ≈ 4 m/s, a run's error ≲ 1e-12 per unit over its steps
    scale = np.linalg.norm(v0) + RADIUS * np.linalg.norm(w0)
    assert stop.t == pytest.approx(t_r, rel=REL)
    for q, v in ((stop.q, stop.v_plus), (traj.q, traj.v)):
        v_w, w_w = _world(q, v)
        np.testing.assert_allclose(v_w, v_r, rtol=0, atol=REL * scale)
        np.testing.assert_allclose(w_w, w_r, rtol=0, atol=REL * scale / RADIUS)
        np.testing.assert_allclose(v_w[:2] + RADIUS * np.array([-w_w[1], w_w[0]]), 0.0, rtol=0, atol=REL * scale)
    np.testing.assert_allclose(traj.q[:3], [*(p_r[:2] + v_r[:2] * (T - t_r)), RADIUS], rtol=0, atol=REL * scale * T)


def test_sphere_jacobian_matches_fd(ball):
    """Flow Jacobian of the sidespin-and-twist sphere through its stop, against central
    differences on the manifold along the admissible directions: q0 ⊕ ε e_k for x, y and the
    rotation about z (rotations about x or y would tilt the local v0 out of the ground), v0 + ε e_k
    for the local linear x, y and all three angular components (local z linear leaves the
    ground). The stop time's gradient against the closed form: t_r = 2 |u0| / (7 μ g) with
    u0 = v_xy + R (-ω_y, ω_x) (world = local at t0), so d t_r / d (v_x, v_y, ω_x, ω_y, ω_z) =
    2 / (7 μ g) (û_x, û_y, R û_y, -R û_x, 0), and a rotation about z turns u0 without changing |u0|."""
    case = "sidespin-and-twist"
    scene = _ball_scene(ball, case)
    u0, t_r, *_ = _sphere_closed_form(*SPINS[case], MU)
    T = t_r + 0.1
    traj = cd.simulate(scene, T, jacobian=True, **TOL)
    (stop,) = traj.events
    cols = [0, 1, 5, 6, 7, 9, 10, 11]
    u_hat = u0 / np.linalg.norm(u0)
    k = 2 / (7 * MU * G)
    grad = np.zeros(12)
    grad[[6, 7, 9, 10]] = k * np.array([u_hat[0], u_hat[1], RADIUS * u_hat[1], -RADIUS * u_hat[0]])
    np.testing.assert_allclose(stop.time_gradient[cols], grad[cols], rtol=0, atol=JAC_REL * k)
    fd, fd_times = _fd(scene, T, [_unit(c, 12) for c in cols], _kinds(traj))
    assert_fd("coulomb sphere", traj.jacobian[:, cols], fd, traj.q, rtol=FD_RTOL)
    assert_fd("coulomb sphere stop time", stop.time_gradient[cols], fd_times[0], t_r, rtol=FD_RTOL)


# ==============================================================================================
# 6. property test: the frictional impact as simulate applies it
# ==============================================================================================
IMPACT_PROPS = settings(max_examples=20, deadline=2000, derandomize=True,
                        suppress_health_check=[HealthCheck.too_slow])


@IMPACT_PROPS
@given(mu=st.floats(0.0, 2.0, exclude_min=True), e=st.one_of(st.just(0.0), st.floats(0.0, 1.0)),
       speed=st.floats(0.0, 4.0), angle=st.floats(-math.pi, math.pi), w=st.floats(0.2, 3.0))
def test_frictional_impact_properties(block3, mu, e, speed, angle, w):
    """Random oblique impacts of the block (h = 0.01 m, downward speed w, tangential speed and
    direction at random): the touchdown's v+ is `_impact_closed_form`'s (normal e V, tangential
    sticks or slides by |v_t| <= μ (1 + e) V), the impulse m (v+ - v-) is in the cone, and the
    kinetic energy does not grow (`_check_impact`); the event kind and sliding follow.

    Excluded draws: within 1e-3 relative (plus 1e-4 m/s) of the stick/slide boundary, where
    round-off decides the branch and the package holds a slip slower than 10 zeno_speed = 1e-5 m/s
    (docs: noise floor); and bounces slower than 10 zeno_speed (e V), which the package treats as
    a Zeno cascade."""
    h = 0.01
    t_td, V = _fall(h, w)
    limit = mu * (1 + e) * V
    assume(abs(speed - limit) > 1e-3 * max(speed, limit) + 1e-4)
    assume(e == 0.0 or e * V > 1e-5)
    v_t = speed * np.array([math.cos(angle), math.sin(angle)])
    scene = cd.Scene(block3, [cd.Contact("block", restitution=e, friction=mu)], gravity=[0, 0, -G],
                     q0=np.array([0.0, 0.0, h]), v0=np.array([*v_t, -w]))
    traj = cd.simulate(scene, t_td + 1e-3, **TOL)
    landing = traj.events[0]
    assert landing.kind == ("bounce" if e > 0 else "touchdown")
    sticks = _check_impact(landing, v_t, V, e, mu)
    event(f"{landing.kind}, {'stick' if sticks else 'slide'}")  # --hypothesis-show-statistics: the mix
    if e == 0:
        assert landing.sliding == (() if sticks else ("block",))


# ==============================================================================================
# 7. "stick" and "none" keep their meaning
# ==============================================================================================
@pytest.mark.parametrize("friction", ["stick", "none", 1e6])
def test_stick_and_none_landings(block3, friction):
    """A plastic landing from h = 0.05 m with v0 = (0.8, -0.6, -1) (t_td, V from `_fall`).

    * ``"none"``: no tangential impulse and no friction: v+ = (v_t, 0) and the block slides on at
      v_t: q(T) = (v_t T, 0), v(T) = (v_t, 0). Jacobian: d q_xy / d q0_xy = I, d q_xy / d v0_xy = T I,
      d v_xy / d v0_xy = I, and nothing depends on (q_z0, v_z0) once the plastic landing has set
      q_z = v_z = 0 (rows and columns z zero but for none of them).
    * ``"stick"`` (and μ = 1e6, far above |v_t| / V): the tangential velocity stops at the impact
      and the block stays at q = (v_t t_td, 0). Jacobian: q_xy = q0_xy + v_t t_td(q_z0, v_z0), with
      d t_td / d q_z0 = 1 / V and d t_td / d v_z0 = t_td / V (`_fall`): d q_xy / d q0_xy = I,
      d q_xy / d v0_xy = t_td I, d q_xy / d q_z0 = v_t / V, d q_xy / d v_z0 = v_t t_td / V; all
      velocity rows zero."""
    h, w = 0.05, 1.0
    v_t = np.array([0.8, -0.6])
    t_td, V = _fall(h, w)
    T = 0.3
    scene = cd.Scene(block3, [cd.Contact("block", friction=friction)], gravity=[0, 0, -G],
                     q0=np.array([0.0, 0.0, h]), v0=np.array([*v_t, -w]))
    traj = cd.simulate(scene, T, jacobian=True, **TOL)
    assert _kinds(traj) == [("touchdown", ("block",))]
    (landing,) = traj.events
    assert landing.t == pytest.approx(t_td, rel=REL) and landing.sliding == ()
    np.testing.assert_allclose(landing.v_minus, [*v_t, -V], rtol=0, atol=REL * V)
    J = np.zeros((6, 6))
    J[:2, :2] = np.eye(2)
    grad = np.zeros(6)
    grad[2], grad[5] = 1 / V, t_td / V
    if friction == "none":
        np.testing.assert_allclose(landing.v_plus, [*v_t, 0.0], rtol=0, atol=REL * V)
        np.testing.assert_allclose(traj.q, [*(v_t * T), 0.0], rtol=0, atol=REL * T)
        np.testing.assert_allclose(traj.v, [*v_t, 0.0], rtol=0, atol=REL)
        J[:2, 3:5] = T * np.eye(2)
        J[3:5, 3:5] = np.eye(2)
    else:
        np.testing.assert_allclose(landing.v_plus, 0.0, rtol=0, atol=REL * V)
        np.testing.assert_allclose(traj.q, [*(v_t * t_td), 0.0], rtol=0, atol=REL * T)
        np.testing.assert_allclose(traj.v, 0.0, rtol=0, atol=REL)
        J[:2, 3:5] = t_td * np.eye(2)
        J[:2, 2] = v_t / V
        J[:2, 5] = v_t * t_td / V
    np.testing.assert_allclose(landing.time_gradient, grad, rtol=0, atol=JAC_REL * np.abs(grad).max())
    np.testing.assert_allclose(traj.jacobian, J, rtol=0, atol=JAC_REL * np.abs(J).max())


def test_stick_block_sliding_at_start_is_stopped(block3):
    """A ``"stick"`` block closed at t = 0 with a tangential velocity has its slip stopped by an
    impact at t = 0 (docs: "with "stick" an impact stops it"): a touchdown at 0 with v+ = 0; a
    ``"none"`` block keeps sliding at v0 with no event."""
    v0 = np.array([0.8, -0.6, 0.0])
    for friction, events, q_T, v_T in (("stick", [("touchdown", ("block",))], np.zeros(3), np.zeros(3)),
                                       ("none", [], 0.3 * v0, v0)):
        scene = cd.Scene(block3, [cd.Contact("block", friction=friction)], gravity=[0, 0, -G], q0=np.zeros(3),
                         v0=v0)
        traj = cd.simulate(scene, 0.3, **TOL)
        assert _kinds(traj) == events
        if events:
            assert traj.events[0].t == 0.0
        np.testing.assert_allclose(traj.q, q_T, rtol=0, atol=REL)
        np.testing.assert_allclose(traj.v, v_T, rtol=0, atol=REL)
