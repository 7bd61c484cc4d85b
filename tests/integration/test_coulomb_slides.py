"""Coulomb friction in `simulate`: slides and stops of a block on flat ground (3-D and planar) and on an
incline, against closed forms derived in each test's docstring and central finite differences
(models, conventions and tolerances: `coulomb_models`).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from coulomb_models import (
    FD_RTOL,
    JAC_REL,
    MASS,
    MU,
    REL,
    TOL,
    G,
    central_differences,
    constant_force,
    event_kinds,
    unit,
)
from helpers import assert_fd

import contactdiff as cd
from contactdiff.dynamics.mode import ModeDynamics

# ==============================================================================================
# 1. a block sliding on flat ground in an arbitrary horizontal direction
# ==============================================================================================
V0_CASES = {"oblique": (1.2, -0.9), "diagonal": (1.1, 1.1), "axis-y": (0.0, -1.7), "second-quadrant": (-0.5, 0.35)}
PARALLEL_FORCES = {"none": 0.0, "pushed-along": 0.4, "braked": -0.5}  # f / (μ m g), along v̂0


def _block_on_ground(block3, v0_xy, force_xy=(0.0, 0.0), mu=MU):
    efforts = [constant_force([*force_xy, 0.0])] if np.any(force_xy) else []
    return cd.Scene(
        block3,
        [cd.Contact("block", friction=mu)],
        efforts,
        gravity=[0, 0, -G],
        q0=np.zeros(3),
        v0=np.array([*v0_xy, 0.0]),
    )


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

    assert event_kinds(traj) == [("stick", ("block",))]
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
    directions = [unit(k, 6) for k in (0, 1, 3, 4)]
    fd, fd_times = central_differences(scene, t_final, directions, event_kinds(traj))
    assert_fd(f"coulomb block {case} {force}", traj.jacobian[:, [0, 1, 3, 4]], fd, traj.q, rtol=FD_RTOL)
    assert_fd(
        f"coulomb block stop time {case} {force}", stop.time_gradient[[0, 1, 3, 4]], fd_times[0], t_s, rtol=FD_RTOL
    )


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
    K = np.linalg.solve(
        M, 2 * W0 * np.outer(a, c * v_hat + a) / D + (W0 + c * V) * np.eye(2) + np.outer(v0, 2 * c * v_hat + a)
    )
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

    assert event_kinds(traj) == [("stick", ("block",))]
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

    directions = [unit(k, 6) for k in (0, 1, 3, 4)]
    fd, fd_times = central_differences(scene, t_final, directions, event_kinds(traj))
    assert_fd(f"coulomb block oblique force {force}", traj.jacobian[:, [0, 1, 3, 4]], fd, traj.q, rtol=FD_RTOL)
    assert_fd(
        f"coulomb block oblique stop time {force}", stop.time_gradient[[0, 1, 3, 4]], fd_times[0], t_s, rtol=FD_RTOL
    )


def test_curved_slide_stops_on_time_wherever_it_starts(block3):
    """Translation invariance: the block's dynamics does not depend on where it starts on the
    ground, so the backward-oblique slide (test above) stops at the closed-form t_s
    (`_curved_slide`) from every start, to the module's REL (1e-10 relative, a 100x margin over
    the ~1e-12 per step of rtol = atol = 1e-12).

    The starts (50 shifts from 1e-4 to 2.5 m) only change the round-off of the run, hence its
    sequence of steps and where the step that crosses the stop ends. That step samples the field
    past the stop; when the slip direction there followed the slip velocity (-u_T / |u_T|), it
    amplified the stages' transverse round-off (a slip slowing under a force at 135° to it turns
    onto the force: damping before the stop, the mirror growth after it) and the step's
    interpolant put up to 2e-9 s of error into the stop time from some starts, which starts
    depended on the BLAS kernel. Past the stop the direction is now the reference (slip.py)."""
    angle, fraction = OBLIQUE_FORCES["backward-oblique"]
    v0 = np.array(V0_CASES["oblique"])
    c, s = math.cos(math.radians(angle)), math.sin(math.radians(angle))
    F = fraction * MU * MASS * G * np.array([[c, -s], [s, c]]) @ (v0 / np.linalg.norm(v0))
    t_s = _curved_slide(v0, F / MASS, MU * G)[0]
    scene = _block_on_ground(block3, v0, F)
    times = []
    for scale in (1e-4, 1e-2):
        for k in range(1, 26):
            run = cd.simulate(
                scene.with_state(np.array([k * scale, -0.7 * k * scale, 0.0]), scene.v0), t_s + 0.01, **TOL
            )
            assert event_kinds(run) == [("stick", ("block",))]
            times.append(run.events[0].t)
    np.testing.assert_allclose(times, t_s, rtol=REL, atol=0)


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
    scene = cd.Scene(
        block2, [cd.Contact("block", friction=MU)], gravity=[0, 0, -G], q0=np.zeros(2), v0=np.array([vx, 0.0])
    )
    traj = cd.simulate(scene, t_final, jacobian=True, **TOL)
    assert event_kinds(traj) == [("stick", ("block",))]
    (stop,) = traj.events
    assert stop.sliding == () and stop.mode_after == ("block",)
    assert stop.t == pytest.approx(t_s, rel=REL)
    np.testing.assert_allclose(traj.q, [vx * abs(vx) / (2 * MU * G), 0.0], rtol=0, atol=REL * abs(vx) * t_s)
    np.testing.assert_allclose(traj.v, 0.0, rtol=0, atol=REL * abs(vx))
    np.testing.assert_allclose(
        stop.time_gradient, [0, 0, math.copysign(1, vx) / (MU * G), 0], rtol=0, atol=JAC_REL * t_s / abs(vx)
    )
    J = np.zeros((4, 4))
    J[0, 0] = J[1, 1] = 1.0
    J[0, 2] = abs(vx) / (MU * G)
    J[1, 3] = t_s  # off the manifold (module doc)
    np.testing.assert_allclose(traj.jacobian, J, rtol=0, atol=JAC_REL * np.abs(J).max())
    fd, _ = central_differences(scene, t_final, [unit(0, 4), unit(2, 4)], event_kinds(traj))
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
    scene = cd.Scene(
        block3, [cd.Contact("block", normal=normal, friction=MU)], gravity=[0, 0, -G], q0=np.zeros(3), v0=np.zeros(3)
    )
    traj = cd.simulate(scene, T, **TOL)
    assert event_kinds(traj) == []
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
    scene = cd.Scene(
        block3, [cd.Contact("block", normal=normal, friction=MU)], gravity=[0, 0, -G], q0=np.zeros(3), v0=-w * d
    )
    traj = cd.simulate(scene, T, jacobian=True, **TOL)

    (stop,) = traj.events
    assert stop.kind == ("slip" if slides_back else "stick") and stop.contacts == ("block",)
    assert stop.sliding == (("block",) if slides_back else ()) and stop.mode_after == ("block",)
    assert stop.differentiable
    assert stop.t == pytest.approx(t_s, rel=REL)
    s_T = -(w**2) / (2 * a_up) + (0.5 * a_dn * (T - t_s) ** 2 if slides_back else 0.0)
    v_T = a_dn * (T - t_s) if slides_back else 0.0
    np.testing.assert_allclose(traj.q, s_T * d, rtol=0, atol=REL * w * T)
    np.testing.assert_allclose(traj.v, v_T * d, rtol=0, atol=REL * w)

    zero = np.zeros(3)
    directions = [np.r_[d, zero], np.r_[y, zero], np.r_[zero, -d], np.r_[zero, y]]
    expected = np.array(
        [
            np.r_[d, zero],
            np.r_[y, zero],
            np.r_[
                (-w / a_up - (a_dn * (T - t_s) / a_up if slides_back else 0.0)) * d,
                (-a_dn / a_up if slides_back else 0.0) * d,
            ],
            np.r_[w / (MU * G * math.cos(alpha) + a_up) * y, zero],
        ]
    ).T
    analytic = traj.jacobian @ np.array(directions).T
    np.testing.assert_allclose(analytic, expected, rtol=0, atol=JAC_REL * np.abs(expected).max())
    np.testing.assert_allclose(
        stop.time_gradient @ np.array(directions).T, [0, 0, 1 / a_up, 0], rtol=0, atol=JAC_REL * t_s / w
    )
    fd, fd_times = central_differences(scene, T, directions, event_kinds(traj))
    assert_fd(f"coulomb incline uphill {ratio}", analytic, fd, traj.q, rtol=FD_RTOL)
    assert_fd(
        f"coulomb incline stop time {ratio}",
        stop.time_gradient @ np.array(directions).T,
        fd_times[0],
        t_s,
        rtol=FD_RTOL,
    )


def test_stop_on_the_cone_boundary_is_flagged_not_differentiable(block3):
    """At tan α = μ the block launched uphill stops with the sticking force it needs, m g sin α,
    exactly on the cone μ m g cos α (to round-off, far inside THRESHOLD_TOL = 1e-9): the stop sits on
    the paper's stick/slip threshold, and the event says so. A tilt 1e-6 relative to either side
    decides it (sticks below, slides back above), each a transversal, differentiable event: the
    outcome switches exactly where the flag is."""
    w = 2.0
    kinds = {}
    for ratio in (1.0 - 1e-6, 1.0, 1.0 + 1e-6):
        alpha, normal, d = _incline(ratio)
        scene = cd.Scene(
            block3, [cd.Contact("block", normal=normal, friction=MU)], gravity=[0, 0, -G], q0=np.zeros(3), v0=-w * d
        )
        t_s = w / (G * (math.sin(alpha) + MU * math.cos(alpha)))
        (stop,) = cd.simulate(scene, t_s + 0.1, **TOL).events
        kinds[ratio] = stop.kind
        if ratio == 1.0:
            assert stop.kind == "stick" and not stop.differentiable
            assert set(stop.nonsmooth) == {cd.NonSmooth.FRICTION_THRESHOLD}
        else:
            assert stop.differentiable
    assert kinds[1.0 - 1e-6] == "stick" and kinds[1.0 + 1e-6] == "slip"
