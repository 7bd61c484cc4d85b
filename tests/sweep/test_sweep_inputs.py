"""Sweep inputs a user types: ``--set NAME=VALUE`` numbers, grids too large to build,
ranges whose count is not a whole number, results files with a damaged line.

The scene is robots/ball.toml: a ball dropped from z = 1 m under g = 1 m/s^2 with
restitution 0.8. Before its first impact it falls freely, z(t) = h - g t^2 / 2, and
lands at t = sqrt(2 h / g); the next impact comes 2 e sqrt(2 g h) / g later
(2.26 s after the first from 1 m), the one after 0.8 times sooner.
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
import tracemalloc
import warnings

import pytest

from contactdiff.cli import main
from contactdiff.errors import InvalidInputError, ModelLoadError
from contactdiff.sweeps import random_points, sweep
from contactdiff.sweeps.points import MAX_POINTS, grid, parse_values, point_list
from contactdiff.sweeps.runner import DamagedRowsWarning

FREE_FALL_TOL = 1e-9
"""m: before its first impact the ball's height is a quadratic in time, which the
eighth-order stepper integrates exactly up to round-off (~1e-15 m over a few steps);
1e-9 m leaves room for any tolerance-controlled step sequence."""


def _rows(argv, capsys) -> list[dict]:
    assert main(["sweep", "ball", *argv, "--jobs", "1", "--json"]) == 0
    return json.loads(capsys.readouterr().out)["rows"]


# -- --set NAME=VALUE: numbers are numbers --------------------------------------------------
def test_set_final_time_is_a_number(capsys):
    rows = _rows(["--grid", "q:z=1,2", "--set", "t_final=2"], capsys)
    assert [r["t_final"] for r in rows] == [2, 2] and [r["t_end"] for r in rows] == [2.0, 2.0]
    assert [r["error"] for r in rows] == [None, None]


def test_set_gravity_changes_the_free_fall(capsys):
    """z(0.5 s) = 1 - g / 8 from 1 m: 0.75 m under g = 2 (0.875 m under the scene's g = 1)."""
    rows = _rows(["--grid", "q:z=1", "--set", "scene:gravity_z=-2", "--t-final", "0.5"], capsys)
    assert rows[0]["scene:gravity_z"] == -2
    assert rows[0]["q_end:z"] == pytest.approx(0.75, abs=FREE_FALL_TOL)


def test_set_initial_height_changes_the_free_fall(capsys):
    """z(0.5 s) = 1.5 - g / 8: 1.375 m under g = 1, 1.25 m under g = 2."""
    rows = _rows(["--grid", "scene:gravity_z=-1,-2", "--set", "q:z=1.5", "--t-final", "0.5"], capsys)
    assert [r["q:z"] for r in rows] == [1.5, 1.5]
    assert [r["q_end:z"] for r in rows] == pytest.approx([1.375, 1.25], abs=FREE_FALL_TOL)


def test_set_tolerance_reaches_the_runs(capsys):
    rows = _rows(["--grid", "q:z=1,2", "--set", "rtol=1e-6", "--t-final", "1"], capsys)
    assert [r["rtol"] for r in rows] == [1e-6, 1e-6] and [r["error"] for r in rows] == [None, None]
    # the value reaches the run's options: one out of range fails every run, naming rtol
    refused = _rows(["--grid", "q:z=1,2", "--set", "rtol=10", "--t-final", "1"], capsys)
    assert all(r["error"] == "InvalidInputError" and "rtol" in r["error_message"] for r in refused)


def test_set_event_budget_is_a_count(capsys):
    """From 1 m the ball hits the ground at 1.41 s and 3.68 s: two events by t = 5 s."""
    rows = _rows(["--grid", "q:z=1", "--set", "max_events=100", "--t-final", "5"], capsys)
    assert rows[0]["max_events"] == 100 and rows[0]["error"] is None and rows[0]["events:bounce"] >= 2
    one = _rows(["--grid", "q:z=1", "--set", "max_events=1", "--t-final", "5"], capsys)
    assert one[0]["error"] == "TooManyEventsError"


# -- grids too large to build --------------------------------------------------------------
@pytest.mark.parametrize(
    "build, count",
    [
        (lambda: grid({"q:z": "1:2:100000000"}), "100,000,000"),
        (lambda: grid({"a": "0:1:1000", "b": "0:1:1000", "c": "0:1:1000"}), "1,000,000,000"),
        (lambda: random_points({"q:z": "uniform:1:2"}, 10**8), "100,000,000"),
    ],
)
def test_a_huge_sweep_is_refused_at_once_and_cheaply(build, count):
    """1e8 points as Python floats alone would take 3.2 GB; the refusal comes before any
    point is made: it allocates far less than a megabyte (the three axes of 1000 values
    of the second case take about 0.1 MB) and returns at once (2 s is generous on a busy
    machine for a call of well under a millisecond; the 1e8-point grid took minutes)."""
    tracemalloc.start()
    started = time.perf_counter()
    try:
        with pytest.raises(InvalidInputError, match=f"has {count} points; a sweep takes at most {MAX_POINTS:,}"):
            build()
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert time.perf_counter() - started < 2.0
    assert peak < 1e6


def test_the_largest_sweep_is_allowed_and_one_more_point_is_not():
    assert len(grid({"x": f"0:1:{MAX_POINTS}"})) == MAX_POINTS
    with pytest.raises(InvalidInputError, match=f"the point list has {MAX_POINTS + 1:,} points"):
        point_list({"x": list(range(MAX_POINTS + 1))})


def test_a_study_split_into_sweeps_shares_one_results_file(tmp_path, fresh):
    """What the refusal of a huge sweep advises: two sweeps of the same names and
    settings, one file; the second runs only its own points, and a third over all of
    them reads every row back, the same as one sweep over all."""
    out = tmp_path / "rows.jsonl"
    assert sweep("ball", {"q:z": [0.5, 1.0]}, t_final=3.0, n_jobs=1, out=out).skipped == 0
    assert sweep("ball", {"q:z": [1.5, 2.0]}, t_final=3.0, n_jobs=1, out=out).skipped == 0
    whole = sweep("ball", HEIGHTS, t_final=3.0, n_jobs=1, out=out)
    assert whole.skipped == 4 and _flat(whole) == _flat(fresh)


def test_a_huge_grid_on_the_command_line_is_one_line(capsys):
    assert main(["sweep", "ball", "--grid", "q:z=1:2:100000000", "--t-final", "1"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "100,000,000 points" in err and "split it into several sweeps" in err


def test_ctrl_c_stops_the_largest_sweep_at_once_and_keeps_its_rows(tmp_path):
    """Ctrl-C once the rows of a sweep of MAX_POINTS points are being written: the
    command ends with one line and status 130 within seconds, and the finished rows
    are in the results file, ready to resume."""
    out = tmp_path / "rows.jsonl"
    code = (
        "import signal, sys; signal.signal(signal.SIGINT, signal.default_int_handler); "
        "from contactdiff.cli import main; sys.exit(main(sys.argv[1:]))"
    )
    proc = subprocess.Popen(
        [
            sys.executable,
            "-c",
            code,
            "sweep",
            "ball",
            "--grid",
            f"q:z=1:2:{MAX_POINTS}",
            "--t-final",
            "0.001",
            "--jobs",
            "1",
            "--out",
            str(out),
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    deadline = time.monotonic() + 60.0  # s: import, scene, points; the first rows follow within a second
    while not (out.exists() and out.stat().st_size) and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.1)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == 130 and err.strip() == "contactdiff sweep: interrupted", err
    kept = len(out.read_text().splitlines())
    assert 0 < kept < MAX_POINTS


# -- ranges whose count is not a positive integer ----------------------------------------------
@pytest.mark.parametrize("count", ["2.5", "0", "-3"])
def test_a_range_count_must_be_a_positive_integer(count):
    with pytest.raises(InvalidInputError, match=f"count n of lo:hi:n must be a positive integer, got '{count}'"):
        parse_values("q:z", f"1:2:{count}")


# -- results files with a damaged line ---------------------------------------------------------
HEIGHTS = {"q:z": "0.5:2:4"}


def _flat(result):
    return [row.to_dict(run_time=False) for row in result]


@pytest.fixture(scope="module")
def fresh():
    return sweep("ball", HEIGHTS, t_final=3.0, n_jobs=1)


def _damage(path, line: int, edit) -> None:
    lines = path.read_text().splitlines(keepends=True)
    lines[line - 1] = edit(lines[line - 1])
    path.write_text("".join(lines))


@pytest.mark.parametrize(
    "suffix, edit, reason",
    [
        (".csv", lambda text: text.replace(",", "", 1), r"line 3: \d+ cells, the header has \d+"),
        (".jsonl", lambda text: text[:10] + text[11:], r"line 2: not JSON"),
        (".jsonl", lambda text: text.replace('"sweep": "', '"sweep": "x'), r"line 2: its sweep 'x[0-9a-f]+' is not"),
    ],
)
def test_a_damaged_row_is_named_and_its_point_runs_again(tmp_path, fresh, suffix, edit, reason):
    """The second row is damaged (a CSV cell lost, a JSON character lost, the sweep's
    identity edited): the warning names its line and what is wrong, the three good
    rows are read back, the damaged row's point runs again, and the line is gone from
    the file, so that the next run reads every row back without a warning."""
    out = tmp_path / f"rows{suffix}"
    sweep("ball", HEIGHTS, t_final=3.0, n_jobs=1, out=out)
    _damage(out, 2 + (suffix == ".csv"), edit)  # the second row (after the CSV header)
    with pytest.warns(DamagedRowsWarning, match=reason):
        resumed = sweep("ball", HEIGHTS, t_final=3.0, n_jobs=1, out=out)
    assert resumed.skipped == 3 and _flat(resumed) == _flat(fresh)
    assert len(out.read_text().splitlines()) == 4 + (suffix == ".csv")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        again = sweep("ball", HEIGHTS, t_final=3.0, n_jobs=1, out=out)
    assert again.skipped == 4 and _flat(again) == _flat(fresh)


def test_a_damaged_line_is_removed_even_when_no_point_runs(tmp_path, fresh):
    """The damaged line is a fifth row, of a point this sweep does not have: nothing
    runs, and the file is cleaned all the same."""
    out = tmp_path / "rows.jsonl"
    sweep("ball", HEIGHTS, t_final=3.0, n_jobs=1, out=out)
    out.write_text(out.read_text() + '{"index": 4, "q:z": 2.5, "sweep": \n')
    out.write_text(out.read_text() + out.read_text().splitlines(keepends=True)[0])  # a good line after it
    with pytest.warns(DamagedRowsWarning, match="line 5: not JSON"):
        resumed = sweep("ball", HEIGHTS, t_final=3.0, n_jobs=1, out=out)
    assert resumed.skipped == 4 and _flat(resumed) == _flat(fresh)
    assert len(out.read_text().splitlines()) == 5 and "2.5" not in out.read_text()


def test_a_damaged_row_is_one_warning_line_on_the_command_line(tmp_path, capsys):
    out = tmp_path / "rows.csv"
    argv = ["sweep", "ball", "--grid", "q:z=1:2:3", "--t-final", "3", "--jobs", "1", "--out", str(out)]
    assert main(argv) == 0
    _damage(out, 4, lambda text: text.rstrip("\n") + ",extra\n")
    capsys.readouterr()
    assert main(argv) == 0
    captured = capsys.readouterr()
    assert captured.err.startswith("contactdiff sweep: warning: results file") and captured.err.count("\n") == 1
    assert "line 4:" in captured.err and "run again" in captured.err
    assert "2 read back" in captured.out


def test_a_file_with_no_good_row_is_refused_naming_its_lines(tmp_path):
    out = tmp_path / "rows.csv"
    out.write_text("index,q:z,sweep\n0,1.0\n")  # a header, and a row a cell short
    with pytest.raises(ModelLoadError, match="no row of this sweep, and 1 damaged line .line 2: 2 cells"):
        sweep("ball", {"q:z": [1.0]}, t_final=1.0, n_jobs=1, out=out)
    assert out.read_text() == "index,q:z,sweep\n0,1.0\n"  # left as it was
