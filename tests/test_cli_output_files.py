"""Files the command line writes (``simulate --plot/--html``, ``sweep --out/--plot``,
``bench --plot``): checked before the run, and a write that fails after the run
still prints the run and ends with one named line, exit status 2.

(The sweep's files failing during a sweep: tests/sweep/test_sweep_output_files.py.)

Permission bits do not stop root, who may run these tests: the folders that refuse a
file here are paths whose parent is a regular file, or a folder replaced by a file
during the run; a read-only folder (chmod) is tried only when not running as root.

The scene is robots/ball.toml: dropped from 1 m under g = 1 m/s^2, the ball lands
at t = sqrt(2) s, so a run to 1.6 s holds exactly one event.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

import contactdiff.bench.runner
import contactdiff.integration.hybrid
import contactdiff.sweeps.runner
from contactdiff.cli import main

SIMULATE = ["simulate", "ball", "--t-final", "1.6"]
SWEEP = ["sweep", "ball", "--grid", "q:z=1,2", "--t-final", "1.6", "--jobs", "1"]
BENCH = ["bench", "--quick", "--scenes", "ball"]


def _outputs(folder: Path) -> list[list[str]]:
    """Each command with one output file inside ``folder``."""
    return [
        SIMULATE + ["--plot", str(folder / "run.png")],
        SIMULATE + ["--html", str(folder / "run.html")],
        SWEEP + ["--out", str(folder / "rows.csv")],
        SWEEP + ["--plot", str(folder / "rows.png")],
        BENCH + ["--plot", str(folder / "bench.png")],
    ]


def _needs(argv: list[str]) -> None:
    pytest.importorskip("matplotlib") if "--plot" in argv else None
    pytest.importorskip("meshcat") if "--html" in argv else None


def _no_run(monkeypatch) -> None:
    def never(*args, **kwargs):
        raise AssertionError("the run started before the output file was checked")

    monkeypatch.setattr(contactdiff.integration.hybrid, "simulate", never)
    monkeypatch.setattr(contactdiff.bench.runner, "run_bench", never)
    monkeypatch.setattr(contactdiff.sweeps.runner, "run_point", never)


@pytest.mark.parametrize("index", range(5))
def test_a_folder_that_is_a_file_is_refused_before_the_run(index, tmp_path, capsys, monkeypatch):
    (tmp_path / "plain").write_text("a file\n")
    argv = _outputs(tmp_path / "plain")[index]
    _needs(argv)
    _no_run(monkeypatch)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "is a file, not a folder" in err and str(tmp_path / "plain") in err, err


def _read_only_folder(folder: Path) -> Path:
    """``folder`` made read-only (chmod 555); the test is skipped where that does not stop
    this process writing in it (root, with its right to override permissions)."""
    folder.mkdir()
    folder.chmod(0o555)
    try:
        (folder / "probe").write_text("")
    except PermissionError:
        return folder
    (folder / "probe").unlink()
    folder.chmod(0o755)
    pytest.skip("this process writes into read-only folders (root): chmod cannot make one here")


@pytest.mark.parametrize("index", range(5))
def test_a_read_only_folder_is_refused_before_the_run(index, tmp_path, capsys, monkeypatch):
    folder = tmp_path / "read-only"
    argv = _outputs(folder)[index]
    _needs(argv)
    _no_run(monkeypatch)
    _read_only_folder(folder)
    try:
        assert main(argv) == 2
    finally:
        folder.chmod(0o755)
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "cannot be written" in err and str(folder) in err, err
    assert list(folder.iterdir()) == []  # the check left nothing behind


def test_a_read_only_results_file_is_refused_before_the_run(tmp_path, capsys, monkeypatch):
    out = tmp_path / "rows.csv"
    out.write_text("index,q:z,sweep\n")
    out.chmod(0o444)
    try:
        out.open("r+b").close()
    except PermissionError:
        pass
    else:
        out.chmod(0o644)
        pytest.skip("this process writes into read-only files (root): chmod cannot make one here")
    _no_run(monkeypatch)
    assert main(SWEEP + ["--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "cannot be written: Permission denied" in err, err


def _break(folder: Path) -> None:
    """Replace ``folder`` by a regular file: nothing can be written in it any more."""
    shutil.rmtree(folder)
    folder.write_text("not a folder any more\n")


def test_simulate_prints_its_run_when_its_files_fail_after_it(tmp_path, capsys, monkeypatch):
    pytest.importorskip("matplotlib")
    pytest.importorskip("meshcat")
    folder = tmp_path / "out"
    folder.mkdir()
    simulate = contactdiff.integration.hybrid.simulate

    def run_then_break(*args, **kwargs):
        traj = simulate(*args, **kwargs)
        _break(folder)
        return traj

    monkeypatch.setattr(contactdiff.integration.hybrid, "simulate", run_then_break)
    assert main(SIMULATE + ["--plot", str(folder / "run.png"), "--html", str(folder / "run.html"), "--json"]) == 2
    captured = capsys.readouterr()
    run = json.loads(captured.out)  # the run, printed whole: one bounce at sqrt(2) s, within the event tolerance
    assert [e["kind"] for e in run["events"]] == ["bounce"] and run["events"][0]["t"] == pytest.approx(2**0.5)
    assert captured.err.count("\n") == 1 and "--plot" in captured.err and "--html" in captured.err
    assert captured.err.startswith("contactdiff simulate: error:") and "results above are complete" in captured.err


def test_bench_prints_its_table_when_its_plot_fails_after_it(tmp_path, capsys, monkeypatch):
    pytest.importorskip("matplotlib")
    folder = tmp_path / "out"
    folder.mkdir()
    run_bench = contactdiff.bench.runner.run_bench

    def run_then_break(*args, **kwargs):
        result = run_bench(*args, **kwargs)
        _break(folder)
        return result

    monkeypatch.setattr(contactdiff.bench.runner, "run_bench", run_then_break)
    assert main(BENCH + ["--plot", str(folder / "bench.png")]) == 2
    captured = capsys.readouterr()
    assert "ball" in captured.out and "plot written" not in captured.out
    last = captured.err.splitlines()[-1]  # after the bench's progress lines
    assert last.startswith("contactdiff bench: error: --plot") and "could not be written" in last
    assert "Traceback" not in captured.err
