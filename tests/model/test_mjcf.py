"""MJCF models: loading, default classes, what Pinocchio would drop, the reference pose,
sphere feet, and the dynamics against closed forms.

Tolerance: the closed forms and Pinocchio's recursions are both a few dozen
floating-point operations on O(1) numbers, so they agree to ~1e-15 relative;
``RTOL = 1e-12`` leaves three orders of margin while a wrong term (a lost joint
``pos`` moves M by ~1e-1) fails.
"""

from __future__ import annotations

import warnings

import numpy as np
import pinocchio as pin
import pytest
from helpers import menagerie_file
from mjcf_models import (
    FOOT_L,
    FOOT_R,
    FREE_XML,
    LEG_XML,
    SLIDER_ARMATURE,
    SLIDER_MASS,
    SLIDER_XML,
    G,
    free_bias,
    free_spatial_inertia,
    leg_bias,
    leg_mass_matrix,
    write,
)

from contactdiff.errors import ModelLoadError, UnsupportedModelError
from contactdiff.model.feet import FootRule
from contactdiff.model.mjcf import MJCFWarning, load_mjcf, mujoco_velocity_map
from contactdiff.model.robot_files import load_robot

RTOL = 1e-12


def _mass_matrix(robot, q):
    M = pin.crba(robot.model, robot.new_data(), q)
    return np.triu(M) + np.triu(M, 1).T


def test_sliding_mass_with_armature_in_every_dynamics_path(tmp_path):
    """``M = m + a`` in crba, aba and computeMinverse (the paths the simulator uses), ``b = m g``."""
    robot = load_robot(write(tmp_path, "slider.xml", SLIDER_XML))
    assert not robot.floating_base and robot.joint_names == ["z"]
    q, v, tau = np.zeros(1), np.array([0.7]), np.array([5.0])
    expected = SLIDER_MASS + SLIDER_ARMATURE
    assert _mass_matrix(robot, q)[0, 0] == pytest.approx(expected, rel=RTOL)
    assert pin.computeMinverse(robot.model, robot.new_data(), q)[0, 0] == pytest.approx(1 / expected, rel=RTOL)
    bias = SLIDER_MASS * G
    assert pin.nle(robot.model, robot.new_data(), q, v)[0] == pytest.approx(bias, rel=RTOL)
    assert pin.aba(robot.model, robot.new_data(), q, v, tau)[0] == pytest.approx((tau[0] - bias) / expected, rel=RTOL)


def test_two_link_leg_with_class_joint_pos(tmp_path):
    """The knee's ``pos`` comes from a default class: M and b match the closed forms of a
    hinge 0.4 m below the hip (0.3 m if the class's ``pos`` were lost: M22 off by ~50 %)."""
    robot = load_robot(write(tmp_path, "leg.xml", LEG_XML))
    rng = np.random.default_rng(3)
    for _ in range(5):
        q, v = rng.uniform(-2, 2, 2), rng.uniform(-3, 3, 2)
        np.testing.assert_allclose(_mass_matrix(robot, q), leg_mass_matrix(q), rtol=RTOL, atol=0)
        scale = np.abs(leg_bias(q, v)).max()
        np.testing.assert_allclose(
            pin.nle(robot.model, robot.new_data(), q, v), leg_bias(q, v), rtol=0, atol=RTOL * scale
        )


def test_leg_reference_pose_is_its_first_keyframe(tmp_path):
    """No ``home`` key: the first keyframe, ``bent``."""
    robot = load_robot(write(tmp_path, "leg.xml", LEG_XML))
    np.testing.assert_array_equal(robot.q_ref, [0.3, -0.6])


def test_home_keyframe_wins_over_the_first(tmp_path):
    text = LEG_XML.replace(
        '<key name="bent" qpos="0.3 -0.6"/>', '<key name="bent" qpos="0.3 -0.6"/><key name="home" qpos="-0.1 0.2"/>'
    )
    robot = load_robot(write(tmp_path, "leg.xml", text))
    np.testing.assert_array_equal(robot.q_ref, [-0.1, 0.2])


def test_qpos0_without_keyframes_is_the_joint_refs(tmp_path):
    """Without keyframes the reference is MuJoCo's ``qpos0``: each hinge at its ``ref``."""
    text = LEG_XML.replace('<keyframe><key name="bent" qpos="0.3 -0.6"/></keyframe>', "").replace(
        '<joint name="hip"/>', '<joint name="hip" ref="0.25"/>'
    )
    robot = load_robot(write(tmp_path, "leg.xml", text))
    np.testing.assert_array_equal(robot.q_ref, [0.25, 0.0])


def test_leg_with_floating_base_stands_on_its_sphere_foot(tmp_path):
    """floating_base=True adds a free joint; the foot sphere on the leaf body (the shank)
    is the foot, a round contact of its radius whose frame sits at the sphere's centre,
    ``FOOT_L`` below the knee."""
    pelvis = '<body name="pelvis" pos="0 0 1"><inertial pos="0 0 0" mass="4" diaginertia="0.1 0.1 0.1"/>'
    text = LEG_XML.replace('<body name="thigh" pos="0 0 1">', pelvis + '<body name="thigh">').replace(
        "</worldbody>", "</body></worldbody>"
    )
    robot = load_robot(write(tmp_path, "leg.xml", text), floating_base=True)
    assert robot.floating_base and robot.nq == 9
    np.testing.assert_array_equal(robot.q_ref, [0, 0, 1, 0, 0, 0, 1, 0.3, -0.6])  # the key, the pelvis's pos
    assert robot.feet == ("foot",)
    assert robot.foot_choice.rule is FootRule.MJCF_SPHERES
    assert robot.foot_choice.radii == {"foot": FOOT_R}
    data = robot.new_data()
    q = robot.q_ref.copy()
    q[7:] = 0.0  # leg straight down: the foot centre is L1 + FOOT_L below the hip
    pin.framesForwardKinematics(robot.model, data, q)
    hip = data.oMi[robot.joint_id("hip")].translation
    foot = data.oMf[robot.frame_id("foot")].translation
    np.testing.assert_allclose(foot - hip, [0, 0, -(0.4 + FOOT_L)], rtol=0, atol=1e-15)
    from contactdiff.model.scene import Scene

    (contact,) = Scene.from_robot(robot).contact_specs
    assert contact.radius == FOOT_R


def test_free_body_with_full_inertia(tmp_path):
    """``<freejoint/>`` is a floating base without asking; M is the spatial inertia about the
    origin and b Newton-Euler's (`mjcf_models.free_bias`), at random states."""
    robot = load_robot(write(tmp_path, "free.xml", FREE_XML))
    assert robot.floating_base and robot.nv == 6
    np.testing.assert_allclose(robot.q_ref[:3], [0, 0, 1])  # qpos0: the body's pos
    rng = np.random.default_rng(0)
    for _ in range(5):
        q = pin.randomConfiguration(robot.model, -np.ones(7), np.ones(7))
        v = rng.uniform(-2, 2, 6)
        M = free_spatial_inertia()
        np.testing.assert_allclose(_mass_matrix(robot, q), M, rtol=0, atol=RTOL * np.abs(M).max())
        rotation = pin.Quaternion(q[6], *q[3:6]).normalized().matrix()
        b = free_bias(rotation, v)
        np.testing.assert_allclose(pin.nle(robot.model, robot.new_data(), q, v), b, rtol=0, atol=RTOL * np.abs(b).max())


def test_geom_mass_and_pos_from_a_class(tmp_path):
    """A body without <inertial>: one sphere geom of mass 2 kg, radius 0.05 m, 0.5 m below a
    hinge, all three from a class. ``M = 2/5 m r² + m d² = 0.002 + 0.5``."""
    text = """<mujoco><default><default class="bob"><geom type="sphere" mass="2" size="0.05" pos="0 0 -0.5"/>
      </default></default><worldbody><body name="b"><joint name="j" axis="0 1 0"/><geom class="bob"/>
      </body></worldbody></mujoco>"""
    robot = load_robot(write(tmp_path, "bob.xml", text))
    assert _mass_matrix(robot, np.zeros(1))[0, 0] == pytest.approx(0.4 * 2 * 0.05**2 + 2 * 0.25, rel=RTOL)


def test_mujoco_velocity_map_by_finite_differences(tmp_path):
    """``T v`` is (d/dt of the body origin's world position, the same angular velocity) along
    ``q(t) = q ⊕ t v``; ``Ṫ v`` is d/dt of ``T(q(t)) v``. Central differences, step 1e-6:
    truncation ~1e-12 and round-off ~1e-10 on O(1) values, so atol 1e-8."""
    robot = load_robot(write(tmp_path, "free.xml", FREE_XML))
    rng = np.random.default_rng(1)
    q = pin.randomConfiguration(robot.model, -np.ones(7), np.ones(7))
    v = rng.uniform(-1, 1, 6)
    T, Tdot_v = mujoco_velocity_map(robot.model, q, v)
    eps = 1e-6
    plus, minus = robot.integrate(q, eps * v), robot.integrate(q, -eps * v)
    np.testing.assert_allclose(T[:3] @ v, (plus[:3] - minus[:3]) / (2 * eps), rtol=0, atol=1e-8)
    np.testing.assert_array_equal(T[3:], np.eye(6)[3:])
    fd = (mujoco_velocity_map(robot.model, plus) @ v - mujoco_velocity_map(robot.model, minus) @ v) / (2 * eps)
    np.testing.assert_allclose(Tdot_v, fd, rtol=0, atol=1e-8)


# -- what Pinocchio would drop ------------------------------------------------------------
def _with(tmp_path, extra: str, body: str = "") -> str:
    text = LEG_XML.replace("</worldbody>", body + "</worldbody>").replace("</mujoco>", extra + "</mujoco>")
    return write(tmp_path, "leg.xml", text)


@pytest.mark.parametrize(
    "extra, phrase",
    [
        (
            '<equality><connect name="loop" body1="thigh" body2="shank" anchor="0 0 0"/></equality>',
            "equality constraint(s) connect 'loop'",
        ),
        ('<equality><joint joint1="hip" joint2="knee"/></equality>', "equality constraint(s) joint (unnamed)"),
        ('<tendon><fixed name="t"><joint joint="hip" coef="1"/></fixed></tendon>', "tendon(s) fixed 't'"),
        ('<asset><hfield name="terrain" nrow="2" ncol="2" size="1 1 0.1 0.1"/></asset>', "height field(s) 'terrain'"),
        (
            '<actuator><general name="m" joint="hip" dyntype="filter"/></actuator>',
            "activation dynamics of actuator(s) general 'm'",
        ),
        ('<actuator><cylinder name="c" joint="knee"/></actuator>', "activation dynamics of actuator(s) cylinder 'c'"),
    ],
)
def test_left_out_features_are_named_in_one_warning(tmp_path, extra, phrase):
    with pytest.warns(MJCFWarning) as caught:
        robot = load_robot(_with(tmp_path, extra))
    (message,) = [str(w.message) for w in caught]
    assert "\n" not in message and phrase in message and "left out of the dynamics" in message
    np.testing.assert_allclose(_mass_matrix(robot, np.zeros(2)), leg_mass_matrix(np.zeros(2)), rtol=RTOL)


def test_passive_joint_forces_are_named_in_one_warning(tmp_path):
    """MuJoCo adds joint stiffness, damping and friction loss as passive forces; the loaded
    dynamics does not: one warning names each attribute's joints, a class's value included
    (the knee's stiffness comes from the class ``knee``), and the mass matrix is the leg's."""
    text = LEG_XML.replace('<joint pos="0 0 -0.1"/>', '<joint pos="0 0 -0.1" stiffness="30"/>').replace(
        '<joint name="hip"/>', '<joint name="hip" damping="0.5" frictionloss="0.1"/>'
    )
    with pytest.warns(MJCFWarning) as caught:
        robot = load_robot(write(tmp_path, "leg.xml", text))
    (message,) = [str(w.message) for w in caught]
    assert "\n" not in message and "left out of the dynamics: joint " in message
    assert "stiffness of 1 joint(s) ('knee')" in message
    assert "damping of 1 joint(s) ('hip')" in message and "frictionloss of 1 joint(s) ('hip')" in message
    np.testing.assert_allclose(_mass_matrix(robot, np.zeros(2)), leg_mass_matrix(np.zeros(2)), rtol=RTOL)


def test_zero_passive_joint_forces_are_not_warned_about(tmp_path):
    text = LEG_XML.replace('<joint name="hip"/>', '<joint name="hip" damping="0" stiffness="0" frictionloss="0"/>')
    with warnings.catch_warnings():
        warnings.simplefilter("error", MJCFWarning)
        load_robot(write(tmp_path, "leg.xml", text))


def test_flex_is_refused(tmp_path):
    flex = '<deformable><flex name="cloth" dim="2" body="thigh thigh thigh" vertex="0 0 0 1 0 0 0 1 0"/></deformable>'
    with pytest.raises(UnsupportedModelError, match=r"<flex> 'cloth'"):
        load_robot(_with(tmp_path, flex))


def test_replicate_is_refused(tmp_path):
    body = (
        '<replicate count="3" offset="0.1 0 0"><body name="r"><joint name="rj"/>'
        '<inertial pos="0 0 0" mass="1" diaginertia="1 1 1"/></body></replicate>'
    )
    with pytest.raises(UnsupportedModelError, match="<replicate>.*mj_saveLastXML"):
        load_robot(_with(tmp_path, "", body))


def test_mesh_mass_without_inertial_is_refused_when_its_file_is_missing(tmp_path):
    text = """<mujoco><asset><mesh name="m" file="m.stl"/></asset><worldbody><body name="b">
      <joint name="j"/><geom type="mesh" mesh="m"/></body></worldbody></mujoco>"""
    with pytest.raises(
        UnsupportedModelError,
        match=r"1 bodies without <inertial> take mass from mesh geoms \('b'\) "
        r"whose mesh files are missing \(m.stl\)",
    ):
        load_robot(write(tmp_path, "mesh.xml", text))


# The mesh box: corners (0, 0, 0) and (0.125, 0.25, 0.5) in the file (binary fractions: exact as
# 32-bit floats), then ``refpos`` 0.5 m along z and ``scale`` 2 along x: half sizes
# (a, b, c) = (0.125, 0.125, 0.25), centre (0.125, 0.125, -0.25) in the mesh frame, and
# (0.125, 0, -0.5) in the body after the geom's ``pos``.
_MESH_PENDULUM = """<mujoco><compiler meshdir="assets"/>
  <asset><mesh name="bob" file="bob.{kind}" refpos="0 0 0.5" scale="2 1 1"{inertia}/></asset>
  <worldbody><body name="b"><joint name="j" axis="0 1 0"/>
  <geom type="mesh" mesh="bob" pos="0 -0.125 -0.25" {weight}/></body></worldbody></mujoco>"""


@pytest.mark.parametrize("weight, mass", [('density="500"', 500 * 0.25 * 0.25 * 0.5), ('mass="3"', 3.0)])
def test_mesh_geom_weighs_as_a_uniform_solid(tmp_path, weight, mass):
    """A pendulum about y whose bob is a mesh box (binary STL): ``m = ρ V`` (``V = 8 a b c``)
    or the geom's ``mass``; about the hinge, ``M = m (a² + c²) / 3 + m (dx² + dz²)``
    (the box's own moment about its centre's y axis, plus parallel axes), and its centre of
    mass is the box's centre."""
    from mjcf_models import box_triangles, write_stl

    (tmp_path / "assets").mkdir()
    write_stl(tmp_path / "assets" / "bob.stl", box_triangles([0, 0, 0], [0.125, 0.25, 0.5]))
    robot = load_robot(write(tmp_path, "pendulum.xml", _MESH_PENDULUM.format(kind="stl", inertia="", weight=weight)))
    a, c, dx, dz = 0.125, 0.25, 0.125, -0.5
    expected = mass * ((a**2 + c**2) / 3 + dx**2 + dz**2)
    assert _mass_matrix(robot, np.zeros(1))[0, 0] == pytest.approx(expected, rel=RTOL)
    assert robot.model.inertias[1].mass == pytest.approx(mass, rel=RTOL)
    np.testing.assert_allclose(robot.model.inertias[1].lever, [dx, 0, dz], rtol=0, atol=1e-15)  # m, round-off


def test_mesh_file_that_is_not_binary_stl_is_named(tmp_path):
    (tmp_path / "assets").mkdir()
    (tmp_path / "assets" / "bob.stl").write_text("solid bob\nendsolid bob\n")
    text = _MESH_PENDULUM.format(kind="stl", inertia="", weight='density="500"')
    with pytest.raises(UnsupportedModelError, match=r"body 'b': mesh file .*bob.stl' is not a binary STL file"):
        load_robot(write(tmp_path, "pendulum.xml", text))


def test_mesh_given_by_vertices_in_the_xml_is_refused_by_name(tmp_path):
    text = """<mujoco><asset><mesh name="m" vertex="0 0 0 1 0 0 0 1 0 0 0 1"/></asset><worldbody><body name="b">
      <joint name="j"/><geom type="mesh" mesh="m"/></body></worldbody></mujoco>"""
    with pytest.raises(UnsupportedModelError, match=r"body 'b': <mesh> 'm' is given by its vertices in the XML"):
        load_robot(write(tmp_path, "mesh.xml", text))


def test_convex_hull_mesh_inertia_is_refused(tmp_path):
    from mjcf_models import box_triangles, write_stl

    (tmp_path / "assets").mkdir()
    write_stl(tmp_path / "assets" / "bob.stl", box_triangles([0, 0, 0], [0.125, 0.25, 0.5]))
    text = _MESH_PENDULUM.format(kind="stl", inertia=' inertia="convex"', weight='density="500"')
    with pytest.raises(
        UnsupportedModelError,
        match=r"inertia='convex'; the mesh inertias computed here are "
        r"'legacy' and 'exact'",
    ):
        load_robot(write(tmp_path, "pendulum.xml", text))


def test_mesh_mass_of_a_body_welded_to_the_world_is_not_needed(tmp_path):
    """A fixed mount weighed by a mesh moves nothing: the pendulum below it keeps ``M = 0.502``."""
    text = """<mujoco><asset><mesh name="m" file="m.stl"/></asset><worldbody><body name="mount">
      <geom type="mesh" mesh="m"/><body name="b"><joint name="j" axis="0 1 0"/>
      <geom type="sphere" mass="2" size="0.05" pos="0 0 -0.5"/></body></body></worldbody></mujoco>"""
    robot = load_robot(write(tmp_path, "mount.xml", text))
    assert _mass_matrix(robot, np.zeros(1))[0, 0] == pytest.approx(0.4 * 2 * 0.05**2 + 2 * 0.25, rel=RTOL)


def test_massless_mesh_geoms_are_removed_not_weighed(tmp_path):
    """A ``density="0"`` mesh weighs nothing in MuJoCo (Pinocchio would give it 1 kg): the
    pendulum of `test_geom_mass_and_pos_from_a_class` keeps ``M = 0.502``."""
    text = """<mujoco><asset><mesh name="m" file="m.stl"/></asset><worldbody><body name="b">
      <joint name="j" axis="0 1 0"/><geom type="mesh" mesh="m" density="0"/>
      <geom type="sphere" mass="2" size="0.05" pos="0 0 -0.5"/></body></worldbody></mujoco>"""
    robot = load_robot(write(tmp_path, "mesh.xml", text))
    assert _mass_matrix(robot, np.zeros(1))[0, 0] == pytest.approx(0.4 * 2 * 0.05**2 + 2 * 0.25, rel=RTOL)


def test_several_fixed_top_level_bodies_are_all_kept(tmp_path):
    """Pinocchio reads the first top-level body only; two fixed-base pendulums both stay."""
    second = LEG_XML.split("<worldbody>")[1].split("</worldbody>")[0]
    second = second.replace('name="', 'name="b_').replace('class="b_', 'class="')
    text = LEG_XML.replace("</worldbody>", second + "</worldbody>").replace('<key name="bent" qpos="0.3 -0.6"/>', "")
    robot = load_robot(write(tmp_path, "two.xml", text))
    assert robot.nv == 4 and {"hip", "b_hip", "knee", "b_knee"} == set(robot.joint_names)


def test_a_second_floating_tree_is_refused(tmp_path):
    body = '<body name="box"><freejoint/><inertial pos="0 0 0" mass="1" diaginertia="1 1 1"/></body>'
    with pytest.raises(UnsupportedModelError, match="2 top-level bodies with joints"):
        load_robot(_with(tmp_path, "", body))


def test_jointless_top_level_bodies_beside_a_floating_robot_are_left_out_with_a_warning(tmp_path):
    text = FREE_XML.replace("</worldbody>", '<body name="target" pos="1 0 0"/></worldbody>')
    with pytest.warns(MJCFWarning, match="top-level body 'target'"):
        robot = load_robot(write(tmp_path, "free.xml", text))
    assert robot.nv == 6


def test_unknown_class_is_named(tmp_path):
    with pytest.raises(ModelLoadError, match="class 'nope', which is not defined; classes: foot, knee, main"):
        load_robot(write(tmp_path, "leg.xml", LEG_XML.replace('"knee" class="knee"', '"knee" class="nope"')))


def test_xml_that_is_not_mjcf_is_read_as_urdf(tmp_path):
    """An ``.xml`` file whose root is ``<robot>`` goes to the URDF reader."""
    from helpers import LEG_URDF

    robot = load_robot(write(tmp_path, "leg_urdf.xml", LEG_URDF))
    assert robot.joint_names == ["body_x", "body_z", "hip"]


# -- Menagerie ------------------------------------------------------------------------------
def test_go2_has_four_sphere_feet_and_its_home_pose():
    path = menagerie_file("unitree_go2/go2.xml")
    with pytest.warns(MJCFWarning) as caught:
        robot = load_robot(path)
    (message,) = [str(w.message) for w in caught]  # only its joints' damping and friction loss are left out
    assert "left out of the dynamics: joint damping of 12 joint(s)" in message
    assert "; frictionloss of 12 joint(s)" in message and "stiffness" not in message
    assert robot.floating_base
    assert robot.feet == ("FL", "FR", "RL", "RR")
    assert robot.foot_choice.rule is FootRule.MJCF_SPHERES
    assert robot.foot_choice.radii == dict.fromkeys(robot.feet, 0.022)  # the class "foot"'s size
    np.testing.assert_allclose(robot.q_ref[:3], [0, 0, 0.27])  # keyframe home
    assert robot.model.armature[6:] == pytest.approx(np.full(12, 0.01))  # class "go2"
    assert "collision spheres on leaf bodies" in robot.foot_choice.describe()


def test_berkeley_humanoid_gets_two_feet_not_hands():
    robot = load_robot(menagerie_file("berkeley_humanoid/berkeley_humanoid.xml"))
    assert len(robot.feet) == 2 and all("FOOT" in f.upper() or "faa" in f for f in robot.feet)
    assert robot.foot_choice.rule is FootRule.LOWEST_END_FRAMES


def test_cli_checks_an_mjcf_file(capsys):
    from contactdiff.cli import main

    path = menagerie_file("unitree_go2/go2.xml")
    assert main(["check", str(path), "--samples", "2"]) == 0
    out = capsys.readouterr().out
    assert "feet FL, FR, RL, RR: the model's collision spheres on leaf bodies" in out


def test_scene_file_names_an_mjcf_robot(tmp_path):
    from contactdiff.scenes.scene_file import load_scene

    write(tmp_path, "free.xml", FREE_XML)
    scene_path = write(tmp_path, "scene.toml", 'robot = "free.xml"\n')
    scene = load_scene(scene_path)
    assert scene.robot.floating_base and scene.robot.nv == 6


def test_load_mjcf_floating_false_removes_the_free_joint(tmp_path):
    robot = load_mjcf(write(tmp_path, "free.xml", FREE_XML), floating_base=False)
    assert robot.nv == 0 and not robot.floating_base
    pelvis = '<body name="pelvis" pos="0 0 1"><freejoint/><inertial pos="0 0 0" mass="4" diaginertia="0.1 0.1 0.1"/>'
    text = (
        LEG_XML.replace('<body name="thigh" pos="0 0 1">', pelvis + '<body name="thigh">')
        .replace("</worldbody>", "</body></worldbody>")
        .replace('qpos="0.3 -0.6"', 'qpos="0 0 1 1 0 0 0 0.3 -0.6"')
    )
    robot = load_mjcf(write(tmp_path, "leg.xml", text), floating_base=False)
    np.testing.assert_array_equal(robot.q_ref, [0.3, -0.6])  # the key without the free joint's part


def test_a_joint_and_a_body_of_one_name_get_distinct_frames(tmp_path):
    """MJCF names joints and bodies apart; the body keeps the name, the joint's frame gets
    ``_joint`` (the joint itself keeps its name)."""
    robot = load_robot(write(tmp_path, "leg.xml", LEG_XML.replace('<joint name="knee"', '<joint name="shank"')))
    assert robot.model.frames[robot.frame_id("shank")].type == pin.FrameType.BODY
    assert robot.model.frames[robot.frame_id("shank_joint")].type == pin.FrameType.JOINT
    assert "shank" in robot.joint_names


def test_cassie_loads_with_its_loops_left_out_and_two_feet():
    with pytest.warns(MJCFWarning, match=r"equality constraint\(s\) connect \(unnamed\) ×4"):
        robot = load_robot(menagerie_file("agility_cassie/cassie.xml"))
    assert robot.feet == ("left-foot", "right-foot") and robot.nv == 32


def test_a_fixed_top_body_keeps_its_placement(tmp_path):
    """The leg hung from a thigh turned upside down (``quat="0 1 0 0"``: 180 deg about x, links
    along +z, hip axis along -y): a rotation ``q`` takes ``(0, 0, L)`` to ``(-L sin q, 0, L cos q)``,
    so the potential and the gravity torques change sign, M is unchanged (Pinocchio alone
    drops a top body's placement: the torques would keep their sign)."""
    text = LEG_XML.replace('<body name="thigh" pos="0 0 1">', '<body name="thigh" pos="0 0 1" quat="0 1 0 0">')
    robot = load_robot(write(tmp_path, "leg.xml", text))
    q = np.array([0.4, -0.9])
    np.testing.assert_allclose(
        pin.nle(robot.model, robot.new_data(), q, np.zeros(2)), -leg_bias(q, np.zeros(2)), rtol=RTOL
    )
    np.testing.assert_allclose(_mass_matrix(robot, q), leg_mass_matrix(q), rtol=RTOL)


def test_joint_limits_are_read_as_mujoco_reads_them(tmp_path):
    """Default ``angle="degree"``: the hinge's -90..45 deg is -pi/2..pi/4 rad; a slide's range is
    a length (0.5 m, not 0.5 deg); no range, or ``limited="false"``, is unlimited."""
    inertial = '<inertial pos="0 0 0" mass="1" diaginertia="1 1 1"/>'
    text = f"""<mujoco><worldbody><body name="a"><joint name="h" axis="0 1 0" range="-90 45"/>{inertial}
      <body name="b"><joint name="s" type="slide" range="-0.5 0.25"/>{inertial}
      <body name="c"><joint name="u" axis="1 0 0"/>{inertial}
      <body name="d"><joint name="l" axis="1 0 0" range="-1 1" limited="false"/>{inertial}
      </body></body></body></body></worldbody></mujoco>"""
    model = load_robot(write(tmp_path, "limits.xml", text)).model
    np.testing.assert_allclose(model.lowerPositionLimit, [-np.pi / 2, -0.5, -np.inf, -np.inf], rtol=1e-15)
    np.testing.assert_allclose(model.upperPositionLimit, [np.pi / 4, 0.25, np.inf, np.inf], rtol=1e-15)


def test_orientations_as_mujoco_defines_them():
    """Closed forms, (w, x, y, z): 90 deg about z is (cos 45°, 0, 0, sin 45°) whatever the axis's
    length; intrinsic ``xyz`` Euler angles compose as ``q_x q_y q_z``, extrinsic ``XYZ`` as
    ``q_z q_y q_x``; ``xyaxes`` (0,1,0), (-1,0,0) is 90 deg about z; ``zaxis`` (0,1,0) takes z to y
    by the shortest turn, -90 deg about x; ``zaxis`` (0,0,-1) is a half turn about x."""
    from xml.etree.ElementTree import Element

    from contactdiff.model.mjcf_tree import orientation, quat_multiply, quat_rotate

    c = np.sqrt(0.5)
    expected = np.array([c, 0, 0, c])
    np.testing.assert_allclose(orientation(Element("b", axisangle="0 0 3 90"), True, "xyz"), expected, atol=1e-15)
    np.testing.assert_allclose(orientation(Element("b", xyaxes="0 1 0 -1 0 0"), True, "xyz"), expected, atol=1e-15)
    np.testing.assert_allclose(orientation(Element("b", zaxis="0 1 0"), True, "xyz"), [c, -c, 0, 0], atol=1e-15)
    np.testing.assert_allclose(orientation(Element("b", zaxis="0 0 -1"), True, "xyz"), [0, 1, 0, 0], atol=1e-15)

    def turn(axis, angle):
        return np.concatenate([[np.cos(angle / 2)], np.sin(angle / 2) * np.eye(3)[axis]])

    a, b, g = 0.3, -0.7, 1.1
    intrinsic = quat_multiply(quat_multiply(turn(0, a), turn(1, b)), turn(2, g))
    extrinsic = quat_multiply(quat_multiply(turn(2, g), turn(1, b)), turn(0, a))
    np.testing.assert_allclose(orientation(Element("b", euler=f"{a} {b} {g}"), False, "xyz"), intrinsic, atol=1e-15)
    np.testing.assert_allclose(orientation(Element("b", euler=f"{a} {b} {g}"), False, "XYZ"), extrinsic, atol=1e-15)
    np.testing.assert_allclose(quat_rotate(expected, np.array([1.0, 0, 0])), [0, 1, 0], atol=1e-15)


def test_sphere_feet_chosen_by_hand_stay_round(tmp_path):
    """``feet=["foot"]`` on the fixed leg: the geom's frame exists and its contact is round."""
    robot = load_robot(write(tmp_path, "leg.xml", LEG_XML), feet=["foot"])
    assert robot.foot_choice.rule is FootRule.GIVEN and robot.foot_choice.radii == {"foot": FOOT_R}


def test_keyframe_of_the_wrong_size_is_named(tmp_path):
    with pytest.raises(ModelLoadError, match=r"keyframe 'bent' has 3 qpos values; the model has nq = 2"):
        load_robot(write(tmp_path, "leg.xml", LEG_XML.replace('qpos="0.3 -0.6"', 'qpos="0.3 -0.6 1"')))


def test_sphere_hands_high_above_the_ground_are_not_feet(tmp_path):
    """Menagerie's H1 pattern: capsule feet on the legs' leaf bodies, collision spheres on the
    arms' leaf bodies (the hands) 0.9 m up. No sphere lies in the foot band (5 % of the 1.3 m
    height): the lowest end frames rule takes the two ankles, and the hands are left out."""
    inertial = '<inertial pos="0 0 0" mass="1" diaginertia="0.01 0.01 0.01"/>'

    def limb(name, y, z, end):
        return (
            f'<body name="{name}_upper" pos="0 {y} {z}"><joint name="{name}_1" axis="0 1 0"/>{inertial}'
            f'<body name="{name}_end" pos="0 0 -0.4"><joint name="{name}_2" axis="0 1 0"/>{inertial}{end}'
            "</body></body>"
        )

    foot = '<geom type="capsule" fromto="-0.05 0 -0.05 0.1 0 -0.05" size="0.02"/>'
    hand = '<geom type="sphere" size="0.03" pos="0 0 -0.3"/>'
    text = f"""<mujoco><worldbody><body name="pelvis" pos="0 0 0.87"><freejoint/>{inertial}
      {limb("left_leg", 0.1, 0, foot)}{limb("right_leg", -0.1, 0, foot)}
      {limb("left_arm", 0.2, 0.4, hand)}{limb("right_arm", -0.2, 0.4, hand)}</body></worldbody></mujoco>"""
    robot = load_robot(write(tmp_path, "humanoid.xml", text))
    assert robot.foot_choice.rule is FootRule.LOWEST_END_FRAMES
    assert robot.feet == ("left_leg_end", "right_leg_end")


def test_round_feet_of_an_mjcf_robot_without_sphere_feet_is_a_named_error(tmp_path):
    """The two-link leg on a floating pelvis, its foot chosen by hand as the shank's body: no
    sphere there, and no URDF to look in."""
    from contactdiff.errors import InvalidInputError
    from contactdiff.model.round_feet import foot_spheres

    robot = load_robot(write(tmp_path, "leg.xml", LEG_XML), feet=["shank"])
    with pytest.raises(InvalidInputError, match="is an MJCF model: its round feet are the collision spheres"):
        foot_spheres(robot)


def test_actuator_dynamics_from_a_class_are_named(tmp_path):
    extra = (
        '<default><default class="slow"><general dyntype="filter" dynprm="0.1"/></default></default>'
        '<actuator><general name="m" class="slow" joint="hip"/></actuator>'
    )
    with pytest.warns(MJCFWarning, match="activation dynamics of actuator\\(s\\) general 'm'"):
        load_robot(_with(tmp_path, extra))
