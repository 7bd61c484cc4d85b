"""`LoopReports` on its own, from its explicit inputs: the statistics it sums over the
steppers and mode fields it is given, the counts it keeps, and the near-grazing misses
(a note each within MAX_NOTES, or `GrazingError` with ``on_grazing="raise"``)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

import contactdiff as cd
from contactdiff.integration.auto_method import AutoMethod
from contactdiff.integration.guards import NearMiss
from contactdiff.integration.loop_reports import MAX_NOTES, LoopReports
from contactdiff.integration.samples import SampleRecorder
from contactdiff.integration.trajectory import Termination


def _stepper(method, steps, rejected, accel, jac, t=0.5):
    return SimpleNamespace(
        method=method,
        n_steps=steps,
        n_rejected=rejected,
        n_accel=accel,
        n_jac=jac,
        t=t,
        q=np.array([0.3]),
        v=np.array([-0.1]),
        phi=None,
    )


def _reports(options=None, notes=None):
    scene = cd.Scene(cd.load_robot("ball"), [cd.Contact("ball")], q0={"z": 1.0})
    options = options or cd.SimulateOptions()
    records = dict(events=[], segments=[], notes=[] if notes is None else notes)
    fields = [SimpleNamespace(n_solve=7, n_derivatives=2), SimpleNamespace(n_solve=5, n_derivatives=1)]
    auto = AutoMethod(None, None, [], MAX_NOTES)  # what method="auto" did: one switch, 4 probes of 11 solves
    auto.retired, auto.switches = [_stepper("DOP853", 10, 3, 130, 0)], [(0.25, "Radau")]
    auto.chooser, auto.n_probe_evaluations = SimpleNamespace(n_probes=4), 11
    reports = LoopReports(
        scene,
        0.0,
        1.0,
        options,
        0,
        None,
        SampleRecorder((), 0, ()),
        **records,
        fields=fields,
        auto=auto,
        mode_names=lambda mode: tuple(f"c{k}" for k in mode),
    )
    return reports, records


def test_the_trajectorys_statistics_sum_what_it_is_given():
    """Steps, rejected steps, evaluations: the retired stepper's plus the current one's
    (10 + 4, 3 + 1, 130 + 40, 0 + 6), the fields' solves (7 + 5) and derivatives (2 + 1);
    the steps by method; the counts it keeps as the loop set them; the final state the
    stepper's."""
    reports, records = _reports()
    reports.max_drift, reports.n_projections = 2e-9, 3
    traj = reports.trajectory(_stepper("Radau", 4, 1, 40, 6), Termination.T_FINAL)
    s = traj.stats
    assert (s.steps, s.rejected_steps, s.stepper_evaluations, s.jacobian_evaluations) == (14, 4, 170, 6)
    assert (s.dynamics_evaluations, s.derivative_evaluations) == (12, 3)
    assert s.steps_by_method == {"DOP853": 10, "Radau": 4} and s.method_switches == [[0.25, "Radau"]]
    assert (s.stiffness_probes, s.probe_evaluations, s.projections, s.near_grazing_misses) == (4, 11, 3, 0)
    assert traj.max_drift == 2e-9 and traj.termination is Termination.T_FINAL
    assert traj.t == 0.5 and traj.q.tolist() == [0.3] and traj.events is records["events"]


def test_near_misses_before_the_event_are_noted_up_to_max_notes_or_raise():
    """Misses at or after ``t_event`` are left for later; each one before it counts, the first
    MAX_NOTES of them with a note naming the contact (through the loop's names); under
    ``on_grazing="raise"`` the first one raises."""
    notes: list[str] = ["an earlier note"]
    reports, _ = _reports(notes=notes)
    misses = [NearMiss(0.1 * k, 0, 1e-9, 1e-8) for k in range(MAX_NOTES + 3)]
    reports.near_misses(misses, t_event=0.1 * (MAX_NOTES + 2))
    assert reports.n_near_misses == MAX_NOTES + 2
    assert len(notes) == 1 + MAX_NOTES and all("near-grazing of ball" in n for n in notes[1:])
    raising, _ = _reports(cd.SimulateOptions(on_grazing="raise"))
    with pytest.raises(cd.GrazingError, match="near-grazing of ball at t = 0"):
        raising.near_misses(misses, t_event=np.inf)
