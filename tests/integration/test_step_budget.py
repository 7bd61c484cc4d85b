"""Step budget: a run that cannot reach its final time within max_steps stops early.

`contactdiff.ode.step_budget`: after WINDOW steady steps (no event, no growth)
the steps still needed are projected at a high percentile of the recent steps; a run
that would need more than MARGIN times the steps it has left stops with
`StepBudgetError`, a `TooManyStepsError` with the run so far, its time, mode and step.
"""

from __future__ import annotations

import numpy as np
import pytest

import contactdiff as cd
from contactdiff.ode.step_budget import CHECK_EVERY, GROWTH, MARGIN, WINDOW, BudgetWatch

OMEGA = 1e6  # rad/s: the body's pitch rate of the fast-spin runs


@pytest.fixture(scope="module")
def spin():
    """planar_trot_soft with its body pitching at OMEGA: free flight whose steps resolve
    the spin, h ~ 1e-6 s from the first step (test_step_collapse)."""
    return cd.load_scene("planar_trot_soft").with_state(None, {"body_pitch": OMEGA})


def test_a_run_that_cannot_finish_stops_after_one_window(spin):
    """2 s of the spin with max_steps = 5,000: the steps resolve a rotation at OMEGA, so
    they are of order 1/OMEGA = 1e-6 s (an accuracy limit at rtol = 1e-8: a few 1e-7 to a
    few 1e-6 s), and 2 s need ~1e6 of them, far beyond 4,000 left after the first window:
    the run stops at WINDOW steps instead of 5,000, with the run so far.

    The projection is the remaining time over the reference step (its definition, checked
    to the printed digits), and it exceeds MARGIN times the steps left (the rule)."""
    max_steps = 5000
    with pytest.raises(cd.StepBudgetError) as info:
        cd.simulate(spin, 2.0, max_steps=max_steps)
    err = info.value
    assert isinstance(err, cd.TooManyStepsError)
    traj = err.trajectory
    assert traj.termination is cd.Termination.MAX_STEPS and traj.stats.steps == WINDOW
    assert err.t == traj.t and err.mode == ()
    assert 1e-7 < err.step < 1e-5  # steps of order 1 / OMEGA
    assert err.steps_needed == pytest.approx((2.0 - err.t) / err.step, rel=1e-12)
    assert err.steps_needed > MARGIN * (max_steps - WINDOW)
    message = str(err)
    assert f"t = {err.t:.6g} s" in message and "free flight" in message and "max_steps" in message
    assert f"{err.step:.3g} s" in message and "raise max_steps" in message


def test_a_run_within_its_budget_is_not_stopped(spin):
    """The same spin to a final time it reaches in n steps (n past 2 WINDOW + 3 CHECK_EVERY,
    so that projections are made with more than WINDOW steps left), run again with
    max_steps = n exactly: the tightest budget it finishes within. Every projection
    there needs at most the n - steps it has left at the reference step (longer than 9
    in 10 of its steps), far below MARGIN times them, so it finishes with the same
    steps; with one step fewer it ends at its budget (no projection is made with a
    window's steps or fewer left)."""
    t_final = 2.7e-3  # ~2,800 steps of ~1e-6 s
    free = cd.simulate(spin, t_final)
    n = free.stats.steps
    assert n > 2 * WINDOW + 3 * CHECK_EVERY  # projections at 1,000 steps and more with > WINDOW left
    tight = cd.simulate(spin, t_final, max_steps=n)
    assert tight.termination is cd.Termination.T_FINAL and tight.stats.steps == n
    np.testing.assert_array_equal(tight.q, free.q)
    # one step fewer: the plain budget error, at the budget (the projection never fired)
    with pytest.raises(cd.TooManyStepsError) as info:
        cd.simulate(spin, t_final, max_steps=n - 1)
    assert not isinstance(info.value, cd.StepBudgetError)
    assert info.value.trajectory.stats.steps == n - 1


def test_the_projection_waits_for_a_steady_window():
    """The watch itself on made-up step sequences (no integration): it projects only after
    WINDOW steps of one regime, never while the steps grow (a run settling to rest: its
    future steps are longer than its past ones), and an event starts the window again.
    The budget: 10,000 steps; 1e6 s to go at 1 s steps needs 1e6 steps."""
    steady = BudgetWatch(10_000)
    fired = [steady.after_step(1.0, False, 1e6, k + 1) for k in range(WINDOW)]
    assert all(f is None for f in fired[:-1])
    needed, reference = fired[-1]
    assert reference == 1.0 and needed == 1e6
    # growing by more than GROWTH between the half-windows: no projection
    growing = BudgetWatch(10_000)
    factor = (2.0 * GROWTH) ** (1.0 / (WINDOW // 2))  # the half-windows' medians differ by 2 GROWTH
    assert all(growing.after_step(factor**k, False, 1e6, k + 1) is None for k in range(3 * WINDOW))
    # an event clears the window; clipped steps are not counted
    restarted = BudgetWatch(10_000)
    for k in range(WINDOW - 1):
        restarted.after_step(1.0, False, 1e6, k + 1)
    restarted.new_regime()
    assert restarted.after_step(1.0, False, 1e6, WINDOW) is None
    assert all(restarted.after_step(1.0, True, 1e6, WINDOW) is None for _ in range(2 * WINDOW))
    # within MARGIN times the budget left, or a window's steps or fewer left: no projection
    within = BudgetWatch(10_000)
    assert all(within.after_step(1.0, False, MARGIN * (10_000 - WINDOW), k + 1) is None for k in range(WINDOW))
    ending = BudgetWatch(2 * WINDOW)
    assert all(ending.after_step(1.0, False, 1e6, k + 1) is None for k in range(2 * WINDOW))
