"""Mass matrix and bias forces of MJCF models against MuJoCo's own (``mujoco`` package).

Tolerance: both libraries run O(n) recursions in double precision on the same
numbers, so they agree to round-off (~1e-15 relative times the depth of the
tree, measured ≤ 7e-15 on Menagerie); ``RTOL = 1e-9`` is the issue's bound and
leaves a factor 1e5, while a dropped term (a class's joint ``pos``, a free
joint's velocity frame) is ~1e-3..1e-1.
"""

from __future__ import annotations

import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco", reason="the MuJoCo cross-checks need the mujoco package (test extra)")

from helpers import menagerie_file  # noqa: E402
from mjcf_models import (  # noqa: E402
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
from mujoco_reference import MujocoReference, random_states, stripped_copy  # noqa: E402

from contactdiff.model import mjcf_xml  # noqa: E402
from contactdiff.model.robot_files import load_robot  # noqa: E402

RTOL = 1e-9


def _close(actual, expected, what):
    scale = max(np.abs(expected).max(), 1e-300)
    error = np.abs(actual - expected).max() / scale
    assert error <= RTOL, f"{what}: relative difference {error:.2e}"


def _compare(robot, path, count=4):
    """M and b of ``robot`` against MuJoCo's model of ``path`` at ``count`` random states."""
    reference = MujocoReference(robot.model, path)
    import pinocchio as pin

    for k, (q, v) in enumerate(random_states(robot.model, count)):
        M_mj, b_mj = reference.dynamics(q, v)
        M = pin.crba(robot.model, robot.new_data(), q)
        M = np.triu(M) + np.triu(M, 1).T
        _close(M, M_mj, f"{path.name} M, state {k}")
        _close(pin.nle(robot.model, robot.new_data(), q, v), b_mj, f"{path.name} bias, state {k}")
    return reference


def test_slider_with_armature_matches_mujoco_and_the_closed_form(tmp_path):
    path = write(tmp_path, "slider.xml", SLIDER_XML)
    reference = _compare(load_robot(path), path)
    M, b = reference.dynamics(np.zeros(1), np.array([0.5]))
    _close(M, np.array([[SLIDER_MASS + SLIDER_ARMATURE]]), "MuJoCo M")
    _close(b, np.array([SLIDER_MASS * G]), "MuJoCo bias")


def test_two_link_leg_matches_mujoco_and_the_closed_form(tmp_path):
    path = write(tmp_path, "leg.xml", LEG_XML)
    reference = _compare(load_robot(path), path)
    for q, v in random_states(reference.pin, 3, seed=5):
        M, b = reference.dynamics(q, v)
        _close(M, leg_mass_matrix(q), "MuJoCo M vs closed form")
        _close(b, leg_bias(q, v), "MuJoCo bias vs closed form")


def test_free_body_with_full_inertia_matches_mujoco_and_the_closed_form(tmp_path):
    """Needs the free joint's conversion: without it M differs in the linear block."""
    import pinocchio as pin

    path = write(tmp_path, "free.xml", FREE_XML)
    reference = _compare(load_robot(path), path)
    for q, v in random_states(reference.pin, 3, seed=7):
        M, b = reference.dynamics(q, v)
        _close(M, free_spatial_inertia(), "MuJoCo M vs closed form")
        rotation = pin.Quaternion(q[6], *q[3:6]).normalized().matrix()
        _close(b, free_bias(rotation, v), "MuJoCo bias vs closed form")


def test_classes_written_inline_do_not_change_mujocos_model(tmp_path):
    """The loader's rewrite (classes inline) read by MuJoCo gives MuJoCo's model of the file."""
    from xml.etree.ElementTree import tostring

    path = write(tmp_path, "leg.xml", LEG_XML)
    resolved = tmp_path / "resolved.xml"
    resolved.write_bytes(tostring(mjcf_xml.resolve(mjcf_xml.read_document(path))))
    robot = load_robot(path)
    original, rewritten = MujocoReference(robot.model, path), MujocoReference(robot.model, resolved)
    for q, v in random_states(robot.model, 3):
        for a, b in zip(original.dynamics(q, v), rewritten.dynamics(q, v)):
            _close(b, a, "rewritten vs original")


@pytest.mark.filterwarnings("ignore::contactdiff.model.mjcf.MJCFWarning")  # Cassie's loops, tested elsewhere
@pytest.mark.parametrize(
    "relative",
    [
        "unitree_go2/go2.xml",
        "berkeley_humanoid/berkeley_humanoid.xml",
        "leap_hand/right_hand.xml",
        "agility_cassie/scene.xml",
    ],
)
def test_menagerie_model_matches_mujoco(tmp_path, relative):
    """Go2, Berkeley Humanoid, the LEAP hand (a fixed palm turned upside down by its ``quat``)
    and Cassie's scene (an include, two ball joints, its loops left out: MuJoCo's M and bias
    hold no constraint either; meshes stripped for MuJoCo) at four random states;
    their joint limits are MuJoCo's; and the reference pose (keyframe ``home``) puts every body
    where MuJoCo does."""
    import pinocchio as pin

    path = menagerie_file(relative)
    robot = load_robot(path)
    reference = _compare(robot, stripped_copy(path, tmp_path))
    for j in range(reference.mj.njnt):  # hinge and slide limits: MuJoCo's range, else unlimited
        if reference.mj.jnt_type[j] not in (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE):
            continue
        name = mujoco.mj_id2name(reference.mj, mujoco.mjtObj.mjOBJ_JOINT, j)
        i = robot.model.joints[robot.joint_id(name)].idx_q
        expected = reference.mj.jnt_range[j] if reference.mj.jnt_limited[j] else [-np.inf, np.inf]
        np.testing.assert_allclose(
            [robot.model.lowerPositionLimit[i], robot.model.upperPositionLimit[i]], expected, rtol=1e-15, err_msg=name
        )  # one degree conversion: round-off
    key = mujoco.mj_name2id(reference.mj, mujoco.mjtObj.mjOBJ_KEY, "home")
    if key >= 0:  # else the first keyframe or qpos0, compared in test_kinematic_tree_matches_mujoco
        mujoco.mj_resetDataKeyframe(reference.mj, reference.data, key)
        mujoco.mj_kinematics(reference.mj, reference.data)
        data = robot.new_data()
        pin.framesForwardKinematics(robot.model, data, robot.q_ref)
        for b in range(1, reference.mj.nbody):
            name = mujoco.mj_id2name(reference.mj, mujoco.mjtObj.mjOBJ_BODY, b)
            np.testing.assert_allclose(
                data.oMf[robot.frame_id(name)].translation, reference.data.xpos[b], rtol=0, atol=1e-12, err_msg=name
            )  # m; lengths O(1), round-off 1e-15


GEOM_CASES = {
    "visual box (contype = conaffinity = 0)": '<geom type="box" size="0.1 0.2 0.05" pos="0 0 -0.3" '
    'contype="0" conaffinity="0"/>',
    "group outside inertiagrouprange": '<geom type="box" size="0.1 0.2 0.05" pos="0 0 -0.3"/>'
    '<geom type="sphere" size="0.1" group="7"/>',
    "capsule by fromto": '<geom type="capsule" fromto="0 0 0 0.1 0 -0.4" size="0.03"/>',
    "turned cylinder with density": '<geom type="cylinder" size="0.05 0.2" quat="0.9 0.3 0.1 0" pos="0.1 0 -0.2" '
    'density="500"/>',
    "ellipsoid": '<geom type="ellipsoid" size="0.05 0.1 0.2" pos="0 0 -0.2"/>',
    "two geoms with masses": '<geom type="box" size="0.1 0.05 0.05" pos="0.1 0 -0.3" mass="2"/>'
    '<geom type="sphere" size="0.05" pos="-0.1 0 0" mass="1"/>',
    "massless mesh beside a box": '<geom type="mesh" mesh="hull" mass="0"/><geom type="box" size="0.1 0.1 0.1"/>',
}


@pytest.mark.parametrize("case", list(GEOM_CASES))
def test_inertia_from_geoms_matches_mujoco(tmp_path, case):
    """A body without <inertial> below a free root: MuJoCo weighs every geom in
    ``inertiagrouprange`` (visual ones too) and none of mass 0; Pinocchio alone weighs only
    colliding geoms, of any group, and a mesh as 1 kg (the loader's copy for it fixes that).
    MuJoCo compiles the file without the mesh (stripped)."""
    geoms = GEOM_CASES[case]
    xml = f"""<mujoco><asset><mesh name="hull" file="hull.stl"/></asset><worldbody><body name="root"><freejoint/>
      <inertial pos="0 0 0" mass="1" diaginertia="0.1 0.1 0.1"/>
      <body name="b" pos="0 0 -0.1" euler="10 20 30"><joint name="h" axis="0 1 0"/>{geoms}</body>
      </body></worldbody></mujoco>"""
    path = write(tmp_path, "geoms.xml", xml)
    (tmp_path / "stripped").mkdir()
    _compare(load_robot(path), stripped_copy(path, tmp_path / "stripped"), count=3)


def _tetrahedron(points) -> np.ndarray:
    """The four faces of the tetrahedron ``points``, each ordered counter-clockwise from outside."""
    points = np.asarray(points, dtype=float)
    faces = []
    for skip in range(4):
        face = points[[i for i in range(4) if i != skip]]
        if np.dot(np.cross(face[1] - face[0], face[2] - face[0]), points[skip] - face[0]) > 0:
            face = face[[0, 2, 1]]
        faces.append(face)
    return np.array(faces)


def _obj_box(path, low, high):
    """An OBJ file of a box with quadrilateral faces (MuJoCo splits them into triangles)."""
    from mjcf_models import BOX_CORNERS, BOX_QUADS

    corners = np.asarray(low) + BOX_CORNERS * (np.asarray(high) - np.asarray(low))
    lines = [f"v {x} {y} {z}" for x, y, z in corners] + ["f " + " ".join(str(i + 1) for i in q) for q in BOX_QUADS]
    path.write_text("\n".join(lines) + "\n")


_TETRA = [[0, 0, 0], [0.3, 0.05, 0], [0.1, 0.25, 0.02], [0.05, 0.1, 0.2]]
MESH_CASES = {
    "STL tetrahedron, refpos, refquat and scale": (
        '<mesh name="t" file="t.stl" refpos="0.1 0 0.05" refquat="0.9 0.2 -0.3 0.1" scale="1.5 0.8 1.2"/>',
        '<geom type="mesh" mesh="t" pos="0.05 0.02 -0.2" quat="0.8 0.1 0.5 0.2" density="700"/>',
    ),
    "exact inertia, mirrored by a negative scale": (
        '<mesh name="t" file="t.stl" scale="-1 1 1" inertia="exact"/>',
        '<geom type="mesh" mesh="t" pos="0 0 -0.3"/>',
    ),
    "OBJ box of quadrilaterals with a mass, beside a box and a visual mesh": (
        '<mesh name="o" file="o.obj"/><mesh name="t" file="t.stl"/>',
        '<geom type="mesh" mesh="o" mass="2" euler="10 40 -20" pos="0.1 0 -0.1"/>'
        '<geom type="box" size="0.05 0.1 0.02" pos="0 0 -0.4"/>'
        '<geom type="mesh" mesh="t" contype="0" conaffinity="0" group="2"/>',
    ),
}


@pytest.mark.parametrize("case", list(MESH_CASES))
def test_mesh_inertia_matches_mujoco(tmp_path, case):
    """A body weighed by mesh geoms (files present) below a free root: the loader's box of
    each mesh's volume inertia gives MuJoCo's M and bias, MuJoCo compiling the file as given."""
    from mjcf_models import write_stl

    assets, geoms = MESH_CASES[case]
    write_stl(tmp_path / "t.stl", _tetrahedron(_TETRA))
    _obj_box(tmp_path / "o.obj", [0, 0, 0], [0.2, 0.1, 0.3])
    xml = f"""<mujoco><asset>{assets}</asset><worldbody><body name="root"><freejoint/>
      <inertial pos="0 0 0" mass="1" diaginertia="0.1 0.1 0.1"/>
      <body name="b" pos="0 0 -0.1" euler="10 20 30"><joint name="h" axis="0 1 0"/>{geoms}</body>
      </body></worldbody></mujoco>"""
    path = write(tmp_path, "meshes.xml", xml)
    _compare(load_robot(path), path, count=3)


_INERTIAL = '<inertial pos="0.01 0.02 -0.1" quat="0.9 0.1 0.3 0.2" mass="1" diaginertia="0.01 0.02 0.03"/>'
TREE_CASES = {
    "joint ref in degrees": f'<body name="b" pos="0 0 -0.1"><joint name="h" axis="0 1 0" ref="30"/>{_INERTIAL}</body>',
    "axisangle in degrees, unnormalised axis": f'<body name="b" pos="0 0 -0.1" axisangle="1 1 0 40">'
    f'<joint name="h" axis="1 2 3"/>{_INERTIAL}</body>',
    "euler with eulerseq ZyX": f'<body name="b" pos="0 0 -0.1" euler="10 -50 80"><joint name="h" axis="0 1 0"/>'
    f'{_INERTIAL}<body name="c" pos="0.1 0 0" euler="30 0 20"><joint name="k"/>'
    f"{_INERTIAL}</body></body>",
    "xyaxes and zaxis": f'<body name="b" pos="0 0 -0.1" xyaxes="1 1 0 -1 2 0.5"><joint name="h" axis="0 1 0"/>'
    f'{_INERTIAL}<body name="c" zaxis="0 1 1"><joint name="k" pos="0.1 0 0"/>{_INERTIAL}'
    "</body></body>",
    "ball joint": f'<body name="b" pos="0 0 -0.1"><joint name="h" type="ball"/>{_INERTIAL}</body>',
    "frame": f'<frame pos="0.1 0 -0.2" euler="0 30 0"><frame quat="0.8 0.6 0 0"><body name="b" pos="0 0.1 0">'
    f'<joint name="h" axis="0 1 0"/>{_INERTIAL}<geom type="box" size="0.1 0.1 0.1"/></body></frame></frame>',
    "two joints in one body": f'<body name="b" pos="0 0 -0.1" euler="0 20 0"><joint name="h" axis="0 1 0"/>'
    f'<joint name="h2" axis="1 0 0" pos="0 0 -0.05"/><joint name="h3" type="slide"/>'
    f"{_INERTIAL}</body>",
    "childclass joint pos and armature": f'<body name="b" pos="0 0 -0.1" childclass="c"><joint name="h"/>'
    f"{_INERTIAL}</body>",
}


@pytest.mark.parametrize("case", list(TREE_CASES))
def test_kinematic_tree_matches_mujoco(tmp_path, case):
    """Placements and joints Pinocchio 4.1 alone reads differently from MuJoCo (an axisangle,
    a <frame>, several joints in one body) or the same (the rest), under a free root: M and b
    at random states, and every body's position at qpos0 (m, round-off on O(1) lengths)."""
    import pinocchio as pin

    xml = f"""<mujoco><compiler eulerseq="ZyX"/>
      <default><default class="c"><joint axis="1 0 0" pos="0 0.05 0" armature="0.2"/></default></default>
      <worldbody><body name="root" pos="0 0 1"><freejoint/><inertial pos="0 0 0" mass="1" diaginertia="0.1 0.1 0.1"/>
      {TREE_CASES[case]}</body></worldbody></mujoco>"""
    path = write(tmp_path, "tree.xml", xml)
    robot = load_robot(path)
    reference = _compare(robot, path, count=3)
    mujoco.mj_resetData(reference.mj, reference.data)
    mujoco.mj_kinematics(reference.mj, reference.data)
    data = robot.new_data()
    pin.framesForwardKinematics(robot.model, data, robot.q_ref)
    for b in range(1, reference.mj.nbody):
        name = mujoco.mj_id2name(reference.mj, mujoco.mjtObj.mjOBJ_BODY, b)
        np.testing.assert_allclose(
            data.oMf[robot.frame_id(name)].translation, reference.data.xpos[b], rtol=0, atol=1e-12, err_msg=name
        )
