"""Step budget: a run that cannot reach its final time within ``max_steps`` says so early.

A run whose steps are short from its start and stay short (a body spinning at 1e6
rad/s: steps of ~1e-6 s throughout, 2 s of it needing ~2e6 steps) has not collapsed
(`contactdiff.ode.step_collapse`): its steps are the mode's own. Without a
projection it ran its 200,000 steps, minutes of work, to end in `TooManyStepsError`
at a tenth of its horizon. `BudgetWatch` projects the steps still needed from the
recent ones and stops such a run after `WINDOW` steps (`StepBudgetError`).

The criterion, after `WINDOW` accepted steps in one regime (no event, no method
switch, no step cut short by a breakpoint or the final time counted):

* the run is *steady*: the median step of the newer half of the window is at most
  `GROWTH` times that of the older half (a run approaching rest, or leaving a stiff
  transient, has steps that grow, and its future steps are not its past ones);
* even at the window's `PERCENTILE`-th percentile step, longer than most of its
  steps, the remaining time needs more than `MARGIN` times the steps left in the
  budget (and more than `WINDOW` steps are left: closer to the end, the budget itself
  stops the run soon).

A run stopped by it would have needed its future steps to be on average `MARGIN`
times longer than nine in ten of its last `WINDOW` steady ones: far from any run
that finishes (a false stop is worse than a slow run). No run that finishes changes
(the watch only ever raises), and its message says how many steps the run would
need, for a user whose run does enter a much faster phase later.
"""

from __future__ import annotations

from collections import deque

import numpy as np

WINDOW = 1000
"""Accepted steps of one regime before any projection: long enough for a steady regime
to show (and cheap: ~1 s of the fast spin's run), short against the default budget
(200,000 steps)."""

CHECK_EVERY = 100
"""Steps between two projections (a projection sorts the window)."""

GROWTH = 2.0
"""Largest ratio of the newer half-window's median step to the older half's for a
steady regime: the step controller grows steps by up to 10 per step, so a run settling
or leaving a transient moves its median by far more than this over 500 steps."""

PERCENTILE = 90.0
"""The reference step of the projection: a high percentile of the window, so that the
projection is optimistic (longer steps than most) but not moved by a few exceptional
ones."""

MARGIN = 4.0
"""Steps needed, at the reference step, over the steps left, beyond which the run stops:
a run would have to take future steps ``MARGIN`` times longer than nine in ten of its
steady recent ones to finish."""


class BudgetWatch:
    """Projects the steps a run still needs from its recent accepted steps (module doc).

    Args:
        max_steps: the run's step budget.
    """

    def __init__(self, max_steps: int):
        self.max_steps = max_steps
        self._window: deque[float] = deque(maxlen=WINDOW)
        self._since_check = 0

    def new_regime(self) -> None:
        """An event or a method switch: the steps before it say nothing of the steps after."""
        self._window.clear()
        self._since_check = 0

    def after_step(self, h: float, clipped: bool, remaining: float, steps: int) -> tuple[float, float] | None:
        """Record an accepted step of ``h`` (s), ``clipped`` if a breakpoint or the final time
        cut it short, after which ``remaining`` (s) is left to the final time and ``steps``
        steps are taken. Returns ``(steps needed, reference step (s))`` when the run cannot
        finish within the budget (module doc), else None."""
        if clipped or not h > 0.0:
            return None
        self._window.append(h)
        self._since_check += 1
        left = self.max_steps - steps
        if len(self._window) < WINDOW or self._since_check < CHECK_EVERY or left <= WINDOW:
            return None  # (with a window's steps or fewer left, the budget itself ends the run soon)
        self._since_check = 0
        window = np.fromiter(self._window, float, WINDOW)
        half = WINDOW // 2
        if np.median(window[half:]) > GROWTH * np.median(window[:half]):
            return None
        reference = float(np.percentile(window, PERCENTILE))
        needed = remaining / reference
        if needed > MARGIN * left:
            return needed, reference
        return None


def budget_message(
    max_steps: int, t_final: float, t: float, mode: tuple[str, ...], steps: int, needed: float, reference: float
) -> str:
    """The message of `StepBudgetError`: when (``t``, s), where (``mode``, the active contacts'
    names), the reference step (s) and the steps ``needed`` against those left."""
    return (
        f"max_steps = {max_steps} cannot reach t_final = {t_final:g} s: at t = {t:.6g} s in mode "
        f"({', '.join(mode) or 'free flight'}), after {steps} steps, the last {WINDOW} steady ones (no "
        f"event) at most ~{reference:.3g} s (9 in 10), the remaining {t_final - t:.6g} s need "
        f"~{needed:.3g} steps, more than {MARGIN:g} times the {max_steps - steps} left; raise max_steps "
        f"to about {steps + needed:.2g} (--max-steps), or look for a runaway state (a body spinning fast, "
        "a stiff spring)"
    )
