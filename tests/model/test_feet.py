"""Which frames are feet: the automatic rule on robots built for the purpose (heights
chosen by hand, so the rule's outcome is known in advance) and on the
example-robot-data models a user meets first; feet chosen by hand; robots with
fewer than two feet."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import contactdiff as cd
from contactdiff.cli import main
from contactdiff.model.feet import BAND_FRACTION, BAND_MIN, FootRule

# A floating body with two legs and an arm, written so that every height is known:
# the body at the origin, legs hanging straight down to feet at z = -LEG, the arm
# hanging down to its hand at z = -ARM.
LEG = 0.5

_TWO_LEGS_AND_ARM = """<?xml version="1.0"?>
<robot name="walker">
  <link name="body"><inertial><mass value="5"/>
    <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial></link>
  {limbs}
</robot>
"""

_LIMB = """
  <link name="{name}_link"><inertial><origin xyz="0 0 {half}"/><mass value="0.5"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>
  <joint name="{name}_joint" type="revolute"><parent link="body"/><child link="{name}_link"/>
    <origin xyz="{x} {y} 0"/><axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" effort="10" velocity="10"/></joint>
  <link name="{end}"/>
  <joint name="{end}_fixed" type="fixed"><parent link="{name}_link"/><child link="{end}"/>
    <origin xyz="0 0 {length}"/></joint>
"""


def _walker(tmp_path: Path, arm_length: float, arm_end: str = "hand") -> Path:
    limbs = "".join(
        _LIMB.format(name=n, end=e, x=x, y=y, half=-length / 2, length=-length)
        for n, e, x, y, length in (
            ("left", "left_foot", 0.0, 0.1, LEG),
            ("right", "right_foot", 0.0, -0.1, LEG),
            ("arm", arm_end, 0.2, 0.0, arm_length),
        )
    )
    path = tmp_path / "walker.urdf"
    path.write_text(_TWO_LEGS_AND_ARM.format(limbs=limbs))
    return path


def test_rule_keeps_the_lowest_limb_ends_within_the_band(tmp_path):
    """Robot height LEG (frames from z = 0 down to -LEG), so the band is
    max(BAND_MIN, BAND_FRACTION * LEG) = 2.5 cm: an arm ending 20 cm above the
    feet is left out with its height; the feet are exactly the two leg ends."""
    robot = cd.load_robot(_walker(tmp_path, LEG - 0.2), floating_base=True)
    choice = robot.foot_choice
    assert robot.feet == ("left_foot", "right_foot") and choice.rule is FootRule.LOWEST_END_FRAMES
    assert choice.band == pytest.approx(max(BAND_MIN, BAND_FRACTION * LEG))
    (hand,) = choice.left_out
    assert hand.frame == "hand" and hand.height == pytest.approx(0.2, abs=1e-12)
    assert choice.heights == pytest.approx({"left_foot": 0.0, "right_foot": 0.0}, abs=1e-12)
    assert "left_foot, right_foot" in choice.describe() and "hand (0.2 m up)" in choice.describe()


def test_rule_prefers_foot_names_among_the_lowest(tmp_path):
    """An arm reaching as low as the feet is within the band; its end is not named
    like a foot while the others are, so it is left out by name."""
    robot = cd.load_robot(_walker(tmp_path, LEG - 0.01), floating_base=True)
    assert robot.feet == ("left_foot", "right_foot")
    assert [(x.frame, x.reason) for x in robot.foot_choice.left_out] == [("hand", "not named like a foot")]


def test_rule_takes_unnamed_ends_when_no_end_is_named_like_a_foot(tmp_path):
    """Three limb ends at one height: the two named like feet win over the arm's 'tip';
    with no end named like a foot, all three are feet (in joint order)."""
    robot = cd.load_robot(_walker(tmp_path, LEG, arm_end="tip"), floating_base=True)
    assert robot.feet == ("left_foot", "right_foot")  # the named two of three in the band
    path = tmp_path / "w2.urdf"
    path.write_text(_walker(tmp_path, LEG, arm_end="tip").read_text().replace("_foot", "_end"))
    robot = cd.load_robot(path, floating_base=True)
    assert sorted(robot.feet) == ["left_end", "right_end", "tip"]


def test_a_urdf_path_is_fixed_unless_told_and_the_check_says_so(tmp_path, capsys):
    path = _walker(tmp_path, LEG - 0.2)
    fixed = cd.load_robot(path)
    assert fixed.feet == () and fixed.foot_choice.rule is FootRule.FIXED_BASE
    assert main(["check", str(path), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["verdict"] is None and "--floating-base" in out["reason"]
    assert main(["check", str(path), "--floating-base", "--samples", "1"]) == 0
    text = capsys.readouterr().out
    assert "feet left_foot, right_foot" in text and "verdict: DECOUPLED" not in text.split("feet")[0]


def test_feet_given_by_hand_and_a_wrong_name_lists_the_frames(tmp_path, capsys):
    robot = cd.load_robot("solo12", feet=["FL_FOOT", "HR_FOOT"])
    assert robot.feet == ("FL_FOOT", "HR_FOOT") and robot.foot_choice.rule is FootRule.GIVEN
    with pytest.raises(cd.UnknownNameError, match="unknown foot frame 'FL_TOE'.*FL_FOOT"):
        cd.load_robot("solo12", feet=["FL_TOE"])
    assert main(["check", "solo12", "--feet", "FL_FOOT,HR_FOOT", "--samples", "1", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert [p["contacts"] for p in out["pairs"]] == [["FL_FOOT", "HR_FOOT"]] and out["feet"].endswith("given by hand")
    assert main(["check", "solo12", "--feet", "FL_FOOT,nope"]) == 2
    assert "unknown foot frame 'nope'" in capsys.readouterr().err
    assert main(["check", "ball", "--feet", "ball"]) == 2  # a scene file sets its own contacts
    assert "feet applies to a robot" in capsys.readouterr().err


# -- example-robot-data models ---------------------------------------------------------
# Expected feet: the robots' documented foot frames (their URDFs' sole / foot links).
@pytest.mark.parametrize(
    "name, feet",
    [
        ("talos", ("left_sole_link", "right_sole_link")),
        ("g1", ("left_ankle_roll_link", "right_ankle_roll_link")),
        ("icub", ("l_foot", "r_foot")),
        ("simple_humanoid", ("l_ankle", "r_ankle")),
        ("alexander", ("LEFT_FOOT", "RIGHT_FOOT")),
        ("bolt", ("FL_FOOT", "FR_FOOT")),
        ("anymal_kinova", ("LF_FOOT", "LH_FOOT", "RF_FOOT", "RH_FOOT")),
        ("b1_z1", ("FL_foot", "FR_foot", "RL_foot", "RR_foot")),
        ("centauro", ("contact_1", "contact_2", "contact_3", "contact_4")),
        ("solo12", ("FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT")),
        ("anymal", ("LF_FOOT", "LH_FOOT", "RF_FOOT", "RH_FOOT")),
        ("hyq", ("lf_foot", "lh_foot", "rf_foot", "rh_foot")),
    ],
)
def test_legged_robots_stand_on_their_feet_only(name, feet):
    robot = cd.load_robot(name)
    assert robot.feet == feet, robot.foot_choice.describe()
    # the chosen feet are the robot's lowest frames: every other frame is at least as high
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, robot.q_ref)
    z = {f.name: data.oMf[i].translation[2] for i, f in enumerate(robot.model.frames) if f.parentJoint}
    lowest = min(z[f] for f in feet)
    assert max(z[f] for f in feet) - lowest <= robot.foot_choice.band


def test_a_y_up_model_is_turned_upright_onto_its_feet():
    """example-robot-data's human is drawn y-up: the reference pose is turned 90 deg
    so that its feet are below its pelvis, and the head is then the highest frame."""
    robot = cd.load_robot("human")
    assert robot.feet == ("left_foot_virtual", "right_foot_virtual")
    assert robot.foot_choice.upright_turn == pytest.approx(np.pi / 2, abs=0.2)
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, robot.q_ref)
    head = data.oMf[robot.model.getFrameId("middle_head")].translation[2]
    feet = [data.oMf[robot.model.getFrameId(f)].translation[2] for f in robot.feet]
    assert head - max(feet) > 1.0  # m: a standing adult


@pytest.mark.parametrize("name, n_feet", [("hector", 0), ("iris", 0), ("pr2", 0), ("borinot", 1)])
def test_fewer_than_two_feet_is_nothing_to_check(name, n_feet, capsys):
    robot = cd.load_robot(name)
    assert len(robot.feet) == n_feet
    assert main(["check", name, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["verdict"] is None and out["reason"].startswith(f"fewer than two contacts ({n_feet}")
    assert main(["check", name]) == 0
    assert "nothing to check: fewer than two contacts" in capsys.readouterr().out


def test_a_robot_example_robot_data_cannot_load_gets_the_reason():
    with pytest.raises(cd.ModelLoadError, match="'cassie' cannot be loaded.*SDF"):
        cd.load_robot("cassie")


def test_ground_contacts_touch_at_the_reference_pose():
    scene = cd.Scene.from_robot(cd.load_robot("talos"))
    assert scene.contact_names == ["left_sole_link", "right_sole_link"]
    assert np.abs(scene.gaps(scene.q0)).max() < 1e-12
