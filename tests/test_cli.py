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
