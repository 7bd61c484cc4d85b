"""Mode dynamics (`ModeDynamics.solve`) against closed forms and physical laws.

References are derived by hand in the docstrings (planar models, g = 1 unless
stated) or are laws of mechanics evaluated independently of the solver:
constraint rows held by finite differences of the positions along the flow,
the power balance of the total energy, and Newton-Euler for the whole robot.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from helpers import random_state, second_derivative_along
from hypothesis import given, settings
from hypothesis import strategies as st

from contactdiff.dynamics.mode import ModeDynamics
from contactdiff.model.contacts import Contact
from contactdiff.model.efforts import JointSpring, Spring
from contactdiff.model.kinematics import Kinematics
from contactdiff.model.objects import RobotFrame, add_objects
from contactdiff.model.robot import Robot
from contactdiff.model.robot_files import load_robot
from contactdiff.model.scene import Scene
from contactdiff.scenes.scene_file import load_source

M_RIGID, I_RIGID = 3.0, 31 / 24
FEET_X = {"rear_foot": -0.25, "front_foot": 0.25}


def set_joints(robot, q=None, v=None, **values):
    """Configuration (or velocity, with ``v``) from joint values by name."""
    base = robot.q_ref.copy() if q is None else q.copy()
    for name, value in values.items():
        base[robot.scalar_joint(name)[0]] = value
    return base


def velocity(robot, **values):
    v = np.zeros(robot.nv)
    for name, value in values.items():
        v[robot.scalar_joint(name)[1]] = value
    return v


def iv(robot, name):
    return robot.scalar_joint(name)[1]


def foot_offset(theta, bx, bz=-1 / 6):
    """(x, z) world offset of the body-frame point (bx, bz) at pitch θ (pitch about -y)."""
    c, s = np.cos(theta), np.sin(theta)
    return np.array([bx * c - bz * s, bx * s + bz * c])


def rigid_scene(friction=("none", "none")):
    robot = load_robot("planar_trot_rigid")
    contacts = [Contact(f, friction=fr) for f, fr in zip(("rear_foot", "front_foot"), friction)]
    return Scene(robot, contacts, gravity=[0, 0, -1], q0={"body_z": 1.0})


# -- rigid trot on one and two feet ----------------------------------------------------
@settings(max_examples=25, deadline=None)
@given(theta=st.floats(-1.3, 1.3), omega=st.floats(-3.0, 3.0), rear=st.booleans())
def test_rigid_trot_one_foot_rotating(theta, omega, rear):
    """Moving version of the one-foot case: pitch rate ω, COM velocity chosen so the foot
    does not move vertically (ż = -r_x ω). The foot's vertical acceleration at zero
    joint acceleration is the centripetal -ω² r_z (drift), so the row gives
    z̈ + r_x θ̈ - ω² r_z = 0; with m z̈ = -m g + λ, I θ̈ = r_x λ:
    λ = (g + ω² r_z) / (1/m + r_x²/I)."""
    scene = rigid_scene()
    robot, g = scene.robot, 1.0
    foot = "rear_foot" if rear else "front_foot"
    rx, rz = foot_offset(theta, FEET_X[foot])
    q = set_joints(robot, body_z=1.0, body_pitch=theta)
    v = velocity(robot, body_x=0.4, body_z=-rx * omega, body_pitch=omega)
    lam = (g + omega**2 * rz) / (1 / M_RIGID + rx**2 / I_RIGID)
    sol = ModeDynamics(scene).solve(q, v, 0.0, [scene.contact_index(foot)])
    assert sol.forces[0] == pytest.approx(lam, rel=1e-10, abs=1e-12)
    assert sol.ddq[iv(robot, "body_x")] == pytest.approx(0.0, abs=1e-12)
    assert sol.ddq[iv(robot, "body_z")] == pytest.approx(-g + lam / M_RIGID, abs=1e-12)
    assert sol.ddq[iv(robot, "body_pitch")] == pytest.approx(rx * lam / I_RIGID, abs=1e-12)


@pytest.mark.parametrize("theta", [0.0, 0.3, -0.5])
@pytest.mark.parametrize("foot", ["rear_foot", "front_foot"])
def test_rigid_trot_one_foot_frictionless(foot, theta):
    """Rigid body (m = 3, I = 31/24 about the COM), at rest, on one frictionless foot.

    The foot's offset from the COM is r = R(θ)(∓1/4, -1/6) = (r_x, r_z); with pitch
    about -y, d r/dθ = (-r_z, r_x), so the gap is a = z + r_z(θ) and its row is
    A = [0, 1, r_x] in (x, z, θ). At rest the drift is 0, and
        m ẍ = 0,  m z̈ = -m g + λ,  I θ̈ = r_x λ,  z̈ + r_x θ̈ = 0
    give λ = g / (1/m + r_x²/I), z̈ = -g + λ/m, θ̈ = r_x λ / I, ẍ = 0.
    """
    scene = rigid_scene()
    robot, g = scene.robot, 1.0
    rx, _ = foot_offset(theta, FEET_X[foot])
    lam = g / (1 / M_RIGID + rx**2 / I_RIGID)
    q = set_joints(robot, body_x=0.2, body_z=1.0, body_pitch=theta)
    sol = ModeDynamics(scene).solve(q, np.zeros(3), 0.0, [scene.contact_index(foot)])
    assert sol.forces == pytest.approx([lam], rel=1e-12)
    assert sol.normal_forces() == pytest.approx([lam], rel=1e-12)
    assert sol.ddq[iv(robot, "body_x")] == pytest.approx(0.0, abs=1e-14)
    assert sol.ddq[iv(robot, "body_z")] == pytest.approx(-g + lam / M_RIGID, abs=1e-13)
    assert sol.ddq[iv(robot, "body_pitch")] == pytest.approx(rx * lam / I_RIGID, abs=1e-13)
    if theta == 0.0:  # λ = 1/(1/3 + 3/62) = 186/71
        assert lam == pytest.approx(186 / 71, rel=1e-15)


@pytest.mark.parametrize("theta", [0.0, 0.4])
@pytest.mark.parametrize("foot", ["rear_foot", "front_foot"])
def test_rigid_trot_one_foot_sticking(foot, theta):
    """The same body on one sticking foot: a pivot. With c the COM and P = c + r(θ) fixed,
    at rest c̈ = -r'(θ) θ̈ = (r_z θ̈, -r_x θ̈). Newton m c̈ = F - m g ẑ gives
    F = (m r_z θ̈, m g - m r_x θ̈); Euler I θ̈ = r'·F = -r_z F_x + r_x F_z gives
    θ̈ = m g r_x / (I + m |r|²). Rows: normal (z) first, then the tangent x.
    """
    scene = rigid_scene(("stick", "stick"))
    robot, g, m = scene.robot, 1.0, M_RIGID
    rx, rz = foot_offset(theta, FEET_X[foot])
    th_dd = m * g * rx / (I_RIGID + m * (rx**2 + rz**2))
    q = set_joints(robot, body_z=1.0, body_pitch=theta)
    contact = scene.contact_index(foot)
    assert scene.contacts[contact].n_rows == 2
    sol = ModeDynamics(scene).solve(q, np.zeros(3), 0.0, [contact])
    assert sol.ddq[iv(robot, "body_pitch")] == pytest.approx(th_dd, abs=1e-13)
    assert sol.ddq[iv(robot, "body_x")] == pytest.approx(rz * th_dd, abs=1e-13)
    assert sol.ddq[iv(robot, "body_z")] == pytest.approx(-rx * th_dd, abs=1e-13)
    assert sol.forces == pytest.approx([m * g - m * rx * th_dd, m * rz * th_dd], abs=1e-13)


@pytest.mark.parametrize("theta", [0.0, 0.25, -0.6])
def test_rigid_trot_two_feet(theta):
    """Both feet frictionless, at rest: two independent rows z̈ + r_x,i θ̈ = 0 force
    z̈ = θ̈ = 0 (and ẍ = 0); statics λ_r + λ_f = m g, r_x,r λ_r + r_x,f λ_f = 0 (lever rule).
    At θ = 0 each foot carries 1.5."""
    scene = rigid_scene()
    robot, g = scene.robot, 1.0
    rr, rf = foot_offset(theta, -0.25)[0], foot_offset(theta, 0.25)[0]
    lam_r, lam_f = M_RIGID * g * rf / (rf - rr), -M_RIGID * g * rr / (rf - rr)
    q = set_joints(robot, body_x=-0.3, body_z=1.0, body_pitch=theta)
    sol = ModeDynamics(scene).solve(q, np.zeros(3), 0.0, [0, 1])
    assert np.allclose(sol.ddq, 0.0, atol=1e-13)
    assert sol.normal_forces() == pytest.approx([lam_r, lam_f], rel=1e-12)
    if theta == 0.0:
        assert sol.forces == pytest.approx([1.5, 1.5], rel=1e-13)


def test_rigid_trot_free_fall():
    scene = load_source("planar_trot_rigid")
    q = set_joints(scene.robot, body_z=2.0, body_pitch=0.7)
    v = velocity(scene.robot, body_x=0.3, body_pitch=-1.1)
    sol = ModeDynamics(scene).solve(q, v, 0.0)
    assert np.allclose(sol.ddq, [0.0, -1.0, 0.0], atol=1e-14)  # body_x, body_z, body_pitch
    assert sol.forces.shape == (0,) and sol.active == ()


# -- ball and two-limb ---------------------------------------------------------------------
@pytest.mark.parametrize("gravity", [None, [0, 0, -1.0]])
def test_ball_resting(gravity):
    """A resting point mass: λ = m g, z̈ = 0 (g = 9.81 from the URDF, or the scene's 1)."""
    robot = load_robot("ball")
    scene = Scene(robot, [Contact("ball")], gravity=gravity)
    g = 9.81 if gravity is None else 1.0
    dyn = ModeDynamics(scene)
    sol = dyn.solve(np.array([0.0]), np.array([0.0]), 0.0, [0])
    assert sol.forces == pytest.approx([1.0 * g], rel=1e-14)
    assert sol.ddq == pytest.approx([0.0], abs=1e-14)
    # moving down at constant speed while in contact changes nothing (no drift for a prismatic joint)
    assert dyn.solve(np.array([0.0]), np.array([-2.0]), 0.0, [0]).forces == pytest.approx([g], rel=1e-14)
    assert dyn.solve(np.array([0.5]), np.array([-2.0]), 0.0).ddq == pytest.approx([-g], rel=1e-14)


def test_two_limb_standing():
    """Body (m 1) at height h on two limbs (m 0.1) standing at z = 0, springs k = 10, L = 0.5
    compressed by 0.5 - h: each limb is pushed down by k (L - h), so λ = 0.1 g + k (L - h);
    the body gets 2 k (L - h) up: z̈_b = -g + 2 k (L - h)."""
    scene = load_source("two_limb")
    robot, h = scene.robot, 0.42
    q = set_joints(robot, body_z=h, left_foot_z=0.0, right_foot_z=0.0)
    sol = ModeDynamics(scene).solve(q, np.zeros(3), 0.0, [0, 1])
    f = 10.0 * (0.5 - h)
    assert sol.forces == pytest.approx([0.1 + f, 0.1 + f], rel=1e-13)
    assert sol.ddq[iv(robot, "body_z")] == pytest.approx(-1.0 + 2 * f, rel=1e-13)
    assert sol.ddq[iv(robot, "left_foot_z")] == pytest.approx(0.0, abs=1e-13)


# -- soft trot ----------------------------------------------------------------------------
def test_soft_trot_standing_vertical_legs():
    """Body centre at (0, h), pitch 0, feet on the ground below the hips, at rest. Each
    spring (k = 27, L = 0.5) is compressed by L - h and pushes its foot down and the body
    up by k (L - h): foot normal force = k (L - h) + foot weight 1; the body's vertical
    acceleration is -1 + 2 k (L - h); moments cancel (θ̈ = 0); no horizontal forces."""
    scene = load_source("planar_trot_soft")
    robot, h, k = scene.robot, 0.4, 27.0
    q = set_joints(
        robot,
        body_x=0.0,
        body_z=h,
        body_pitch=0.0,
        rear_foot_x=-0.25,
        rear_foot_z=0.0,
        front_foot_x=0.25,
        front_foot_z=0.0,
    )
    assert np.allclose(scene.gaps(q), 0.0)
    sol = ModeDynamics(scene).solve(q, np.zeros(7), 0.0, [0, 1])
    assert sol.forces == pytest.approx([k * (0.5 - h) + 1.0] * 2, rel=1e-13)
    expected = velocity(robot, body_z=-1.0 + 2 * k * (0.5 - h))
    assert np.allclose(sol.ddq, expected, atol=1e-13)


@pytest.mark.parametrize("theta", [0.15, -0.3])
def test_soft_trot_standing_tilted(theta):
    """Same at pitch θ with the feet on the ground at arbitrary x. With d = foot - hip,
    l = |d|, the spring force on the foot is F = -k (l - L) d / l and on the hip -F.
    Foot z: 0 = -1 + F_z + λ → λ = 1 - F_z; foot x: ẍ_f = F_x.
    Body: ẍ = -F_x,sum, z̈ = -1 - F_z,sum, θ̈ = Σ (-r_z (-F_x) + r_x (-F_z)) with
    r = hip - body centre (pitch inertia 1, d r/dθ = (-r_z, r_x))."""
    scene = load_source("planar_trot_soft")
    robot, k, L = scene.robot, 27.0, 0.5
    body = np.array([0.05, 0.42])
    feet = {"rear": np.array([-0.35, 0.0]), "front": np.array([0.3, 0.0])}
    q = set_joints(
        robot,
        body_x=body[0],
        body_z=body[1],
        body_pitch=theta,
        rear_foot_x=feet["rear"][0],
        rear_foot_z=0.0,
        front_foot_x=feet["front"][0],
        front_foot_z=0.0,
    )
    sol = ModeDynamics(scene).solve(q, np.zeros(7), 0.0, [0, 1])
    expected = np.zeros(7)
    expected[iv(robot, "body_z")] = -1.0
    lam = []
    for side, bx in (("rear", -0.25), ("front", 0.25)):
        r = foot_offset(theta, bx, 0.0)
        d = feet[side] - (body + r)
        length = np.linalg.norm(d)
        F = -k * (length - L) * d / length
        lam.append(1.0 - F[1])
        expected[iv(robot, f"{side}_foot_x")] = F[0]
        expected[iv(robot, "body_x")] -= F[0]
        expected[iv(robot, "body_z")] -= F[1]
        expected[iv(robot, "body_pitch")] += -r[1] * (-F[0]) + r[0] * (-F[1])
    assert sol.forces == pytest.approx(lam, rel=1e-12)
    assert np.allclose(sol.ddq, expected, atol=1e-12)


@pytest.mark.parametrize("theta0", [0.0, 0.3, -0.2])
def test_soft_trot_free_fall_from_touchdown_state(theta0):
    """From the touchdown state (feet at their hips + R(θ0)(0, -0.5): springs at rest length)
    every mass falls with g = 1 and nothing turns."""
    scene = load_source("planar_trot_soft")
    robot = scene.robot
    feet = {
        bx: np.array([0.0, 1.0]) + foot_offset(theta0, bx, 0.0) + foot_offset(theta0, 0.0, -0.5) for bx in (-0.25, 0.25)
    }
    q = set_joints(
        robot,
        body_z=1.0,
        body_pitch=theta0,
        rear_foot_x=feet[-0.25][0],
        rear_foot_z=feet[-0.25][1],
        front_foot_x=feet[0.25][0],
        front_foot_z=feet[0.25][1],
    )
    sol = ModeDynamics(scene).solve(q, np.zeros(7), 0.0)
    expected = velocity(robot, body_z=-1.0, rear_foot_z=-1.0, front_foot_z=-1.0)
    assert np.allclose(sol.ddq, expected, atol=1e-13)


# -- constraint rows are held: finite differences of positions along the flow ------------------
def _soft_sticking():
    robot = load_robot("planar_trot_soft")
    return Scene(
        robot,
        [Contact("rear_foot", friction="stick"), Contact("front_foot", friction="stick")],
        [Spring("rear_hip", "rear_foot", 27.0, 0.4, 0.5), Spring("front_hip", "front_foot", 27.0, 0.4, 0.5)],
        gravity=[0, 0, -1],
    )


def _solo(friction="stick"):
    return Scene.from_robot(load_robot("solo12"), friction=friction)


HELD_CASES = {
    "rigid, both feet": (rigid_scene, (0, 1)),
    "rigid, rear sticking": (lambda: rigid_scene(("stick", "none")), (0,)),
    "soft, both sticking": (_soft_sticking, (0, 1)),
    "soft, front only": (lambda: load_source("planar_trot_soft"), (1,)),
    "two_limb, left": (lambda: load_source("two_limb"), (0,)),
    "solo12, four sticking": (_solo, (0, 1, 2, 3)),
    "solo12, two frictionless": (lambda: _solo("none"), (1, 2)),
}


def _state(robot, seed):
    rng = np.random.default_rng(seed)
    if robot.floating_base:
        return random_state(robot.model, robot.q_ref, rng, 0.3, 1.0)
    q = robot.q_ref + rng.uniform(-0.5, 0.5, robot.nq)
    if "body_z" in robot.joint_names:
        q[robot.scalar_joint("body_z")[0]] += 1.0
    return q, rng.standard_normal(robot.nv)


@pytest.mark.parametrize("case", sorted(HELD_CASES))
@pytest.mark.parametrize("seed", [0, 1])
def test_active_rows_have_zero_acceleration(case, seed):
    """For every row d of an active contact, d²/dt² [d · (p - p')](q(t)) = 0 along the flow
    (q(0), q̇(0), q̈(0)) = (q, v, ddq), by a second difference of positions only; for inactive
    contacts the same second derivative equals the row's A ddq + drift."""
    make, active = HELD_CASES[case]
    scene = make()
    robot = scene.robot
    q, v = _state(robot, seed)
    sol = ModeDynamics(scene).solve(q, v, 0.0, active)
    kin = Kinematics(robot.model)
    kin.update(q, v)
    scale = max(1.0, np.abs(sol.ddq).max(), np.abs(v).max() ** 2)
    for i, contact in enumerate(scene.contacts):
        rows, drift = contact.rows(kin).copy(), contact.drift(kin).copy()
        for r, d in enumerate(contact.directions):

            def position(qq, d=d):
                k2 = Kinematics(robot.model)
                k2.update(qq, np.zeros(robot.nv))
                p = k2.position(contact.fid)
                if contact.against_fid is not None:
                    p = p - k2.position(contact.against_fid)
                return float(d @ p)

            acc = second_derivative_along(position, robot.model, q, v, sol.ddq)
            if i in active:
                assert abs(acc) < 1e-6 * scale, (case, contact.name, r, acc)
                assert abs(rows[r] @ sol.ddq + drift[r]) < 1e-10 * scale
            else:
                assert abs(acc - (rows[r] @ sol.ddq + drift[r])) < 1e-6 * scale


# -- power balance ----------------------------------------------------------------------------
def _energy(scene, q, v):
    """Kinetic + gravitational + spring energy (springs from frame positions, by hand)."""
    model = scene.model
    data = model.createData()
    M = pin.crba(model, data, q)
    energy = 0.5 * v @ M @ v + pin.computePotentialEnergy(model, data, q)
    kin = Kinematics(model)
    kin.update(q, v)
    for spec in scene.effort_specs:
        if isinstance(spec, Spring):
            d = kin.position(scene.robot.frame_id(spec.frame_b)) - kin.position(scene.robot.frame_id(spec.frame_a))
            energy += 0.5 * spec.stiffness * (np.linalg.norm(d) - spec.rest_length) ** 2
        elif isinstance(spec, JointSpring):
            iq, _ = scene.robot.scalar_joint(spec.joint)
            energy += 0.5 * spec.stiffness * (q[iq] - spec.rest) ** 2
    return energy


def _damping_power(scene, q, v):
    """Power of the dampers, -c l̇² per spring and -c v_j² per joint spring (by hand)."""
    kin = Kinematics(scene.model)
    kin.update(q, v)
    power = 0.0
    for spec in scene.effort_specs:
        if isinstance(spec, Spring):
            fa, fb = scene.robot.frame_id(spec.frame_a), scene.robot.frame_id(spec.frame_b)
            d = kin.position(fb) - kin.position(fa)
            rate = d @ (kin.velocity(fb) - kin.velocity(fa)) / np.linalg.norm(d)
            power -= spec.damping * rate**2
        elif isinstance(spec, JointSpring):
            power -= spec.damping * v[scene.robot.scalar_joint(spec.joint)[1]] ** 2
    return power


def _soft_damped_mixed():
    robot = load_robot("planar_trot_soft")
    return Scene(
        robot,
        [Contact("rear_foot"), Contact("front_foot", friction="stick")],
        [
            Spring("rear_hip", "rear_foot", 27.0, 0.6, 0.5),
            Spring("front_hip", "front_foot", 20.0, 0.9, 0.45),
            JointSpring("body_pitch", 2.0, 0.3, 0.1),
        ],
        gravity=[0, 0, -1],
    )


ENERGY_CASES = {
    "rigid, both feet": (rigid_scene, (0, 1)),
    "rigid, free": (rigid_scene, ()),
    "soft, damped, rear + sticking front": (_soft_damped_mixed, (0, 1)),
    "two_limb": (lambda: load_source("two_limb"), (0, 1)),
    "solo12, four sticking": (_solo, (0, 1, 2, 3)),
    "solo12, three frictionless": (lambda: _solo("none"), (0, 1, 3)),
}


@pytest.mark.parametrize("case", sorted(ENERGY_CASES))
@pytest.mark.parametrize("on_manifold", [True, False])
def test_power_balance(case, on_manifold):
    """dE/dt = λ · (A v) + damper power, with E = ½ vᵀ M v + V_gravity + V_springs.

    From M ddq + nle = τ + Aᵀλ and dE/dt = vᵀ M ddq + ½ vᵀ Ṁ v + vᵀ g(q) + dV_springs/dt,
    with Ṁ - 2C skew: dE/dt = vᵀ(τ - τ_conservative springs) + λᵀ A v. On the constraint
    manifold (A v = 0: v projected onto the null space of A) plastic contacts do no work,
    so without dampers dE/dt = 0. dE/dt is the central difference of E along the
    state tangent (v, ddq): [E(q ⊕ h v, v + h ddq) - E(q ⊕ -h v, v - h ddq)] / 2h.
    """
    make, active = ENERGY_CASES[case]
    scene = make()
    robot = scene.robot
    q, v = _state(robot, 7)
    kin = Kinematics(robot.model)
    kin.update(q, v)
    A = np.vstack([scene.contacts[i].rows(kin) for i in active]) if active else np.zeros((0, robot.nv))
    if on_manifold and active:
        _, s, vt = np.linalg.svd(A)
        null = vt[np.sum(s > 1e-10) :]
        v = null.T @ (null @ v)
        assert np.allclose(A @ v, 0, atol=1e-12)
    sol = ModeDynamics(scene).solve(q, v, 0.0, active)
    h = 1e-6
    rate = (
        _energy(scene, pin.integrate(robot.model, q, h * v), v + h * sol.ddq)
        - _energy(scene, pin.integrate(robot.model, q, -h * v), v - h * sol.ddq)
    ) / (2 * h)
    expected = sol.forces @ (A @ v) + _damping_power(scene, q, v)
    data = robot.model.createData()
    scale = max(1.0, abs(v @ pin.crba(robot.model, data, q) @ sol.ddq), abs(_energy(scene, q, v)))
    assert abs(rate - expected) < 1e-7 * scale, (rate, expected, scale)
    if on_manifold and not any(isinstance(e, (Spring, JointSpring)) and e.damping for e in scene.effort_specs):
        assert abs(rate) < 1e-7 * scale


# -- solo12: Newton-Euler for the whole robot -----------------------------------------------
def _world_forces(scene, sol):
    """Per active contact: world force vector (directions^T row forces) and its point."""
    out = []
    for i, s in zip(sol.active, sol.row_slices):
        out.append((scene.contacts[i], scene.contacts[i].directions.T @ sol.forces[s]))
    return out


@pytest.mark.parametrize("friction", ["stick", "none"])
def test_solo12_standing_newton_euler(friction):
    """solo12 at its standing pose, at rest, all four feet active. The legs are passive, so
    the robot starts to sag; Newton-Euler for the whole robot still holds:
        Σ F_i + m g_vec = m c̈,     c̈ = J_com ddq (v = 0),
        Σ (p_i - c) × F_i = d h_G/dt = A_G,angular ddq (centroidal map, v = 0),
    with m = computeTotalMass. Frictionless feet carry no horizontal force, so then c̈_xy = 0;
    the stance is left-right and front-hind mirrored, so Σ F_xy ≈ 0 with sticking feet too."""
    scene = _solo(friction)
    robot, model = scene.robot, scene.model
    q, v = robot.q_ref, np.zeros(robot.nv)
    sol = ModeDynamics(scene).solve(q, v, 0.0, range(4))
    data = model.createData()
    m = pin.computeTotalMass(model)
    c = pin.centerOfMass(model, data, q)
    c_dd = pin.jacobianCenterOfMass(model, data, q) @ sol.ddq
    Ag = pin.computeCentroidalMap(model, data, q)
    kin = Kinematics(model)
    kin.update(q, v)
    total, moment = np.zeros(3), np.zeros(3)
    for contact, F in _world_forces(scene, sol):
        total += F
        moment += np.cross(kin.position(contact.fid) - c, F)
    g_vec = model.gravity.linear
    assert np.allclose(g_vec, [0, 0, -9.81])
    assert np.allclose(total + m * g_vec, m * c_dd, atol=1e-9 * m * 9.81)
    assert np.allclose(moment, Ag[3:] @ sol.ddq, atol=1e-9 * m * 9.81)
    assert np.all(sol.normal_forces() > 0)
    assert np.allclose(total[:2], 0.0, atol=1e-3 * m * 9.81)
    if friction == "none":
        assert np.allclose(c_dd[:2], 0.0, atol=1e-12)


@pytest.mark.parametrize("friction", ["stick", "none"])
def test_solo12_locked_joints_stands_still(friction):
    """solo12 with every joint locked at the standing pose is one rigid body on four feet:
    at rest it cannot move (ddq = 0), so Σ F_z = total mass × 9.81, Σ F_xy = 0 and the
    moment about the centre of mass is 0. The rows are redundant (12 or 4 rows on 6
    coordinates): the force split is the minimum-norm one, the sums are unique."""
    full = load_robot("solo12")
    model = pin.buildReducedModel(full.model, list(range(2, full.model.njoints)), full.q_ref)
    robot = Robot(model, "solo12_locked", floating_base=True, q_ref=full.q_ref[:7].copy())
    kin = Kinematics(model)
    kin.update(robot.q_ref, np.zeros(6))
    contacts = [Contact(f, offset=float(kin.position(model.getFrameId(f))[2]), friction=friction) for f in full.feet]
    scene = Scene(robot, contacts)
    sol = ModeDynamics(scene).solve(robot.q_ref, np.zeros(6), 0.0, range(4))
    m = pin.computeTotalMass(model)
    assert m == pytest.approx(pin.computeTotalMass(full.model), rel=1e-12)
    assert np.allclose(sol.ddq, 0.0, atol=1e-10)
    c = pin.centerOfMass(model, model.createData(), robot.q_ref)
    total, moment = np.zeros(3), np.zeros(3)
    for contact, F in _world_forces(scene, sol):
        total += F
        moment += np.cross(kin.position(contact.fid) - c, F)
    assert total == pytest.approx([0.0, 0.0, m * 9.81], abs=1e-10)
    assert np.allclose(moment, 0.0, atol=1e-10)


# -- Pinocchio's constraint dynamics against the Python KKT assembly ---------------------------
@pytest.mark.parametrize("mode", [(0,), (1, 2), (0, 1, 2, 3)])
@pytest.mark.parametrize("normal", [(0.0, 0.0, 1.0), (0.3, -0.2, 1.0)])
def test_rigid_contact_path_matches_python_kkt(monkeypatch, mode, normal):
    """Sticking ground contacts go through `rigid_contacts` (C++); the same mode assembled
    row by row in Python must give the same accelerations and row forces (normal first,
    then the tangents of `tangent_basis`), and the same derivatives: the two share no code
    beyond Pinocchio's kinematics, so agreement checks the force rotation and signs."""
    import contactdiff.dynamics.mode as dynamics_module

    robot = load_robot("solo12")
    contacts = [Contact(f, normal=normal, offset=-1.0, friction="stick") for f in robot.feet]  # never penetrating
    scene = Scene(
        robot, contacts, [JointSpring("FL_KFE", 2.0, 0.1, -1.0), Spring("FL_FOOT", "HR_FOOT", 30.0, 1.5, 0.2)]
    )
    q, v = _state(robot, 7)
    fast, fast_der = ModeDynamics(scene).solve(q, v, 0.0, mode, derivatives=True)
    monkeypatch.setattr(dynamics_module, "rigid_eligible", lambda contacts: False)
    slow, slow_der = ModeDynamics(scene).solve(q, v, 0.0, mode, derivatives=True)
    # both solve the same SPD system by Cholesky: agreement to round-off times its condition
    assert np.allclose(fast.ddq, slow.ddq, rtol=1e-9, atol=1e-9 * np.abs(slow.ddq).max())
    assert np.allclose(fast.forces, slow.forces, rtol=1e-9, atol=1e-9 * np.abs(slow.forces).max())
    for name in ("ddq_dq", "ddq_dv", "forces_dq", "forces_dv"):
        a, b = getattr(fast_der, name), getattr(slow_der, name)
        assert np.allclose(a, b, rtol=1e-8, atol=1e-8 * np.abs(b).max()), name


@pytest.mark.parametrize("mode", [(), (0,), (1, 2), (0, 1, 2, 3), (4, 1)])
def test_accelerator_equals_solve(mode):
    """The stepper's hot path (`ModeDynamics.accelerator`) calls Pinocchio directly on
    rigid modes and keeps raw forces; on every mode kind (free flight, rigid sticking,
    a sliding key that takes the Python path) it must give `solve`'s accelerations and
    normal forces. Same arithmetic on the rigid path up to the force rotation: equal
    to round-off of the forces' size."""
    robot = load_robot("solo12")
    contacts = [Contact(f, offset=-1.0, friction="stick") for f in robot.feet]  # never penetrating
    scene = Scene(robot, contacts, [JointSpring("FL_KFE", 2.0, 0.1, -1.0)])
    dyn = ModeDynamics(scene)
    accel = dyn.accelerator(mode)
    for seed in (3, 4):
        q, v = _state(robot, seed)
        ddq = accel(q, v, 0.2)
        ref = dyn.solve(q, v, 0.2, mode)
        np.testing.assert_allclose(ddq, ref.ddq, rtol=0, atol=1e-12 * max(1.0, np.abs(ref.ddq).max()))
        forces = ref.normal_forces()
        np.testing.assert_allclose(
            accel.normal_forces(), forces, rtol=0, atol=1e-12 * max(1.0, np.abs(forces).max(initial=0.0))
        )
    assert (accel.rigid is not None) == (len(mode) > 0 and all(k < 4 for k in mode))


def test_accelerator_falls_back_on_redundant_contacts():
    """Two sticking contacts at the same foot (its frame and a second frame at its origin:
    one frame may not hold two contacts of one surface) make Pinocchio's factorisation
    fail; the accelerator then gives `solve`'s least-squares answer (the same forces split)."""
    robot = add_objects(load_robot("solo12"), frames=[RobotFrame("FL_TWIN", "FL_FOOT")])
    contacts = [
        Contact("FL_FOOT", offset=-1.0, friction="stick"),
        Contact("FL_TWIN", offset=-1.0, friction="stick", name="twin"),
    ]
    dyn = ModeDynamics(Scene(robot, contacts))
    q, v = _state(robot, 5)
    accel = dyn.accelerator((0, 1))
    ddq = accel(q, v, 0.0)
    ref = dyn.solve(q, v, 0.0, (0, 1))
    assert accel._raw is None  # the fallback ran
    np.testing.assert_allclose(ddq, ref.ddq, rtol=0, atol=1e-12 * max(1.0, np.abs(ref.ddq).max()))
    np.testing.assert_allclose(accel.normal_forces(), ref.normal_forces(), rtol=0, atol=1e-9)
