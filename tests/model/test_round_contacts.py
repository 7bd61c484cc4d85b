"""Round contacts (``Contact(..., radius=r)``): a sphere of radius r centred at the frame.

References are closed forms derived here or central finite differences of
Pinocchio's placements, never the contact code's own output:

* geometry: the gap ``n·p - r - offset`` of a free-flyer ball (``z - r`` on flat
  ground); the rows ``A_d`` are the gradients of ``d · X(q)``, ``X(q)`` the
  material point of the sphere that sits at the bottom ``p - r n`` at the base
  state (it moves with the body); the drift is ``d/dt (A(q(t)) v)`` along
  ``q ⊕ t v``; every derivative method against central differences on the
  manifold (``helpers``: ε = 1e-6, rtol 1e-6), for r = 0 and r > 0, on the ball,
  a solo12 foot (a chain of joints under a free-flyer) and a planar foot (one
  tangent kept);
* rolling: a solid ball (I = 2/5 m r²) released at rest on an incline of angle α
  rolls without slipping: ``a = (5/7) g sin α`` down the slope, ``ω = v / r``,
  normal force ``m g cos α``, friction ``(2/7) m g sin α`` up the slope;
* the flow Jacobian of a spinning ball dropped onto the incline (touchdown, plastic
  sticking impact, rolling) against central differences of the simulator;
* r = 0: explicit ``radius=0.0`` gives bit-identical runs, and Pinocchio's 3-D
  contact dynamics is used only for point contacts;
* the TOML key ``radius`` and its validation;
* round feet (``round_feet``): a1's spheres are centred on the feet (the contacts
  stay there, bit for bit); ANYmal's are not, and its contacts move to a new frame
  at each sphere's centre, checked against the centres Pinocchio's collision model
  places (``buildGeomFromUrdf``, ``updateGeometryPlacements``) and against the
  point-foot scene's gaps at the reference pose.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pinocchio as pin
import pytest
from helpers import EPS, ContactEvaluator, assert_fd, fd_dq, random_state, sphere_urdf

import contactdiff as cd
from contactdiff.dynamics.constraint_dynamics import eligible
from contactdiff.dynamics.mode import ModeDynamics
from contactdiff.errors import InvalidInputError
from contactdiff.model.contacts import Contact
from contactdiff.model.kinematics import Kinematics
from contactdiff.model.round_feet import foot_spheres, round_feet
from contactdiff.scenes.scene_file import load_scene

MASS, RADIUS, G = 2.0, 0.1, 9.81
INERTIA = 0.4 * MASS * RADIUS**2  # solid sphere
ALPHA = 0.3  # incline (rad)
NORMAL = np.array([math.sin(ALPHA), 0.0, math.cos(ALPHA)])  # the incline's normal
DOWNHILL = np.array([math.cos(ALPHA), 0.0, -math.sin(ALPHA)])  # unit, n · s = 0, g · s = g sin α > 0
TILTED = tuple(np.array([0.6, -0.3, 1.0]) / np.linalg.norm([0.6, -0.3, 1.0]))

BALL_URDF = sphere_urdf(MASS, INERTIA)


@pytest.fixture(scope="module")
def ball(tmp_path_factory):
    """A free-flyer solid sphere whose frame ``ball`` is its centre."""
    path = tmp_path_factory.mktemp("round") / "ball3d.urdf"
    path.write_text(BALL_URDF)
    return cd.load_robot(str(path), floating_base=True)


# -- geometry ----------------------------------------------------------------------------
CASES = [  # (robot, contact, tangent rows kept)
    ("ball", Contact("ball", radius=RADIUS, friction="stick"), 2),
    ("ball", Contact("ball", normal=TILTED, radius=RADIUS, offset=0.2, friction="stick"), 2),
    ("ball", Contact("ball", normal=TILTED, radius=0.0, friction="stick"), 2),
    ("ball", Contact("ball", radius=RADIUS), 0),
    ("solo12", Contact("FR_FOOT", normal=TILTED, radius=0.02, offset=0.01, friction="stick"), 2),
    ("solo12", Contact("FR_FOOT", normal=TILTED, friction="stick"), 2),
    ("planar_trot_rigid", Contact("front_foot", radius=0.05, friction="stick"), 1),
    ("planar_trot_rigid", Contact("front_foot", normal=(-0.4, 0.0, 1.0), radius=0.05, friction="stick"), 1),
    # a ball object against a finger on a slide: the finger's point moves too
    ("finger+ball", Contact("ball", against="tip", normal=TILTED, radius=RADIUS, offset=0.01, friction="stick"), 2),
]
IDS = [f"{r}-{c.frame}-r{c.radius}-n{i}" for i, (r, c, _) in enumerate(CASES)]


def _case(ball, i, seed):
    name, spec, tangents = CASES[i]
    robot = {"ball": lambda: ball, "finger+ball": _finger_and_ball}.get(name, lambda: cd.load_robot(name))()
    rng = np.random.default_rng(seed)
    if robot.model.nq == robot.model.nv:  # planar: pitch well away from 0
        q = robot.q_ref + rng.uniform(-0.6, 0.6, robot.nq)
        v = rng.standard_normal(robot.nv)
    else:
        q, v = random_state(robot.model, robot.q_ref, rng, 0.3, 1.0)
        if name == "ball":
            q[:3] = rng.standard_normal(3)
            v *= 2.0  # spin of order 1 rad/s and more
    return robot, spec.bind(robot), tangents, q, v


def _finger_and_ball():
    """The project's finger on its slide and a free ball (a sphere object, I = 2/5 m r²)."""
    return cd.add_objects(
        cd.load_robot("finger"), [cd.SceneObject("ball", "sphere", MASS, radius=RADIUS, position=(RADIUS, 0.0, 0.03))]
    )


class Evaluator(ContactEvaluator):
    """`ContactEvaluator` with the frame's placement."""

    def placement(self, q):
        data = self.robot.new_data()
        pin.framesForwardKinematics(self.robot.model, data, q)
        return data.oMf[self.c.fid]

    def against_point(self, q):
        """The other frame's origin (world, m); zero for a ground contact."""
        if self.c.against_fid is None:
            return np.zeros(3)
        data = self.robot.new_data()
        pin.framesForwardKinematics(self.robot.model, data, q)
        return data.oMf[self.c.against_fid].translation


def test_ball_gap_closed_form(ball):
    """The gap is the height of the sphere's lowest point: z - r on flat ground and
    n · p - r - offset on a tilted plane (p = the free-flyer's translation q[:3])."""
    flat = Contact("ball", radius=RADIUS).bind(ball)
    tilted = Contact("ball", normal=TILTED, radius=RADIUS, offset=0.2).bind(ball)
    kin = Kinematics(ball.model)
    rng = np.random.default_rng(0)
    for _ in range(5):
        q, v = random_state(ball.model, ball.q_ref, rng, 1.0, 1.0)
        q[:3] = rng.standard_normal(3)
        kin.update(q, v)
        # the frame is the root joint's origin: p = q[:3] exactly; one rounding per operation
        assert flat.gap(kin) == pytest.approx(q[2] - RADIUS, abs=1e-15)
        assert tilted.gap(kin) == pytest.approx(np.dot(TILTED, q[:3]) - RADIUS - 0.2, abs=4e-16 * 4)
        # the normal row has no rotation term: the gap rate is n · v_p
        assert flat.gap_rate(kin) == pytest.approx(float(flat.rows(kin)[0] @ v), abs=1e-14)


@pytest.mark.parametrize("i", range(len(CASES)), ids=IDS)
def test_round_rows_are_the_rolling_point_velocity(ball, i):
    """Row d is the gradient of d · X(q), X the body-fixed point that sits at the
    sphere's bottom p - r n at the base state; rows 0 is the gap's gradient; the
    rows keep the tangents the point can move along."""
    robot, c, tangents, q, v = _case(ball, i, seed=3)
    ev = Evaluator(robot, c)
    A = ev.rows(q)
    assert A.shape == (1 + tangents, robot.nv)
    n, r = np.array(c.spec.normal), c.spec.radius
    base = ev.placement(q)
    local = base.rotation.T @ (-r * n)  # the bottom point in the frame's own axes

    def material(qq, d):  # less the other frame's point, for a contact against one
        m = ev.placement(qq)
        return d @ (m.translation + m.rotation @ local - ev.against_point(qq))

    assert_fd("round rows[0] vs d gap/dq", A[0], fd_dq(ev.gap, robot.model, q), value=ev.gap(q))
    for k, d in enumerate(c.directions):
        assert_fd(
            "round rows vs d(d · X)/dq",
            A[k],
            fd_dq(lambda qq, d=d: material(qq, d), robot.model, q),
            value=material(q, d),
        )
    # and A v = D (v_p + ω × (-r n)) from Pinocchio's frame velocity (a second reference)
    data = robot.new_data()
    pin.forwardKinematics(robot.model, data, q, v)
    pin.updateFramePlacements(robot.model, data)
    twist = pin.getFrameVelocity(robot.model, data, c.fid, pin.LOCAL_WORLD_ALIGNED)
    expected = c.directions @ (twist.linear + np.cross(twist.angular, -r * n))
    if c.against_fid is not None:
        expected -= (
            c.directions @ pin.getFrameVelocity(robot.model, data, c.against_fid, pin.LOCAL_WORLD_ALIGNED).linear
        )
    # one product of O(1) entries over nv terms: round-off 1e-15 relative
    np.testing.assert_allclose(A @ v, expected, rtol=0, atol=1e-13 * max(1.0, np.abs(expected).max()))


@pytest.mark.parametrize("i", range(len(CASES)), ids=IDS)
def test_round_drift(ball, i):
    """With ddq = 0 along q(t) = q ⊕ t v: d/dt [A(q(t)) v] = drift."""
    robot, c, _, q, v = _case(ball, i, seed=5)
    ev = Evaluator(robot, c)
    h = EPS
    rate = (ev.rows(pin.integrate(robot.model, q, h * v)) @ v - ev.rows(pin.integrate(robot.model, q, -h * v)) @ v) / (
        2 * h
    )
    assert_fd("round drift vs d/dt(A v) along q+tv", ev.drift(q, v), rate, value=ev.rows(q) @ v)


@pytest.mark.parametrize("seed", [7, 8])
@pytest.mark.parametrize("i", range(len(CASES)), ids=IDS)
def test_round_derivatives(ball, i, seed):
    robot, c, _, q, v = _case(ball, i, seed)
    ev = Evaluator(robot, c)
    nv = robot.nv
    rng = np.random.default_rng(seed + 100)
    x = rng.standard_normal(nv)
    lam = rng.standard_normal(c.n_rows)
    ev.assert_derivatives("round", q, v, x, lam)


def test_sliding_view_of_a_round_contact_is_the_normal_row(ball):
    """Sliding keeps the normal row only; it has no rotation term."""
    c = Contact("ball", normal=TILTED, radius=RADIUS, friction="stick").bind(ball)
    point = Contact("ball", normal=TILTED, friction="stick").bind(ball)
    kin = Kinematics(ball.model)
    q, v = random_state(ball.model, ball.q_ref, np.random.default_rng(1))
    kin.update(q, v)
    view = c.sliding_view()
    assert view.n_rows == 1 and view.rolling is None
    assert np.array_equal(view.rows(kin), point.sliding_view().rows(kin))
    assert np.array_equal(view.drift(kin), point.sliding_view().drift(kin))


# -- where a round contact is solved ---------------------------------------------------------
def test_round_contacts_are_not_pinocchio_eligible(ball):
    solo = cd.load_robot("solo12")
    feet = [Contact(f, friction="stick").bind(solo) for f in solo.feet]
    assert eligible(feet)
    assert eligible([Contact(f, friction="stick", radius=0.0).bind(solo) for f in solo.feet])
    round_one = feet[:3] + [Contact(solo.feet[3], friction="stick", radius=0.02).bind(solo)]
    assert not eligible(round_one)
    assert not eligible([Contact("ball", friction="stick", radius=RADIUS).bind(ball)])


# -- rolling down an incline -------------------------------------------------------------------
def _incline_scene(ball, q0=None, v0=None, restitution=0.0):
    q = ball.q_ref.copy()
    q[:3] = RADIUS * NORMAL  # touching the plane n · p = 0
    scene = cd.Scene(
        ball,
        [Contact("ball", normal=tuple(NORMAL), radius=RADIUS, friction="stick", restitution=restitution)],
        gravity=[0.0, 0.0, -G],
        q0=q if q0 is None else q0,
    )
    return scene if v0 is None else scene.with_state(None, v0)


def test_ball_rolls_down_an_incline(ball):
    """m a = m g sin α - F, I ω̇ = F r, ω̇ = a / r (no slip), I = 2/5 m r²: a = 5/7 g sin α,
    F = 2/7 m g sin α, N = m g cos α. From rest: p = p0 + a t²/2 s, v = a t s,
    ω = (v / r) (n × s) = (v / r) ŷ, R = R_y(|p - p0| / r)."""
    scene = _incline_scene(ball)
    T = 1.0
    traj = cd.simulate(scene, T, rtol=1e-10, atol=1e-12, dense=True)
    assert traj.modes == [("ball",)] and not traj.events
    a = 5.0 / 7.0 * G * math.sin(ALPHA)
    kin = Kinematics(ball.model)
    contact = scene.contacts[0]
    worst = dict(position=0.0, velocity=0.0, spin=0.0, rotation=0.0, slip=0.0)
    for t in np.linspace(0.0, T, 11):
        q, v = traj.at(float(t)) if t < T else (traj.q, traj.v)
        R = pin.Quaternion(q[3:7]).matrix()
        speed, travel = a * t, 0.5 * a * t * t
        worst["position"] = max(worst["position"], np.abs(q[:3] - (RADIUS * NORMAL + travel * DOWNHILL)).max())
        worst["velocity"] = max(worst["velocity"], np.abs(R @ v[:3] - speed * DOWNHILL).max())  # v[:3] local
        worst["spin"] = max(worst["spin"], np.abs(R @ v[3:] - np.array([0.0, speed / RADIUS, 0.0])).max())
        worst["rotation"] = max(worst["rotation"], np.abs(R - pin.exp3(np.array([0.0, travel / RADIUS, 0.0]))).max())
        kin.update(q, v)
        worst["slip"] = max(worst["slip"], np.abs(contact.rows(kin) @ v).max())
    # scales at T: travel 1.5 m, speed 3.0 m/s, spin 30 rad/s. DOP853 at rtol 1e-10 keeps each
    # step's local error below 1e-10 relative; ~50 steps (measured: 43) accumulate at most
    # ~5e-9 relative, so 1e-8 relative to each scale; measured errors ~4e-11 relative.
    # The contact point's velocity (A v, held at the acceleration level, projected back
    # when it drifts past the projection tolerance) errs like the velocity: 1e-8 x 3 m/s
    # (measured 1.6e-10 m/s on the dense output between steps).
    assert worst["position"] < 1e-8 * 1.5, worst
    assert worst["velocity"] < 1e-8 * 3.0, worst
    assert worst["spin"] < 1e-8 * 30.0, worst
    assert worst["rotation"] < 1e-8, worst
    assert worst["slip"] < 1e-8 * 3.0, worst
    # the forces of the rolling mode: normal m g cos α, friction 2/7 m g sin α up the slope (t1 = s)
    sol = ModeDynamics(scene).solve(traj.q, traj.v, T, [0])
    np.testing.assert_allclose(contact.directions[1], DOWNHILL, atol=1e-15)
    expected = [MASS * G * math.cos(ALPHA), -2.0 / 7.0 * MASS * G * math.sin(ALPHA), 0.0]
    # one KKT solve with a 3x3 Delassus matrix of condition ~4 at 30 rad/s of spin: 1e-12 relative
    np.testing.assert_allclose(sol.forces, expected, rtol=0, atol=1e-12 * MASS * G)


def test_point_contact_slides_where_the_ball_rolls(ball):
    """Contrast: with r = 0 the sticking point holds the centre still (no rolling)."""
    scene = _incline_scene(ball)
    point = cd.Scene(
        ball,
        [dataclasses.replace(scene.contact_specs[0], radius=0.0, offset=RADIUS)],
        gravity=[0.0, 0.0, -G],
        q0=scene.q0,
    )
    traj = cd.simulate(point, 0.5, rtol=1e-10, atol=1e-12)
    assert np.abs(traj.q[:3] - scene.q0[:3]).max() < 1e-12 and np.abs(traj.v).max() < 1e-12


# -- the flow Jacobian through a touchdown ------------------------------------------------------
JAC_EPS = 1e-5
JAC_RTOL = 1e-6  # docs/design.md §7: flow Jacobians vs FD of the simulator
SIM_TOL = dict(rtol=1e-12, atol=1e-13)


def test_flow_jacobian_of_a_spinning_ball_landing_on_an_incline(ball):
    """Dropped 2 cm above the incline with a spin: touchdown (plastic sticking impact),
    then rolling. The flow Jacobian against central differences of the simulator
    (q0 perturbed on the manifold, v0 in R^6; ε = 1e-5 as the state study)."""
    q0 = ball.q_ref.copy()
    q0[:3] = (RADIUS + 0.02) * NORMAL
    q0[3:7] = pin.Quaternion(pin.exp3(np.array([0.2, -0.1, 0.3]))).coeffs()
    v0 = np.array([0.3, -0.2, 0.1, 1.5, -2.0, 4.0])  # local linear and angular velocity
    scene = _incline_scene(ball, q0, v0)
    T = 0.15
    traj = cd.simulate(scene, T, jacobian=True, **SIM_TOL)
    assert [(e.kind, e.contacts) for e in traj.events] == [("touchdown", ("ball",))]
    assert traj.differentiable, traj.notes
    model, nv = ball.model, ball.nv
    cols = []
    for k in range(2 * nv):
        e = np.zeros(nv)
        e[k % nv] = JAC_EPS
        runs = []
        for sign in (1.0, -1.0):
            q, v = (pin.integrate(model, q0, sign * e), v0) if k < nv else (q0, v0 + sign * e)
            run = cd.simulate(scene.with_state(q, v), T, **SIM_TOL)
            assert [(x.kind, x.contacts) for x in run.events] == [(x.kind, x.contacts) for x in traj.events]
            runs.append(run)
        p, m = runs
        cols.append(np.concatenate([pin.difference(model, m.q, p.q), p.v - m.v]) / (2 * JAC_EPS))
    # central differences at ε = 1e-5 of runs at rtol 1e-12: truncation ~ε² |x'''| ~ 1e-10 and
    # integration noise ~1e-12 / ε = 1e-7 relative, under the study's 1e-6
    assert_fd("round flow jacobian (ball landing on an incline)", traj.jacobian, np.array(cols).T, rtol=JAC_RTOL)
    # after the plastic impact the ball rolls: its contact point does not move
    kin = Kinematics(model)
    kin.update(traj.q, traj.v)
    assert np.abs(scene.contacts[0].rows(kin) @ traj.v).max() < 1e-12


# -- r = 0 unchanged --------------------------------------------------------------------------
def test_explicit_zero_radius_is_bit_identical():
    """The tilted solo12 drop (the state study's scene) for 0.1 s with every contact given
    radius=0.0 explicitly: the same floats, Jacobian included."""
    from scipy.spatial.transform import Rotation

    scene = cd.load_scene("solo12_drop")
    q = scene.q0.copy()
    q[3:7] = Rotation.from_euler("xyz", [0.03, 0.05, 0.0]).as_quat()
    q[2] += 0.01
    scene = scene.with_state(q)
    explicit = cd.Scene(
        scene.robot,
        [dataclasses.replace(c, radius=0.0) for c in scene.contact_specs],
        scene.effort_specs,
        None,
        scene.q0,
        scene.v0,
    )
    assert all(c.rolling is None for c in explicit.contacts)
    a = cd.simulate(scene, 0.104, jacobian=True)
    b = cd.simulate(explicit, 0.104, jacobian=True)
    assert [e.t for e in a.events] == [e.t for e in b.events] and a.events
    assert np.array_equal(a.q, b.q) and np.array_equal(a.v, b.v) and np.array_equal(a.jacobian, b.jacobian)


# -- input checks and the scene file --------------------------------------------------------
@pytest.mark.parametrize(
    "value,message",
    [
        (-0.01, "radius must be >= 0, got -0.01"),
        (float("nan"), "radius must be finite, got nan"),
        (float("inf"), "radius must be finite, got inf"),
        ("big", "radius must be a number, got 'big'"),
    ],
)
def test_radius_validation(value, message):
    with pytest.raises(InvalidInputError, match=message):
        Contact("ball", radius=value)


def test_a_ball_rolls_down_a_sticking_vertical_face():
    """A ball held by a sticking round contact against the finger's vertical face (normal
    x, no ground) rolls down it as down an incline of 90°: a = 5/7 g, the friction
    (2/7) m g holds it up, the normal force is 0, and the finger, pushed by nothing
    along its slide, does not move."""
    robot = _finger_and_ball()
    face = Contact("ball", against="tip", normal=(1.0, 0.0, 0.0), offset=0.0, radius=RADIUS, friction="stick")
    scene = cd.Scene(robot, [face], gravity=[0.0, 0.0, -9.81])  # the ball's centre r from the tip: touching
    sol = cd.ModeDynamics(scene).solve(scene.q0, scene.v0, 0.0, (0,))
    ball_v = robot.model.joints[robot.joint_id("ball")].idx_v
    # sums of a few O(g) products: round-off ~1e-15 g
    np.testing.assert_allclose(sol.ddq[ball_v : ball_v + 3], [0.0, 0.0, -5 / 7 * 9.81], atol=1e-12)
    # the touching point c = p - r x stays: v + ω × (-r x) = 0, so falling (-z) turns about +y: α_y = a / r
    assert sol.ddq[ball_v + 4] == pytest.approx(5 / 7 * 9.81 / RADIUS, abs=1e-10)
    assert sol.ddq[robot.scalar_joint("slide")[1]] == pytest.approx(0.0, abs=1e-12)
    normal, *tangential = sol.forces
    assert normal == pytest.approx(0.0, abs=1e-12)
    vertical = face.bind(robot).directions[1:, 2] @ tangential
    assert vertical == pytest.approx(2 / 7 * MASS * 9.81, abs=1e-12)


SCENE = """robot = "solo12"
floating_base = true
gravity = [0.0, 0.0, -9.81]

[[contact]]
frame = "FL_FOOT"
offset = 0.0
friction = "stick"
{extra}

[initial]
q = {{ root_joint = [0.0, 0.0, 0.4, 0.0, 0.0, 0.0, 1.0] }}
"""


def test_scene_file_radius(tmp_path):
    path = tmp_path / "round.toml"
    path.write_text(SCENE.format(extra="radius = 0.02"))
    scene = load_scene(path)
    assert scene.contact_specs[0].radius == 0.02 and scene.contacts[0].radius == 0.02
    path.write_text(SCENE.format(extra=""))
    assert load_scene(path).contact_specs[0].radius == 0.0
    for bad, message in (
        ("radius = -0.02", "radius must be >= 0, got -0.02"),
        ("radius = nan", "radius must be finite, got nan"),
        ('radius = "2 cm"', "radius must be a number, got '2 cm'"),
    ):
        path.write_text(SCENE.format(extra=bad))
        with pytest.raises(InvalidInputError, match=message):
            load_scene(path)


SPHERE_SCENE = """gravity = [0.0, 0.0, -9.81]
[[object]]
name = "ball"
shape = "sphere"
radius = 0.03
mass = 0.2
position = [0.0, 0.0, 0.1]
[[contact]]
frame = "ball"
{extra}
"""


def test_a_sphere_object_lands_on_its_surface_without_a_radius_key(tmp_path):
    """A ground contact on a sphere object's centre frame, written without ``radius``, is a
    round contact of the sphere's radius (docs/scene-files.md). Dropped at rest from centre
    height z0 = 0.1 m (g = 9.81 m/s², r = 0.03 m), the gap is z - r = z0 - g t²/2 - r, so
    it lands at t = sqrt(2 (z0 - r) / g) = 0.11946 s (at its centre, t = sqrt(2 z0 / g) =
    0.14278 s, as it did), and after the plastic impact (e = 0) rests at z = r.
    Tolerances: free fall is quadratic in t, which DOP853's dense output reproduces to
    round-off, and the event is located to a few ulps of t (`events.locate`): 1e-12 s;
    the resting contact holds the gap at 0 to round-off of O(0.1) m positions: 1e-12 m."""
    g, z0, r = 9.81, 0.1, 0.03
    path = tmp_path / "ball.toml"
    path.write_text(SPHERE_SCENE.format(extra=""))
    scene = load_scene(path)
    assert scene.contact_specs[0].radius == r and scene.contacts[0].radius == r
    traj = cd.simulate(scene, 0.5)
    assert [e.kind for e in traj.events] == ["touchdown"]
    assert traj.events[0].t == pytest.approx(math.sqrt(2.0 * (z0 - r) / g), abs=1e-12)
    assert traj.q[2] == pytest.approx(r, abs=1e-12)
    # an explicit radius wins: 0 is a point contact at the centre, which lands at sqrt(2 z0 / g)
    path.write_text(SPHERE_SCENE.format(extra="radius = 0.0"))
    traj = cd.simulate(load_scene(path), 0.5)
    assert traj.events[0].t == pytest.approx(math.sqrt(2.0 * z0 / g), abs=1e-12)


def test_a_contact_against_a_frame_keeps_a_point_by_default():
    """Only a ground contact takes the sphere's radius by default: a contact between two
    balls (Newton's cradle) measures its gap between the centres, its offset holding the
    two radii (0.04 m), so the balls that touch at the start have gap 0, not -0.02 m."""
    scene = load_scene("newtons_cradle")
    assert [c.radius for c in scene.contact_specs] == [0.0, 0.0]
    np.testing.assert_allclose(scene.gaps(scene.q0), [0.1, 0.0], rtol=0, atol=1e-15)


# -- foot radii from the collision geometry ------------------------------------------------------
def test_foot_spheres_of_the_quadrupeds():
    """The URDFs' foot collision spheres: a1 and hyq put a <sphere radius="0.02"/> and
    <sphere radius="0.02175"/> at the foot frame; anymal a <sphere radius="0.031"/> on
    the foot link at 0.02325 m along the frame's z; solo12's feet are meshes."""
    a1 = foot_spheres(cd.load_robot("a1"))
    assert set(a1) == {"FL_foot", "FR_foot", "RL_foot", "RR_foot"}
    assert all(s.radius == 0.02 and s.centred and s.centre == (0.0, 0.0, 0.0) for s in a1.values())
    hyq = foot_spheres(cd.load_robot("hyq"))
    assert all(s.radius == 0.02175 and s.centred for s in hyq.values()) and len(hyq) == 4
    anymal = foot_spheres(cd.load_robot("anymal"))
    for s in anymal.values():
        assert s.radius == 0.031 and not s.centred
        np.testing.assert_allclose(s.centre, [0.0, 0.0, 0.02325], atol=1e-12)  # URDF decimals, summed
    solo = cd.load_robot("solo12")
    assert foot_spheres(solo) == dict.fromkeys(solo.feet)
    with pytest.raises(InvalidInputError, match="FL_FOOT has no collision sphere"):
        round_feet(cd.Scene.from_robot(solo))


def test_round_feet_keep_the_gaps_and_roll():
    """round_feet gives each foot contact its sphere's radius and lowers its offset by it:
    every gap is unchanged (to one rounding of offset - r + r), the tangent rows gain the
    rolling term, and the mode leaves Pinocchio's path for the Python KKT one."""
    robot = cd.load_robot("a1")
    point = cd.Scene.from_robot(robot)
    rounded = round_feet(point)
    assert [c.radius for c in rounded.contact_specs] == [0.02] * 4
    assert [c.offset for c in rounded.contact_specs] == [c.offset - 0.02 for c in point.contact_specs]
    with pytest.raises(InvalidInputError, match="already round"):  # twice would sink the feet by r
        round_feet(rounded)
    rng = np.random.default_rng(2)
    kin = Kinematics(robot.model)
    for q in (point.q0, robot.integrate(point.q0, 0.2 * rng.standard_normal(robot.nv))):
        kin.update(q, np.zeros(robot.nv))
        for a, b in zip(point.contacts, rounded.contacts):
            assert b.gap(kin) == pytest.approx(a.gap(kin), abs=1e-16)
            assert np.array_equal(a.rows(kin)[0], b.rows(kin)[0])
            assert np.abs(a.rows(kin)[1:] - b.rows(kin)[1:]).max() > 1e-3  # r J_ω: 0.02 m × O(1)
    assert eligible(point.contacts) and not eligible(rounded.contacts)
    # a short drop onto the round feet: they land, stick and hold their rolling points
    q = rounded.q0.copy()
    q[2] += 0.005
    traj = cd.simulate(rounded.with_state(q), 0.06)
    assert [(e.kind, e.contacts) for e in traj.events] == [("touchdown", tuple(robot.feet))]
    assert traj.modes[-1] == tuple(robot.feet)
    kin.update(traj.q, traj.v)
    for c in rounded.contacts:  # default tolerances (rtol 1e-8) on velocities of O(0.1) m/s
        assert np.abs(c.rows(kin) @ traj.v).max() < 1e-7


# -- spheres off the foot frame: a frame at the centre ------------------------------------------
def _sphere_centres(robot, q):
    """World centres of the feet's collision spheres at ``q``, from Pinocchio's collision model
    (the URDF's <collision><sphere> on each foot link), independently of foot_spheres."""
    from pathlib import Path

    model = robot.model
    geom = pin.buildGeomFromUrdf(
        model, robot.urdf, pin.GeometryType.COLLISION, package_dirs=[str(p) for p in Path(robot.urdf).parents]
    )
    data, geom_data = model.createData(), geom.createData()
    pin.updateGeometryPlacements(model, data, geom, geom_data, q)
    centres = {}
    for foot in robot.feet:
        fid = model.getFrameId(foot)
        found = [
            k
            for k, g in enumerate(geom.geometryObjects)
            if g.parentFrame == fid and isinstance(g.geometry, pin.hppfcl.Sphere)
        ]
        assert len(found) == 1, (foot, found)
        centres[foot] = geom_data.oMg[found[0]].translation.copy()
    return centres


@pytest.fixture(scope="module")
def anymal_round():
    point = cd.Scene.from_robot(cd.load_robot("anymal"))
    frames_before = [f.name for f in point.robot.model.frames]
    return point, round_feet(point), frames_before


def test_anymal_feet_get_a_frame_at_the_sphere_centre(anymal_round):
    """Each foot's contact moves to an OP_FRAME <foot>_sphere on the foot's joint, at the
    sphere's centre (Pinocchio's collision placements, at the reference pose and at a
    random one), with the sphere's radius and the contact's own name; the given scene
    and its robot are untouched."""
    point, rounded, frames_before = anymal_round
    robot, new = point.robot, rounded.robot
    assert new is not robot and [f.name for f in robot.model.frames] == frames_before
    assert [f.name for f in new.model.frames] == frames_before + [f + "_sphere" for f in sorted(robot.feet)]
    assert new.feet == robot.feet and np.array_equal(new.q_ref, robot.q_ref)
    assert rounded.contact_names == point.contact_names == list(robot.feet)
    with pytest.raises(InvalidInputError, match="no ground contact at a foot .* already round"):
        round_feet(rounded)
    # parameters name the contact, not its frame: the same names, and they still apply
    contact_parameters = [n for n in point.parameter_names() if n.startswith("contact:")]
    assert contact_parameters and contact_parameters == [
        n for n in rounded.parameter_names() if n.startswith("contact:")
    ]
    lowered = rounded.with_parameters({"contact:LF_FOOT:offset": rounded.contact_specs[0].offset - 0.001})
    assert lowered.contact_specs[0].frame == "LF_FOOT_sphere"
    assert lowered.gaps(robot.q_ref)[0] == pytest.approx(0.001, abs=1e-12)
    assert [c.frame for c in rounded.contact_specs] == [f + "_sphere" for f in robot.feet]
    assert [c.radius for c in rounded.contact_specs] == [0.031] * 4
    for foot in robot.feet:
        frame = new.model.frames[new.model.getFrameId(foot + "_sphere")]
        assert frame.type == pin.FrameType.OP_FRAME
        assert frame.parentJoint == robot.model.frames[robot.model.getFrameId(foot)].parentJoint
    rng = np.random.default_rng(3)
    data = new.model.createData()
    for q in (robot.q_ref, robot.integrate(robot.q_ref, 0.3 * rng.standard_normal(robot.nv))):
        centres = _sphere_centres(robot, q)
        pin.framesForwardKinematics(new.model, data, q)
        for foot, centre in centres.items():
            # two compositions of the same placements, O(1 m) coordinates: round-off 1e-15 m
            np.testing.assert_allclose(
                data.oMf[new.model.getFrameId(foot + "_sphere")].translation, centre, rtol=0, atol=1e-14
            )


def test_anymal_round_feet_keep_the_gaps_at_the_reference_pose(anymal_round):
    """At the reference pose every gap equals the point-foot scene's (to 1e-12 m); the
    offset is the plane's height along n of the sphere's bottom there. At another pose
    the gap is the sphere's: n · c - r - offset with c the collision model's centre."""
    point, rounded, _ = anymal_round
    robot = point.robot
    np.testing.assert_allclose(rounded.gaps(robot.q_ref), point.gaps(robot.q_ref), rtol=0, atol=1e-12)
    np.testing.assert_allclose(rounded.gaps(rounded.q0), point.gaps(point.q0), rtol=0, atol=1e-12)
    centres = _sphere_centres(robot, robot.q_ref)
    for c in rounded.contact_specs:  # the bottom of the sphere at the reference pose
        assert c.offset == pytest.approx(np.array(c.normal) @ centres[c.name] - 0.031, abs=1e-12)
    q = robot.integrate(robot.q_ref, 0.3 * np.random.default_rng(4).standard_normal(robot.nv))
    centres = _sphere_centres(robot, q)
    expected = [np.array(c.normal) @ centres[c.name] - c.radius - c.offset for c in rounded.contact_specs]
    np.testing.assert_allclose(rounded.gaps(q), expected, rtol=0, atol=1e-12)
    assert np.abs(rounded.gaps(q) - point.gaps(q)).max() > 1e-4  # the feet tilt: the gaps follow the spheres


def test_anymal_drops_onto_round_feet(anymal_round):
    """Dropped 5 mm, ANYmal lands on its four round feet at the point feet's touchdown time
    (the gaps agree at every pose of the fall: the joints do not move in free fall), and
    the feet stick: their rolling points hold still to the integrator's tolerance."""
    point, rounded, _ = anymal_round
    runs = []
    for scene in (point, rounded):
        q = scene.q0.copy()
        q[2] += 0.005
        runs.append(cd.simulate(scene.with_state(q), 0.15))
    traj = runs[1]
    feet = tuple(rounded.contact_names)
    assert [(e.kind, e.contacts) for e in traj.events] == [("touchdown", feet)]
    # touchdowns located by root finding on gaps equal to round-off (measured: the same float)
    assert abs(traj.events[0].t - runs[0].events[0].t) < 1e-9
    assert traj.modes[-1] == feet
    kin = Kinematics(rounded.robot.model)
    kin.update(traj.q, traj.v)
    for c in rounded.contacts:  # default tolerances (rtol 1e-8) on velocities of O(1) m/s (measured 3e-10)
        assert np.abs(c.rows(kin) @ traj.v).max() < 1e-7
    assert np.abs(rounded.gaps(traj.q)).max() < 1e-9  # measured 1.4e-11 m


def test_centred_spheres_are_unchanged():
    """a1's spheres are centred on its feet: the scene keeps its robot and frames, and its
    gaps are bit-identical to the contacts rounded in place (radius r, offset - r)."""
    robot = cd.load_robot("a1")
    point = cd.Scene.from_robot(robot)
    frames = [f.name for f in robot.model.frames]
    rounded = round_feet(point)
    assert rounded.robot is robot and [f.name for f in robot.model.frames] == frames
    assert [c.frame for c in rounded.contact_specs] == list(robot.feet)
    by_hand = cd.Scene(
        robot, [dataclasses.replace(c, radius=0.02, offset=c.offset - 0.02) for c in point.contact_specs], q0=point.q0
    )
    rng = np.random.default_rng(5)
    for q in (point.q0, robot.integrate(point.q0, 0.3 * rng.standard_normal(robot.nv))):
        assert np.array_equal(rounded.gaps(q), by_hand.gaps(q))


def test_one_foot_off_centre_moves_that_contact_only():
    """Given spheres: a1 with one sphere moved 1 cm along its foot's x. Only that contact
    moves (to FL_foot_sphere); the others stay, bit for bit; all gaps at the reference pose
    are the point scene's."""
    from contactdiff.model.round_feet import FootSphere

    robot = cd.load_robot("a1")
    point = cd.Scene.from_robot(robot)
    spheres = foot_spheres(robot)
    spheres["FL_foot"] = FootSphere("FL_foot", 0.02, (0.01, 0.0, 0.0), "moved")
    rounded = round_feet(point, spheres)
    assert [c.frame for c in rounded.contact_specs] == ["FL_foot_sphere", "FR_foot", "RL_foot", "RR_foot"]
    assert rounded.robot.model.nframes == robot.model.nframes + 1
    np.testing.assert_allclose(rounded.gaps(robot.q_ref), point.gaps(robot.q_ref), rtol=0, atol=1e-12)
    same = round_feet(point)
    q = robot.integrate(robot.q_ref, 0.3 * np.random.default_rng(6).standard_normal(robot.nv))
    assert np.array_equal(rounded.gaps(q)[1:], same.gaps(q)[1:])
    data = rounded.robot.model.createData()
    pin.framesForwardKinematics(rounded.robot.model, data, q)
    foot = data.oMf[rounded.robot.model.getFrameId("FL_foot")]
    np.testing.assert_allclose(
        data.oMf[rounded.robot.model.getFrameId("FL_foot_sphere")].translation,
        foot.act(np.array([0.01, 0.0, 0.0])),
        rtol=0,
        atol=1e-14,
    )
