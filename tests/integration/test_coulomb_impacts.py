"""Coulomb friction in `simulate`: oblique impacts of a point mass, a sphere thrown sliding with spin,
hypothesis properties of the frictional impact, and ``"stick"`` and ``"none"`` unchanged, against
closed forms derived in each test's docstring and central finite differences (models, conventions
and tolerances: `coulomb_models`).
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
from coulomb_models import (
    FD_RTOL,
    INERTIA,
    JAC_REL,
    MASS,
    MU,
    RADIUS,
    REL,
    TOL,
    G,
    central_differences,
    event_kinds,
    unit,
)
from helpers import assert_fd
from hypothesis import HealthCheck, assume, event, given, settings
from hypothesis import strategies as st

import contactdiff as cd


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
    scene = cd.Scene(
        block3,
        [cd.Contact("block", restitution=e, friction=MU)],
        gravity=[0, 0, -G],
        q0=np.array([0.0, 0.0, h]),
        v0=np.array([*v_t, -w]),
    )
    traj = cd.simulate(scene, T, jacobian=True, **TOL)
    landing = traj.events[0]
    assert landing.kind == ("bounce" if e > 0 else "touchdown") and landing.contacts == ("block",)
    assert landing.t == pytest.approx(t_td, rel=REL)
    _check_impact(landing, v_t, V, e, MU)
    q_td = np.array([*(v_t * t_td), 0.0])
    if e > 0:
        assert event_kinds(traj) == [("bounce", ("block",))] and landing.mode_after == ()
        np.testing.assert_allclose(
            traj.q,
            q_td + [*(v_plus[:2] * (T - t_td)), (e * V) ** 2 / (2 * G)],
            rtol=0,
            atol=REL * np.linalg.norm(v_t) * T,
        )
        np.testing.assert_allclose(traj.v, [*v_plus[:2], 0.0], rtol=0, atol=REL * V)
    elif sticks:
        assert event_kinds(traj) == [("touchdown", ("block",))]
        assert landing.mode_after == ("block",) and landing.sliding == ()
        np.testing.assert_allclose(traj.q, q_td, rtol=0, atol=REL * np.linalg.norm(v_t) * T)
        np.testing.assert_allclose(traj.v, 0.0, rtol=0, atol=REL * V)
    else:
        assert event_kinds(traj) == [("touchdown", ("block",)), ("stick", ("block",))]
        assert landing.mode_after == ("block",) and landing.sliding == ("block",)
        assert traj.events[1].t == pytest.approx(t_stop, rel=REL)
        np.testing.assert_allclose(
            traj.q, q_td + [*(v_plus[:2] * slip_speed / (2 * MU * G)), 0.0], rtol=0, atol=REL * np.linalg.norm(v_t) * T
        )
        np.testing.assert_allclose(traj.v, 0.0, rtol=0, atol=REL * V)
    fd, fd_times = central_differences(scene, T, np.eye(6), event_kinds(traj))
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
    return cd.Scene(ball, [cd.Contact("ball", radius=RADIUS, friction=mu)], gravity=[0, 0, -G], q0=q0, v0=np.r_[v0, w0])


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
    assert event_kinds(traj) == [("stick", ("ball",))]
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
    fd, fd_times = central_differences(scene, T, [unit(c, 12) for c in cols], event_kinds(traj))
    assert_fd("coulomb sphere", traj.jacobian[:, cols], fd, traj.q, rtol=FD_RTOL)
    assert_fd("coulomb sphere stop time", stop.time_gradient[cols], fd_times[0], t_r, rtol=FD_RTOL)


# ==============================================================================================
# 6. property test: the frictional impact as simulate applies it
# ==============================================================================================
IMPACT_PROPS = settings(max_examples=20, deadline=2000, derandomize=True, suppress_health_check=[HealthCheck.too_slow])


@IMPACT_PROPS
@given(
    mu=st.floats(0.0, 2.0, exclude_min=True),
    e=st.one_of(st.just(0.0), st.floats(0.0, 1.0)),
    speed=st.floats(0.0, 4.0),
    angle=st.floats(-math.pi, math.pi),
    w=st.floats(0.2, 3.0),
)
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
    scene = cd.Scene(
        block3,
        [cd.Contact("block", restitution=e, friction=mu)],
        gravity=[0, 0, -G],
        q0=np.array([0.0, 0.0, h]),
        v0=np.array([*v_t, -w]),
    )
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
    scene = cd.Scene(
        block3,
        [cd.Contact("block", friction=friction)],
        gravity=[0, 0, -G],
        q0=np.array([0.0, 0.0, h]),
        v0=np.array([*v_t, -w]),
    )
    traj = cd.simulate(scene, T, jacobian=True, **TOL)
    assert event_kinds(traj) == [("touchdown", ("block",))]
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
    for friction, events, q_T, v_T in (
        ("stick", [("touchdown", ("block",))], np.zeros(3), np.zeros(3)),
        ("none", [], 0.3 * v0, v0),
    ):
        scene = cd.Scene(block3, [cd.Contact("block", friction=friction)], gravity=[0, 0, -G], q0=np.zeros(3), v0=v0)
        traj = cd.simulate(scene, 0.3, **TOL)
        assert event_kinds(traj) == events
        if events:
            assert traj.events[0].t == 0.0
        np.testing.assert_allclose(traj.q, q_T, rtol=0, atol=REL)
        np.testing.assert_allclose(traj.v, v_T, rtol=0, atol=REL)
