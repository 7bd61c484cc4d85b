"""Objects beside a robot (contactdiff.model.objects): frames, inertias, state layout, errors.

References: a box's corners are its half sizes with every sign; a uniform box's
inertia about its centre is m (b² + c²)/12 about x (and so on), a sphere's 2 m r²/5,
a cylinder's m r²/2 about its axis and m (3 r² + l²)/12 across it; a free object
under gravity alone falls with acceleration g and no rotation.
"""

from __future__ import annotations

import itertools

import numpy as np
import pinocchio as pin
import pytest

import contactdiff as cd
from contactdiff.model.objects import RobotFrame, SceneObject, add_objects, empty_robot

BOX = dict(name="box", shape="box", mass=0.2, size=(0.04, 0.05, 0.06), position=(0.3, 0.1, 0.5))
ATOL = 1e-14  # m: a placement is one product of exact-ish O(1) numbers


def _placements(robot, names, q=None):
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, robot.q_ref if q is None else q)
    return {n: data.oMf[robot.frame_id(n)] for n in names}


def test_box_frames_are_its_centre_corners_and_points():
    robot = add_objects(empty_robot(), [SceneObject(**BOX, points={"left": (0.0, -0.025, 0.0)})])
    half = np.array(BOX["size"]) / 2
    corners = {
        "box/" + "".join(("+" if s > 0 else "-") + a for s, a in zip(signs, "xyz")): half * signs
        for signs in itertools.product((1, -1), repeat=3)
    }
    where = _placements(robot, ["box", "box/left", *corners])
    centre = np.array(BOX["position"])
    np.testing.assert_allclose(where["box"].translation, centre, atol=ATOL)
    np.testing.assert_allclose(where["box/left"].translation, centre + [0, -0.025, 0], atol=ATOL)
    for name, offset in corners.items():
        np.testing.assert_allclose(where[name].translation, centre + offset, atol=ATOL)


def test_an_orientation_turns_the_points():
    robot = add_objects(empty_robot(), [SceneObject(**{**BOX, "rpy": (0.0, 0.0, np.pi / 2)})])
    # a quarter turn about z takes the object's +x to the world's +y
    corner = _placements(robot, ["box/+x-y+z"])["box/+x-y+z"].translation
    np.testing.assert_allclose(corner, np.array(BOX["position"]) + [0.025, 0.02, 0.03], atol=1e-12)


@pytest.mark.parametrize(
    "spec, diagonal",
    [
        (dict(shape="box", mass=2.0, size=(1.0, 2.0, 3.0)), [2 * 13 / 12, 2 * 10 / 12, 2 * 5 / 12]),
        (dict(shape="sphere", mass=2.0, radius=0.5), [0.2] * 3),
        (dict(shape="cylinder", mass=2.0, radius=0.5, length=3.0), [2 * (0.75 + 9) / 12] * 2 + [0.25]),
    ],
)
def test_shape_inertias_are_those_of_uniform_solids(spec, diagonal):
    robot = add_objects(empty_robot(), [SceneObject("thing", **spec)])
    M = pin.crba(robot.model, robot.model.createData(), robot.q_ref)
    np.testing.assert_allclose(M, np.diag([spec["mass"]] * 3 + diagonal), atol=1e-14)


@pytest.mark.parametrize(
    "spec, volume",
    [
        (dict(shape="box", size=(0.1, 0.2, 0.3)), 0.1 * 0.2 * 0.3),  # m³: x y z
        (dict(shape="sphere", radius=0.02), 4.0 / 3.0 * np.pi * 0.02**3),  # 4/3 π r³
        (dict(shape="cylinder", radius=0.05, length=0.4), np.pi * 0.05**2 * 0.4),  # π r² l
    ],
)
def test_a_density_gives_the_mass_of_the_uniform_solid(spec, volume):
    """``density`` (kg/m³) instead of ``mass``: the mass is density × volume (steel, 7850
    kg/m³: a ball of radius 2 cm weighs 0.263 kg), and the inertia is that of the same
    shape given that mass. Round-off of a few products: 1e-15 relative."""
    dense = SceneObject("thing", density=7850.0, **spec)
    assert dense.mass == pytest.approx(7850.0 * volume, rel=1e-15) and dense.density is None
    weighed = SceneObject("thing", mass=7850.0 * volume, **spec)
    np.testing.assert_allclose(dense.inertia().matrix(), weighed.inertia().matrix(), rtol=1e-15, atol=0)


def test_objects_come_after_the_robot_and_a_fixed_object_has_no_joint():
    panda = cd.load_robot("panda")
    robot = add_objects(
        panda,
        [
            SceneObject(**BOX),
            SceneObject("post", "cylinder", 1.0, radius=0.1, length=1.0, position=(1.0, 0.0, 0.5), fixed=True),
        ],
    )
    assert robot.nq == panda.nq + 7 and robot.nv == panda.nv + 6
    np.testing.assert_array_equal(robot.q_ref[: panda.nq], panda.q_ref)
    np.testing.assert_allclose(robot.q_ref[panda.nq :], [0.3, 0.1, 0.5, 0, 0, 0, 1], atol=ATOL)
    assert robot.joint_names[-1] == "box" and [o.name for o in robot.objects] == ["box", "post"]
    np.testing.assert_allclose(_placements(robot, ["post"])["post"].translation, [1.0, 0.0, 0.5], atol=ATOL)
    assert panda.nq == 9 and not panda.objects  # the robot itself is untouched


def test_a_robot_frame_is_a_point_of_its_parent():
    panda = cd.load_robot("panda")
    robot = add_objects(panda, frames=[RobotFrame("left_pad", "panda_leftfinger", (0.0, 0.0, 0.045))])
    where = _placements(robot, ["left_pad", "panda_leftfinger"])
    finger = where["panda_leftfinger"]
    np.testing.assert_allclose(where["left_pad"].translation, finger.act(np.array([0.0, 0.0, 0.045])), atol=ATOL)


def test_a_free_object_falls_with_gravity(tmp_path):
    scene = cd.Scene(
        add_objects(empty_robot(), [SceneObject(**{**BOX, "rpy": (0.3, -0.2, 1.0)})]), gravity=[0.0, 0.0, -9.81]
    )
    traj = cd.simulate(scene, 0.5)
    fallen = _placements(scene.robot, ["box"], traj.q)["box"]
    # z(t) = z0 - g t²/2, no rotation: exact for the integrator's polynomial steps up to its tolerance
    np.testing.assert_allclose(fallen.translation, np.array(BOX["position"]) - [0, 0, 9.81 * 0.125], atol=1e-9)
    np.testing.assert_allclose(fallen.rotation, scene.robot.objects[0].pose.rotation, atol=1e-12)


def test_a_urdf_object_keeps_its_frames_under_its_name(tmp_path):
    urdf = tmp_path / "brick.urdf"
    urdf.write_text(
        '<?xml version="1.0"?><robot name="brick"><link name="body"><inertial><mass value="1"/>'
        '<inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link>'
        '<link name="tip"/><joint name="tip_joint" type="fixed"><parent link="body"/>'
        '<child link="tip"/><origin xyz="0 0 0.2"/></joint></robot>'
    )
    robot = add_objects(
        empty_robot(), [SceneObject("brick", urdf="brick.urdf", position=(1.0, 2.0, 3.0))], base=tmp_path
    )
    assert robot.joint_names == ["brick"] and robot.nq == 7
    np.testing.assert_allclose(_placements(robot, ["brick/tip"])["brick/tip"].translation, [1.0, 2.0, 3.2], atol=ATOL)
    fixed = add_objects(
        empty_robot(),
        [SceneObject("brick", urdf="brick.urdf", position=(1.0, 2.0, 3.0), rpy=(np.pi / 2, 0.0, 0.0), fixed=True)],
        base=tmp_path,
    )
    assert fixed.nq == 0  # no joint: its frames hang on the universe at its pose (x turned 90°: z -> -y)
    np.testing.assert_allclose(_placements(fixed, ["brick/tip"])["brick/tip"].translation, [1.0, 1.8, 3.0], atol=1e-12)


@pytest.mark.parametrize(
    "spec, message",
    [
        (dict(name="b", shape="cone", mass=1.0), "box, cylinder, sphere"),
        (dict(name="b", shape="sphere", mass=1.0), "needs radius"),
        (dict(name="b", shape="box", mass=1.0, size=(1, 1, 1), radius=0.5), "no radius"),
        (dict(name="b", shape="box", mass=0.0, size=(1, 1, 1)), "mass must be > 0"),
        (dict(name="b", shape="box", mass=1.0, size=(1, -1, 1)), "(1, -1, 1)"),
        (dict(name="b", shape="sphere", mass=1.0, radius=float("nan")), "nan"),
        (dict(name="a/b", shape="sphere", mass=1.0, radius=1.0), "'a/b'"),
        (dict(name="b", urdf="x.urdf", radius=1.0), "drop radius"),
        (dict(name="b", shape="box", size=(1, 1, 1)), "'b': a box needs its mass (kg"),  # was 1 kg silently
        (dict(name="b", mass=1.0, radius=0.5), "'b' needs a shape (box, sphere, cylinder) or a urdf"),
        (dict(name="b", urdf="x.urdf", mass=2.0), "masses from its file; drop mass"),
        (dict(name="b", shape="sphere", radius=0.1, mass=1.0, density=1000.0), "mass = 1.0, density = 1000.0"),
        (dict(name="b", shape="sphere", radius=0.1, density=0.0), "density must be > 0 kg/m³, got 0.0"),
        (dict(name="b", urdf="x.urdf", density=2.0), "drop density"),
    ],
)
def test_bad_objects_are_refused_with_the_bad_value(spec, message):
    with pytest.raises(cd.InvalidInputError, match=message.replace("(", r"\(").replace(")", r"\)")):
        SceneObject(**spec)


def test_names_must_be_free():
    panda = cd.load_robot("panda")
    with pytest.raises(cd.InvalidInputError, match="'panda_hand' is already"):
        add_objects(panda, [SceneObject("panda_hand", "sphere", 1.0, radius=0.1)])
    with pytest.raises(cd.InvalidInputError, match="repeated: 'b'"):
        add_objects(panda, [SceneObject("b", "sphere", 1.0, radius=0.1)] * 2)
    with pytest.raises(cd.UnknownNameError, match="panda_hand_tcp"):
        add_objects(panda, frames=[RobotFrame("pad", "no_such_frame")])


def test_a_scene_file_of_objects_alone(tmp_path):
    path = tmp_path / "two.toml"
    path.write_text(
        'gravity = [0, 0, 0]\n[[object]]\nname = "a"\nshape = "sphere"\nradius = 0.1\nmass = 1.0\n'
        '[[object]]\nname = "b"\nshape = "sphere"\nradius = 0.1\nmass = 1.0\nposition = [1, 0, 0]\n'
    )
    scene = cd.load_scene(path)
    assert scene.robot.joint_names == ["a", "b"]
    path.write_text('floating_base = true\n[[object]]\nname = "a"\nshape = "sphere"\nradius = 0.1\nmass = 1.0\n')
    with pytest.raises(cd.InvalidInputError, match="has none"):
        cd.load_scene(path)
    path.write_text('[[object]]\nname = "a"\nshape = "sphere"\nradius = 0.1\nmass = 1.0\ncolour = "red"\n')
    with pytest.raises(cd.UnknownNameError, match="colour"):
        cd.load_scene(path)
    path.write_text('[[object]]\nname = "a"\nshape = "sphere"\nradius = 0.1\n')  # no mass
    with pytest.raises(cd.InvalidInputError, match="object 'a': a sphere needs its mass"):
        cd.load_scene(path)
    path.write_text("gravity = [0, 0, 0]\n")
    with pytest.raises(cd.InvalidInputError, match="missing the key 'robot'"):
        cd.load_scene(path)


def test_scenes_that_drive_a_robot_include_its_joint_targets():
    from contactdiff.scenes.scene_file import driving_scenes

    assert driving_scenes("panda") == ["panda_lift"]  # the only robots/ scene on the panda: [[joint_targets]]
    assert {"solo12_drop", "solo12_trot"} <= set(driving_scenes("solo12"))  # joint springs, a trot
