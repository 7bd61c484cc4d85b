"""A sweep whose files (``--out``, ``--plot``) fail during the sweep: every point still
runs, the rows are printed (or returned in the error), and one named line says which
file failed. The user job ``sweep_user_jobs:break_folder`` replaces the output folder
by a regular file at its second point (a failure that stops root too)."""

from __future__ import annotations

import json

import pytest

from contactdiff.cli import main
from contactdiff.errors import OutputFileError
from contactdiff.sweeps import sweep


def test_a_sweep_runs_on_and_prints_its_rows_when_its_files_fail(tmp_path, capsys):
    """The user job breaks the folder at its second point: the third point still runs,
    every row is printed, and the one error line names --out and --plot."""
    pytest.importorskip("matplotlib")
    folder = tmp_path / "out"
    folder.mkdir()
    argv = [
        "sweep",
        "ball",
        "--grid",
        "q:z=1,2,3",
        "--job",
        "sweep_user_jobs:break_folder",
        "--jobs",
        "1",
        "--set",
        f"job:folder={folder}",
        "--out",
        str(folder / "rows.jsonl"),
        "--plot",
        str(folder / "rows.png"),
        "--json",
    ]
    assert main(argv) == 2
    captured = capsys.readouterr()
    assert [r["height"] for r in json.loads(captured.out)["rows"]] == [1, 2, 3]
    assert captured.err.count("\n") == 1 and "--out" in captured.err and "--plot" in captured.err


def test_a_sweep_whose_results_file_fails_returns_its_rows_in_the_error(tmp_path):
    folder = tmp_path / "out"
    folder.mkdir()
    with pytest.raises(OutputFileError, match="--out .* could not be written") as caught:
        sweep(
            "ball",
            {"q:z": [1, 2, 3]},
            "sweep_user_jobs:break_folder",
            fixed={"job:folder": str(folder)},
            n_jobs=1,
            out=folder / "rows.csv",
        )
    assert [row.outputs["height"] for row in caught.value.result] == [1, 2, 3]
