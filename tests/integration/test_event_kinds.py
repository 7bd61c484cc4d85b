"""Event kinds are an enum (`EventKind`) that reads, compares and writes as its strings."""

import json

import numpy as np
import pytest

import contactdiff as cd
from contactdiff.errors import UnknownNameError
from contactdiff.integration.trajectory import EVENT_KINDS, Event, EventKind


def test_a_bounce_is_an_event_kind_equal_to_its_string_in_every_output(tmp_path):
    """robots/ball.toml: dropped from 1 m under g = 1 m/s², restitution 0.8; it lands at
    t = sqrt(2) s and leaves again, so its first event is a bounce. The kind is an
    `EventKind` that equals the string "bounce", and the JSON summary and the .npz
    export hold the plain string."""
    scene = cd.load_scene("ball")
    traj = cd.simulate(scene, 2.0, dense=True)
    event = traj.events[0]
    assert event.kind is EventKind.BOUNCE and event.kind == "bounce" and f"{event.kind}" == "bounce"
    data = json.loads(json.dumps(traj.summary()))
    assert data["events"][0]["kind"] == "bounce" and type(event.to_dict()["kind"]) is str
    traj.save_npz(tmp_path / "ball.npz", n_samples=3)
    assert np.load(tmp_path / "ball.npz")["event_kind"].tolist() == ["bounce"]


def test_event_kinds_are_the_strings_of_before_and_a_string_given_becomes_one():
    """The kinds and their order (the sweeps' ``events:<kind>`` columns) are the strings
    the events have always carried; an event built with a string holds the enum; an
    unknown kind is refused, the valid ones listed."""
    assert [str(k) for k in EVENT_KINDS] == [
        "touchdown",
        "lift-off",
        "slip",
        "stick",
        "bounce",
        "grazing",
        "zeno",
        "bear",
    ]
    fields = dict(
        t=0.0,
        contacts=("a",),
        simultaneous=False,
        q=np.zeros(1),
        v_minus=np.zeros(1),
        v_plus=np.zeros(1),
        impulses={},
        mode_before=(),
        mode_after=("a",),
    )
    assert Event(kind="lift-off", **fields).kind is EventKind.LIFT_OFF
    with pytest.raises(UnknownNameError, match=r"'landing'.*bear, bounce, grazing, lift-off"):
        Event(kind="landing", **fields)
