"""Bad input gets a named error that says what is wrong and what is valid."""

import math

import numpy as np
import pytest

import contactdiff as cd

BALL_URDF = """<?xml version="1.0"?>
<robot name="b"><link name="world"/>
<link name="ball"><inertial><mass value="{mass}"/>
<inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
<joint name="z" type="prismatic"><parent link="world"/><child link="ball"/>
<axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="0" velocity="1"/></joint></robot>
"""


def write_scene(tmp_path, text, urdf_mass="1"):
    (tmp_path / "b.urdf").write_text(BALL_URDF.format(mass=urdf_mass))
    path = tmp_path / "s.toml"
    path.write_text('robot = "b.urdf"\n' + text)
    return path


def test_unknown_robot_lists_known_names():
    with pytest.raises(cd.UnknownNameError, match="solo12") as err:
        cd.load_robot("solo13")
    assert "planar_trot_soft" in str(err.value) and "'solo13'" in str(err.value)


def test_missing_urdf(tmp_path):
    with pytest.raises(cd.ModelLoadError, match="does not exist"):
        cd.load_robot(tmp_path / "nope.urdf")


def test_unreadable_urdf(tmp_path):
    bad = tmp_path / "bad.urdf"
    bad.write_text("<robot name='x'><link name='a'>")
    with pytest.raises(cd.ModelLoadError, match="cannot read URDF"):
        cd.load_robot(bad)


@pytest.mark.parametrize("mass", ["-1", "nan"])
def test_bad_mass_in_urdf(tmp_path, mass):
    path = tmp_path / "m.urdf"
    path.write_text(BALL_URDF.format(mass=mass))
    with pytest.raises(cd.ModelLoadError, match="mass"):  # nan: the parser drops it, M singular
        cd.load_robot(path)


def test_unknown_frame_lists_frames():
    robot = cd.load_robot("ball")
    with pytest.raises(cd.UnknownNameError, match="unknown frame.*'foot'.*ball"):
        cd.Scene(robot, [cd.Contact("foot")])


def test_unknown_joint_in_initial_state_lists_joints():
    robot = cd.load_robot("ball")
    with pytest.raises(cd.UnknownNameError, match="unknown joint.*'x'.*valid: z"):
        cd.Scene(robot, q0={"x": 1.0})


def test_unknown_toml_key_lists_valid_keys(tmp_path):
    path = write_scene(tmp_path, "[[contact]]\nframe = 'ball'\nrestitutoin = 0.5\n")
    with pytest.raises(cd.UnknownNameError, match="restitutoin.*restitution"):
        cd.load_scene(path)


def test_unknown_top_level_key(tmp_path):
    path = write_scene(tmp_path, "gravitee = [0, 0, -1]\n")
    with pytest.raises(cd.UnknownNameError, match="gravitee.*gravity"):
        cd.load_scene(path)


def test_unparsable_toml(tmp_path):
    path = write_scene(tmp_path, "[[contact]\n")
    with pytest.raises(cd.ModelLoadError, match="cannot read scene"):
        cd.load_scene(path)


def test_unknown_scene_name_lists_scenes():
    with pytest.raises(cd.UnknownNameError, match="planar_trot_soft"):
        cd.load_scene("planar_trot_sfot")


@pytest.mark.parametrize("restitution", [-0.1, 1.5, math.nan, math.inf])
def test_restitution_outside_unit_interval(restitution):
    with pytest.raises(cd.InvalidInputError, match="restitution"):
        cd.Contact("ball", restitution=restitution)


def test_zero_normal():
    with pytest.raises(cd.InvalidInputError, match="non-zero"):
        cd.Contact("ball", normal=(0, 0, 0))


def test_unknown_friction_lists_modes():
    with pytest.raises(cd.InvalidInputError, match="none, stick"):
        cd.Contact("ball", friction="coulomb")


@pytest.mark.parametrize(
    "field,value", [("stiffness", -1.0), ("stiffness", math.inf), ("damping", -0.5), ("rest_length", math.nan)]
)
def test_bad_spring_numbers(field, value):
    kwargs = dict(stiffness=1.0, damping=0.0, rest_length=0.5)
    kwargs[field] = value
    with pytest.raises(cd.InvalidInputError, match=field):
        cd.Spring("a", "b", **kwargs)


def test_negative_joint_spring_in_toml(tmp_path):
    path = write_scene(tmp_path, "[[joint_spring]]\njoint = 'z'\nstiffness = -3.0\n")
    with pytest.raises(cd.InvalidInputError, match="stiffness must be >= 0"):
        cd.load_scene(path)


def test_non_finite_initial_state(tmp_path):
    path = write_scene(tmp_path, "[initial]\nq = { z = nan }\n")
    with pytest.raises(cd.InvalidInputError, match="finite"):
        cd.load_scene(path)


def test_penetrating_initial_state_names_the_contact(tmp_path):
    path = write_scene(tmp_path, "[[contact]]\nframe = 'ball'\n[initial]\nq = { z = -0.01 }\n")
    with pytest.raises(cd.InconsistentStateError, match="'ball'.*gap -0.01"):
        cd.load_scene(path)


def test_closed_contact_is_not_penetration():
    robot = cd.load_robot("ball")
    scene = cd.Scene(robot, [cd.Contact("ball")], q0={"z": 0.0})
    assert scene.gaps(scene.q0) == pytest.approx([0.0])


def test_initial_state_of_wrong_size():
    with pytest.raises(cd.InvalidInputError, match="1 entries"):
        cd.Scene(cd.load_robot("ball"), q0=np.zeros(3))


def test_duplicate_contact_names():
    with pytest.raises(cd.InvalidInputError, match="unique.*ball"):
        cd.Scene(cd.load_robot("ball"), [cd.Contact("ball"), cd.Contact("ball")], q0={"z": 1.0})


@pytest.mark.parametrize(
    "second",
    [
        dict(name="again"),  # a copy
        dict(name="again", offset=0.1, restitution=0.5, friction="stick"),  # other numbers, same surface
        dict(name="again", normal=(0.0, 0.0, 2.0)),  # the same normal, unnormalised
    ],
)
def test_two_contacts_of_one_frame_on_one_surface_are_refused(second):
    """Two ground contacts of one frame along one normal have gaps that differ by a
    constant: one surface, two rows that are equal, which closed in an order set by
    round-off (the run reported a landing order between them). The error names both,
    the frame, the normal and what to do instead."""
    with pytest.raises(
        cd.InvalidInputError,
        match=r"'ball' and 'again' are both frame 'ball' against the ground along the normal "
        r"\(0\.0, 0\.0, 1\.0\).*different normals",
    ):
        cd.Scene(cd.load_robot("ball"), [cd.Contact("ball"), cd.Contact("ball", **second)], q0={"z": 1.0})


def test_one_frame_may_touch_different_surfaces():
    """A floor and a ceiling (opposite normals) are two surfaces of one frame, and so are
    a box's contacts against a ball along two normals; the pair written once each way
    (box against ball along n, ball against box along -n) is one contact twice: refused."""
    robot = cd.load_robot("ball")
    scene = cd.Scene(
        robot, [cd.Contact("ball"), cd.Contact("ball", normal=(0, 0, -1), offset=-2.0, name="ceiling")], q0={"z": 1.0}
    )
    np.testing.assert_allclose(scene.gaps(scene.q0), [1.0, 1.0], rtol=0, atol=1e-15)  # z - 0, 2 - z
    box = cd.SceneObject("box", "box", 1.0, size=(0.1, 0.1, 0.1), position=(0.0, 0.0, 0.5))
    robot = cd.add_objects(robot, [box])
    with pytest.raises(cd.InvalidInputError, match="'box' and 'back' are both frame 'box' against frame 'ball'"):
        cd.Scene(
            robot,
            [
                cd.Contact("box", against="ball", normal=(0, 0, 1)),
                cd.Contact("ball", against="box", normal=(0, 0, -1), name="back"),
            ],
            q0={"z": 1.0},
        )
    scene = cd.Scene(
        robot,
        [
            cd.Contact("box", against="ball", normal=(0, 0, 1)),
            cd.Contact("box", against="ball", normal=(1, 0, 0), name="side"),
        ],
        q0={"z": 0.0},
    )
    assert scene.contact_names == ["box", "side"]


@pytest.mark.parametrize(
    "entry, message",
    [
        ("[[contact]]\nframe = 'ball'\nrestitution = true\n", "restitution must be a number, got True"),
        ("[[contact]]\nframe = 'ball'\noffset = false\n", "offset must be a number, got False"),
        ("[[joint_spring]]\njoint = 'z'\nstiffness = true\n", "stiffness must be a number, got True"),
    ],
)
def test_a_boolean_is_not_a_number(tmp_path, entry, message):
    """TOML's ``true`` was taken as 1 (an elastic contact) and ``false`` as 0."""
    with pytest.raises(cd.InvalidInputError, match=message):
        cd.load_scene(write_scene(tmp_path, entry + "[initial]\nq = { z = 0.5 }\n"))


def test_contact_that_cannot_move_along_its_normal():
    """The ball moves along z only: a contact with a horizontal normal can never act."""
    with pytest.raises(cd.InvalidInputError, match="cannot move along the normal"):
        cd.Scene(cd.load_robot("ball"), [cd.Contact("ball", normal=(1, 0, 0))], q0={"z": 1.0})


def test_fixed_base_robot_gets_no_feet_and_the_check_says_how_to_give_them():
    scene = cd.Scene.from_robot(cd.load_robot("ball"))
    assert scene.contacts == []
    report = cd.check_decoupling(scene, samples=1)
    assert report.verdict is None and "fixed base" in report.reason and "--floating-base" in report.reason


def test_user_effort_of_wrong_shape_is_refused():
    robot = cd.load_robot("ball")
    scene = cd.Scene(robot, efforts=[cd.UserEffort(lambda q, v, t: np.zeros(2), name="bad")])
    with pytest.raises(cd.InvalidInputError, match="bad: function returned shape"):
        cd.ModeDynamics(scene).solve(scene.q0, scene.v0, 0.0)


# -- tolerances, budgets and states that cannot be meant ------------------------------
@pytest.mark.parametrize(
    "options, message",
    [
        (dict(rtol=1.0), r"rtol must be in \[2.22e-14, 0.1\], got 1.0"),
        (dict(rtol=1e-16), r"rtol must be in \[2.22e-14, 0.1\]"),
        (dict(atol=0.0), r"atol must be in \(0, 0.1\], got 0.0"),
        (dict(atol=1.0), r"atol must be in \(0, 0.1\]"),
        (dict(max_steps=-1), "max_steps must be an integer >= 1"),
        (dict(max_steps=2.5), "max_steps must be an integer >= 1"),
        (dict(max_steps=0), "max_steps must be an integer >= 1, got 0"),
        (dict(progress="yes"), "progress must be a callable or None"),
    ],
)
def test_simulate_refuses_options_that_cannot_be_meant(options, message):
    with pytest.raises(cd.InvalidInputError, match=message):
        cd.simulate(cd.load_scene("ball"), 1.0, **options)


def test_a_runaway_run_stops_at_its_step_budget_with_the_run_so_far():
    """A body pitching at 1e6 rad/s needs steps of about 1e-6 s: 40 steps reach
    only a few tens of microseconds of the 2-s horizon."""
    scene = cd.load_scene("planar_trot_soft").with_state(v0={"body_pitch": 1e6})
    seen = []
    with pytest.raises(cd.TooManyStepsError, match="max_steps = 40 steps taken") as err:
        cd.simulate(scene, 2.0, max_steps=40, progress=lambda t, events, steps: seen.append((t, events, steps)))
    traj = err.value.trajectory
    assert traj.termination == "max_steps" and traj.stats.steps == 40
    assert 0.0 < traj.t < 1e-3 and np.all(np.isfinite(traj.q))
    assert [s for _, _, s in seen] == list(range(1, 41))  # one call per accepted step
    assert np.all(np.diff([t for t, _, _ in seen]) > 0) and seen[-1][0] == traj.t


def test_zero_quaternion_is_refused_up_front():
    scene = cd.Scene.from_robot(cd.load_robot("solo12"))
    q = scene.q0.copy()
    q[3:7] = 0.0
    with pytest.raises(cd.InvalidInputError, match="root_joint.*norm is not 1"):
        cd.simulate(scene, 0.1, q0=q)
    with pytest.raises(cd.InvalidInputError, match="root_joint.*norm is not 1"):
        scene.with_state({"root_joint": [0, 0, 0.3, 0, 0, 0, 0]})


def test_check_refuses_a_negative_seed():
    with pytest.raises(cd.InvalidInputError, match="seed must be an integer >= 0, got -1"):
        cd.check_decoupling("planar_trot_soft", seed=-1)


@pytest.mark.parametrize(
    "args, message",
    [
        ((np.zeros(3), None, 0.0, ()), r"q must be 7 numbers, got shape \(3,\)"),
        ((None, np.ones(2), 0.0, ()), r"v must be 7 numbers, got shape \(2,\)"),
        ((None, None, 0.0, (7,)), "7 is not a contact key; valid: keys 0..1"),
        ((None, None, 0.0, (-1,)), "-1 is not a contact key"),
        ((None, None, 0.0, (0, 0)), "names a contact twice"),
    ],
)
def test_mode_dynamics_names_bad_arguments(args, message):
    scene = cd.load_scene("planar_trot_soft")
    q, v, t, active = args
    with pytest.raises(cd.InvalidInputError, match=message):
        cd.ModeDynamics(scene).solve(scene.q0 if q is None else q, scene.v0 if v is None else v, t, active)
