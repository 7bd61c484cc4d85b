"""Derivatives of whole runs in Coulomb's friction coefficient ``contact:NAME:friction`` and in the
parameters a group of contacts shares (``group:GROUP:field``), through sliding flows, stick → slip
and slip → stick guards and frictional impacts (point, sphere, cube corner and cube face).

References, never the code's own output: closed forms derived in each test's docstring, and
central finite differences of whole runs through `Scene.with_parameters`.

Step and tolerance of the differences. Runs use rtol = atol = 1e-12 (`TOL`); after the few events
here a run's final state is within ``NOISE = 1e-11 max(1, |x|)`` (test_parameter_sensitivity's
measured figure), so a central difference with step ``h`` carries noise ``2 NOISE / (2 h)``; its
truncation is ``h² |x'''| / 6``. With ``h = REL_STEP |p| = 1e-5 μ`` (μ = 0.18 .. 0.5 here: h ≈ 2e-6
.. 5e-6) the noise is ≤ 5e-6 per unit of the state and the truncation, for the stop distances
∝ 1/μ (``x''' = -6 x / μ³``, |x| ≤ 0.3 m), ≤ 1e-12 · 6 · 0.3 / 0.18³ / 6 ≈ 5e-11: the noise
dominates. A column is compared to ``JAC_RTOL = 1e-6`` of its own size plus that noise (`_check`),
while a wrong term (a missing λ_N change, a sign) is O(1) of the column. Closed forms are compared
at ``JAC_REL = 1e-8`` relative (the variational equation's columns carry the run's ~1e-10 relative
error, 100x margin).
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
from coulomb_models import MASS, MU, RADIUS, TOL, G, event_kinds
from helpers import LEG_URDF, leg_lift, leg_lift_jacobian, leg_lift_rate

import contactdiff as cd

REL_STEP = 1e-5
JAC_RTOL = 1e-6
NOISE = 1e-11
JAC_REL = 1e-8


def _fd(scene, names, T, kinds):
    """Central differences of the final state (tangent space) in each parameter of ``names``,
    and of each event's time; every perturbed run keeps the nominal event ``kinds``.
    Returns ``(columns (2nv × p), event-time columns (events × p), steps (p,))``."""
    cols, times, steps = [], [], []
    for name in names:
        value = float(scene.parameter_values([name])[0])
        h = REL_STEP * (abs(value) if value else 1.0)
        runs = []
        for sign in (1.0, -1.0):
            run = cd.simulate(scene.with_parameters({name: value + sign * h}), T, **TOL)
            assert event_kinds(run) == kinds, (name, sign, event_kinds(run))
            runs.append(run)
        plus, minus = runs
        cols.append(np.r_[pin.difference(scene.model, minus.q, plus.q), plus.v - minus.v] / (2 * h))
        times.append([(a.t - b.t) / (2 * h) for a, b in zip(plus.events, minus.events)])
        steps.append(h)
    return np.array(cols).T, np.array(times).T, np.array(steps)


def _check(label, J, fd, x, steps):
    """Each column within JAC_RTOL of its size plus the differences' noise (module doc)."""
    size = max(1.0, float(np.abs(x).max()))
    for k in range(J.shape[1]):
        allowed = JAC_RTOL * np.abs(fd[:, k]).max() + NOISE * size / steps[k]
        err = np.abs(J[:, k] - fd[:, k]).max()
        assert err <= allowed, f"{label} column {k}: error {err:.3g} > {allowed:.3g}\n{J[:, k]}\n{fd[:, k]}"


def _run(scene, T, names):
    traj = cd.simulate(scene, T, parameters=names, **TOL)
    return traj, traj.parameter_jacobian


# ==============================================================================================
# the friction coefficient of a sliding block
# ==============================================================================================
def _block(block3, v0, *, mu=MU, normal=(0.0, 0.0, 1.0), efforts=(), q0=(0.0, 0.0, 0.0), restitution=0.0):
    return cd.Scene(
        block3,
        [cd.Contact("block", normal=normal, friction=mu, restitution=restitution)],
        list(efforts),
        gravity=[0, 0, -G],
        q0=np.asarray(q0, float),
        v0=np.asarray(v0, float),
    )


@pytest.mark.parametrize("before_stop", [True, False], ids=["sliding", "stopped"])
def test_block_sliding_to_a_stop(block3, before_stop):
    """A point mass sliding on flat ground from v0 (speed V, direction v̂): λ_N = m g, so
    v(t) = v0 - μ g t v̂ and it stops at t_s = V / (μ g) after V² / (2 μ g).

    * Sliding (T < t_s): q(T) = v0 T - ½ μ g T² v̂, so ∂q/∂μ = -½ g T² v̂, ∂v/∂μ = -g T v̂
      (the sliding flow's ``-λ_N A_T^T s`` column; a wrong λ_N scales it).
    * Stopped (T > t_s): q = V² / (2 μ g) v̂, so ∂q/∂μ = -V² / (2 μ² g) v̂, ∂v/∂μ = 0, and the
      stop moves by ∂t_s/∂μ = -V / (μ² g) (the slip → stick guard: no parameter of its own).
    The normal direction does not move (λ_N = m g whatever μ)."""
    v0 = np.array([1.2, -0.9, 0.0])
    V = float(np.linalg.norm(v0))
    v_hat = v0 / V
    t_s = V / (MU * G)
    T = 0.6 * t_s if before_stop else t_s + 0.1
    scene = _block(block3, v0)
    traj, J = _run(scene, T, ["contact:block:friction"])
    if before_stop:
        assert event_kinds(traj) == []
        expected = np.r_[-0.5 * G * T**2 * v_hat, -G * T * v_hat]
    else:
        assert event_kinds(traj) == [("stick", ("block",))]
        expected = np.r_[-(V**2) / (2 * MU**2 * G) * v_hat, np.zeros(3)]
        assert traj.events[0].parameter_time_gradient[0] == pytest.approx(-V / (MU**2 * G), rel=JAC_REL)
    np.testing.assert_allclose(J[:, 0], expected, rtol=0, atol=JAC_REL * np.abs(expected).max())
    fd, fd_times, steps = _fd(scene, ["contact:block:friction"], T, event_kinds(traj))
    _check("block slide", J, fd, np.r_[traj.q, traj.v], steps)
    if not before_stop:
        assert traj.events[0].parameter_time_gradient[0] == pytest.approx(fd_times[0, 0], rel=1e-5)


# ==============================================================================================
# a block on an incline: below the threshold, sliding from the start, pushed past the threshold
# ==============================================================================================
def _incline(ratio):
    """Tilt α with tan α = ratio μ; normal n = (sin α, 0, cos α); downhill d = (cos α, 0, -sin α)."""
    alpha = math.atan(ratio * MU)
    return alpha, (math.sin(alpha), 0.0, math.cos(alpha)), np.array([math.cos(alpha), 0.0, -math.sin(alpha)])


def _ramp(k, d):
    """A force k t d (N; k in N/s) on the block's three prismatic joints, with its exact derivatives."""
    d = np.asarray(d, float)
    return cd.UserEffort(
        lambda q, v, t: k * t * d,
        lambda q, v, t: (np.zeros((3, 3)), np.zeros((3, 3))),
        name="ramp",
        time_derivative=lambda q, v, t: k * d,
    )


@pytest.mark.parametrize("case", ["below", "sliding", "pushed"])
def test_block_on_an_incline(block3, case):
    """λ_N = m g cos α on the incline (n · gravity); downhill gravity m g sin α.

    * below (tan α = 0.8 μ, at rest): it sticks for every μ near the nominal one, so every
      derivative in μ is 0 (the sticking forces do not depend on μ).
    * sliding (tan α = 1.2 μ, at rest): it slides from t = 0 with a = g (sin α - μ cos α), so
      q = ½ a T² d, ∂q/∂μ = -½ g cos α T² d, ∂v/∂μ = -g cos α T d.
    * pushed (tan α = 0.8 μ, force k t along d from rest): it sticks until the cone margin
      h = μ m g cos α - (m g sin α + k t) reaches 0 at t* = m g (μ cos α - sin α) / k (the
      stick → slip guard, ∂h/∂μ = λ_N), so ∂t*/∂μ = m g cos α / k. Then a(t) = k (t - t*) / m
      (μ enters only through t*): s(T) = k (T - t*)³ / (6 m), v = k (T - t*)² / (2 m), so
      ∂s/∂μ = -½ g cos α (T - t*)², ∂v/∂μ = -g cos α (T - t*), along d."""
    ratio = 0.8 if case in ("below", "pushed") else 1.2
    alpha, normal, d = _incline(ratio)
    k = 2.0  # N/s
    efforts = [_ramp(k, d)] if case == "pushed" else []
    t_star = MASS * G * (MU * math.cos(alpha) - math.sin(alpha)) / k
    T = t_star + 0.3 if case == "pushed" else 0.5
    scene = _block(block3, np.zeros(3), normal=normal, efforts=efforts)
    traj, J = _run(scene, T, ["contact:block:friction"])
    if case == "below":
        assert event_kinds(traj) == [] and [s.sliding for s in traj.segments] == [()]
        expected = np.zeros(6)
    elif case == "sliding":
        assert event_kinds(traj) == [] and [s.sliding for s in traj.segments] == [("block",)]
        c = G * math.cos(alpha)
        expected = np.r_[-0.5 * c * T**2 * d, -c * T * d]
    else:
        assert event_kinds(traj) == [("slip", ("block",))]
        assert traj.events[0].t == pytest.approx(t_star, rel=1e-9)
        c, r = G * math.cos(alpha), T - t_star
        expected = np.r_[-0.5 * c * r**2 * d, -c * r * d]
        grad = traj.events[0].parameter_time_gradient[0]
        assert grad == pytest.approx(MASS * G * math.cos(alpha) / k, rel=JAC_REL)
    # the below case: the exact 0 up to the round-off of the sticking forces (1e-15 of m g)
    np.testing.assert_allclose(J[:, 0], expected, rtol=0, atol=max(JAC_REL * np.abs(expected).max(), 1e-12))
    fd, _, steps = _fd(scene, ["contact:block:friction"], T, event_kinds(traj))
    _check(f"incline {case}", J, fd, np.r_[traj.q, traj.v], steps)


# ==============================================================================================
# frictional impacts of a point mass: sliding and sticking patterns
# ==============================================================================================
@pytest.mark.parametrize("case", ["slide-bounce", "slide-stop", "stick"])
def test_oblique_impact(block3, case):
    """A point mass falls from h with v0 = (v_t, -w) and lands at normal speed V = √(w² + 2 g h),
    at t_td = (V - w) / g whatever μ. Its impulse Λ_N = m (1 + e) V; sticking needs
    |v_t| ≤ μ (1 + e) V, and then v_T+ = 0 (no μ). Sliding: v_T+ = v_t - μ (1 + e) V v̂_t, so
    ∂v_T+/∂μ = -(1 + e) V v̂_t (the impact map's μ column).

    * slide-bounce (e = 0.6, run to the apex T = t_td + e V / g): ∂q_xy/∂μ = -(1 + e) V (T - t_td) v̂_t,
      ∂v_xy/∂μ = -(1 + e) V v̂_t, the vertical untouched.
    * slide-stop (e = 0): with S = |v_t|, it slides on from S - μ V and stops after
      (S - μ V)² / (2 μ g), at t_td + (S - μ V) / (μ g): ∂(distance)/∂μ = -(S² - μ² V²) / (2 μ² g),
      ∂t_stop/∂μ = -S / (μ² g), ∂v = 0.
    * stick (e = 0.6, |v_t| = ½ μ (1 + e) V): zero."""
    h, w = 0.05, 1.0
    V = math.sqrt(w * w + 2 * G * h)
    t_td = (V - w) / G
    e = 0.0 if case == "slide-stop" else 0.6
    ratio = 0.5 if case == "stick" else 2.0  # |v_t| / (μ (1 + e) V)
    direction = np.array([0.8, -0.6])
    S = ratio * MU * (1 + e) * V
    v_t = S * direction
    T = t_td + e * V / G if e > 0 else t_td + (S - MU * V) / (MU * G) + 0.1
    scene = _block(block3, [*v_t, -w], q0=(0.0, 0.0, h), restitution=e)
    # the restitution's column too where e > 0 (at e = 0 a difference would make it bounce)
    names = ["contact:block:friction"] + (["contact:block:restitution"] if e > 0 else [])
    traj, J = _run(scene, T, names)
    dir3 = np.r_[direction, 0.0]
    if case == "slide-bounce":
        assert event_kinds(traj) == [("bounce", ("block",))]
        expected = np.r_[-(1 + e) * V * (T - t_td) * dir3, -(1 + e) * V * dir3]
    elif case == "slide-stop":
        assert event_kinds(traj) == [("touchdown", ("block",)), ("stick", ("block",))]
        expected = np.r_[-(S**2 - MU**2 * V**2) / (2 * MU**2 * G) * dir3, np.zeros(3)]
        assert traj.events[1].parameter_time_gradient[0] == pytest.approx(-S / (MU**2 * G), rel=JAC_REL)
    else:
        assert event_kinds(traj) == [("bounce", ("block",))]
        assert traj.events[0].v_plus[:2] == pytest.approx(0, abs=1e-12)  # m/s: it sticks
        expected = np.zeros(6)
    assert traj.events[0].parameter_time_gradient[0] == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(J[:, 0], expected, rtol=0, atol=max(JAC_REL * np.abs(expected).max(), 1e-12))
    fd, _, steps = _fd(scene, names, T, event_kinds(traj))
    _check(f"oblique impact {case}", J, fd, np.r_[traj.q, traj.v], steps)


# ==============================================================================================
# a sphere sliding with spin until it rolls
# ==============================================================================================
def test_sphere_slides_then_rolls(ball):
    """A solid sphere (I = 2/5 m R²) on flat ground with contact-point slip u0 (direction ŝ):
    u̇ = -(7/2) μ g ŝ, so it rolls from t_r = 2 |u0| / (7 μ g) with v_r = v0 - μ g t_r ŝ =
    v0 - (2/7) |u0| ŝ and ω_r likewise free of μ. The centre is then at
    p(T) = v0 t_r - ½ μ g t_r² ŝ + v_r (T - t_r); with ∂t_r/∂μ = -t_r / μ,
    ∂p/∂μ = (v0 - μ g t_r ŝ - v_r) ∂t_r/∂μ - ½ g t_r² ŝ = -½ g t_r² ŝ, and the world velocities
    do not move. The columns are in the tangent space at q(T) = (p, R): a world position change
    is R δp_local, a world velocity change R (δθ × v_local + δv_local) (δθ the rotation column)."""
    v0, w0 = np.array([1.0, 0.4, 0.0]), np.array([3.0, -5.0, 2.0])
    scene = cd.Scene(
        ball,
        [cd.Contact("ball", radius=RADIUS, friction=MU)],
        gravity=[0, 0, -G],
        q0=np.array([0.0, 0.0, RADIUS, 0.0, 0.0, 0.0, 1.0]),
        v0=np.r_[v0, w0],
    )
    u0 = v0[:2] + RADIUS * np.array([-w0[1], w0[0]])
    s = u0 / np.linalg.norm(u0)
    t_r = 2 * np.linalg.norm(u0) / (7 * MU * G)
    T = t_r + 0.1
    traj, J = _run(scene, T, ["contact:ball:friction"])
    assert event_kinds(traj) == [("stick", ("ball",))]
    assert traj.events[0].parameter_time_gradient[0] == pytest.approx(-t_r / MU, rel=JAC_REL)
    R = pin.XYZQUATToSE3(traj.q).rotation  # tangent-space position columns are in the body frame
    dp_world = R @ J[:3, 0]
    expected = np.r_[-0.5 * G * t_r**2 * s, 0.0]
    np.testing.assert_allclose(dp_world, expected, rtol=0, atol=JAC_REL * np.abs(expected).max())
    dtheta, v_local = J[3:6, 0], traj.v
    for rows, local in ((slice(6, 9), v_local[:3]), (slice(9, 12), v_local[3:])):
        world = R @ (np.cross(dtheta, local) + J[rows, 0])
        # velocities of ~10 rad/s, 1 m/s: their columns' error ~JAC_REL of that size
        np.testing.assert_allclose(world, 0.0, rtol=0, atol=JAC_REL * 10.0)
    fd, _, steps = _fd(scene, ["contact:ball:friction"], T, event_kinds(traj))
    _check("sphere", J, fd, np.r_[traj.q, traj.v], steps)


# ==============================================================================================
# the cube: one corner's landing with slip, and a face's (range principle)
# ==============================================================================================
CUBE = cd.cube_scene()
CUBE_EDGE = 0.1048  # m, the cube's (`CubeParameters.edge`)


def _corner_toss():
    """The cube held with its -x-y-z corner lowest (turned 0.5 rad about x, 0.4 about y), 3 cm
    above the board, thrown with horizontal velocity and spin: the corner lands alone and slides."""
    rotation = pin.rpy.rpyToMatrix(0.5, 0.4, 0.0)
    corners = np.array([[sx, sy, sz] for sx in (1, -1) for sy in (1, -1) for sz in (1, -1)]) * CUBE_EDGE / 2
    low = float(-(corners @ rotation.T)[:, 2].min())
    q = np.r_[0.0, 0.0, low + 0.03, pin.Quaternion(rotation).coeffs()]
    v = np.r_[rotation.T @ np.array([0.9, 0.3, -0.5]), 1.0, -2.0, 0.5]
    return CUBE.with_state(q, v)


@pytest.mark.parametrize("T", [0.07, 0.092], ids=["one-corner", "two-corners"])
def test_cube_corner_landing_and_group_parameters(T):
    """A corner's frictional impact and the flight after it (T = 0.07 s: the first, sliding
    corner's bounce at 0.044 s; 0.092 s: a second corner's bounce at 0.091 s), in the group's μ,
    e and offset and in each member's μ: against central differences, and the group's friction
    column equals the sum of its eight members' columns (a group parameter moves every member's
    coefficient by the same amount). After one bounce only the landing corner's μ acts."""
    scene = _corner_toss()
    members = [f"contact:{n}:friction" for n in scene.contact_names]
    group = ["group:cube:friction", "group:cube:restitution", "group:cube:offset"]
    traj, J = _run(scene, T, group + members)
    kinds = event_kinds(traj)
    assert [k for k, _ in kinds] == ["bounce"] * (1 if T < 0.08 else 2), kinds
    assert all(len(c) == 1 for _, c in kinds) and traj.differentiable
    landed = [members.index(f"contact:{c[0]}:friction") + len(group) for _, c in kinds]
    # the impacts slide: the friction column is not zero, and only the landed corners' are
    assert np.abs(J[:, 0]).max() > 1e-3
    others = [k for k in range(len(group), len(group) + len(members)) if k not in landed]
    assert np.abs(J[:, others]).max() == 0.0
    # a sum of columns formed in one run: equal up to the round-off of adding them (1e-15 each)
    scale = np.abs(J[:, 0]).max()
    np.testing.assert_allclose(J[:, 0], J[:, len(group) :].sum(axis=1), rtol=0, atol=1e-12 * scale)
    fd, _, steps = _fd(scene, group + [members[k - len(group)] for k in landed], T, kinds)
    _check("cube corner", J[:, [0, 1, 2, *landed]], fd, np.r_[traj.q, traj.v], steps)


def test_cube_face_landing_slides_to_a_stop():
    """The cube dropped flat (e = 0) from h = 5 cm with horizontal velocity v_t (S = |v_t| = 0.6 m/s)
    and no spin: its four bottom corners land together (a redundant set, the range principle of
    `contactdiff.dynamics.redundant`). Without spin every corner slides along v̂_t, so the friction
    sums to μ Λ ŝ whatever the corners' shares, and the cube moves as the point mass of
    `test_oblique_impact` with e = 0: V = √(2 g h), v_T+ = (S - μ V) v̂_t, a stop after
    (S - μ V)² / (2 μ g), so ∂(distance)/∂μ = -(S² - μ² V²) / (2 μ² g), ∂v = ∂ω = 0 (no rotation),
    and ∂t_stop/∂μ = -S / (μ² g). The landing's order verdict does not matter: μ does not move
    the landing (each order's and the simultaneous reset's μ column is the impact map's at a fixed
    pre-impact state)."""
    mu, h = 0.18, 0.05
    scene = cd.cube_scene(restitution=0.0)
    direction = np.array([0.6, 0.8])
    S = 0.6
    q = np.r_[0.0, 0.0, CUBE_EDGE / 2 + h, 0.0, 0.0, 0.0, 1.0]
    v = np.r_[S * direction, 0.0, 0.0, 0.0, 0.0]
    scene = scene.with_state(q, v)
    V = math.sqrt(2 * G * h)
    t_td = V / G
    T = t_td + (S - mu * V) / (mu * G) + 0.05
    name = "group:cube:friction"
    traj, J = _run(scene, T, [name])
    kinds = event_kinds(traj)
    assert [k for k, _ in kinds] == ["touchdown", "stick"] and len(kinds[0][1]) == 4, kinds
    dir3 = np.r_[direction, 0.0]
    expected_p = -(S**2 - mu**2 * V**2) / (2 * mu**2 * G) * dir3
    scale = np.abs(expected_p).max()
    # the cube is not turned: tangent-space position columns are world ones
    np.testing.assert_allclose(J[:3, 0], expected_p, rtol=0, atol=1e-7 * scale)
    np.testing.assert_allclose(J[3:, 0], 0.0, rtol=0, atol=1e-7 * scale)
    assert traj.events[1].parameter_time_gradient[0] == pytest.approx(-S / (mu**2 * G), rel=1e-7)
    fd, _, steps = _fd(scene, [name], T, kinds)
    _check("cube face", J, fd, np.r_[traj.q, traj.v], steps)


# ==============================================================================================
# a leg whose foot lands, sticks, slips and lifts off; or slides and reverses
# ==============================================================================================
@pytest.mark.parametrize(
    "mu, kinds",
    [(1.0, ["touchdown", "slip", "lift-off"]), (0.3, ["touchdown", "slip"])],
    ids=["stick-slip-liftoff", "slide-reverse"],
)
def test_leg_foot_friction(mu, kinds, tmp_path):
    """The planar leg of test_friction_events (a body free in x and z, a leg on a hip hinge, landing
    inclined by 0.4 rad; from t = 0.1 s an upward force ramps and unloads the foot) in its foot's μ,
    against central differences. μ = 1: the foot sticks, its tangential force reaches the cone (the
    stick → slip guard, ∂h/∂μ = λ_N), it slides (the hip couples the friction to the normal force:
    λ_N moves with μ) and lifts off (the lift-off guard of a sliding contact, ∂λ_N/∂μ). μ = 0.3: the
    impact leaves it sliding (the frictional impact's μ column) and its slip reverses (a guard with
    no parameter of its own)."""
    path = tmp_path / "leg.urdf"
    path.write_text(LEG_URDF)
    robot = cd.load_robot(str(path))
    tilt = 0.4
    effort = cd.UserEffort(leg_lift, leg_lift_jacobian, name="lift", time_derivative=leg_lift_rate)
    scene = cd.Scene(
        robot,
        [cd.Contact("foot", friction=mu)],
        [effort],
        gravity=[0, 0, -9.81],
        q0=np.array([0.0, 0.5 * math.cos(tilt) + 0.01, tilt]),
        v0=np.zeros(3),
    )
    T = 0.6
    traj, J = _run(scene, T, ["contact:foot:friction"])
    assert [k for k, _ in event_kinds(traj)] == kinds
    assert np.abs(J).max() > 1e-3  # μ moves the outcome: not an empty check
    fd, fd_times, steps = _fd(scene, ["contact:foot:friction"], T, event_kinds(traj))
    _check(f"leg {mu}", J, fd, np.r_[traj.q, traj.v], steps)
    for event, fd_t in zip(traj.events, fd_times[:, 0]):
        # event times: located to ~1e-12 s per run, so their differences carry 2e-12 / (2 h) ~ 1e-6 s
        assert event.parameter_time_gradient[0] == pytest.approx(fd_t, abs=1e-12 / steps[0] + 1e-6 * abs(fd_t))


def test_spinning_cube_face_slides():
    """The cube dropped flat (e = 0) with a horizontal velocity and a spin of 6 rad/s about the
    vertical: its four corners land together and slide in different directions, so the impact's
    velocities and the sliding flow depend on the corners' load shares (the range principle of
    `contactdiff.dynamics.redundant`, in the impact and in the flow). The group's μ against
    central differences at T = 0.2 s, while it still slides and spins (its slide and spin stop
    together at 0.437 s)."""
    rotation = pin.rpy.rpyToMatrix(0.0, 0.0, 0.3)
    q = np.r_[0.0, 0.0, CUBE_EDGE / 2 + 0.05, pin.Quaternion(rotation).coeffs()]
    v = np.r_[rotation.T @ np.array([0.7, -0.2, 0.0]), 0.0, 0.0, 6.0]
    scene = cd.cube_scene(restitution=0.0).with_state(q, v)
    T = 0.2
    traj, J = _run(scene, T, ["group:cube:friction"])
    kinds = event_kinds(traj)
    assert [k for k, _ in kinds] == ["touchdown"] and len(kinds[0][1]) == 4
    assert traj.segments[-1].sliding and len(traj.segments[-1].sliding) == 4
    fd, _, steps = _fd(scene, ["group:cube:friction"], T, kinds)
    assert np.abs(fd).max() > 1.0  # μ moves the slide: not an empty check
    _check("spinning cube face", J, fd, np.r_[traj.q, traj.v], steps)
