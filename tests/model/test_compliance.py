"""Compliant feet (`contactdiff.model.compliance`): the transform and how decoupling moves with it.

Reference values:

* moving a foot's mass from the lower leg onto a joint placed at the foot point
  keeps every mass, centre of mass and, at the spring's rest, the mass matrix of
  the original coordinates (the mass sits at the same place on the same rigid
  body): exact up to round-off, tolerance 1e-12 relative;
* the spring joint is a slide along the shank: moving its coordinate by s moves
  the foot by s times the unit knee-to-foot direction (rigid-body kinematics);
* a plastic frictionless impact on a foot that slides along the impulse
  direction stops the foot mass alone (the slide transmits no axial force and
  the spring has none at rest): the body keeps its velocity.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from helpers import assert_fd, fd_dq, fd_dv, random_state

import contactdiff as cd
from contactdiff.analysis.order_gap import diagonal_touchdown, order_gap
from contactdiff.errors import InvalidInputError, UnknownNameError
from contactdiff.model.compliance import SPRING_SUFFIX, add_compliant_feet, compliant_state


@pytest.fixture(scope="module")
def solo():
    return cd.load_robot("solo12")


def _total_mass(model):
    return sum(inertia.mass for inertia in model.inertias)


def _old_coordinates(robot, compliant):
    """Tangent indices of ``robot``'s coordinates inside ``compliant`` (joints matched by name)."""
    out = []
    for j in range(1, robot.model.njoints):
        k = compliant.model.getJointId(robot.model.names[j])
        out += range(compliant.model.idx_vs[k], compliant.model.idx_vs[k] + robot.model.nvs[j])
    return out


def test_mass_from_leg_keeps_mass_and_mass_matrix(solo):
    scene = add_compliant_feet(solo, 5000.0, 0.01)
    model = scene.model
    assert _total_mass(model) == pytest.approx(_total_mass(solo.model), rel=1e-14)
    assert model.nv == solo.nv + 4 and model.nq == solo.nq + 4
    assert [c.spec.frame for c in scene.contacts] == list(solo.feet)
    rng = np.random.default_rng(3)
    old = _old_coordinates(solo, scene.robot)
    for _ in range(3):
        q, v = random_state(solo.model, solo.q_ref, rng)
        qc, vc = compliant_state(solo, scene.robot, q, v)
        M0 = pin.crba(solo.model, solo.model.createData(), q)
        M1 = pin.crba(model, model.createData(), qc)
        np.testing.assert_allclose(M1[np.ix_(old, old)], M0, atol=1e-12 * np.abs(M0).max())
        # centre of mass and gravity torques too
        c0 = pin.centerOfMass(solo.model, solo.model.createData(), q)
        c1 = pin.centerOfMass(model, model.createData(), qc)
        np.testing.assert_allclose(c1, c0, atol=1e-14)
        np.testing.assert_allclose(vc[old], v, atol=0)


def test_mass_added_adds_foot_mass_per_foot(solo):
    scene = add_compliant_feet(solo, 5000.0, 0.02, mass_from="added")
    assert _total_mass(scene.model) == pytest.approx(_total_mass(solo.model) + 4 * 0.02, rel=1e-14)


@pytest.mark.parametrize("source", ["solo12", "planar_trot_rigid"])
def test_kinematics_at_spring_rest_equal_the_original(source):
    base = cd.load_scene(source) if source.startswith("planar") else cd.Scene.from_robot(cd.load_robot(source))
    scene = add_compliant_feet(base, 3000.0, 0.003)
    robot, new = base.robot, scene.robot
    rng = np.random.default_rng(0)
    d0, d1 = robot.model.createData(), new.model.createData()
    for _ in range(3):
        q, _ = random_state(robot.model, robot.q_ref, rng)
        qc, _ = compliant_state(robot, new, q)
        pin.framesForwardKinematics(robot.model, d0, q)
        pin.framesForwardKinematics(new.model, d1, qc)
        for f in robot.model.frames:  # every frame, feet included, is where it was
            k = new.model.getFrameId(f.name)
            np.testing.assert_allclose(
                d1.oMf[k].homogeneous, d0.oMf[robot.model.getFrameId(f.name)].homogeneous, atol=1e-14
            )
    # contacts are closed at the same standing/touchdown poses
    np.testing.assert_allclose(scene.gaps(scene.q0), base.gaps(base.q0), atol=1e-15)


def test_spring_slides_the_foot_along_the_shank(solo):
    scene = add_compliant_feet(solo, 3000.0, 0.003)
    new = scene.robot
    q, _ = compliant_state(solo, new, solo.q_ref)
    data = new.model.createData()
    for foot in solo.feet:
        frame = solo.model.frames[solo.model.getFrameId(foot)]
        pin.framesForwardKinematics(solo.model, solo.data, solo.q_ref)
        shank = solo.data.oMi[frame.parentJoint].rotation @ frame.placement.translation
        shank /= np.linalg.norm(shank)
        j = new.model.joints[new.model.getJointId(foot + SPRING_SUFFIX)]
        qs = q.copy()
        qs[j.idx_q] = 0.013
        pin.framesForwardKinematics(new.model, data, q)
        p0 = data.oMf[new.model.getFrameId(foot)].translation.copy()
        pin.framesForwardKinematics(new.model, data, qs)
        np.testing.assert_allclose(data.oMf[new.model.getFrameId(foot)].translation - p0, 0.013 * shank, atol=1e-15)


def test_springs_are_joint_springs_on_the_new_joints(solo):
    scene = add_compliant_feet(solo, 4000.0, 0.005, damping=2.5)
    springs = [e for e in scene.effort_specs if isinstance(e, cd.JointSpring)]
    assert [s.joint for s in springs] == [f + SPRING_SUFFIX for f in solo.feet]
    assert all((s.stiffness, s.damping, s.rest) == (4000.0, 2.5, 0.0) for s in springs)
    # tau on a spring coordinate = -k s - c s'
    q, v = scene.q0.copy(), np.zeros(scene.nv)
    j = scene.model.joints[scene.model.getJointId(solo.feet[0] + SPRING_SUFFIX)]
    q[j.idx_q], v[j.idx_v] = -0.002, 0.1
    kin = scene.kinematics
    kin.update(q, v)
    assert scene.tau(kin, 0.0)[j.idx_v] == pytest.approx(4000.0 * 0.002 - 2.5 * 0.1, rel=1e-14)


def test_scene_transform_keeps_contacts_efforts_state():
    base = cd.load_scene("planar_trot_soft")
    scene = add_compliant_feet(base, 300.0, 0.05, axis=(0, 0, -1))
    assert scene.contact_names == base.contact_names
    assert scene.effort_specs[: len(base.effort_specs)] == base.effort_specs
    q0, v0 = compliant_state(base.robot, scene.robot, base.q0, base.v0)
    np.testing.assert_array_equal(scene.q0, q0)
    np.testing.assert_array_equal(scene.v0, v0)


# -- decoupling moves with the design --------------------------------------------------
def test_coupling_decreases_with_foot_mass_on_solo12(solo):
    """Lighter feet: the checker's coupling at the touchdown state and its max over
    sampled poses shrink, all below the rigid-footed robot's (with rotor inertia,
    where the rigid robot is strongly coupled)."""
    rigid = cd.Scene.from_robot(solo).with_armature(3.6e-3)
    q, v, pair = diagonal_touchdown(rigid)
    names = {rigid.contact_names[k] for k in pair}

    def coupling(scene, state):
        at_state = cd.check_decoupling(scene, states=[state])
        sampled = cd.check_decoupling(scene, samples=3, seed=1, spread=0.2)
        return next(p.max for p in at_state.pairs if set(p.contacts) == names), sampled.max_coupling

    previous = coupling(rigid, (q, v))
    for foot_mass in (1e-2, 1e-3, 1e-4):
        scene = add_compliant_feet(rigid, 1e4, foot_mass)
        current = coupling(scene, compliant_state(solo, scene.robot, q, v))
        assert current[0] < previous[0] and current[1] < previous[1], (foot_mass, current, previous)
        previous = current
    assert previous[0] < 1e-2 * coupling(rigid, (q, v))[0]


def test_coupling_and_order_gap_decrease_with_foot_mass_on_the_rigid_trot():
    """planar_trot_rigid (coupling 0.7465, outcome gap 0.497 at its touchdown) with
    feet on vertical springs: the max coupling over poses shrinks with the foot
    mass; at the pitch-0 touchdown the springs slide along the impulse, so the
    impacts stop only the feet: no coupling and no order gap at all there."""
    base = cd.load_scene("planar_trot_rigid")
    q, v = np.array([0.0, 1 / 6, 0.0]), np.array([0.0, -1.0, 0.0])
    previous = cd.check_decoupling(base, samples=5).max_coupling
    assert previous == pytest.approx(0.7465, abs=1e-4)
    for foot_mass in (0.3, 0.03, 0.003):
        scene = add_compliant_feet(base, 100.0, foot_mass, axis=(0, 0, -1))
        current = cd.check_decoupling(scene, samples=5).max_coupling
        assert current < previous
        previous = current
        qc, vc = compliant_state(base.robot, scene.robot, q, v)
        gap = order_gap(scene, qc, vc, (0, 1))
        assert gap.outcome <= 1e-14 and gap.saltation <= 1e-13
        for v_after in (*gap.v_after.values(), gap.v_simultaneous):
            np.testing.assert_allclose(v_after[:3], v, atol=1e-14)  # the body is untouched
            scene.kinematics.update(qc, v_after)
            for c in scene.contacts:  # each foot stopped
                assert abs(c.rows(scene.kinematics)[0] @ v_after) <= 1e-14


def test_simulate_runs_on_a_compliant_scene():
    """The compliant rigid trot lands at t = 1 (free fall of 1/2 from rest, g = 1) and
    the body keeps falling at speed 1 through the impact (see above)."""
    scene = add_compliant_feet(cd.load_scene("planar_trot_rigid"), 100.0, 0.01, axis=(0, 0, -1))
    traj = cd.simulate(scene, 1.05, rtol=1e-10, atol=1e-12)
    event = traj.events[0]
    assert event.t == pytest.approx(1.0, abs=1e-9) and event.simultaneous
    assert event.v_plus[1] == pytest.approx(-1.0, abs=1e-9)


def test_mode_dynamics_derivatives_on_a_compliant_model():
    """The analytic derivatives of the mode dynamics hold on the rebuilt model
    (central differences on the manifold, tests/helpers.py tolerances)."""
    scene = add_compliant_feet(cd.Scene.from_robot(cd.load_robot("solo12")), 2000.0, 0.005, damping=1.0)
    dyn = cd.ModeDynamics(scene)
    q, v = random_state(scene.model, scene.robot.q_ref, np.random.default_rng(2), q_scale=0.1)
    mode = (0, 3)
    _, der = dyn.solve(q, v, 0.0, mode, derivatives=True)
    value = dyn.solve(q, v, 0.0, mode).ddq
    assert_fd("compliant: ddq/dq", der.ddq_dq, fd_dq(lambda x: dyn.solve(x, v, 0.0, mode).ddq, scene.model, q), value)
    assert_fd("compliant: ddq/dv", der.ddq_dv, fd_dv(lambda x: dyn.solve(q, x, 0.0, mode).ddq, v), value)


# -- bad input ---------------------------------------------------------------------------
def test_add_compliant_feet_rejects_bad_input(solo):
    with pytest.raises(InvalidInputError, match=r"at most 0\.019"):
        add_compliant_feet(solo, 1000.0, 0.03)
    add_compliant_feet(solo, 1000.0, 0.03, mass_from="added")  # fine when added
    with pytest.raises(InvalidInputError, match="stiffness"):
        add_compliant_feet(solo, -1.0, 0.01)
    with pytest.raises(InvalidInputError, match="> 0"):
        add_compliant_feet(solo, 1000.0, 0.0)
    with pytest.raises(InvalidInputError, match="finite"):
        add_compliant_feet(solo, float("nan"), 0.01)
    with pytest.raises(InvalidInputError, match="leg, added"):
        add_compliant_feet(solo, 1000.0, 0.01, mass_from="body")
    with pytest.raises(UnknownNameError, match="FL_FOOT"):
        add_compliant_feet(solo, 1000.0, 0.01, feet=["paw"])
    with pytest.raises(UnknownNameError, match="shank"):
        add_compliant_feet(solo, 1000.0, 0.01, axis="vertical")
    with pytest.raises(InvalidInputError, match="non-zero"):
        add_compliant_feet(solo, 1000.0, 0.01, axis=(0, 0, 0))
    with pytest.raises(InvalidInputError, match="Robot or a Scene"):
        add_compliant_feet("solo12", 1000.0, 0.01)
    user = cd.Scene(
        solo,
        cd.Scene.from_robot(solo).contact_specs,
        efforts=[cd.UserEffort(lambda q, v, t: np.zeros(18), name="hold")],
    )
    with pytest.raises(InvalidInputError, match="hold"):
        add_compliant_feet(user, 1000.0, 0.01)
    with pytest.raises(InvalidInputError, match="shape"):
        compliant_state(solo, add_compliant_feet(solo, 1000.0, 0.01).robot, np.zeros(3))


def test_objects_beside_the_robot_stay_where_they_were():
    """A box beside solo12 keeps its joint, its frames and its pose on the compliant robot
    (the springs only add joints inside the legs), and the robot keeps its objects' list
    (the replay draws them from it)."""
    box = cd.SceneObject("box", "box", 0.5, size=(0.1, 0.1, 0.1), position=(0.6, 0.0, 0.05))
    robot = cd.add_objects(cd.load_robot("solo12"), [box])
    # the SRDF's named poses cover the box too (the compliant model maps each of them)
    assert {len(entry.data()) for entry in robot.model.referenceConfigurations} == {robot.nq}
    compliant = add_compliant_feet(robot, stiffness=2000.0, foot_mass=0.01).robot
    assert compliant.objects == (box,) and compliant.joint_names[-1] == "box"
    for model, q in ((robot.model, robot.q_ref), (compliant.model, compliant.q_ref)):
        data = model.createData()
        pin.framesForwardKinematics(model, data, q)
        corner = data.oMf[model.getFrameId("box/+x+y-z")].translation
        np.testing.assert_allclose(corner, [0.65, 0.05, 0.0], atol=1e-15)  # the pose plus half the size
