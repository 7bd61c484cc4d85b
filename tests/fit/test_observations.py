"""Observation files: the format's conventions against closed forms, round trips through
CSV and ``.npz``, and one named, one-line error for every kind of bad file.

Tolerances. A CSV holds 17 significant digits, which read back give the float written, so
times, positions and joint coordinates round-trip exactly; quaternions are normalised again
on reading, which moves a unit quaternion's components by a few units in the last place
(|q| = 1 within 2 eps; dividing by it changes each component by at most ~2 eps), hence 1e-15.
Velocities of a free body are rotated to the world frame on writing and back on reading:
two rotations by a unit quaternion, each exact to a few eps times |v| (1e-14 for |v| <= 10).
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

import contactdiff as cd
from contactdiff.fit.observations import QUATERNION_TOLERANCE, valid_columns

QUAT = 1e-15
VEL = 1e-14
CUBE_HEADER = "t,cube:x,cube:y,cube:z,cube:qw,cube:qx,cube:qy,cube:qz"
ROW = "{t},0.1,0.2,0.3,{qw},0,0,{qz}"
S = math.sqrt(0.5)


def _csv(tmp_path, text, name="obs.csv"):
    path = tmp_path / name
    path.write_text(text)
    return path


def _rows(times, qw=1.0, qz=0.0):
    return "\n".join(ROW.format(t=t, qw=qw, qz=qz) for t in times)


@pytest.fixture(scope="module")
def cube():
    return cd.cube_scene()


# ---------------------------------------------------------------------------------------
# conventions
# ---------------------------------------------------------------------------------------
def test_a_free_body_reads_as_pinocchio_configuration_and_local_velocity(tmp_path, cube):
    """The cube turned 90° about z (qw = qz = √½, scalar first, body to world) moving at
    1 m/s along world x and spinning at 2 rad/s about its own x axis. Pinocchio's free-flyer
    holds ``[x y z qx qy qz qw]`` and the linear velocity in the body's frame: Rᵀ (1, 0, 0)
    with R the rotation by +90° about z is (0, -1, 0); the angular velocity stays (2, 0, 0)."""
    header = CUBE_HEADER + ",cube:vx,cube:vy,cube:vz,cube:wx,cube:wy,cube:wz,weight"
    rows = [f"{t},0.1,0.2,0.3,{S},0,0,{S},1,0,0,2,0,0,{w}" for t, w in ((0.0, 1.0), (0.01, 0.5))]
    obs = cd.load_observations(_csv(tmp_path, "\n".join([header, *rows]) + "\n"), cube)
    assert obs.t.tolist() == [0.0, 0.01] and obs.weights.tolist() == [1.0, 0.5]
    assert np.abs(obs.q[1] - [0.1, 0.2, 0.3, 0.0, 0.0, S, S]).max() <= QUAT
    assert np.abs(obs.v[0] - [0.0, -1.0, 0.0, 2.0, 0.0, 0.0]).max() <= VEL
    assert obs.mask.all() and obs.v_mask.all() and obs.joints == ("cube",)
    assert obs.source == str(tmp_path / "obs.csv") and obs.scene_name == "cube"


def test_comments_blank_lines_spaces_and_column_order_are_free(tmp_path, cube):
    text = (
        "# a toss\n t , cube:qz, cube:qw ,cube:x,cube:y,cube:z,cube:qx,cube:qy\n\n"
        "0, 0, 1, 1, 2, 3, 0, 0\n# pause\n0.5, 1, 0, 4, 5, 6, 0, 0\n"
    )
    obs = cd.load_observations(_csv(tmp_path, text), cube)
    assert obs.q.tolist() == [[1, 2, 3, 0, 0, 0, 1], [4, 5, 6, 0, 0, 1, 0]]
    assert obs.v is None and obs.v_mask is None


def test_quaternions_near_unit_norm_are_normalised(tmp_path, cube):
    """A norm of 1.05 (within QUATERNION_TOLERANCE = 0.1) is divided out: (1.05, 0, 0, 0) is identity."""
    assert QUATERNION_TOLERANCE == 0.1
    obs = cd.load_observations(_csv(tmp_path, CUBE_HEADER + "\n" + _rows([0, 1], qw=1.05)), cube)
    assert obs.q[:, 6].tolist() == [1.0, 1.0]


def test_joints_by_name_and_unmeasured_joints_keep_the_scene_pose(tmp_path):
    """solo12: the base and one knee measured; the mask covers the base's 6 tangent coordinates
    and the knee's one; the other joints hold the scene's initial configuration."""
    scene = cd.load_scene("solo12_trot")
    text = (
        "t,root_joint:x,root_joint:y,root_joint:z,root_joint:qw,root_joint:qx,root_joint:qy,root_joint:qz,"
        "FL_KFE,FL_KFE:v\n0,0,0,0.3,1,0,0,0,-1.5,0.25\n0.1,0,0,0.3,1,0,0,0,-1.4,0.5\n"
    )
    obs = cd.load_observations(_csv(tmp_path, text), scene)
    model = scene.model
    knee = model.joints[model.getJointId("FL_KFE")]
    assert obs.q[:, knee.idx_q].tolist() == [-1.5, -1.4] and obs.v[:, knee.idx_v].tolist() == [0.25, 0.5]
    expected = np.zeros(scene.nv, bool)
    expected[:6] = expected[knee.idx_v] = True
    assert obs.mask.tolist() == expected.tolist() and obs.joints == ("root_joint", "FL_KFE")
    others = [i for i in range(7, model.nq) if i != knee.idx_q]
    assert np.array_equal(obs.q[:, others], np.tile(scene.q0[others], (2, 1)))


def test_a_toss_becomes_the_cube_scenes_states(cube):
    """`toss_observations` against `Toss.state`, which turns the velocity with Pinocchio's
    rotation matrix (an independent path from the file reader's quaternion rotation)."""
    toss = cd.load_tosses()["toss_000"]
    obs = cd.toss_observations(toss)
    assert np.array_equal(obs.t, toss.t) and len(obs) == len(toss)
    for k in (0, len(toss) // 2, len(toss) - 1):
        q, v = toss.state(k)
        assert np.abs(obs.q[k] - q).max() <= QUAT and np.abs(obs.v[k] - v).max() <= VEL
    assert cd.toss_observations(toss, velocities=False).v is None


# ---------------------------------------------------------------------------------------
# round trips
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("suffix", [".csv", ".npz"])
def test_a_simulated_toss_round_trips(tmp_path, cube, suffix):
    """A simulated cube toss (its samples at the measured times), written and read back."""
    toss = cd.load_tosses()["toss_000"]
    traj = cd.simulate(cube.with_state(*toss.state(0)), toss.t[30], sample_times=toss.t[:31])
    s = traj.samples
    weights = np.linspace(0.0, 1.0, len(s))
    obs = cd.Observations.from_states(cube, s.t, s.q, s.v, weights=weights)
    path = obs.save(tmp_path / f"toss{suffix}", cube)
    back = cd.load_observations(path, cube)
    assert np.array_equal(back.t, s.t) and np.array_equal(back.weights, weights)
    assert np.array_equal(back.q[:, :3], s.q[:, :3]) and np.abs(back.q - s.q).max() <= QUAT
    assert np.abs(back.v - s.v).max() <= VEL * max(1.0, np.abs(s.v).max() / 10)
    assert back.mask.all() and back.v_mask.all()


@pytest.mark.parametrize("suffix", [".csv", ".npz"])
def test_a_robot_with_joints_round_trips(tmp_path, suffix):
    """solo12's free base and twelve revolute joints at perturbed poses, without velocities."""
    scene = cd.load_scene("solo12_trot")
    rng = np.random.default_rng(3)
    q = np.array([pin.integrate(scene.model, scene.q0, 0.3 * rng.standard_normal(scene.nv)) for _ in range(4)])
    obs = cd.Observations.from_states(scene, [0.0, 0.1, 0.2, 0.3], q)
    back = cd.load_observations(obs.save(tmp_path / f"solo{suffix}", scene), scene)
    assert np.abs(back.q - q).max() <= QUAT and back.v is None and back.mask.all()
    assert np.array_equal(back.q[:, 7:], q[:, 7:])


# ---------------------------------------------------------------------------------------
# bad files: one line, the file named, the fault named
# ---------------------------------------------------------------------------------------
def _refused(path, scene, *fragments):
    with pytest.raises(cd.ObservationFileError) as info:
        cd.load_observations(path, scene)
    message = str(info.value)
    assert "\n" not in message and message.startswith(str(path)), message
    for fragment in fragments:
        assert fragment in message, message
    return message


BAD_CSV = {
    "missing t": (
        CUBE_HEADER.replace("t,", "") + "\n0.1,0.2,0.3,1,0,0,0\n0.1,0.2,0.3,1,0,0,0\n",
        ["missing column 't'", "valid: t, weight, cube:x"],
    ),
    "unknown column": (
        CUBE_HEADER + ",cube:roll\n" + "0,0.1,0.2,0.3,1,0,0,0,0\n1,0.1,0.2,0.3,1,0,0,0,0\n",
        ["unknown column(s) 'cube:roll'", "valid: t, weight, cube:x, cube:y", "cube:wz"],
    ),
    "part of a joint": (
        "t,cube:x,cube:y,cube:z,cube:qx,cube:qy,cube:qz\n0,0,0,0,0,0,0\n1,0,0,0,0,0,0\n",
        ["missing column(s) 'cube:qw' of joint 'cube'"],
    ),
    "velocity alone": (
        "t,cube:vx,cube:vy,cube:vz,cube:wx,cube:wy,cube:wz\n0,0,0,0,0,0,0\n1,0,0,0,0,0,0\n",
        ["missing column(s) 'cube:x', 'cube:y', 'cube:z', 'cube:qw'"],
    ),
    "part of a velocity": (
        CUBE_HEADER + ",cube:vx\n0,0,0,0,1,0,0,0,0\n1,0,0,0,1,0,0,0,0\n",
        ["missing column(s) 'cube:vy', 'cube:vz', 'cube:wx'"],
    ),
    "no configuration": ("t,weight\n0,1\n1,1\n", ["no configuration column"]),
    "times not increasing": (
        CUBE_HEADER + "\n" + _rows([0, 0.1, 0.1, 0.2]) + "\n",
        ["times must increase: row 2 (line 4) has t = 0.1 s, not after 0.1 s of row 1"],
    ),
    "times going back": (
        CUBE_HEADER + "\n" + _rows([0, 0.2, 0.1]) + "\n",
        ["row 2 (line 4) has t = 0.1 s, not after 0.2 s"],
    ),
    "NaN": (
        CUBE_HEADER + "\n" + _rows([0, 0.1]) + "\n0.2,0.1,nan,0.3,1,0,0,0\n",
        ["row 2 (line 4), column 'cube:y': nan is not a finite number"],
    ),
    "zero quaternion": (
        CUBE_HEADER + "\n" + _rows([0, 0.1]) + "\n" + _rows([0.2], qw=0.0) + "\n",
        ["row 2 (line 4): the quaternion of joint 'cube' has zero norm"],
    ),
    "quaternion far from unit": (
        CUBE_HEADER + "\n" + _rows([0, 0.1], qw=2.0) + "\n",
        ["row 0 (line 2): the quaternion of joint 'cube' has norm 2, not 1 within 0.1"],
    ),
    "one sample": (CUBE_HEADER + "\n" + _rows([0]) + "\n", ["at least two samples, got 1"]),
    "header only": (CUBE_HEADER + "\n", ["at least two samples, got 0"]),
    "empty": ("", ["empty"]),
    "not a number": (
        CUBE_HEADER + "\n" + _rows([0]) + "\n0.1,0.1,0.2,zero,1,0,0,0\n",
        ["row 1 (line 3), column 'cube:z': 'zero' is not a number"],
    ),
    "ragged row": (CUBE_HEADER + "\n" + _rows([0]) + "\n0.1,0.1,0.2\n", ["row 1 (line 3) has 3 values for 8 columns"]),
    "column twice": (CUBE_HEADER + ",cube:x\n", ["named twice: cube:x"]),
    "nameless column": ("t,,cube:x\n", ["header column 2 has no name"]),
    "negative weight": (
        CUBE_HEADER + ",weight\n0,0.1,0.2,0.3,1,0,0,0,1\n1,0.1,0.2,0.3,1,0,0,0,-1\n",
        ["row 1 (line 3): weight -1.0 is negative"],
    ),
    "all weights zero": (
        CUBE_HEADER + ",weight\n0,0.1,0.2,0.3,1,0,0,0,0\n1,0.1,0.2,0.3,1,0,0,0,0\n",
        ["every weight is 0"],
    ),
}


@pytest.mark.parametrize("case", BAD_CSV)
def test_bad_csv_files_are_named(tmp_path, cube, case):
    text, fragments = BAD_CSV[case]
    _refused(_csv(tmp_path, text), cube, *fragments)


def test_bad_npz_files_are_named(tmp_path, cube):
    good = {
        "t": np.array([0.0, 0.1]),
        "cube:x": np.zeros(2),
        "cube:y": np.zeros(2),
        "cube:z": np.zeros(2),
        "cube:qw": np.ones(2),
        "cube:qx": np.zeros(2),
        "cube:qy": np.zeros(2),
        "cube:qz": np.zeros(2),
    }
    cases = {
        "lengths": (good | {"cube:z": np.zeros(3)}, ["columns of different lengths", "cube:z 3", "t 2"]),
        "2-D column": (good | {"cube:x": np.zeros((2, 2))}, ["column 'cube:x' must be one number per sample"]),
        "text column": (good | {"cube:x": np.array(["a", "b"])}, ["column 'cube:x' must be one number per sample"]),
        "unknown": (good | {"cube:pitch": np.zeros(2)}, ["unknown column(s) 'cube:pitch'", "valid: t, weight"]),
        "NaN": (good | {"cube:qx": np.array([0.0, np.nan])}, ["row 1, column 'cube:qx': nan is not a finite number"]),
        "times": (good | {"t": np.array([0.1, 0.0])}, ["times must increase: row 1 has t = 0.0 s"]),
    }
    for name, (arrays, fragments) in cases.items():
        path = tmp_path / f"{name.replace(' ', '_')}.npz"
        np.savez(path, **arrays)
        _refused(path, cube, *fragments)


def test_missing_unreadable_and_unknown_kinds_of_file_are_named(tmp_path, cube):
    _refused(tmp_path / "absent.csv", cube, "no such file")
    (tmp_path / "garbage.npz").write_bytes(b"not a zip archive")
    _refused(tmp_path / "garbage.npz", cube, "not a readable .npz file")
    (tmp_path / "latin.csv").write_bytes(b"t,cube:x\n0,\xff\xfe\n")
    _refused(tmp_path / "latin.csv", cube, "not a readable CSV file")
    (tmp_path / "obs.txt").write_text("t\n0\n")
    _refused(tmp_path / "obs.txt", cube, "unknown kind of observation file '.txt'; valid: .csv, .npz")


def test_valid_columns_name_every_observable_joint(cube):
    assert valid_columns(cube) == [
        "t",
        "weight",
        "cube:x",
        "cube:y",
        "cube:z",
        "cube:qw",
        "cube:qx",
        "cube:qy",
        "cube:qz",
        "cube:vx",
        "cube:vy",
        "cube:vz",
        "cube:wx",
        "cube:wy",
        "cube:wz",
    ]
    ball = valid_columns(cd.load_scene("ball"))
    assert ball == ["t", "weight", "z", "z:v"]


def test_states_of_the_wrong_shape_are_refused(cube):
    with pytest.raises(cd.InvalidInputError, match=r"q \(k, 7\)"):
        cd.Observations.from_states(cube, [0.0, 1.0], np.zeros((2, 6)))
    with pytest.raises(cd.InvalidInputError, match="unknown joint"):
        cd.Observations.from_states(cube, [0.0, 1.0], np.tile(cube.q0, (2, 1)), joints=["lid"])
