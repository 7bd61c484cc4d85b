"""`scripts/toss_events.py`: recordings of real tosses, and the comparison that tells a
changed run from the same one."""

from __future__ import annotations

import json

import numpy as np
import pytest
from helpers import load_script


@pytest.fixture(scope="module")
def script():
    return load_script("toss_events")


@pytest.fixture(scope="module")
def recording(script, tmp_path_factory):
    """The first shipped toss recorded once."""
    path = tmp_path_factory.mktemp("tosses") / "a.npz"
    assert script.main(["record", str(path), "--limit", "1"]) == 0
    return path


def _changed(recording, tmp_path, change) -> str:
    """A copy of the recording with ``change`` applied to its event lists."""
    with np.load(recording) as data:
        arrays = {k: data[k] for k in data.files}
    for key in [k for k in arrays if k.endswith(":events")]:
        arrays[key] = np.array(json.dumps(change(json.loads(str(arrays[key])))))
    path = tmp_path / "b.npz"
    np.savez(path, **arrays)
    return str(path)


def test_a_run_recorded_again_is_the_same_bit_for_bit(script, recording, tmp_path):
    """The simulator is deterministic in one process: a second recording of the same
    toss compares equal with zero tolerances."""
    again = tmp_path / "again.npz"
    assert script.main(["record", str(again), "--limit", "1"]) == 0
    assert script.main(["compare", str(recording), str(again), "--time-tol", "0", "--state-tol", "0"]) == 0


def test_an_event_moved_beyond_the_tolerance_is_reported(script, recording, tmp_path, capsys):
    """An event 2e-9 s later fails the default 1e-9 s and passes 1e-8 s."""

    def later(events):
        events[0][2] += 2e-9
        return events

    moved = _changed(recording, tmp_path, later)
    assert script.main(["compare", str(recording), moved]) == 1
    assert "time diff" in capsys.readouterr().out
    assert script.main(["compare", str(recording), moved, "--time-tol", "1e-8"]) == 0


def test_another_event_kind_or_a_missing_event_is_reported(script, recording, tmp_path):
    """A different kind at the first event, or one event fewer, fails whatever the tolerances."""

    def other_kind(events):
        events[0][0] = "grazing" if events[0][0] != "grazing" else "bounce"
        return events

    kind = _changed(recording, tmp_path, other_kind)
    assert script.main(["compare", str(recording), kind, "--time-tol", "1", "--state-tol", "1"]) == 1
    fewer = _changed(recording, tmp_path, lambda ev: ev[:-1])
    assert script.main(["compare", str(recording), fewer, "--time-tol", "1", "--state-tol", "1"]) == 1


def test_a_limit_below_one_is_refused(script, tmp_path):
    with pytest.raises(SystemExit) as exc:
        script.main(["record", str(tmp_path / "x.npz"), "--limit", "0"])
    assert exc.value.code == 2
