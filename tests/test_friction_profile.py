"""The counting of ``scripts/friction_trots.py --profile`` (`time_shares`) on a made-up run whose
counts are known by construction: which steps count as slipping, the evaluations per simulated
second of each part, and the split of the slipping ones by stops and onsets."""

from __future__ import annotations

from types import SimpleNamespace as NS

import pytest
from helpers import load_script


@pytest.fixture(scope="module")
def friction_trots():
    return load_script("friction_trots")


def test_time_shares_counts(friction_trots):
    """Three segments: sticking on [0, 1), a slip from sticking on [1, 1.5) ending in a lift-off,
    a slip an impact left on [1.5, 2) ending in a stop at 2. Steps (t_old, t, rejected, wall,
    evaluations): the sticking one 1 s with 24 evaluations (24 per s); the onset's two steps
    (10 + 30 evaluations over 0.5 s), ending 0.25 s and 0.5 s after the onset (decade 1e-1; the
    second crossed the lift-off, to 1.6, and counts up to it); the stop's steps starting 0.5 s and
    0.005 s before it (decades 1e-1 and 1e-3), 12 + 48 evaluations. Slipping: 100 evaluations
    over 1 s, so 100 per s, and 100 / 24 over the sticking rate; one 24-evaluation step (the
    sticking steps' mean) in each of the two slipping segments would give 48 per s, 2 times the
    sticking rate. An impact's wall time is kept apart."""
    segments = [NS(t0=0.0, t1=1.0, sliding=()), NS(t0=1.0, t1=1.5, sliding=("a",)), NS(t0=1.5, t1=2.0, sliding=("b",))]
    events = [NS(t=1.0, kind="slip"), NS(t=1.5, kind="lift-off"), NS(t=2.0, kind="stick")]
    record = [
        (0.0, 1.0, 0, 0.1, 24),
        (1.0, 1.25, 1, 0.1, 10),
        (1.25, 1.6, 0, 0.1, 30),
        ("impact", 0.05),
        (1.5, 1.995, 2, 0.1, 12),
        (1.995, 2.0, 3, 0.1, 48),
    ]
    shares = friction_trots.time_shares(record, segments, 1.0, events)
    slipping, other = shares["slipping"], shares["other"]
    assert (slipping["steps"], slipping["rejected"], slipping["evaluations"]) == (4, 6, 100)
    assert (other["steps"], other["rejected"], other["evaluations"]) == (1, 0, 24)
    assert slipping["sim_time"] == pytest.approx(1.0) and other["sim_time"] == pytest.approx(1.0)
    assert slipping["evaluations_per_s"] == pytest.approx(100.0)
    assert shares["slip_to_other"] == pytest.approx(100.0 / 24.0)
    assert slipping["segments"] == 2 and shares["one_step_floor"] == pytest.approx(2.0)
    assert shares["stops"] == {"segments": 1, "evaluations": 60, "by_time_left": {"1e-3": 48, "1e-1": 12}}
    assert shares["onsets"] == {"segments": 1, "evaluations": 40, "by_time_since": {"1e-1": 40}}
    assert shares["impacts"]["wall"] == pytest.approx(0.05)
    assert shares["rest"]["wall"] == pytest.approx(1.0 - 0.05 - 0.5)
