"""What the command line writes besides its results: progress bars only on a terminal
(unless forced), and help texts that say what the options do."""

from __future__ import annotations

import io
import sys

import pytest

from contactdiff.bench.runner import _Progress
from contactdiff.bench.scene_table import QUICK_SCENES
from contactdiff.cli import main
from contactdiff.progress_bar import ProgressBar


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


@pytest.mark.parametrize(
    "stream, progress, drawn",
    [
        (io.StringIO, None, False),  # a file or a pipe: no bar
        (_Terminal, None, True),  # a terminal: the bar
        (io.StringIO, True, True),  # forced
        (_Terminal, False, False),  # hidden
    ],
)
def test_the_bench_bar_draws_only_on_a_terminal(monkeypatch, stream, progress, drawn):
    err = stream()
    monkeypatch.setattr(sys, "stderr", err)
    bar = _Progress(2, progress)
    bar.step("one")
    bar.step("two")
    assert ("\r[" in err.getvalue()) is drawn
    assert bool(err.getvalue()) is drawn


def test_the_simulate_bar_is_off_when_stderr_is_not_a_terminal(monkeypatch):
    err = io.StringIO()
    monkeypatch.setattr(sys, "stderr", err)
    with ProgressBar("run", (0.0, 1.0)) as bar:
        assert bar.bar.disable
        bar(0.5, 1, 10)
    assert err.getvalue() == ""


def test_bench_cli_writes_no_bar_into_a_pipe(capsys):
    """capsys's stderr is not a terminal: the bench's bar must not appear in it."""
    assert main(["bench", "--quick", "--scenes", "ball", "--repeats", "1"]) == 0
    err = capsys.readouterr().err
    assert "\r" not in err and "[#" not in err


def test_bench_quick_help_names_the_scenes_it_runs(capsys):
    try:
        code = main(["bench", "--help"])
    except SystemExit as exc:
        code = exc.code
    assert code == 0
    text = " ".join(capsys.readouterr().out.split())
    quick = text[text.index("--quick") :]
    assert all(name in quick for name in QUICK_SCENES)
    assert "default all; with --quick: " + " and ".join(QUICK_SCENES) in text
