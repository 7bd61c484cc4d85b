"""The paper's planar models and the real quadrupeds against hand-derived facts.

Everything compared here is derived in this file from docs/design.md §6 (masses,
inertias, frame offsets, the pitch convention), not read back from the code.

Pitch turns about the world axis (0, -1, 0): R(θ) = R_y(-θ) maps body x to
(cos θ, 0, sin θ) (positive pitch lifts the front) and body z to
(-sin θ, 0, cos θ). So a body-frame point (bx, 0, bz) sits at
(bx cos θ - bz sin θ, 0, bx sin θ + bz cos θ) from the joint origin.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pinocchio as pin
import pytest

from contactdiff.model.contacts import Contact
from contactdiff.model.kinematics import Kinematics
from contactdiff.model.robot_files import QUADRUPEDS, load_robot
from contactdiff.model.scene import Scene
from contactdiff.scenes.scene_file import load_scene, load_source

PITCHES = (0.0, 0.3, -0.7, 1.2)


def rotate(theta: float, bx: float, bz: float) -> np.ndarray:
    """World offset of the body-frame point (bx, 0, bz) at pitch θ (see module docstring)."""
    c, s = np.cos(theta), np.sin(theta)
    return np.array([bx * c - bz * s, 0.0, bx * s + bz * c])


def config(robot, **values) -> np.ndarray:
    """Configuration from joint values by name (others at the reference pose)."""
    q = robot.q_ref.copy()
    for name, value in values.items():
        iq, _ = robot.scalar_joint(name)
        q[iq] = value
    return q


def mass_matrix(robot, q) -> np.ndarray:
    return pin.crba(robot.model, robot.model.createData(), q)


def permuted(robot, diagonal: dict[str, float]) -> np.ndarray:
    """Diagonal matrix with the given entries placed at each named joint's velocity index."""
    M = np.zeros((robot.nv, robot.nv))
    for name, value in diagonal.items():
        _, iv = robot.scalar_joint(name)
        assert iv == robot.model.joints[robot.joint_id(name)].idx_v
        M[iv, iv] = value
    return M


def frame_position(robot, q, frame) -> np.ndarray:
    kin = Kinematics(robot.model)
    kin.update(q, np.zeros(robot.nv))
    return kin.position(robot.frame_id(frame)).copy()


# -- names (docs/design.md §6) -------------------------------------------------------------
NAMES = {
    "planar_trot_soft": (
        {"body_x", "body_z", "body_pitch", "rear_foot_x", "rear_foot_z", "front_foot_x", "front_foot_z"},
        {"rear_hip", "front_hip", "rear_foot", "front_foot"},
    ),
    "planar_trot_rigid": ({"body_x", "body_z", "body_pitch"}, {"rear_foot", "front_foot"}),
    "ball": ({"z"}, {"ball"}),
    "two_limb": ({"body_z", "left_foot_z", "right_foot_z"}, {"left_hip", "right_hip", "left_foot", "right_foot"}),
}


@pytest.mark.parametrize("name", sorted(NAMES))
def test_planar_model_names(name):
    robot = load_robot(name)
    joints, frames = NAMES[name]
    assert set(robot.joint_names) == joints
    assert frames <= set(robot.frame_names)
    assert not robot.floating_base and robot.nq == robot.nv == len(joints)
    assert np.allclose(robot.model.gravity.linear, [0, 0, -9.81])  # the scene sets g = 1


# -- mass matrices ---------------------------------------------------------------------
def _random_configs(robot, n=4, seed=0):
    rng = np.random.default_rng(seed)
    out = []
    for theta in PITCHES[:n]:
        q = robot.q_ref + rng.uniform(-1, 1, robot.nq)
        if "body_pitch" in robot.joint_names:
            q[robot.scalar_joint("body_pitch")[0]] = theta
        out.append(q)
    return out


def test_mass_matrix_planar_trot_soft_is_identity():
    """Body mass 1 and pitch inertia 1 about its centre (the joints' origin), feet
    point masses 1 on their own x-z chains from the world: M = I_7 everywhere."""
    robot = load_robot("planar_trot_soft")
    expected = permuted(robot, dict.fromkeys(NAMES["planar_trot_soft"][0], 1.0))
    assert np.array_equal(expected, np.eye(7))
    for q in _random_configs(robot):
        assert np.allclose(mass_matrix(robot, q), expected, atol=1e-14)


def test_rigid_trot_inertia_from_lumped_masses():
    """planar_trot_rigid is the soft trot with the legs locked at rest length 0.5:
    body (m 1, I 1) at the body centre, feet (m 1) at (∓0.25, -0.5) from it.
    Centre of mass: z = (0 - 0.5 - 0.5)/3 = -1/3, so the feet sit at (∓0.25, -1/6)
    from it and I = 1 + 1·(1/3)² + 2·(1/4² + (1/6)²) = 31/24."""
    m_body, m_foot, L = Fraction(1), Fraction(1), Fraction(1, 2)
    com = (m_body * 0 + 2 * m_foot * (-L)) / (m_body + 2 * m_foot)
    inertia = 1 + m_body * com**2 + 2 * m_foot * (Fraction(1, 4) ** 2 + (-L - com) ** 2)
    assert com == Fraction(-1, 3) and -L - com == Fraction(-1, 6)
    assert inertia == Fraction(31, 24)


def test_mass_matrix_planar_trot_rigid():
    robot = load_robot("planar_trot_rigid")
    expected = permuted(robot, {"body_x": 3.0, "body_z": 3.0, "body_pitch": 31 / 24})
    for q in _random_configs(robot):
        assert np.allclose(mass_matrix(robot, q), expected, atol=1e-14)
    assert np.isclose(pin.computeTotalMass(robot.model), 3.0)


def test_mass_matrix_ball_and_two_limb():
    ball = load_robot("ball")
    for z in (-1.0, 0.0, 2.5):
        assert np.allclose(mass_matrix(ball, np.array([z])), [[1.0]], atol=1e-15)
    limb = load_robot("two_limb")
    expected = permuted(limb, {"body_z": 1.0, "left_foot_z": 0.1, "right_foot_z": 0.1})
    for q in _random_configs(limb):
        assert np.allclose(mass_matrix(limb, q), expected, atol=1e-15)


# -- frame positions -------------------------------------------------------------------
@pytest.mark.parametrize("theta", PITCHES)
def test_soft_trot_frames(theta):
    robot = load_robot("planar_trot_soft")
    x, z = 0.3, 1.1
    q = config(
        robot,
        body_x=x,
        body_z=z,
        body_pitch=theta,
        rear_foot_x=-0.4,
        rear_foot_z=0.2,
        front_foot_x=0.7,
        front_foot_z=-0.1,
    )
    body = np.array([x, 0.0, z])
    front = frame_position(robot, q, "front_hip")
    assert np.allclose(front, body + 0.25 * np.array([np.cos(theta), 0, np.sin(theta)]), atol=1e-14)
    assert np.allclose(frame_position(robot, q, "rear_hip"), body + rotate(theta, -0.25, 0), atol=1e-14)
    assert np.allclose(frame_position(robot, q, "rear_foot"), [-0.4, 0, 0.2], atol=1e-14)
    assert np.allclose(frame_position(robot, q, "front_foot"), [0.7, 0, -0.1], atol=1e-14)


def test_positive_pitch_lifts_the_front():
    robot = load_robot("planar_trot_soft")
    q = config(robot, body_pitch=0.2)
    assert frame_position(robot, q, "front_hip")[2] > 0 > frame_position(robot, q, "rear_hip")[2]


@pytest.mark.parametrize("theta", PITCHES)
def test_rigid_trot_feet(theta):
    """Feet at COM + R(θ)(∓0.25, 0, -1/6)."""
    robot = load_robot("planar_trot_rigid")
    q = config(robot, body_x=-0.2, body_z=0.9, body_pitch=theta)
    com = np.array([-0.2, 0.0, 0.9])
    for frame, bx in (("rear_foot", -0.25), ("front_foot", 0.25)):
        expected = com + rotate(theta, bx, -1 / 6)
        assert np.allclose(frame_position(robot, q, frame), expected, atol=1e-14)
    data = robot.model.createData()
    assert np.allclose(pin.centerOfMass(robot.model, data, q), com, atol=1e-14)


def test_two_limb_and_ball_frames():
    limb = load_robot("two_limb")
    q = config(limb, body_z=1.3, left_foot_z=0.4, right_foot_z=0.25)
    assert np.allclose(frame_position(limb, q, "left_hip"), [-0.25, 0, 1.3], atol=1e-14)
    assert np.allclose(frame_position(limb, q, "right_hip"), [0.25, 0, 1.3], atol=1e-14)
    assert np.allclose(frame_position(limb, q, "left_foot"), [-0.25, 0, 0.4], atol=1e-14)
    assert np.allclose(frame_position(limb, q, "right_foot"), [0.25, 0, 0.25], atol=1e-14)
    ball = load_robot("ball")
    assert np.allclose(frame_position(ball, np.array([0.7]), "ball"), [0, 0, 0.7], atol=1e-15)


# -- scene files -----------------------------------------------------------------------
def fall_time(gap: float, g: float) -> float:
    """Free fall over ``gap`` from rest: gap = g t² / 2."""
    return float(np.sqrt(gap / (g / 2)))


def test_soft_trot_scene():
    scene = load_source("planar_trot_soft")
    robot, q = scene.robot, scene.q0
    assert np.allclose(scene.model.gravity.linear, [0, 0, -1])
    assert np.allclose(frame_position(robot, q, "rear_hip"), [-0.25, 0, 1.0], atol=1e-14)
    for side in ("rear", "front"):
        hip = frame_position(robot, q, f"{side}_hip")
        foot = frame_position(robot, q, f"{side}_foot")
        assert np.allclose(foot - hip, [0, 0, -0.5], atol=1e-14)
    assert np.allclose(scene.v0, 0)
    assert scene.contact_names == ["rear_foot", "front_foot"]
    assert np.allclose(scene.gaps(q), [0.5, 0.5], atol=1e-14)
    for c in scene.contacts:
        assert c.restitution == 0.0 and not c.sticking and c.n_rows == 1
        assert np.allclose(c.normal, [0, 0, 1])
    springs = sorted((s.frame_a, s.frame_b, s.stiffness, s.damping, s.rest_length) for s in scene.effort_specs)
    assert springs == [("front_hip", "front_foot", 27.0, 0.0, 0.5), ("rear_hip", "rear_foot", 27.0, 0.0, 0.5)]
    for gap in scene.gaps(q):
        assert np.isclose(fall_time(gap, 1.0), 1.0)
    # the centre of mass starts where the rigid trot's does
    com = pin.centerOfMass(scene.model, scene.model.createData(), q)
    assert np.allclose(com, [0, 0, 2 / 3], atol=1e-14)


def test_rigid_trot_scene():
    scene = load_source("planar_trot_rigid")
    q = scene.q0
    assert np.allclose(scene.model.gravity.linear, [0, 0, -1])
    assert np.allclose(pin.centerOfMass(scene.model, scene.model.createData(), q), [0, 0, 2 / 3], atol=1e-14)
    assert np.allclose(scene.gaps(q), [0.5, 0.5], atol=1e-14)
    assert scene.contact_names == ["rear_foot", "front_foot"]
    assert all(c.restitution == 0.0 and not c.sticking for c in scene.contacts)
    assert [fall_time(g, 1.0) for g in scene.gaps(q)] == pytest.approx([1.0, 1.0])


def test_two_limb_and_ball_scenes():
    limb = load_source("two_limb")
    assert np.allclose(limb.gaps(limb.q0), [0.5, 0.5], atol=1e-14)
    for side in ("left", "right"):
        d = frame_position(limb.robot, limb.q0, f"{side}_foot") - frame_position(limb.robot, limb.q0, f"{side}_hip")
        assert np.allclose(d, [0, 0, -0.5], atol=1e-14)
    assert [fall_time(g, 1.0) for g in limb.gaps(limb.q0)] == pytest.approx([1.0, 1.0])
    ball = load_scene("ball")
    assert np.allclose(ball.model.gravity.linear, [0, 0, -1])
    assert ball.gaps(ball.q0) == pytest.approx([1.0])
    assert ball.contacts[0].restitution == 0.8


@pytest.mark.parametrize("theta0", [0.2, -0.35])
def test_soft_trot_tilted_touchdown_state(theta0):
    """docs/design.md §6: body centre (0, 1), pitch θ0, each foot at hip + R(θ0)(0, 0, -0.5)."""
    scene = load_source("planar_trot_soft")
    feet = {
        side: np.array([0, 0, 1.0]) + rotate(theta0, bx, 0) + rotate(theta0, 0, -0.5)
        for side, bx in (("rear", -0.25), ("front", 0.25))
    }
    # a mapping sets the named joints; the others take the robot's reference pose (0)
    tilted = scene.with_state(
        q0={
            "body_z": 1.0,
            "body_pitch": theta0,
            "rear_foot_x": feet["rear"][0],
            "rear_foot_z": feet["rear"][2],
            "front_foot_x": feet["front"][0],
            "front_foot_z": feet["front"][2],
        }
    )
    for side in ("rear", "front"):
        hip = frame_position(tilted.robot, tilted.q0, f"{side}_hip")
        foot = frame_position(tilted.robot, tilted.q0, f"{side}_foot")
        assert np.isclose(np.linalg.norm(foot - hip), 0.5)
    assert np.allclose(tilted.gaps(tilted.q0), [feet["rear"][2], feet["front"][2]])
    # positive pitch lowers the rear foot
    assert (tilted.gaps(tilted.q0)[0] < tilted.gaps(tilted.q0)[1]) == (theta0 > 0)


# -- real quadrupeds -------------------------------------------------------------------
FEET = {  # notes/pinocchio.md §1, in joint order
    "solo12": ("FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT"),
    "anymal": ("LF_FOOT", "LH_FOOT", "RF_FOOT", "RH_FOOT"),
    "a1": ("FL_foot", "FR_foot", "RL_foot", "RR_foot"),
    "go1": ("FL_foot", "FR_foot", "RL_foot", "RR_foot"),
    "go2": ("FL_foot", "FR_foot", "RL_foot", "RR_foot"),
    "hyq": ("lf_foot", "lh_foot", "rf_foot", "rh_foot"),
}


def test_quadruped_list():
    assert set(QUADRUPEDS) == set(FEET)


@pytest.mark.quadrupeds
@pytest.mark.parametrize("name", QUADRUPEDS)
def test_quadruped_loads(name):
    robot = load_robot(name)
    assert robot.floating_base
    assert (robot.nq, robot.nv) == (19, 18)
    assert robot.model.joints[1].shortname() == "JointModelFreeFlyer"
    assert robot.feet == FEET[name]
    assert len(robot.actuated) == 12
    q = robot.q_ref
    assert q.shape == (19,) and np.isclose(np.linalg.norm(q[3:7]), 1.0)
    # standing pose: base above the feet, feet below the base
    kin = Kinematics(robot.model)
    kin.update(q, np.zeros(18))
    base_z = q[2]
    for foot in robot.feet:
        assert kin.position(robot.frame_id(foot))[2] < base_z - 0.1
    # the translational block of M is the total mass times I (base velocity in the base frame)
    m = sum(inertia.mass for inertia in robot.model.inertias)
    assert np.isclose(pin.computeTotalMass(robot.model), m)
    qr = pin.integrate(robot.model, q, 0.4 * np.random.default_rng(1).standard_normal(18))
    M = pin.crba(robot.model, robot.model.createData(), qr)
    assert np.allclose(M[:3, :3], m * np.eye(3), rtol=1e-12, atol=1e-12)


@pytest.mark.quadrupeds
@pytest.mark.parametrize("name", QUADRUPEDS)
def test_quadruped_scene_from_robot(name):
    robot = load_robot(name)
    scene = Scene.from_robot(robot)
    assert scene.contact_names == list(FEET[name])
    assert np.allclose(scene.gaps(robot.q_ref), 0.0, atol=1e-12)
    assert np.allclose(scene.model.gravity.linear, [0, 0, -9.81])
    for contact in scene.contacts:
        assert contact.sticking and contact.n_rows == 3
        assert np.allclose(contact.directions @ contact.directions.T, np.eye(3), atol=1e-14)
        assert np.allclose(contact.normal, [0, 0, 1])
    # lifting the base by 5 cm opens every gap by 5 cm
    q_up = robot.q_ref.copy()
    q_up[2] += 0.05
    assert np.allclose(scene.gaps(q_up), 0.05, atol=1e-12)
    # a frictionless variant has one row per foot
    plain = Scene(robot, [Contact(f, offset=c.offset) for f, c in zip(robot.feet, scene.contacts)])
    assert [c.n_rows for c in plain.contacts] == [1, 1, 1, 1]
    assert np.allclose(plain.gaps(robot.q_ref), 0.0, atol=1e-12)


def test_load_source_robot_name_gives_standing_scene():
    scene = load_source("solo12")
    assert scene.contact_names == list(FEET["solo12"])
    assert np.allclose(scene.gaps(scene.q0), 0, atol=1e-12)
