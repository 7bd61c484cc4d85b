"""The command line: tables, --json, armature comparison, errors with exit status 2."""

import json

from contactdiff.cli import main


def test_check_prints_a_verdict(capsys):
    assert main(["check", "planar_trot_soft", "--samples", "2"]) == 0
    out = capsys.readouterr().out
    assert "verdict: DECOUPLED" in out and "rear_foot / front_foot" in out


def test_check_json(capsys):
    assert main(["check", "planar_trot_rigid", "--samples", "2", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["verdict"] == "coupled" and len(data["pairs"]) == 1


def test_check_armature_compares(capsys):
    assert main(["check", "solo12", "--samples", "1", "--armature", "0.01", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["armature"] == 0.01 and data["without_armature"]["armature"] == 0.0
    assert data["max_coupling"] > data["without_armature"]["max_coupling"]


def test_unknown_source_exits_2_with_the_valid_names(capsys):
    assert main(["check", "no_such_robot"]) == 2
    err = capsys.readouterr().err
    assert "unknown scene or robot 'no_such_robot'" in err and "solo12" in err


def test_missing_scene_file_exits_2(capsys, tmp_path):
    assert main(["check", str(tmp_path / "missing.toml")]) == 2
    assert "does not exist" in capsys.readouterr().err


# -- a new user's bad inputs: one named line on stderr, exit status 2, no traceback ------
import os  # noqa: E402
import signal  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402

import pytest  # noqa: E402


@pytest.mark.parametrize(
    "argv, message",
    [
        (["check", "solo12", "--seed", "-5"], "--seed: must be an integer seed >= 0, got '-5'"),
        (["check", "solo12", "--samples", "abc"], "--samples: must be an integer >= 0, got 'abc'"),
        (["check", "solo12", "--tol", "0"], "--tol: must be a finite number > 0"),
        (["simulate", "ball", "--t-final", "1", "--rtol", "10"], "rtol must be in [2.22e-14, 0.1], got 10.0"),
        (["simulate", "ball", "--t-final", "1", "--atol", "0"], "atol must be in (0, 0.1], got 0.0"),
        (["simulate", "ball", "--t-final", "nan"], "--t-final: must be a finite number"),
        (["stride", "ball", "--foot", "ball", "--t-max", "0"], "t_max must be > 0 s, got 0.0"),
        (["check", "/dev/null"], "'/dev/null' is not a regular file"),
        (
            ["simulate", "solo12", "--t-final", "1", "--q", "root_joint=0,0,0.3,0,0,0,0"],
            "joint 'root_joint' (JointModelFreeFlyer) holds a quaternion or unit complex number whose norm is not 1",
        ),
        (
            ["simulate", "planar_trot_soft", "--t-final", "2", "--v", "body_pitch=1e6", "--max-steps", "50"],
            "max_steps = 50 steps taken by t = ",
        ),
    ],
)
def test_bad_input_is_one_named_line(argv, message, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err, err
    assert err.count("\n") == 1, err


def test_a_directory_as_source_is_named(capsys, tmp_path):
    assert main(["check", str(tmp_path)]) == 2
    assert "is a directory, not a URDF file" in capsys.readouterr().err
    (tmp_path / "s.toml").mkdir()
    assert main(["check", str(tmp_path / "s.toml")]) == 2
    assert "is a directory, not a TOML file" in capsys.readouterr().err


@pytest.mark.parametrize(
    "command", [["simulate", "ball", "--t-final", "0.1"], ["bench", "--quick", "--scenes", "ball"]]
)
def test_plot_target_is_checked_before_any_work(command, capsys, tmp_path, monkeypatch):
    pytest.importorskip("matplotlib")
    import contactdiff.bench.runner
    import contactdiff.integration.hybrid

    def never(*args, **kwargs):
        raise AssertionError("the run started before the plot file was checked")

    monkeypatch.setattr(contactdiff.integration.hybrid, "simulate", never)
    monkeypatch.setattr(contactdiff.bench.runner, "run_bench", never)
    assert main(command + ["--plot", str(tmp_path / "missing" / "x.png")]) == 2
    assert "folder" in capsys.readouterr().err
    assert main(command + ["--plot", str(tmp_path / "x.docx")]) == 2
    err = capsys.readouterr().err
    assert "unknown format 'docx'" in err and "png" in err


def test_urdf_errors_name_the_link_and_print_nothing_else(capfd, tmp_path):
    """A non-finite number inside an unnamed element is reported with its link (not
    'in None'); the URDF parser's own lines do not reach the terminal."""
    bad = tmp_path / "nan.urdf"
    bad.write_text(
        '<robot name="r"><link name="arm"><inertial><origin xyz="0 0 nan"/><mass value="1"/>'
        '<inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link></robot>'
    )
    assert main(["check", str(bad)]) == 2
    err = capfd.readouterr().err
    assert "in <link name='arm'>" in err and "None" not in err
    broken = tmp_path / "tree.urdf"
    broken.write_text(
        '<robot name="r"><link name="a"/><joint name="j" type="fixed"><parent link="a"/>'
        '<child link="missing"/></joint></robot>'
    )
    assert main(["check", str(broken)]) == 2
    err = capfd.readouterr().err
    assert err.count("\n") == 1 and "child link [missing] of joint [j] not found" in err, err


def test_a_passive_robot_is_named_with_the_scenes_that_drive_it(capsys):
    assert main(["simulate", "solo12", "--t-final", "0.05"]) == 0
    out = capsys.readouterr().out
    assert "robot 'solo12' has no efforts" in out and "solo12_trot" in out


def _cli(*argv, **kwargs):
    """Run the command line in a new interpreter (signals and pipes need a process)."""
    code = (
        "import signal, sys; signal.signal(signal.SIGINT, signal.default_int_handler); "
        "from contactdiff.cli import main; sys.exit(main(sys.argv[1:]))"
    )
    return subprocess.Popen([sys.executable, "-c", code, *argv], stderr=subprocess.PIPE, text=True, **kwargs)


def test_ctrl_c_ends_with_one_line_and_status_130():
    """A runaway run (1e6 rad/s) interrupted once it is under way: with a budget of 1e7 steps
    it goes on for its ~2e6 steps of ~1e-6 s (its projection is within the budget, so the
    step budget's early stop does not end it first)."""
    proc = _cli(
        "simulate",
        "planar_trot_soft",
        "--t-final",
        "2",
        "--v",
        "body_pitch=1e6",
        "--max-steps",
        "10000000",
        stdout=subprocess.DEVNULL,
    )
    import time

    time.sleep(4.0)  # s: import and start; the run itself needs far longer
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130
    assert err.strip() == "contactdiff simulate: interrupted"


def test_a_closed_pipe_ends_quietly():
    read, write = os.pipe()
    os.close(read)  # the reader is gone before anything is written (| head that exits)
    proc = _cli("check", "ball", stdout=write)
    os.close(write)
    _, err = proc.communicate(timeout=60)
    assert err == "" and proc.returncode == 141


def test_a_long_run_draws_a_progress_bar_on_a_terminal(monkeypatch):
    """The bar appears once a run has lasted its delay (1 s) and shows simulated time,
    events and steps; on a stream that is not a terminal it stays silent."""
    import io
    import time

    from contactdiff.progress_bar import ProgressBar

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    for stream, shown in ((Terminal(), True), (io.StringIO(), False)):
        monkeypatch.setattr(sys, "stderr", stream)
        with ProgressBar("simulate ball", (0.0, 2.0)) as bar:
            start = time.monotonic()
            while time.monotonic() - start < 1.3:  # s: past the bar's 1-s delay
                bar(0.5, 3, 40)
                time.sleep(0.05)
        text = stream.getvalue()
        assert ("t = 0.5 / 2 s, 3 events, 40 steps" in text) == shown, text


def test_simulate_param_json_carries_the_parameter_jacobian(capsys):
    """The ball after one bounce: d z / d e = u (T - t1) with u = t1 = sqrt(2) (g = 1, height 1)."""
    assert (
        main(
            [
                "simulate",
                "ball",
                "--t-final",
                "2.5",
                "--jacobian",
                "--rtol",
                "1e-12",
                "--atol",
                "1e-13",
                "--param",
                "contact:ball:restitution",
                "--json",
            ]
        )
        == 0
    )
    data = json.loads(capsys.readouterr().out)
    assert data["parameter_names"] == ["contact:ball:restitution"]
    assert abs(data["parameter_jacobian"][0][0] - 2**0.5 * (2.5 - 2**0.5)) < 1e-9
    assert len(data["events"][0]["parameter_time_gradient"]) == 1


def test_simulate_param_all_and_list(capsys):
    assert main(["simulate", "ball", "--t-final", "0.5", "--param", "list"]) == 0
    names = capsys.readouterr().out.split()
    assert "contact:ball:restitution" in names and "scene:gravity_z" in names
    assert main(["simulate", "ball", "--t-final", "0.5", "--jacobian", "--param", "all"]) == 0
    out = capsys.readouterr().out
    assert "parameter Jacobian" in out and all(n in out for n in names)


def test_simulate_param_list_json_is_json(capsys):
    """``--param list --json`` prints one JSON list (not the text list): per parameter its
    name, kind, target, field and value; robots/ball.toml sets gravity (0, 0, -1) m/s²
    and restitution 0.8, and its contact is named after the frame "ball"."""
    assert main(["simulate", "ball", "--t-final", "0.5", "--param", "list", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    by_name = {row["name"]: row for row in rows}
    assert by_name["contact:ball:restitution"] == {
        "name": "contact:ball:restitution",
        "kind": "contact",
        "target": "ball",
        "field": "restitution",
        "value": 0.8,
    }
    assert by_name["scene:gravity_z"] == {
        "name": "scene:gravity_z",
        "kind": "scene",
        "target": "",
        "field": "gravity_z",
        "value": -1.0,
    }
    assert main(["simulate", "ball", "--t-final", "0.5", "--param", "list"]) == 0
    assert capsys.readouterr().out.split() == [row["name"] for row in rows]  # the same names, in order
