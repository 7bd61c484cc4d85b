"""Every analytic derivative against central finite differences on the manifold.

Perturbations: ``q ⊕ ε e_k = pin.integrate(model, q, ε e_k)`` and ``v + ε e_k`` with
ε = 1e-6; relative tolerance 1e-6 (see ``helpers`` for why). Models: the planar
paper models (vector-space configurations) and solo12 with a free-flyer at a
random tilted state ``q_ref ⊕ 0.3·N(0, I)``, where the tangent-space convention
matters (quaternion base, ``nq != nv``).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from helpers import EPS, ContactEvaluator, assert_fd, fd_dq, fd_dv, random_state, second_derivative_along

from contactdiff.dynamics.mode import ModeDynamics
from contactdiff.model.contacts import Contact
from contactdiff.model.efforts import JointSpring, Spring, UserEffort
from contactdiff.model.kinematics import Kinematics
from contactdiff.model.robot_files import load_robot
from contactdiff.model.scene import Scene
from contactdiff.scenes.scene_file import load_source

T = 0.37  # time passed to efforts (only user efforts use it)

TILTED = np.array([0.6, -0.3, 1.0]) / np.linalg.norm([0.6, -0.3, 1.0])


# -- states ------------------------------------------------------------------------------
def planar_state(robot, seed):
    """A random state of a planar model (pitch well away from 0)."""
    rng = np.random.default_rng(seed)
    q = robot.q_ref + rng.uniform(-0.6, 0.6, robot.nq)
    if "body_z" in robot.joint_names:
        q[robot.scalar_joint("body_z")[0]] += 1.0
    if "body_pitch" in robot.joint_names:
        q[robot.scalar_joint("body_pitch")[0]] = 0.45
    return q, rng.standard_normal(robot.nv)


def solo_state(robot, seed):
    return random_state(robot.model, robot.q_ref, np.random.default_rng(seed), 0.3, 1.0)


# -- contacts --------------------------------------------------------------------------
PLANAR_CONTACTS = {
    "planar_trot_soft": [
        Contact("rear_foot"),
        Contact("front_foot", friction="stick"),
        Contact("front_foot", normal=(1.0, 0.0, 1.0), against="front_hip", offset=0.3, name="knee_stop"),
        Contact("rear_hip", normal=(0.3, 0.0, 1.0), friction="stick", name="hip_tilted"),
    ],
    "two_limb": [Contact("left_foot"), Contact("left_foot", against="right_hip", name="vs_hip")],
    "ball": [Contact("ball", normal=(0.0, 0.0, -1.0), offset=-2.0, friction="stick", name="ceiling")],
    "planar_trot_rigid": [
        Contact("rear_foot"),
        Contact("front_foot", friction="stick"),
        Contact("front_foot", normal=(-0.4, 0.0, 1.0), friction="stick", name="slope"),
    ],
}
SOLO_CONTACTS = [
    Contact("FL_FOOT"),
    Contact("HR_FOOT", friction="stick", offset=0.02),
    Contact("FR_FOOT", normal=tuple(TILTED), friction="stick", name="slope"),
    Contact("FL_FOOT", normal=(0.2, 1.0, 0.1), against="HR_FOOT", offset=0.1, friction="stick", name="feet"),
    Contact("HL_FOOT", against="base_link", name="under_base"),
]

CONTACT_CASES = [(name, i) for name, cs in PLANAR_CONTACTS.items() for i in range(len(cs))] + [
    ("solo12", i) for i in range(len(SOLO_CONTACTS))
]


def _contact_case(name, i, seed=3):
    robot = load_robot(name)
    if name == "solo12":
        return robot, SOLO_CONTACTS[i].bind(robot), *solo_state(robot, seed)
    return robot, PLANAR_CONTACTS[name][i].bind(robot), *planar_state(robot, seed)


@pytest.mark.parametrize("name,i", CONTACT_CASES)
def test_contact_rows_and_gap(name, i):
    robot, c, q, v = _contact_case(name, i)
    ev = ContactEvaluator(robot, c)
    model = robot.model
    A = ev.rows(q)
    assert A.shape == (c.n_rows, robot.nv)
    assert c.n_rows == (1 if not c.sticking else {"solo12": 3, "ball": 1}.get(name, 2))
    # row 0 is the gap gradient
    assert_fd("contact rows[0] vs d gap/dq", A[0], fd_dq(ev.gap, model, q), value=ev.gap(q))
    # every row is d(direction · (p - p'))/dq: check the tangent rows too
    for r, d in enumerate(c.directions):

        def along(qq, d=d):
            kin = ev.at(qq)
            p = kin.position(c.fid) - (kin.position(c.against_fid) if c.against_fid is not None else 0)
            return d @ p

        assert_fd("contact rows vs d(d·p)/dq", A[r], fd_dq(along, model, q), value=along(q))


@pytest.mark.parametrize("name,i", CONTACT_CASES)
def test_contact_gap_rate(name, i):
    """The gap rate read from the forward pass (frame velocities, no Jacobian) is
    d/dt gap(q ⊕ t v) at t = 0, and row 0 of the rows times v to round-off."""
    robot, c, q, v = _contact_case(name, i)
    ev = ContactEvaluator(robot, c)
    rate = c.gap_rate(ev.at(q, v))
    along = fd_dq(lambda qq: ev.gap(qq), robot.model, q) @ v
    assert_fd("gap rate vs d gap(q + t v)/dt", rate, along, value=ev.gap(q))
    assert rate == pytest.approx(float(ev.rows(q)[0] @ v), rel=1e-12, abs=1e-12 * np.abs(v).max())


@pytest.mark.parametrize("name,i", CONTACT_CASES)
def test_contact_drift(name, i):
    """With ddq = 0 along q(t) = q ⊕ t v (constant tangent velocity v),
    d/dt [A(q(t)) v] = drift and d²/dt² gap(q(t)) = drift[0]."""
    robot, c, q, v = _contact_case(name, i)
    ev = ContactEvaluator(robot, c)
    model = robot.model
    drift = ev.drift(q, v)
    h = EPS
    rate = (ev.rows(pin.integrate(model, q, h * v)) @ v - ev.rows(pin.integrate(model, q, -h * v)) @ v) / (2 * h)
    assert_fd("contact drift vs d/dt(A v) along q+tv", drift, rate, value=ev.rows(q) @ v)
    second = second_derivative_along(ev.gap, model, q, v)
    scale = max(abs(drift[0]), np.linalg.norm(v) ** 2, 1.0)
    assert abs(second - drift[0]) < 1e-6 * scale, (second, drift[0])


@pytest.mark.parametrize("name,i", CONTACT_CASES)
def test_contact_derivatives(name, i):
    robot, c, q, v = _contact_case(name, i)
    ev = ContactEvaluator(robot, c)
    nv = robot.nv
    rng = np.random.default_rng(11)
    x = rng.standard_normal(nv)
    lam = rng.standard_normal(c.n_rows)

    d = ev.assert_derivatives("contact", q, v, x, lam)
    for name in ("rows_velocity_dq", "drift_dq", "drift_dv", "rows_times_dq"):
        assert d[name].shape == (c.n_rows, nv)
    assert d["rows_transpose_dq"].shape == (nv, nv)
    # d(A v)/dq is d(A x)/dq at x = v
    rows_v_dq = d["rows_velocity_dq"]
    assert np.allclose(rows_v_dq, d["rows_times_v_dq"], rtol=1e-9, atol=1e-9 * max(1, abs(rows_v_dq).max()))


def test_drift_is_not_the_spatial_acceleration():
    """Pitfall (notes §3): the drift must include ω × v. A rotating rigid trot has a
    centripetal foot acceleration -θ̇² r even at zero joint acceleration."""
    robot = load_robot("planar_trot_rigid")
    c = Contact("front_foot", friction="stick").bind(robot)
    kin = Kinematics(robot.model)
    theta, w = 0.3, 2.0
    q = np.array([0.0, 1.0, theta])
    v = np.array([0.0, 0.0, w])
    kin.update(q, v)
    # foot offset from the COM (x, z), see test_models: R(θ)(0.25, 0, -1/6)
    r = np.array([0.25 * np.cos(theta) + np.sin(theta) / 6, 0.25 * np.sin(theta) - np.cos(theta) / 6])
    centripetal = -w * w * r  # (x, z)
    assert np.allclose(c.drift(kin), [centripetal[1], centripetal[0]], atol=1e-13)


# -- efforts -----------------------------------------------------------------------------
def _solo_user_effort(robot, with_jacobian: bool):
    """tau = -K difference(q_ref, q) - D v + sin(t) b: a PD pull toward q_ref; jacobian
    (-K dDifference/dq1, -D) in closed form."""
    model, q_ref = robot.model, robot.q_ref
    rng = np.random.default_rng(5)
    K = np.diag(rng.uniform(1, 3, robot.nv))
    K[0, 3] = K[4, 1] = 0.7  # couple base translation and rotation
    D = np.diag(rng.uniform(0.1, 0.5, robot.nv))
    b = rng.standard_normal(robot.nv)

    def function(q, v, t):
        return -K @ pin.difference(model, q_ref, q) - D @ v + np.sin(t) * b

    def jacobian(q, v, t):
        return -K @ pin.dDifference(model, q_ref, q, pin.ARG1), -D

    return UserEffort(function, jacobian if with_jacobian else None, name="pd")


def _planar_user_effort(robot, with_jacobian: bool):
    """tau_i = -sin(q_i) q_{i+1} - v_i |v_i| + t; exact jacobian."""
    n = robot.nv

    def function(q, v, t):
        return -np.sin(q) * np.roll(q, -1) - v * np.abs(v) + t

    def jacobian(q, v, t):
        dq = -np.diag(np.cos(q) * np.roll(q, -1))
        dq[np.arange(n), (np.arange(n) + 1) % n] += -np.sin(q)
        return dq, -np.diag(2 * np.abs(v))

    return UserEffort(function, jacobian if with_jacobian else None, name="wobble")


EFFORT_CASES = {
    "soft spring (damped, oblique)": ("planar_trot_soft", lambda r: Spring("front_hip", "front_foot", 27.0, 0.8, 0.5)),
    "soft spring (rear, hip first)": ("planar_trot_soft", lambda r: Spring("rear_foot", "rear_hip", 5.0, 0.3, 0.2)),
    "ball spring (nv = 1)": ("ball", lambda r: Spring("universe", "ball", 3.0, 0.2, 0.4)),
    "two_limb spring": ("two_limb", lambda r: Spring("left_hip", "left_foot", 10.0, 0.4, 0.5)),
    "soft joint spring": ("planar_trot_soft", lambda r: JointSpring("body_pitch", 4.0, 0.2, 0.1)),
    "planar user effort + jacobian": ("planar_trot_soft", lambda r: _planar_user_effort(r, True)),
    "solo spring feet": ("solo12", lambda r: Spring("FL_FOOT", "HR_FOOT", 30.0, 1.5, 0.2)),
    "solo spring base-knee": ("solo12", lambda r: Spring("base_link", "FR_LOWER_LEG", 12.0, 0.7, 0.05)),
    "solo knee joint spring": ("solo12", lambda r: JointSpring("HL_KFE", 3.0, 0.05, 1.2)),
    "solo user effort + jacobian": ("solo12", lambda r: _solo_user_effort(r, True)),
}


@pytest.mark.parametrize("case", sorted(EFFORT_CASES))
def test_effort_derivatives(case):
    name, make = EFFORT_CASES[case]
    robot = load_robot(name)
    effort = make(robot).bind(robot)
    q, v = solo_state(robot, 8) if name == "solo12" else planar_state(robot, 8)
    kin = Kinematics(robot.model)

    def tau(qq, vv):
        kin.update(qq, vv)
        return effort.tau(kin, T).copy()

    tau0 = tau(q, v)
    kin.update(q, v, derivatives=True)
    dq, dv = effort.derivatives(kin, T)
    assert dq.shape == dv.shape == (robot.nv, robot.nv)
    category = "effort " + case.split(" (")[0].replace("soft ", "").replace("two_limb ", "")
    assert_fd(f"{category} dq", dq, fd_dq(lambda qq: tau(qq, v), robot.model, q), value=tau0)
    assert_fd(f"{category} dv", dv, fd_dv(lambda vv: tau(q, vv), v), value=tau0)


@pytest.mark.parametrize("name", ["planar_trot_rigid", "solo12"])
def test_user_effort_internal_fd_matches_closed_form(name):
    """Without a user jacobian, UserEffort differentiates by central FD on the manifold;
    compare with the closed-form jacobian of the same function."""
    robot = load_robot(name)
    make = _solo_user_effort if name == "solo12" else _planar_user_effort
    spec = make(robot, True)
    effort = make(robot, False).bind(robot)
    q, v = solo_state(robot, 9) if name == "solo12" else planar_state(robot, 9)
    kin = Kinematics(robot.model)
    kin.update(q, v, derivatives=True)
    dq, dv = effort.derivatives(kin, T)
    ref_dq, ref_dv = spec.jacobian(q, v, T)
    tau0 = spec.function(q, v, T)
    assert_fd("effort user effort (internal FD) dq vs closed form", dq, ref_dq, value=tau0)
    assert_fd("effort user effort (internal FD) dv vs closed form", dv, ref_dv, value=tau0)


def test_spring_tau_closed_form():
    """Spring force on the foot of the soft trot: -(k (l - L) + c l̇) u, u = (foot - hip)/l;
    the hip (body) gets the opposite force and its moment about the body centre."""
    scene = load_source("planar_trot_soft")
    robot = scene.robot
    k, c, L = 27.0, 0.8, 0.5
    spring = Spring("front_hip", "front_foot", k, c, L).bind(robot)
    theta = 0.4
    q = robot.q_ref.copy()
    vals = dict(body_x=0.1, body_z=1.0, body_pitch=theta, front_foot_x=0.5, front_foot_z=0.6)
    vdot = dict(body_x=0.2, body_z=-0.3, body_pitch=0.5, front_foot_x=-0.1, front_foot_z=0.4)
    v = np.zeros(robot.nv)
    for n, x in vals.items():
        q[robot.scalar_joint(n)[0]] = x
    for n, x in vdot.items():
        v[robot.scalar_joint(n)[1]] = x
    hip = np.array([0.1 + 0.25 * np.cos(theta), 1.0 + 0.25 * np.sin(theta)])
    hip_vel = np.array([0.2, -0.3]) + 0.5 * 0.25 * np.array([-np.sin(theta), np.cos(theta)])
    foot, foot_vel = np.array([0.5, 0.6]), np.array([-0.1, 0.4])
    d = foot - hip
    length = np.linalg.norm(d)
    u = d / length
    rate = u @ (foot_vel - hip_vel)
    f_foot = -(k * (length - L) + c * rate) * u
    r_hip = hip - np.array([0.1, 1.0])
    f_hip = -f_foot
    expected = np.zeros(robot.nv)
    for n, x in (
        ("front_foot_x", f_foot[0]),
        ("front_foot_z", f_foot[1]),
        ("body_x", f_hip[0]),
        ("body_z", f_hip[1]),
        ("body_pitch", -r_hip[1] * f_hip[0] + r_hip[0] * f_hip[1]),
    ):
        expected[robot.scalar_joint(n)[1]] = x
    kin = Kinematics(robot.model)
    kin.update(q, v)
    assert np.allclose(spring.tau(kin, 0.0), expected, atol=1e-13)


# -- mode dynamics -------------------------------------------------------------------------
def _soft_damped():
    robot = load_robot("planar_trot_soft")
    return Scene(
        robot,
        [Contact("rear_foot"), Contact("front_foot", friction="stick")],
        [
            Spring("rear_hip", "rear_foot", 27.0, 0.6, 0.5),
            Spring("front_hip", "front_foot", 27.0, 0.9, 0.5),
            JointSpring("body_pitch", 2.0, 0.3),
        ],
        gravity=[0, 0, -1],
    )


def _rigid_sticking():
    robot = load_robot("planar_trot_rigid")
    return Scene(
        robot, [Contact("rear_foot", friction="stick"), Contact("front_foot")], gravity=[0, 0, -1], q0={"body_z": 1.0}
    )


def _solo(friction):
    robot = load_robot("solo12")
    base = Scene.from_robot(robot, friction=friction)
    efforts = [Spring("FL_FOOT", "HR_FOOT", 30.0, 1.5, 0.2)]
    efforts += [JointSpring(j, 2.0, 0.05, 1.0) for j in ("FL_KFE", "FR_KFE", "HL_KFE", "HR_KFE")]
    efforts.append(_solo_user_effort(robot, True))
    return Scene(robot, base.contact_specs, efforts)


MODE_SCENES = {
    "soft": (lambda: load_source("planar_trot_soft"), [(), (0,), (1,), (0, 1)]),
    "soft damped, sticking front": (_soft_damped, [(1,), (0, 1)]),
    "two_limb": (lambda: load_source("two_limb"), [(), (1,), (0, 1)]),
    "ball (nv = 1)": (
        lambda: Scene(
            load_robot("ball"),
            [Contact("ball")],
            [Spring("universe", "ball", 3.0, 0.2, 0.4)],
            gravity=[0, 0, -1],
            q0=[1.0],
        ),
        [(), (0,)],
    ),
    "rigid": (lambda: load_source("planar_trot_rigid"), [(), (0,), (1,), (0, 1)]),
    "rigid sticking rear": (_rigid_sticking, [(0,), (0, 1)]),
    "solo sticking": (lambda: _solo("stick"), [(), (0,), (1, 2), (0, 1, 2, 3)]),
    "solo frictionless": (lambda: _solo("none"), [(2,), (0, 3), (0, 1, 2, 3)]),
    "solo sticking, armature 0.01": (lambda: _solo("stick").with_armature(0.01), [(), (0, 1, 2, 3)]),
}
MODE_CASES = [(name, mode) for name, (_, modes) in MODE_SCENES.items() for mode in modes]


@pytest.mark.parametrize("name,mode", MODE_CASES, ids=[f"{n}-{m}" for n, m in MODE_CASES])
def test_mode_dynamics_derivatives(name, mode):
    scene = MODE_SCENES[name][0]()
    dyn = ModeDynamics(scene)
    robot = scene.robot
    q, v = solo_state(robot, 21) if robot.floating_base else planar_state(robot, 21)
    sol, der = dyn.solve(q, v, T, mode, derivatives=True)
    n_rows = sum(scene.contacts[i].n_rows for i in mode)
    assert sol.forces.shape == (n_rows,) and der.forces_dq.shape == (n_rows, robot.nv)

    def ddq(qq, vv):
        return dyn.solve(qq, vv, T, mode).ddq.copy()

    def forces(qq, vv):
        return dyn.solve(qq, vv, T, mode).forces.copy()

    kind = "sticking" if any(scene.contacts[i].sticking for i in mode) else f"{len(mode)} contacts"
    tag = f"mode ({'solo12' if robot.floating_base else 'planar'}, {kind})"
    assert_fd(f"{tag} ddq_dq", der.ddq_dq, fd_dq(lambda qq: ddq(qq, v), robot.model, q), value=sol.ddq)
    assert_fd(f"{tag} ddq_dv", der.ddq_dv, fd_dv(lambda vv: ddq(q, vv), v), value=sol.ddq)
    if n_rows:
        assert_fd(f"{tag} forces_dq", der.forces_dq, fd_dq(lambda qq: forces(qq, v), robot.model, q), value=sol.forces)
        assert_fd(f"{tag} forces_dv", der.forces_dv, fd_dv(lambda vv: forces(q, vv), v), value=sol.forces)
    # derivatives=True must not change the solution
    plain = dyn.solve(q, v, T, mode)
    assert np.allclose(plain.ddq, sol.ddq, rtol=1e-12, atol=1e-12)
    assert np.allclose(plain.forces, sol.forces, rtol=1e-12, atol=1e-12)


def test_mode_ddq_without_contacts_matches_aba():
    """Mode ∅ is Pinocchio's forward dynamics with the scene's efforts as torque."""
    scene = _solo("stick")
    dyn = ModeDynamics(scene)
    q, v = solo_state(scene.robot, 4)
    sol = dyn.solve(q, v, T)
    kin = Kinematics(scene.model)
    kin.update(q, v)
    tau = scene.tau(kin, T)
    assert np.allclose(sol.ddq, pin.aba(scene.model, scene.model.createData(), q, v, tau), rtol=1e-10, atol=1e-9)
