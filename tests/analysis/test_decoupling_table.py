"""The state source of scripts/quadruped_decoupling_table.py: diagonal touchdowns
of the simulated trot.

What must hold at every state the script measures (each could fail):

* both feet of the landing pair are closed (|gap| <= 1e-12 m: the partner's gap
  is closed to 1e-13 m by Gauss-Newton, the landing foot's is the event's, at
  round-off) and approach faster than the script's TROT_MIN_SPEED;
* closing the partner's gap moves only the partner's own leg joints (base pose
  and the other legs as at the event), by a partner gap no larger than
  TROT_MAX_PARTNER_GAP;
* the other pair's mode agrees with the geometry and with the simulation: its
  feet are closed (|gap| <= 1e-9 m, the integrator's contact tolerance scale)
  and are exactly the contacts active in the trajectory just before the event,
  and every foot neither landing nor in the mode is in the air (gap > 0);
* the state's time is the event's time (the trot controller is clock-driven,
  so the order gap evaluates its torques there).

solo12 over half a period from rest: its first diagonal touchdown (front-right
and hind-left, about 60 ms in) is inside that window, which keeps this fast.
"""

from __future__ import annotations

import numpy as np
import pytest
from helpers import load_script

import contactdiff as cd
from contactdiff.analysis.order_gap import diagonal_pairs, order_gap
from contactdiff.errors import InvalidInputError


@pytest.fixture(scope="module")
def script():
    return load_script("quadruped_decoupling_table")


@pytest.fixture(scope="module")
def solo12_trot(script):
    from contactdiff.control.trot_scenes import trot_parameters

    strides = 0.5
    scene, states = script.trot_touchdowns("solo12", strides=strides)
    traj = cd.simulate(scene, strides * trot_parameters("solo12")["period"])
    return scene, states, traj


def _leg_coordinates(scene, contact):
    model = scene.model
    joint = model.frames[scene.contacts[contact].fid].parentJoint
    return {
        k
        for j in model.supports[joint]
        if j > 1
        for k in range(model.joints[j].idx_v, model.joints[j].idx_v + model.joints[j].nv)
    }


def test_trot_touchdowns_are_closed_approaching_and_consistent(script, solo12_trot):
    scene, states, traj = solo12_trot
    assert states, "solo12's first diagonal touchdown should qualify"
    kin, n = scene.kinematics, len(scene.contacts)
    events = {e.t: e for e in traj.events if e.kind == "touchdown"}
    for s in states:
        assert tuple(sorted(s.pair)) in {tuple(sorted(p)) for p in diagonal_pairs(scene)}
        kin.update(s.q, s.v)
        for k in s.pair:
            assert abs(scene.contacts[k].gap(kin)) <= 1e-12
            assert scene.contacts[k].rows(kin)[0] @ s.v < -script.TROT_MIN_SPEED
        for k in s.mode:
            assert abs(scene.contacts[k].gap(kin)) <= 1e-9
        for k in set(range(n)) - set(s.mode) - set(s.pair):
            assert scene.contacts[k].gap(kin) > 0
        # the state is the event's, up to the partner's leg
        event = events[s.t]
        assert np.array_equal(event.v_minus, s.v)
        assert set(s.mode) == {scene.contact_index(c) for c in event.mode_before}
        segment = next(seg for seg in traj.segments if seg.t1 == s.t and seg.t1 > seg.t0)
        assert set(s.mode) == {scene.contact_index(c) for c in segment.mode}
        moved = np.flatnonzero(np.abs(scene.robot.difference(event.q, s.q)) > 0)
        fired = {scene.contact_index(c) for c in event.contacts}
        partners = set(s.pair) - fired
        allowed = set().union(*(_leg_coordinates(scene, k) for k in partners)) if partners else set()
        assert set(moved) <= allowed
        assert (len(moved) > 0) == (s.partner_gap > 0)
        assert 0 <= s.partner_gap <= script.TROT_MAX_PARTNER_GAP


def test_trot_state_order_gap_uses_event_time(solo12_trot):
    """The trot controller is clock-driven. At the event time (the approach phase
    of the landing pair's swing, its legs pressing down) both landing feet stay
    down after either order; at t = 0 the schedule has that pair in mid-swing, its
    PD torques pulling both feet towards a reference centimetres up, and neither
    stays down: the order gap must be evaluated at the event's time."""
    scene, states, _ = solo12_trot
    s = states[0]
    landing = {scene.contact_names[k] for k in s.pair}
    at_event = order_gap(scene, s.q, s.v, s.pair, mode=s.mode, t=s.t)
    assert all(landing <= set(m) for m in at_event.mode_after.values())
    at_zero = order_gap(scene, s.q, s.v, s.pair, mode=s.mode, t=0.0)
    assert all(not landing & set(m) for m in at_zero.mode_after.values())


def test_state_sources(script):
    scene, states, label = script.touchdown_states("solo12", "standing")
    assert label.startswith("standing") and len(states) == 1
    assert states[0].t == 0.0 and states[0].partner_gap == 0.0 and states[0].mode == ()
    with pytest.raises(InvalidInputError, match="standing"):
        script.touchdown_states("solo12", "gallop")


def test_trend_figure_labels_both_axes_of_both_panels(script):
    """Synthetic rows (one value per key and size): the figure is about its axes."""
    pytest.importorskip("matplotlib")
    rows = [
        {
            "friction": f,
            "foot_mass": m,
            "stiffness": k,
            "pair_coupling": 1e-2,
            "saltation_gap": 1e-3,
            "later_base_saltation_gap": 1e-4,
        }
        for f in ("stick", "none")
        for m in (*script.TREND_FOOT_MASSES, None)
        for k in (script.TREND_STIFFNESSES if m is not None else (None,))
    ]
    fig = script.trend_figure(rows)
    assert all(ax.get_xlabel() and ax.get_ylabel() for ax in fig.axes)
