"""``contactdiff sweep``: exit statuses, --json, --out, --plot, one-line errors."""

from __future__ import annotations

import json

import pytest

from contactdiff.cli import main

BALL = ["sweep", "ball", "--grid", "q:z=1,2", "--t-final", "3", "--jobs", "1"]


def test_text_output_lists_each_point(capsys):
    assert main(BALL) == 0
    out = capsys.readouterr().out
    assert "sweep of ball: 2 points, 0 failed" in out
    assert out.count("\n  1 ") + out.count("\n  2 ") == 2  # one line per point, the value first


def test_json_holds_every_row(capsys):
    assert main(BALL + ["--t-final", "1.5", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["points"] == 2 and data["failed"] == 0 and data["names"] == ["q:z"]
    assert [row["q:z"] for row in data["rows"]] == [1, 2]
    # under g = 1 the ball dropped from h lands at sqrt(2 h): 1.41 s from 1 m, 2 s from 2 m
    assert [row["events:bounce"] for row in data["rows"]] == [1, 0]


def test_out_is_written_and_resumed(tmp_path, capsys):
    out = tmp_path / "rows.jsonl"
    assert main(BALL + ["--out", str(out)]) == 0
    assert len(out.read_text().splitlines()) == 2
    capsys.readouterr()
    assert main(BALL + ["--out", str(out), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["skipped"] == 2
    assert len(out.read_text().splitlines()) == 2


@pytest.mark.parametrize(
    "points",
    [
        ["--grid", "q:z=1:2:3"],
        ["--grid", "q:z=1,2", "--grid", "scene:gravity_z=-1,-2"],
        ["--random", "q:z=uniform:1:2", "--random", "scene:gravity_z=normal:-1:0.1", "--samples", "5", "--seed", "3"],
    ],
)
def test_plot_writes_a_line_or_a_heatmap(tmp_path, capsys, points):
    pytest.importorskip("matplotlib")
    png = tmp_path / "plot.png"
    assert (
        main(
            ["sweep", "ball", *points, "--t-final", "3", "--jobs", "1", "--plot", str(png), "--plot-output", "q_end:z"]
        )
        == 0
    )
    assert png.stat().st_size > 1000 and png.read_bytes()[:4] == b"\x89PNG"


def test_points_from_a_file_and_a_zipped_list(tmp_path, capsys):
    listing = tmp_path / "points.json"
    listing.write_text(json.dumps([{"q:z": 1.0, "t_final": 2.0}, {"q:z": 2.0, "t_final": 2.5}]))
    assert main(["sweep", "ball", "--points", str(listing), "--jobs", "1", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)["rows"]
    assert [r["t_end"] for r in rows] == [2.0, 2.5]
    assert main(["sweep", "ball", "--list", "q:z=1,2", "--list", "t_final=2,2.5", "--jobs", "1", "--json"]) == 0
    again = json.loads(capsys.readouterr().out)["rows"]
    assert [(r["q:z"], r["t_end"]) for r in again] == [(1, 2.0), (2, 2.5)]


@pytest.mark.parametrize(
    "argv, match",
    [
        (["sweep", "ball", "--grid", "q:zz=1,2", "--t-final", "1"], "unknown quantity 'q:zz'"),
        (["sweep", "ball", "--grid", "q:z=1:2:0", "--t-final", "1"], "must be a positive integer, got '0'"),
        (["sweep", "ball", "--grid", "q:z=1,2", "--t-final", "1", "--backend", "mpi"], "valid: dask, loky, ray"),
        (["sweep", "ball", "--grid", "q:z=1,2", "--random", "q:z=uniform:0:1", "--samples", "2"], "one way"),
        (["sweep", "ball", "--random", "q:z=uniform:0:1", "--t-final", "1"], "--samples"),
        (["sweep", "ball", "--grid", "q:z", "--t-final", "1"], "NAME=VALUES"),
        (["sweep", "ball", "--grid", "q:z=1,2"], "t_final"),
        (["sweep", "ball", "--grid", "q:z=1,2", "--t-final", "1", "--job", "nosuchmodule:f"], "cannot import"),
        (["sweep", "ball", "--grid", "q:z=1,2", "--t-final", "1", "--out", "rows.txt"], "valid: .jsonl, .csv"),
        (["sweep", "ball", "--grid", "q:z=1,2", "--t-final", "1", "--plot", "nowhere/p.png"], "does not exist"),
        (["sweep", "ball", "--points", "missing.json", "--t-final", "1"], "cannot read"),
    ],
)
def test_bad_input_exits_2_with_one_line(argv, match, capsys, tmp_path, monkeypatch):
    if "--plot" in argv:  # without matplotlib (not in the test extra) that error comes first
        pytest.importorskip("matplotlib", reason="the plot path is checked once matplotlib is there")
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert match in err and err.count("\n") == 1 and err.startswith("contactdiff sweep: error:")


def test_a_failed_point_is_reported_and_the_status_is_0(capsys):
    assert main(["sweep", "ball", "--grid", "q:z=1,-0.5", "--t-final", "1", "--jobs", "1"]) == 0
    out = capsys.readouterr().out
    assert "1 failed" in out and "point #1 failed: InconsistentStateError" in out
