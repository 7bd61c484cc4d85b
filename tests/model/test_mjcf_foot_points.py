"""MJCF feet of several sphere points: one limb each for the decoupling check, and the
names of unnamed sphere geoms' frames.

The reference couplings are computed directly: ``G = A M^-1 A^T`` with ``M`` from
``pin.crba`` (inverted by numpy) and each row of ``A`` the vertical row of the
world-aligned Jacobian of a sphere's centre (a sphere's lowest point moves along
the vertical as its centre does: ``(ω × -r e_z) · e_z = 0``). The checker takes
``computeMinverse`` and the contacts' own rows; both are a few hundred
floating-point operations on O(1) numbers, so they agree to ~1e-14 relative:
``REL = 1e-10`` leaves margin while a coupling of the wrong pair (values apart
by more than 1e-2 here) fails.
"""

from __future__ import annotations

import itertools

import numpy as np
import pinocchio as pin
import pytest
from mjcf_models import write

import contactdiff as cd
from contactdiff.model.feet import FootRule
from contactdiff.model.robot_files import load_robot

REL = 1e-10

# a pelvis on a free joint, two legs hinged about y, each leg's leaf body carrying two
# unnamed collision spheres 2 cm apart (toe and heel) 0.3 m below the hip
_LEG = """<body name="{s}_foot" pos="0 {y} 0"><joint name="{s}_hip" axis="0 1 0"/>
  <inertial pos="0.01 0 -0.15" mass="0.5" diaginertia="0.004 0.004 0.0005"/>
  <geom type="capsule" fromto="0 0 0 0 0 -0.28" size="0.01" contype="0" conaffinity="0"/>
  {spheres}</body>"""
_TWO = '<geom type="sphere" size="0.02" pos="0.01 0 -0.3"/><geom type="sphere" size="0.02" pos="-0.01 0 -0.3"/>'
_XML = """<mujoco model="points"><worldbody><body name="pelvis" pos="0 0 0.32"><freejoint/>
  <inertial pos="0 0 0.05" mass="4" diaginertia="0.05 0.04 0.03"/>
  {left}{right}</body></worldbody></mujoco>"""


def _biped(tmp_path, left=_TWO, right=_TWO, feet=None):
    xml = _XML.format(
        left=_LEG.format(s="left", y=0.1, spheres=left), right=_LEG.format(s="right", y=-0.1, spheres=right)
    )
    return load_robot(write(tmp_path, "points.xml", xml), feet=feet)


def _direct_coupling(robot, q, a, b) -> float:
    """|G_ab| / sqrt(G_aa G_bb) from crba and the spheres' centre Jacobians (module notes)."""
    model, data = robot.model, robot.new_data()
    M = pin.crba(model, data, q)
    M = np.triu(M) + np.triu(M, 1).T  # crba fills the upper triangle
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    A = np.vstack([pin.getFrameJacobian(model, data, robot.frame_id(f), pin.LOCAL_WORLD_ALIGNED)[2] for f in (a, b)])
    G = A @ np.linalg.solve(M, A.T)
    return abs(G[0, 1]) / np.sqrt(G[0, 0] * G[1, 1])


def test_a_foot_of_two_spheres_is_one_limb_and_its_points_are_not_coupled_limbs(tmp_path):
    """Two feet of two spheres each: four feet, two limbs. The limb of each foot body is
    its hip (not empty, as it would be if each sphere were a limb: two spheres share
    one chain); the orthogonality pairs are the four toe/heel pairs across the legs,
    each equal to the direct coupling; the two pairs within a foot are reported apart
    (also equal to the direct value) and do not enter ``max_coupling``: two points 2 cm
    apart on one body move nearly alike (coupling near 1), more alike than points on
    two legs, so counting them would raise ``max_coupling`` above every leg pair. The mass
    matrix's block between the two hips is zero exactly: they lie on separate branches,
    and CRBA adds nothing between them."""
    robot = _biped(tmp_path)
    left, right = ("left_foot_sphere1", "left_foot_sphere2"), ("right_foot_sphere1", "right_foot_sphere2")
    assert robot.feet == left + right
    assert robot.foot_choice.rule is FootRule.MJCF_SPHERES
    assert robot.foot_choice.limbs == {"left_foot": left, "right_foot": right}
    assert robot.foot_choice.describe().endswith("; one foot of several points each: left_foot (2), right_foot (2)")
    assert "(radius 20 mm)" in robot.foot_choice.describe()

    rng = np.random.default_rng(3)
    poses = [robot.q_ref] + [robot.integrate(robot.q_ref, rng.uniform(-0.3, 0.3, robot.nv)) for _ in range(2)]
    report = cd.check_decoupling(robot, states=[(q, np.zeros(robot.nv)) for q in poses])
    assert report.limbs == {"left_foot": ["left_hip"], "right_foot": ["right_hip"]}
    assert report.limb_contacts == {"left_foot": list(left), "right_foot": list(right)}
    assert report.body == [robot.model.names[1]]  # the free joint

    between = {tuple(p.contacts): p for p in report.pairs}
    assert set(between) == set(itertools.product(left, right))
    within = {tuple(p.contacts): p for p in report.within_limb}
    assert set(within) == {left, right}
    for pair in list(between.values()) + list(within.values()):
        expected = max(_direct_coupling(robot, q, *pair.contacts) for q in poses)
        assert pair.max == pytest.approx(expected, rel=REL)
    assert report.max_coupling == max(p.max for p in between.values())
    assert min(p.max for p in within.values()) > report.max_coupling
    (block,) = [t for t in report.terms if t.where == "block limb left_foot / limb right_foot"]
    assert block.value == 0.0 and set(block.contacts) == set(left + right)
    gap_terms = {t.where for t in report.terms if t.condition == "gap"}
    assert gap_terms == {f"{f} depends on coordinates outside its limb" for f in left + right}
    assert any(n.startswith("the points of limb left_foot") for n in report.notes)
    assert "within one limb (points of one foot; not part of the verdict)" in report.format()


def test_one_foot_of_two_points_alone_has_no_verdict(tmp_path):
    """Two spheres on one foot and none elsewhere: two contacts but one limb, so there is
    nothing between limbs to check (no vacuous verdict)."""
    robot = _biped(tmp_path, right="")
    assert robot.feet == ("left_foot_sphere1", "left_foot_sphere2")
    report = cd.check_decoupling(robot, samples=1)
    assert report.verdict is None and report.pairs == []
    assert report.reason == "fewer than two limbs (1: left_foot, contacts left_foot_sphere1, left_foot_sphere2)"


def test_unnamed_sphere_frames_are_named_after_their_body(tmp_path):
    """A body's only unnamed sphere: ``<body>_sphere``; several: ``<body>_sphere1``, ... in
    file order, a named geom keeping its name and taking no index."""
    one = '<geom type="sphere" size="0.02" pos="0 0 -0.3"/>'
    three = (
        '<geom type="sphere" size="0.02" pos="0.05 0 -0.3"/>'
        '<geom name="heel" type="sphere" size="0.02" pos="-0.05 0 -0.3"/>'
        '<geom type="sphere" size="0.02" pos="0 0.02 -0.3"/>'
    )
    robot = _biped(tmp_path, left=one, right=three)
    assert robot.feet == ("left_foot_sphere", "right_foot_sphere1", "heel", "right_foot_sphere2")
    assert robot.foot_choice.limbs == {"right_foot": ("right_foot_sphere1", "heel", "right_foot_sphere2")}
    data = robot.new_data()
    pin.framesForwardKinematics(robot.model, data, robot.q_ref)
    hip = data.oMi[robot.joint_id("right_hip")].translation
    np.testing.assert_allclose(
        data.oMf[robot.frame_id("right_foot_sphere2")].translation - hip, [0, 0.02, -0.3], rtol=0, atol=1e-15
    )  # its own pos, at the reference pose


def test_sphere_feet_given_by_hand_on_one_body_are_one_limb(tmp_path):
    """``feet=`` naming two spheres of the left foot and one of the right: the left two are
    one foot of two points (``limbs``), the right one a limb of its own; all stay round."""
    given = ["left_foot_sphere1", "left_foot_sphere2", "right_foot_sphere2"]
    robot = _biped(tmp_path, feet=given)
    assert robot.foot_choice.rule is FootRule.GIVEN
    assert robot.foot_choice.limbs == {"left_foot": tuple(given[:2])}
    assert robot.foot_choice.radii == dict.fromkeys(given, 0.02)
    report = cd.check_decoupling(robot, samples=1)
    assert report.limb_contacts == {"left_foot": given[:2], "right_foot_sphere2": given[2:]}
    assert [p.contacts for p in report.within_limb] == [tuple(given[:2])]
