"""Named parameters of a scene: their names, values, changed copies and the efforts' derivatives.

Reference values come from the URDF and scene files themselves (link names,
masses, the numbers of the TOML files), from mechanics in closed form (the
mass matrix of a rigid body by the parallel-axis theorem, generalised gravity
of a point mass) and from central differences of `Scene.tau` through
`Scene.with_parameters` (a scene built again from the changed specs, an
independent path from the evaluators' closed forms).

Tolerances of the differences. A central difference with step h has truncation
error h²/6 |d³tau/dp³| and round-off about eps |tau| / h (eps = 2.2e-16).
Most efforts are affine in each of their parameters (a spring in its stiffness,
damping and rest length, the PD terms in kp and kd, the feed-forward in a
body's mass and centre of mass and in gravity): the third derivative is zero
and the difference is exact up to round-off, so those checks use a large step
and a tolerance of a few hundred eps |tau| / h.
"""

from __future__ import annotations

import dataclasses
import math
import xml.etree.ElementTree as ElementTree

import numpy as np
import pinocchio as pin
import pytest

import contactdiff as cd
from contactdiff.control.trot_controller import TrotController, TrotControllerEvaluator
from contactdiff.errors import InconsistentStateError, InvalidInputError, UnknownNameError
from contactdiff.model.compliance import add_compliant_feet
from contactdiff.model.efforts import EffortParameters, JointSpring, Spring, UserEffort
from contactdiff.model.kinematics import Kinematics
from contactdiff.model.parameters import BODY_FIELDS, Parameter, ParameterKind, body_names, resolve

EPS = np.finfo(float).eps
INERTIAL = ("mass", "com_x", "com_y", "com_z", "ixx", "ixy", "ixz", "iyy", "iyz", "izz")


@pytest.fixture(scope="module")
def drop():
    return cd.load_scene("solo12_drop")


@pytest.fixture(scope="module")
def trot():
    return cd.load_scene("solo12_trot")


def urdf_child_links(path: str) -> dict[str, str]:
    """Joint name -> child link, and ``root_joint`` -> the root link, read from the URDF."""
    root = ElementTree.parse(path).getroot()
    children = {j.get("name"): j.find("child").get("link") for j in root.iter("joint")}
    child_links = set(children.values())
    roots = [link.get("name") for link in root.iter("link") if link.get("name") not in child_links]
    return {**children, "root_joint": roots[0]}


def state(scene, seed=0, scale=0.2):
    """A random state near the scene's initial one, and its kinematics."""
    rng = np.random.default_rng(seed)
    q = scene.robot.integrate(scene.q0, scale * rng.standard_normal(scene.nv))
    v = rng.standard_normal(scene.nv)
    kin = Kinematics(scene.model)
    kin.update(q, v)
    return q, v, kin


def tau_at(scene, q, v, t):
    kin = Kinematics(scene.model)
    kin.update(q, v)
    return scene.tau(kin, t)


def central_difference(scene, name, q, v, t, h):
    """d tau/dp by a central difference through two scenes built with p ± h."""
    p = scene.parameter_values(name)[0]
    plus, minus = scene.with_parameters({name: p + h}), scene.with_parameters({name: p - h})
    return (tau_at(plus, q, v, t) - tau_at(minus, q, v, t)) / ((p + h) - (p - h))


# -- names ---------------------------------------------------------------------------------
def test_ball_names_from_its_urdf_and_scene_file():
    """ball.urdf: one link 'ball' on the prismatic joint 'z'; ball.toml: one contact."""
    names = cd.load_scene("ball").parameter_names()
    assert names == (
        ["scene:gravity_x", "scene:gravity_y", "scene:gravity_z"]
        + [f"body:ball:{f}" for f in INERTIAL]
        + ["joint:z:armature", "contact:ball:restitution", "contact:ball:offset"]
    )


def test_two_limb_merged_hips_are_not_bodies_and_springs_are_named_by_their_frames():
    """two_limb.urdf: three links on joints (body, left_foot, right_foot); the hips and
    rails are fixed links, merged; two.toml: two springs hip -> foot."""
    names = cd.load_scene("two_limb").parameter_names()
    bodies = sorted({n.split(":")[1] for n in names if n.startswith("body:")})
    assert bodies == ["body", "left_foot", "right_foot"]
    assert [n for n in names if n.startswith("joint:")] == [
        "joint:body_z:armature",
        "joint:left_foot_z:armature",
        "joint:right_foot_z:armature",
    ]
    assert [n for n in names if n.startswith("spring:")] == [
        f"spring:{s}:{f}"
        for s in ("left_hip-left_foot", "right_hip-right_foot")
        for f in ("stiffness", "damping", "rest_length")
    ]
    assert len(names) == len(set(names)) == 3 + 3 * 10 + 3 + 2 * 2 + 2 * 3


def test_planar_trot_soft_names_and_its_massless_links():
    """planar_trot_soft.urdf: seven joints, each with its own (child) link; the x-slider
    links carry no mass, as the file says."""
    scene = cd.load_scene("planar_trot_soft")
    names = scene.parameter_names()
    links = urdf_child_links(scene.robot.urdf)
    expected_bodies = [links[j] for j in scene.robot.joint_names]
    assert body_names(scene.model) == expected_bodies
    assert scene.parameter_values("body:body_x_link:mass")[0] == 0.0
    assert scene.parameter_values(["body:body:mass", "body:front_foot:mass"]).tolist() == [1.0, 1.0]
    assert sum(n.startswith("spring:") for n in names) == 6
    assert [n for n in names if n.startswith("contact:")] == [
        "contact:rear_foot:restitution",
        "contact:rear_foot:offset",
        "contact:front_foot:restitution",
        "contact:front_foot:offset",
    ]


def test_solo12_has_130_inertial_parameters_named_after_its_urdf_links(drop):
    """13 bodies (the base and 12 leg links, each the child link of its joint in the URDF)
    x 10, 12 one-dof joints, 4 contacts, 12 joint springs, in the documented order."""
    names = drop.parameter_names()
    links = urdf_child_links(drop.robot.urdf)
    bodies = [links[j] for j in drop.robot.joint_names]
    assert bodies[0] == "base_link" and len(bodies) == 13
    assert names[:3] == ["scene:gravity_x", "scene:gravity_y", "scene:gravity_z"]
    assert names[3:133] == [f"body:{b}:{f}" for b in bodies for f in INERTIAL]
    assert names[133:145] == [f"joint:{j}:armature" for j in drop.robot.joint_names[1:]]
    assert names[145:153] == [
        f"contact:{c}:{f}" for c in ("FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT") for f in ("restitution", "offset")
    ]
    assert names[153:] == [
        f"joint_spring:{j}:{f}" for j in drop.robot.joint_names[1:] for f in ("stiffness", "damping", "rest")
    ]
    assert len(set(names)) == len(names) == 3 + 130 + 12 + 8 + 36


def test_trot_names_are_the_controllers_real_numbers(trot):
    """Every float field of TrotController, none of feedforward (bool), stance (angles
    by joint), samples (a count)."""
    names = [n for n in trot.parameter_names() if n.startswith("trot:")]
    floats = [f.name for f in dataclasses.fields(TrotController) if f.name not in ("feedforward", "stance", "samples")]
    assert names == [f"trot:{f}" for f in floats]
    assert trot.parameter_values(["trot:kp", "trot:kd", "trot:period", "trot:step_height"]).tolist() == [
        10.0,
        0.2,
        0.4,
        0.035,
    ]  # solo12_trot.toml


def test_a_link_fixed_at_the_joint_origin_does_not_name_the_body():
    """anymal's 'base_inertia' link is fixed to 'base' at the identity: the base body is
    named 'base' (the joint's own child link), and base_inertia is no body."""
    robot = cd.load_robot("anymal")
    model = robot.model
    fixed = [f for f in model.frames if f.name == "base_inertia"][0]
    assert fixed.parentJoint == 1 and fixed.placement.isIdentity()  # the case the rule is for
    assert body_names(model)[0] == "base"
    assert "base_inertia" not in body_names(model)


def test_compliant_feet_bodies_and_springs():
    """add_compliant_feet moves each foot frame onto a new prismatic joint carrying the foot
    mass: the new body is named after the foot frame and has that mass; its spring is a
    joint spring named by the new joint."""
    scene = add_compliant_feet(cd.load_scene("solo12_drop"), stiffness=800.0, foot_mass=0.01, damping=2.0)
    names = scene.parameter_names()
    assert scene.parameter_values("body:FL_FOOT:mass")[0] == pytest.approx(0.01, rel=1e-15)
    assert "joint:FL_FOOT_spring:armature" in names
    assert scene.parameter_values(
        ["joint_spring:FL_FOOT_spring:stiffness", "joint_spring:FL_FOOT_spring:damping"]
    ).tolist() == [800.0, 2.0]


def test_repeated_targets_are_numbered_and_changed_one_by_one():
    """Two joint springs on one joint, two springs between the same frames, two user
    efforts with one name: #1, #2 in scene order, each changing its own spec only."""
    robot = cd.load_robot("two_limb")
    effort = UserEffort(lambda q, v, t, k: -k * v, name="drag", parameters={"k": 1.0})
    scene = cd.Scene(
        robot,
        [],
        [
            JointSpring("body_z", 1.0),
            JointSpring("body_z", 2.0, rest=0.3),
            Spring("left_hip", "left_foot", 3.0),
            Spring("left_hip", "left_foot", 4.0),
            effort,
            dataclasses.replace(effort, parameters={"k": 5.0}),
        ],
        q0=[1.0, 0.5, 0.5],
    )
    names = scene.parameter_names()
    for target in (
        "joint_spring:body_z#1",
        "joint_spring:body_z#2",
        "spring:left_hip-left_foot#1",
        "spring:left_hip-left_foot#2",
        "effort:drag#1",
        "effort:drag#2",
    ):
        assert any(n.startswith(target + ":") for n in names), target
    assert scene.parameter_values(
        ["joint_spring:body_z#2:stiffness", "spring:left_hip-left_foot#2:stiffness", "effort:drag#2:k"]
    ).tolist() == [2.0, 4.0, 5.0]
    new = scene.with_parameters({"joint_spring:body_z#2:rest": 0.7, "effort:drag#1:k": 9.0})
    assert [s.rest for s in new.effort_specs[:2]] == [0.0, 0.7]
    assert [dict(s.parameters)["k"] for s in new.effort_specs[4:]] == [9.0, 5.0]


@dataclasses.dataclass(frozen=True)
class _Misdeclared:
    """An effort spec whose parameters claim a kind that is not an effort's (``body``)."""

    def named_parameters(self) -> EffortParameters:
        return EffortParameters("body", "drag", ("gain",))

    def bind(self, robot):
        return JointSpring("body_z", 0.0).bind(robot)


def test_each_effort_declares_its_parameters_and_a_kind_of_no_effort_is_refused():
    """The names come from each spec's own declaration (kind, target, fields); a
    declaration of a kind that is not an effort's is refused naming the spec and the
    kinds an effort may declare, not listed as a body's."""
    assert JointSpring("knee", 1.0).named_parameters() == EffortParameters(
        "joint_spring", "knee", ("stiffness", "damping", "rest")
    )
    assert TrotController().named_parameters() == EffortParameters("trot", "", TrotController.NUMBERS)
    scene = cd.Scene(cd.load_robot("two_limb"), [], [_Misdeclared()], q0=[1.0, 0.5, 0.5])
    with pytest.raises(InvalidInputError, match=r"_Misdeclared.*spring, joint_spring, trot, effort"):
        scene.parameter_names()


def test_spring_name_defaults_to_its_frames_and_can_be_given():
    assert Spring("a", "b", 1.0).name == "a-b"
    scene = cd.Scene(
        cd.load_robot("two_limb"), [], [Spring("left_hip", "left_foot", 3.0, name="leg")], q0=[1.0, 0.5, 0.5]
    )
    assert "spring:leg:rest_length" in scene.parameter_names()
    with pytest.raises(InvalidInputError, match="name"):
        Spring("a", "b", 1.0, name="")


# -- values ----------------------------------------------------------------------------------
def test_values_read_back_equal_the_model_and_the_scene_file(drop):
    model = drop.model
    names = drop.parameter_names()
    values = dict(zip(names, drop.parameter_values(names)))
    masses = [values[n] for n in names if n.endswith(":mass")]
    assert sum(masses) == pytest.approx(pin.computeTotalMass(model), rel=1e-14)
    for j, body in enumerate(body_names(model), start=1):
        inertia = model.inertias[j]
        assert [values[f"body:{body}:com_{a}"] for a in "xyz"] == inertia.lever.tolist()
        assert values[f"body:{body}:ixy"] == inertia.inertia[1, 0]
        assert values[f"body:{body}:izz"] == inertia.inertia[2, 2]
    assert [values[f"scene:gravity_{a}"] for a in "xyz"] == [0.0, 0.0, -9.81]  # solo12_drop.toml
    assert values["contact:FL_FOOT:offset"] == 0.019102751730829468 and values["contact:HR_FOOT:restitution"] == 0
    assert [values[f"joint_spring:HL_KFE:{f}"] for f in ("stiffness", "damping", "rest")] == [20.0, 0.3, 1.6]
    assert all(values[n] == 0.0 for n in names if n.endswith(":armature"))  # example-robot-data has none
    assert drop.parameter_values("all").tolist() == [values[n] for n in names]


def test_with_parameters_round_trip_and_the_original_untouched(drop):
    before_values = drop.parameter_values("all")
    before_inertias = [pin.Inertia(i) for i in drop.model.inertias]
    before_armature = np.array(drop.model.armature)
    changes = {
        "body:FL_LOWER_LEG:mass": 0.05,
        "body:FL_LOWER_LEG:com_x": 0.01,  # two fields of one body
        "body:FL_LOWER_LEG:com_z": -0.08,
        "body:FL_LOWER_LEG:iyy": 1.5e-4,
        "joint:FL_KFE:armature": 1e-4,
        "scene:gravity_x": 0.5,
        "contact:FL_FOOT:restitution": 0.3,
        "contact:HR_FOOT:offset": 0.018,
        "joint_spring:FR_HFE:damping": 0.5,
    }
    new = drop.with_parameters(changes)
    assert new.parameter_values(list(changes)).tolist() == list(changes.values())
    untouched = [n for n in drop.parameter_names() if n not in changes]
    assert np.array_equal(new.parameter_values(untouched), drop.parameter_values(untouched))
    # the original scene, its robot's model and its specs are as before
    assert np.array_equal(drop.parameter_values("all"), before_values)
    assert all(
        np.array_equal(a.toDynamicParameters(), b.toDynamicParameters())
        for a, b in zip(before_inertias, drop.model.inertias)
    )
    assert np.array_equal(np.array(drop.model.armature), before_armature)
    assert drop.model.gravity.linear.tolist() == [0.0, 0.0, -9.81]
    assert new.model is not drop.model and new.robot is not drop.robot
    # kept: the state, name, foot choice; re-bound: the contacts on the new specs
    assert np.array_equal(new.q0, drop.q0) and np.array_equal(new.v0, drop.v0)
    assert new.name == drop.name and new.foot_choice == drop.foot_choice
    assert new.contacts[0].restitution == 0.3 and new.contacts[3].offset == 0.018
    # the new model's body is one inertia with both the new mass and the new centre of mass
    j = new.robot.joint_id("FL_KFE")
    inertia = new.model.inertias[j]
    assert inertia.mass == 0.05 and inertia.lever[0] == 0.01 and inertia.lever[2] == -0.08
    assert inertia.inertia[1, 1] == 1.5e-4
    assert new.model.armature[new.model.joints[j].idx_v] == 1e-4


def test_parameter_objects_and_all_are_accepted(drop):
    params = resolve(drop, ["body:base_link:mass", "scene:gravity_z"])
    assert params[0] == Parameter(ParameterKind.BODY, "base_link", "mass", joint=1)
    assert params[1].name == "scene:gravity_z" and params[1].target == ""
    assert drop.with_parameters({params[0]: 2.0}).parameter_values(params[:1])[0] == 2.0
    assert len(resolve(drop, "all")) == len(drop.parameter_names())
    assert drop.with_parameters({}).parameter_values("all").tolist() == drop.parameter_values("all").tolist()


def test_mass_matrix_follows_the_parallel_axis_theorem():
    """planar_trot_rigid at pitch 0 (only the body has mass; pitch about world -y): with
    mass m, centre of mass (a, 0, b) in the body frame and I_yy = J about it, the centre
    of mass moves with (x, z, pitch) as (x - b pitch, z + a pitch), so
    M = [[m, 0, -m b], [0, m, m a], [-m b, m a, J + m (a² + b²)]]."""
    scene = cd.load_scene("planar_trot_rigid")
    m, a, b, J = 2.0, 0.1, -0.2, 0.5
    new = scene.with_parameters({"body:body:mass": m, "body:body:com_x": a, "body:body:com_z": b, "body:body:iyy": J})
    M = pin.crba(new.model, new.model.createData(), new.q0)
    expected = np.array([[m, 0, -m * b], [0, m, m * a], [-m * b, m * a, J + m * (a * a + b * b)]])
    assert np.allclose(M, expected, rtol=0, atol=1e-14)
    # and gravity: g = -m Jcᵀ G with the same centre-of-mass Jacobian
    G = np.array([0.3, 0.0, -2.0])
    g = pin.computeGeneralizedGravity(
        *(lambda s: (s.model, s.model.createData(), s.q0))(
            new.with_parameters({"scene:gravity_x": G[0], "scene:gravity_z": G[2]})
        )
    )
    assert np.allclose(g, -m * np.array([G[0], G[2], -b * G[0] + a * G[2]]), rtol=0, atol=1e-14)


def test_ball_mass_armature_and_gravity():
    """A point mass on a vertical slider: M = m + armature, g = -m g_z."""
    ball = cd.load_scene("ball")
    new = ball.with_parameters({"body:ball:mass": 2.5, "joint:z:armature": 0.25, "scene:gravity_z": -3.0})
    data = new.model.createData()
    assert pin.crba(new.model, data, new.q0)[0, 0] == 2.75
    assert pin.computeGeneralizedGravity(new.model, data, new.q0)[0] == 7.5
    assert pin.crba(ball.model, ball.model.createData(), ball.q0)[0, 0] == 1.0  # the original


# -- errors ----------------------------------------------------------------------------------
def test_unknown_names_list_the_valid_ones():
    ball = cd.load_scene("ball")
    with pytest.raises(UnknownNameError, match="body:ball:mass") as info:
        ball.parameter_values("body:ball:weight")
    assert "'body:ball:weight'" in str(info.value) and "contact:ball:offset" in str(info.value)
    with pytest.raises(UnknownNameError, match="joint:z:armature"):
        ball.with_parameters({"trot:kp": 1.0})
    other = Parameter(ParameterKind.BODY, "ball", "mass", joint=2)  # not this scene's
    with pytest.raises(UnknownNameError):
        resolve(ball, [other])


@pytest.mark.parametrize(
    "name, value, words",
    [
        ("body:FL_LOWER_LEG:mass", 0.0, ["mass > 0", "0.0"]),
        ("body:FL_LOWER_LEG:mass", -1.0, ["mass > 0", "-1.0"]),
        ("body:FL_LOWER_LEG:ixy", 1e-3, ["positive", "semi-definite"]),
        ("body:base_link:izz", 0.1, ["I1 <= I2 + I3"]),  # the largest moment above the sum of the others
        ("body:base_link:com_y", math.nan, ["finite", "nan"]),
        ("joint:FL_HAA:armature", -1e-3, [">= 0", "-0.001"]),
        ("contact:FL_FOOT:restitution", -0.1, ["[0, 1]", "-0.1"]),
        ("contact:FL_FOOT:restitution", 1.5, ["[0, 1]", "1.5"]),
        ("contact:FL_FOOT:offset", math.inf, ["finite", "inf"]),
        ("joint_spring:FL_HAA:stiffness", -2.0, [">= 0", "-2"]),
        ("scene:gravity_z", "down", ["number", "down"]),
    ],
)
def test_invalid_values_are_refused_with_the_value_in_the_message(drop, name, value, words):
    with pytest.raises(InvalidInputError) as info:
        drop.with_parameters({name: value})
    message = str(info.value)
    assert name in message
    for w in words:
        assert w in message


def test_a_massless_body_needs_a_mass_before_a_centre_of_mass():
    soft = cd.load_scene("planar_trot_soft")
    with pytest.raises(InvalidInputError, match="massless"):
        soft.with_parameters({"body:body_x_link:com_x": 0.1})
    new = soft.with_parameters({"body:body_x_link:mass": 0.5, "body:body_x_link:com_x": 0.1})
    assert new.parameter_values(["body:body_x_link:mass", "body:body_x_link:com_x"]).tolist() == [0.5, 0.1]


def test_trot_and_spring_values_go_through_their_own_checks(trot):
    with pytest.raises(InvalidInputError, match=r"trot:duty.*duty must be in \(0, 1\)"):
        trot.with_parameters({"trot:duty": 1.2})
    with pytest.raises(InvalidInputError, match="rest_length.*-0.1"):
        cd.load_scene("two_limb").with_parameters({"spring:left_hip-left_foot:rest_length": -0.1})


def test_a_contact_offset_that_makes_the_initial_state_penetrate():
    with pytest.raises(InconsistentStateError, match="penetrates"):
        cd.load_scene("ball").with_parameters({"contact:ball:offset": 1.5})  # the ball starts at z = 1


# -- derivatives of the efforts ------------------------------------------------------------
def affine_tolerance(tau_scale: float, h: float) -> float:
    """Round-off of a central difference of an effort affine in the parameter: each tau
    carries a few eps of its size; the difference divides by 2h. 100 eps |tau| / h leaves
    an order of magnitude of margin over that."""
    return 100 * EPS * max(tau_scale, 1.0) / h


def test_joint_spring_derivatives_against_differences_and_closed_forms(drop):
    """Each joint spring: d/dk = -(q_j - rest), d/dc = -v_j, d/drest = k on its coordinate."""
    q, v, kin = state(drop, seed=1)
    params = resolve(drop, [n for n in drop.parameter_names() if n.startswith("joint_spring:")])
    D = drop.tau_parameter_derivatives(kin, 0.3, params)
    tau_scale = np.abs(drop.tau(kin, 0.3)).max()
    for k, p in enumerate(params):
        spec = next(s for s in drop.effort_specs if s.joint == p.target)
        iq, iv = drop.robot.scalar_joint(p.target)
        expected = np.zeros(drop.nv)
        expected[iv] = {"stiffness": -(q[iq] - spec.rest), "damping": -v[iv], "rest": spec.stiffness}[p.field]
        assert np.array_equal(D[:, k], expected), p.name
    for k in (0, 4, 8, 35):  # stiffness, damping, rest of a few (all are affine in these)
        h = 0.1
        fd = central_difference(drop, params[k].name, q, v, 0.3, h)
        assert np.abs(fd - D[:, k]).max() <= affine_tolerance(tau_scale, h), params[k].name


@pytest.mark.parametrize("scene_name", ["two_limb", "planar_trot_soft"])
def test_frame_spring_derivatives_against_differences(scene_name):
    scene = cd.load_scene(scene_name)
    scene = scene.with_parameters({n: 0.4 for n in scene.parameter_names() if n.endswith(":damping")})
    q, v, kin = state(scene, seed=2, scale=0.1)
    names = [n for n in scene.parameter_names() if n.startswith("spring:")]
    D = scene.tau_parameter_derivatives(kin, 0.0, names)
    tau_scale = np.abs(scene.tau(kin, 0.0)).max()
    h = 0.05
    for k, name in enumerate(names):
        fd = central_difference(scene, name, q, v, 0.0, h)
        assert np.abs(fd - D[:, k]).max() <= affine_tolerance(tau_scale, h), name
        assert np.abs(D[:, k]).max() > 1e-5, name  # every column acts here (far above the tolerance)


def test_two_limb_spring_stiffness_in_closed_form():
    """two_limb: the left limb hangs on a vertical spring from the left hip; stretched to
    l = z_body - z_foot above its rest length, a stiffer spring pulls the body down and
    the limb up: d tau/dk = (l - rest) (-1 on body_z, +1 on left_foot_z)."""
    scene = cd.load_scene("two_limb")
    kin = Kinematics(scene.model)
    kin.update(np.array([1.0, 0.3, 0.6]), np.zeros(3))
    D = scene.tau_parameter_derivatives(kin, 0.0, ["spring:left_hip-left_foot:stiffness"])[:, 0]
    assert np.allclose(D, [-(0.7 - 0.5), 0.7 - 0.5, 0.0], rtol=0, atol=1e-15)


def test_models_bodies_gravity_and_contacts_have_zero_columns_without_a_model_based_effort(drop):
    _, _, kin = state(drop, seed=3)
    names = [n for n in drop.parameter_names() if n.split(":")[0] in ("scene", "body", "joint", "contact")]
    assert not drop.tau_parameter_derivatives(kin, 0.1, names).any()


def test_trot_gains_derivatives_against_differences(trot):
    """tau is affine in kp and kd (b = g (kp q* + kd q̇*) + ff): exact differences."""
    q, v, kin = state(trot, seed=4, scale=0.1)
    for t in (0.0731, 0.2413):  # inside pieces of the schedule, away from its breakpoints
        D = trot.tau_parameter_derivatives(kin, t, ["trot:kp", "trot:kd"])
        tau_scale = np.abs(trot.tau(kin, t)).max()
        for k, name in enumerate(["trot:kp", "trot:kd"]):
            h = 0.1 * trot.parameter_values(name)[0]
            fd = central_difference(trot, name, q, v, t, h)
            assert np.abs(fd - D[:, k]).max() <= affine_tolerance(tau_scale, h), name
            assert np.abs(D[:, k]).max() > 1e-2 and not D[:6, k].any()  # the legs only


def table_noise(evaluator, tau_scale: float, value: float) -> float:
    """Bound on the round-off of a difference through two rebuilt controllers, with the
    controller's own step ``h = SCHEDULE_STEP * max(|value|, 0.1)``: each table
    reproduces the schedule to condition · (degree + 1) · eps of its size (which also
    covers the inverse kinematics' 1e-12 m residual moving the reference: kp times
    ~1e-11 rad), and the difference of two divides by 2h."""
    table = evaluator._schedule
    step = TrotControllerEvaluator.SCHEDULE_STEP * max(abs(value), 0.1)
    return table.condition * (table.degree + 1) * EPS * max(tau_scale, np.abs(table.table).max()) / step


def test_trot_schedule_and_clock_derivatives_against_richardson_differences(trot):
    """The schedule numbers (and t_start) move breakpoints and the reference: compare with
    Richardson's extrapolation R = (4 D(h/2) - D(h)) / 3 of differences through rebuilt
    scenes, h = 1e-3 max(|p|, 0.1). Tolerance: R's own error is O(h⁴), well below
    |D(h) - D(h/2)| (the h² term's size); the derivative under test has truncation
    ~(SCHEDULE_STEP/1e-3)² |D(h) - D(h/2)| (1e-4 of it) and round-off, `table_noise`,
    counted twice for margin. t_start's derivative is -d tau/dt, a central difference
    in t of its own (`time_derivative`, step 1e-6 period), within the same bound."""
    q, v, kin = state(trot, seed=5, scale=0.1)
    # between knots of the reference (phases 43.5/240, 202.5/240): one with a foot in its
    # final approach, one with a foot rising in swing (step_height acts only there)
    times = (0.0725, 0.3375)
    names = [f"trot:{f}" for f in TrotController.NUMBERS if f not in ("kp", "kd", "release_gain")]
    D = [trot.tau_parameter_derivatives(kin, t, names) for t in times]
    tau_scale = max(np.abs(trot.tau(kin, t)).max() for t in times)
    for k, name in enumerate(names):
        p = trot.parameter_values(name)[0]
        h = 1e-3 * max(abs(p), 0.1)
        scenes = {x: trot.with_parameters({name: p + x}) for x in (h, -h, h / 2, -h / 2)}
        for i, t in enumerate(times):
            tau = {x: tau_at(sc, q, v, t) for x, sc in scenes.items()}
            wide, narrow = (tau[h] - tau[-h]) / (2 * h), (tau[h / 2] - tau[-h / 2]) / h
            richardson = (4 * narrow - wide) / 3
            tol = np.abs(wide - narrow).max() + 2 * table_noise(trot.efforts[0], tau_scale, p)
            assert np.abs(D[i][:, k] - richardson).max() <= tol, (name, t, np.abs(D[i][:, k] - richardson).max(), tol)
    assert np.maximum(np.abs(D[0]).max(axis=0), np.abs(D[1]).max(axis=0)).min() > 1e-2  # every column acts


def test_trot_release_gain_at_its_bound_uses_a_one_sided_difference(trot):
    """release_gain = 0 (solo12_trot) cannot go below 0; during a leg's lift-off window the
    gain scale is g = r + (1 - r) S(d), affine in r, so dtau/dr = (1 - S) kp (q* - q) + ...
    is checked against a forward difference through rebuilt scenes (exact for affine)."""
    q, v, kin = state(trot, seed=6, scale=0.1)
    evaluator = trot.efforts[0]
    leg = 0
    liftoff = evaluator.scheduled_liftoff(leg)  # gait phase of leg 0's lift-off
    t = (liftoff + 0.3 * evaluator.spec.transfer) * evaluator.spec.period  # inside its gain window
    D = trot.tau_parameter_derivatives(kin, t, ["trot:release_gain"])[:, 0]
    h = 0.05
    forward = (tau_at(trot.with_parameters({"trot:release_gain": h}), q, v, t) - trot.tau(kin, t)) / h
    tau_scale = np.abs(trot.tau(kin, t)).max()
    # one-sided weights (-3/2, 2, -1/2) / h: round-off up to 4 table errors / h = 4 table_noise; 2 for margin
    tol = affine_tolerance(tau_scale, h) + 2 * 4 * table_noise(evaluator, tau_scale, 0.0)
    assert np.abs(D - forward).max() <= tol
    assert np.abs(D[list(evaluator.legs[leg].iv)]).max() > 1e-3  # leg 0's joints feel it


def test_trot_feedforward_follows_masses_and_gravity(trot):
    """The feed-forward is built from the model when the controller is bound: it is
    affine in a body's mass and centre of mass and in gravity (exact differences), and
    does not depend on inertias or armatures (bit-identical torques)."""
    q, v, kin = state(trot, seed=7, scale=0.1)
    t = 0.2413
    names = [
        "body:base_link:mass",
        "body:base_link:com_x",
        "body:FR_LOWER_LEG:mass",
        "body:HL_UPPER_LEG:com_z",
        "scene:gravity_x",
        "scene:gravity_z",
        "body:base_link:izz",
        "joint:FL_KFE:armature",
    ]
    D = trot.tau_parameter_derivatives(kin, t, names)
    tau_scale = np.abs(trot.tau(kin, t)).max()
    for k, name in enumerate(names[:6]):
        p = trot.parameter_values(name)[0]
        h = 0.2 * abs(p) if name.endswith("mass") else 0.05
        fd = central_difference(trot, name, q, v, t, h)
        assert np.abs(fd - D[:, k]).max() <= affine_tolerance(tau_scale, h), name
        assert np.abs(D[:, k]).max() > 1e-3, name
    assert not D[:, 6:].any()
    changed = trot.with_parameters({"body:base_link:izz": 0.02, "joint:FL_KFE:armature": 1e-3})
    assert np.array_equal(tau_at(changed, q, v, t), trot.tau(kin, t))
    # without feed-forward the model does not enter the controller
    no_ff = cd.Scene(
        trot.robot,
        trot.contact_specs,
        [dataclasses.replace(trot.effort_specs[0], feedforward=False)],
        None,
        trot.q0,
        trot.v0,
    )
    assert not no_ff.tau_parameter_derivatives(kin, t, names).any()


def _drag(q, v, t, k, w):
    """A user effort nonlinear in its parameter w: tau = -k v - sin(w t) q (ball: nv = 1)."""
    return -k * v - np.sin(w * t) * q


def _drag_parameter_jacobian(q, v, t, k, w):
    return np.column_stack([-v, -t * np.cos(w * t) * q])


@pytest.mark.parametrize("closed_form", [True, False])
def test_user_effort_parameters(closed_form):
    """Keyword parameters reach the function; with_parameters changes them; their
    derivative is the parameter_jacobian's, or central differences with step
    fd_step max(1, |p|) whose error is h²/6 |d³tau/dw³| + eps |tau| / h, with
    |d³tau/dw³| <= t³ |q|."""
    ball = cd.load_scene("ball")
    effort = UserEffort(
        _drag,
        name="drag",
        parameters={"k": 0.3, "w": 2.0},
        parameter_jacobian=_drag_parameter_jacobian if closed_form else None,
    )
    scene = cd.Scene(ball.robot, ball.contact_specs, [effort], q0=ball.q0)
    assert scene.parameter_names()[-2:] == ["effort:drag:k", "effort:drag:w"]
    q, v, t = np.array([0.8]), np.array([-0.5]), 1.7
    kin = Kinematics(scene.model)
    kin.update(q, v)
    assert scene.tau(kin, t)[0] == pytest.approx(0.3 * 0.5 - math.sin(2.0 * t) * 0.8, rel=1e-15)
    changed = scene.with_parameters({"effort:drag:w": 3.0})
    assert tau_at(changed, q, v, t)[0] == pytest.approx(0.3 * 0.5 - math.sin(3.0 * t) * 0.8, rel=1e-15)
    D = scene.tau_parameter_derivatives(kin, t, ["effort:drag:w", "effort:drag:k"])
    exact = np.array([[-t * math.cos(2.0 * t) * 0.8, 0.5]])
    if closed_form:
        assert np.allclose(D, exact, rtol=1e-15, atol=0)
    else:
        h = effort.fd_step * 2.0
        tol = h * h / 6 * t**3 * 0.8 + 10 * EPS * 1.0 / h
        assert np.abs(D - exact).max() <= tol


def test_user_effort_parameter_protocol_errors():
    f = lambda q, v, t, k: -k * q  # noqa: E731
    with pytest.raises(InvalidInputError, match="identifier"):
        UserEffort(f, parameters={"not a name": 1.0})
    with pytest.raises(InvalidInputError, match="finite.*nan"):
        UserEffort(f, parameters={"k": math.nan})
    with pytest.raises(InvalidInputError, match="repeated: k"):
        UserEffort(f, parameters=[("k", 1.0), ("k", 2.0)])
    with pytest.raises(InvalidInputError, match="no parameters"):
        UserEffort(lambda q, v, t: q, parameter_jacobian=lambda q, v, t: q)
    assert UserEffort(f, parameters={"k": 2}).parameters == (("k", 2.0),)
    ball = cd.load_scene("ball")
    bad = UserEffort(f, name="spring", parameters={"k": 2.0}, parameter_jacobian=lambda q, v, t, k: np.zeros(3))
    scene = cd.Scene(ball.robot, [], [bad], q0=ball.q0)
    kin = Kinematics(scene.model)
    kin.update(scene.q0, scene.v0)
    with pytest.raises(InvalidInputError, match="parameter_jacobian returned shape"):
        scene.tau_parameter_derivatives(kin, 0.0, ["effort:spring:k"])


def test_derivatives_of_a_mixed_list_fill_their_own_columns(drop):
    """Columns in the order asked, effort and model parameters interleaved, and the same
    list twice gives the same numbers (the plan is reused)."""
    q, v, kin = state(drop, seed=8)
    names = [
        "body:base_link:mass",
        "joint_spring:FR_KFE:stiffness",
        "contact:FL_FOOT:offset",
        "joint_spring:FL_HAA:rest",
    ]
    params = resolve(drop, names)
    D = drop.tau_parameter_derivatives(kin, 0.0, params)
    again = drop.tau_parameter_derivatives(kin, 0.0, params)
    assert np.array_equal(D, again)
    iq, iv = drop.robot.scalar_joint("FR_KFE")
    assert D[iv, 1] == -(q[iq] - (-1.6)) and np.count_nonzero(D[:, 1]) == 1
    assert D[drop.robot.scalar_joint("FL_HAA")[1], 3] == 20.0
    assert not D[:, [0, 2]].any()
    assert set(BODY_FIELDS) == set(INERTIAL)
