"""A box on one face with Coulomb friction at its four bottom corners: runs against
closed forms (the four normal rows are redundant; their loads follow
`contactdiff.dynamics.redundant`).

Box of half edges a, b, c (x, y, z), mass m, uniform; corners at (±a, ±b, -c) in
its frame; ground z = 0; gravity g; coefficient μ.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import contactdiff as cd
from contactdiff.model.objects import SceneObject, add_objects, empty_robot

A_HALF, B_HALF, C_HALF = 0.15, 0.10, 0.05
MASS, G, MU = 2.0, 9.81, 0.3
CORNERS = [f"box/{sx}x{sy}y-z" for sx in "+-" for sy in "+-"]
# events are located to ~(atol + rtol |x|) / |guard rate| with rates O(1) here, and the
# states carry the integration error ~rtol over O(1) s: at rtol 1e-10 both are ~1e-10
TIGHT = dict(rtol=1e-10, atol=1e-12)
EVENT_ATOL = 1e-8  # s
STATE_ATOL = 1e-8  # m, m/s, rad


def box_scene(mu=MU, gravity=(0.0, 0.0, -G)):
    box = SceneObject(
        "box", shape="box", size=(2 * A_HALF, 2 * B_HALF, 2 * C_HALF), mass=MASS, position=(0.0, 0.0, C_HALF)
    )
    return cd.Scene(add_objects(empty_robot(), [box]), [cd.Contact(n, friction=mu) for n in CORNERS], gravity=gravity)


def flat_state(yaw=0.0, velocity=(0.0, 0.0), omega_z=0.0):
    """The box flat on the ground: yaw (rad), centre velocity (m/s, world, horizontal),
    spin about the vertical (rad/s)."""
    rotation = pin.rpy.rpyToMatrix(0.0, 0.0, yaw)
    q = np.r_[0.0, 0.0, C_HALF, pin.Quaternion(rotation).coeffs()]
    v = np.r_[rotation.T @ np.r_[velocity, 0.0], 0.0, 0.0, omega_z]
    return q, v


def yaw_of(q):
    return pin.rpy.matrixToRpy(pin.Quaternion(q[3:7]).matrix())[2]


@pytest.mark.parametrize("direction", [0.0, 0.7, 2.9])
def test_box_slides_to_a_stop_on_its_face(direction):
    """Sliding at u0 along d: friction μ m g decelerates it, so it stops at
    t_s = u0 / (μ g) after u0² / (2 μ g), all four corners at once, and stays
    (sticking needs a tangential force of zero at rest)."""
    u0 = 1.0
    d = np.array([np.cos(direction), np.sin(direction)])
    q, v = flat_state(0.3, u0 * d)
    traj = cd.simulate(box_scene().with_state(q, v), 0.6, **TIGHT)
    (stop,) = traj.events
    assert stop.kind == "stick" and set(stop.contacts) == set(CORNERS)
    assert stop.t == pytest.approx(u0 / (MU * G), abs=EVENT_ATOL)
    np.testing.assert_allclose(traj.q[:2], u0**2 / (2 * MU * G) * d, atol=STATE_ATOL)
    assert traj.q[2] == pytest.approx(C_HALF, abs=STATE_ATOL)
    assert yaw_of(traj.q) == pytest.approx(0.3, abs=STATE_ATOL)
    np.testing.assert_allclose(traj.v, 0.0, atol=STATE_ATOL)


def test_box_spins_down_on_its_face():
    """Spinning at ω0 about the vertical, centre at rest: every corner is r = √(a²+b²)
    from the centre, so the friction torque is μ m g r and I_z = m (a² + b²)/3 spins
    down in t_s = I_z ω0 / (μ m g r), turning I_z ω0² / (2 μ m g r)."""
    omega0 = 3.0
    q, v = flat_state(0.0, omega_z=omega0)
    traj = cd.simulate(box_scene().with_state(q, v), 0.5, **TIGHT)
    r = np.hypot(A_HALF, B_HALF)
    inertia = MASS * (A_HALF**2 + B_HALF**2) / 3
    (stop,) = traj.events
    assert stop.kind == "stick"
    assert stop.t == pytest.approx(inertia * omega0 / (MU * MASS * G * r), abs=EVENT_ATOL)
    assert yaw_of(traj.q) == pytest.approx(inertia * omega0**2 / (2 * MU * MASS * G * r), abs=STATE_ATOL)
    np.testing.assert_allclose(traj.q[:3], [0.0, 0.0, C_HALF], atol=STATE_ATOL)
    np.testing.assert_allclose(traj.v, 0.0, atol=STATE_ATOL)


@pytest.mark.parametrize("tilt", [0.9, 1.1])
def test_box_on_an_incline_sticks_or_slides(tilt):
    """An incline of angle α (gravity tilted by α about y instead of the ground): the box
    at rest on its face sticks when tan α <= μ and otherwise slides down with
    a = g (sin α - μ cos α), x = a t² / 2. ``tilt`` is tan α / μ."""
    alpha = np.arctan(tilt * MU)
    gravity = G * np.array([np.sin(alpha), 0.0, -np.cos(alpha)])
    q, v = flat_state()
    T = 0.4
    traj = cd.simulate(box_scene(gravity=gravity).with_state(q, v), T, **TIGHT)
    accel = max(0.0, G * (np.sin(alpha) - MU * np.cos(alpha)))
    assert traj.q[0] == pytest.approx(accel * T**2 / 2, abs=STATE_ATOL)
    np.testing.assert_allclose(traj.q[1:3], [0.0, C_HALF], atol=STATE_ATOL)
    assert traj.v[0] == pytest.approx(accel * T, abs=STATE_ATOL)
    sliding = traj.segments[-1].sliding
    assert set(sliding) == (set(CORNERS) if tilt > 1 else set())


def test_flow_jacobian_through_the_face_stop_matches_finite_differences():
    """The flow Jacobian through the four corners' simultaneous slip → stick, along
    perturbations that keep the box flat and not spinning (horizontal position, yaw,
    horizontal velocity: the stop stays simultaneous), against central differences on
    the manifold. ε = 1e-6 with rtol 1e-12: the differences' error is ~1e-12/ε plus
    ε² terms, so 1e-5 relative to the columns' size."""
    scene = box_scene()
    q, v = flat_state(0.3, (0.8, 0.3))
    T = 0.45
    opts = dict(rtol=1e-12, atol=1e-14)
    traj = cd.simulate(scene.with_state(q, v), T, jacobian=True, **opts)
    assert traj.differentiable
    model = scene.model
    nv = model.nv
    directions = []
    for k in (0, 1, 5):  # x, y, yaw
        dq = np.zeros(nv)
        dq[k] = 1.0
        directions.append((dq, np.zeros(nv)))
    rotation = pin.Quaternion(q[3:7]).matrix()
    for w in (np.r_[1.0, 0.0, 0.0], np.r_[0.0, 1.0, 0.0]):  # world horizontal velocity
        directions.append((np.zeros(nv), np.r_[rotation.T @ w, 0.0, 0.0, 0.0]))
    eps = 1e-6

    def final(dq, dv, sign):
        run = cd.simulate(scene.with_state(pin.integrate(model, q, sign * eps * dq), v + sign * eps * dv), T, **opts)
        return run.q, run.v

    for dq, dv in directions:
        qp, vp = final(dq, dv, 1.0)
        qm, vm = final(dq, dv, -1.0)
        fd = np.r_[pin.difference(model, qm, qp), vp - vm] / (2 * eps)
        exact = traj.jacobian @ np.r_[dq, dv]
        assert np.abs(exact - fd).max() <= 1e-5 * max(1.0, np.abs(fd).max()), (dq, dv, exact, fd)


def test_a_face_landing_is_flagged_by_its_landing_orders_with_or_without_sensitivities():
    """A box landing flat lands on four corners of one body: the order in which they land
    changes the outcome (each corner's impulse turns the box), so the event is not
    differentiable, in a plain run (which stops comparing at the first two orders that
    disagree) as in a Jacobian run (which forms all 24)."""
    q, v = flat_state(0.3, (0.5, 0.2))
    q[2] += 0.05
    scene = cd.Scene(
        box_scene().robot, [cd.Contact(n, friction=MU, restitution=0.5) for n in CORNERS], gravity=(0.0, 0.0, -G)
    ).with_state(q, v)
    T = np.sqrt(2 * 0.05 / G) + 1e-3
    plain = cd.simulate(scene, T)
    full = cd.simulate(scene, T, jacobian=True)
    for traj in (plain, full):
        landing = traj.events[0]
        assert set(landing.contacts) == set(CORNERS)
        assert cd.NonSmooth.ORDER in landing.nonsmooth and not traj.differentiable
    assert len(full.events[0].saltation_orders) == 24


def cube_on_edge(moment=None, mu=1.0, restitution=0.0, tilt=0.05, omega=0.0, b=0.05, mass=0.4):
    """A cube of half edge ``b`` on its bottom edge x = -b (corners ``-x±y-z`` on the
    ground), tilted by ``tilt`` (rad) about that edge (its +x side up), turning about it
    at ``omega`` (rad/s, + tips it further up); moments ``moment`` (kg m², default uniform)."""
    cube = SceneObject("cube", shape="box", size=(2 * b,) * 3, mass=mass, moments=moment, position=(0.0, 0.0, b))
    corners = [f"cube/{sx}x{sy}y-z" for sx in "+-" for sy in "+-"]
    scene = cd.Scene(
        add_objects(empty_robot(), [cube]),
        [cd.Contact(n, friction=mu, restitution=restitution) for n in corners],
        gravity=(0.0, 0.0, -G),
    )
    rotation = pin.rpy.rpyToMatrix(0.0, -tilt, 0.0)  # about y: -tilt raises the +x side
    edge = np.array([-b, 0.0, 0.0])
    centre = edge + rotation @ np.array([b, 0.0, b])  # the corner (-b, y, -b) of the cube frame on the edge
    q = np.r_[centre, pin.Quaternion(rotation).coeffs()]
    w_world = np.array([0.0, -omega, 0.0])
    v_world = np.cross(w_world, centre - edge)
    v = np.r_[rotation.T @ v_world, rotation.T @ w_world]
    return scene.with_state(q, v), corners


@pytest.mark.parametrize("moment", [None, 8.1e-4])
def test_housner_rocking_cube_lands_on_its_other_edge(moment):
    """A cube rocking on one bottom edge falls flat onto the opposite edge (plastic, that
    edge sticking): the impulse acts at the new edge only, so angular momentum about it is
    kept. With half edge b, centre at (0, b) from the face's middle, the old edge O1 at
    x = -b and the new one O2 at x = +b, the centre moves at ω1 (b, -b) (turning about
    O1); about O2, H = I_c ω1 + m ((c - O2) × v)_y = (I_c + m (b² - b²)) ω1 = I_c ω1 before
    and (I_c + 2 m b²) ω2 after: ω2/ω1 = I_c / (I_c + 2 m b²), 1/4 for a uniform cube
    (I_c = 2 m b² / 3; Housner's 1 - 3/2 sin² α with α = 45°). The old edge then lifts.
    Tolerance: the event's velocities carry the run's error, ~1e-10 relative at rtol 1e-10."""
    b, mass = 0.05, 0.4
    scene, corners = cube_on_edge(moment, b=b, mass=mass)
    traj = cd.simulate(scene, 0.5, **TIGHT)
    landing = next(e for e in traj.events if "cube/+x+y-z" in e.contacts)
    assert set(landing.contacts) == {"cube/+x+y-z", "cube/+x-y-z"}
    i_c = mass * (2 * b) ** 2 / 6 if moment is None else moment
    ratio = landing.v_plus[4] / landing.v_minus[4]  # ω_y, cube frame = world at the flat pose
    assert ratio == pytest.approx(i_c / (i_c + 2 * mass * b * b), rel=1e-8)
    assert set(landing.mode_after) == {"cube/+x+y-z", "cube/+x-y-z"}  # the old edge lifted


def test_a_face_tilted_by_a_nanoradian_lands_without_a_cascade():
    """A box dropped flat but for a 1e-9 rad tilt: its corners land 1e-10 s apart
    (2.5e-11 m of height over a 0.5 m/s landing), one simultaneous event by the
    simultaneity tolerance or a short cascade: the run must end promptly, at rest on its
    face, with its energy not above the drop's."""
    box = SceneObject(
        "box", shape="box", size=(2 * A_HALF, 2 * B_HALF, 2 * C_HALF), mass=MASS, position=(0.0, 0.0, C_HALF)
    )
    scene = cd.Scene(
        add_objects(empty_robot(), [box]),
        [cd.Contact(n, friction=MU, restitution=0.3) for n in CORNERS],
        gravity=(0.0, 0.0, -G),
    )
    rotation = pin.rpy.rpyToMatrix(1e-9, 0.0, 0.0)
    q = np.r_[0.0, 0.0, C_HALF + 0.0125 + 2e-9, pin.Quaternion(rotation).coeffs()]
    traj = cd.simulate(scene.with_state(q, np.zeros(6)), 1.0)
    assert traj.t == 1.0 and len(traj.events) < 200
    assert traj.q[2] == pytest.approx(C_HALF, abs=1e-6)
    np.testing.assert_allclose(traj.v, 0.0, atol=1e-6)


def test_flow_jacobian_through_an_edge_release_matches_finite_differences():
    """A cube falling back from its bottom edge (Coulomb, μ = 1) fast enough that the
    edge's normal force reaches zero (the centre's circular motion asks more than gravity
    gives): the edge's two corners release together, and slide rather than lift since the
    friction they carried pressed them down (a ``slip`` event of both; the two rows of the
    edge are redundant with its four sticking rows). The flow Jacobian through that event,
    along random directions of the state space, against central differences on the
    manifold. rtol 1e-10 (tighter, the slip's start from zero speed takes thousands of
    steps: the slow approach of slips), ε = 1e-5: the differences' error is ~1e-10/ε
    plus ε² terms, so 1e-4 relative to the columns' size allows a factor 10 for the
    event time's error, which enters through the release's rate."""
    scene, corners = cube_on_edge(tilt=0.6, omega=-11.0)
    opts = dict(rtol=1e-10, atol=1e-12)
    T = 0.04  # after the release (~0.011 s), before the face lands (~0.051 s)
    traj = cd.simulate(scene, T, jacobian=True, **opts)
    assert [e.kind for e in traj.events] == ["slip"] and traj.differentiable
    model, q, v = scene.model, scene.q0, scene.v0
    eps = 1e-5
    # perturbations that keep the edge on the ground and sticking: horizontal moves and
    # turns of the cube (rigid motions of the plane) and the turn about the edge
    rotation = pin.Quaternion(q[3:7]).matrix()
    directions = [(np.r_[rotation.T @ e, 0.0, 0.0, 0.0], np.zeros(6)) for e in np.eye(3)[:2]]
    directions.append((np.r_[0.0, 0.0, 0.0, rotation.T @ np.array([0.0, 0.0, 1.0])], np.zeros(6)))
    dyn = cd.ModeDynamics(scene)
    dyn.kin.update(q, v)
    rows = np.vstack([dyn.contact(scene.contact_names.index(n)).rows(dyn.kin) for n in corners if "-x" in n])
    turn = np.linalg.svd(rows)[2][-1]  # six rows of rank 5: the one velocity they leave free
    directions.append((np.zeros(6), turn))
    for dq, dv in directions:
        runs = [
            cd.simulate(scene.with_state(pin.integrate(model, q, s * eps * dq), v + s * eps * dv), T, **opts)
            for s in (1.0, -1.0)
        ]
        assert [e.kind for e in runs[0].events] == [e.kind for e in runs[1].events] == [e.kind for e in traj.events]
        fd = np.r_[pin.difference(model, runs[1].q, runs[0].q), runs[0].v - runs[1].v] / (2 * eps)
        exact = traj.jacobian @ np.r_[dq, dv]
        assert np.abs(exact - fd).max() <= 1e-4 * max(1.0, np.abs(fd).max()), np.abs(exact - fd).max()


def test_a_rocking_cube_comes_to_rest_on_its_face():
    """The rocking cube of Housner's test, plastic (e = 0): each landing on an edge keeps
    a quarter of the angular velocity, so the rocking dies out in a Zeno sequence that
    the Zeno rule ends, and the cube rests flat: centre at height b, level, still.
    Tolerances: the state at rest carries the run's error (rtol 1e-8) and the Zeno rule's
    cut at zeno_speed = 1e-6 m/s."""
    b = 0.05
    scene, corners = cube_on_edge(tilt=0.2, b=b)
    traj = cd.simulate(scene, 2.0)
    assert traj.t == 2.0
    assert traj.q[2] == pytest.approx(b, abs=1e-6)
    rotation = pin.Quaternion(traj.q[3:7]).matrix()
    assert rotation[2, 2] == pytest.approx(1.0, abs=1e-9)  # the face is level
    np.testing.assert_allclose(traj.v, 0.0, atol=1e-5)
    assert len(traj.events) < 200
