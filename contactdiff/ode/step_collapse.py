"""Step collapse: a run whose steps shrink by orders of magnitude with no event in sight.

Where the vector field of a mode becomes singular (a mechanism reaching a singular
pose with its contacts held: solo8 folding under gravity until its knees fold flat,
where the contact forces holding its feet grow without bound), the error control
shrinks the steps towards zero and the run creeps: 200,000 steps of 1e-11 s took two
minutes to end in `TooManyStepsError`. `CollapseWatch` says so within a few hundred
steps instead (`StepCollapseError`).

The criterion:

* the reference is the run's typical step: the largest value so far of the median of
  its accepted steps (to a decade: a histogram of log10 h), counting only steps longer
  than `TYPICAL_BAND` times the reference. A median is not moved by a few exceptional
  steps (an exact free flight's steps of hundreds of seconds, the short first steps of
  a mode), and neither the band nor the maximum lets a gradual approach to a singular
  pose, whose steps shrink over hundreds of steps and many decades, drag the
  reference down with it;
* a step is *collapsed* when it is shorter than `COLLAPSE_RATIO` times that median
  (six orders of magnitude);
* the run has collapsed after `COLLAPSE_STEPS` collapsed steps in a row with no event
  between them (an event restarts the count: events change the field, and close to a
  singular pose they may come in the middle of the collapse, as the contact forces
  there pass through zero and back; solo8's slips).

There is no knife edge in the outcome: a run near the thresholds ends in this error
or, later, in `TooManyStepsError`, both of which stop it; no accepted run changes. A
run that needs short steps from its start (a body spinning at 1e6 rad/s: steps of
1e-6 s throughout) has not collapsed: its steps are its own, and its budget is
``max_steps`` (`contactdiff.ode.step_budget` stops it early when its steps
cannot reach the final time within it). Steps cut short by an effort's breakpoint or by ``t_final`` are short by
choice, not by the error control, and count as neither collapsed nor typical.
"""

from __future__ import annotations

import math

COLLAPSE_RATIO = 1e-6
"""A step shorter than this share of the run's typical step is collapsed. Stiff or fast
phases within a mode (a stiff spring taking up a load, a fast swing) shorten steps by two
to four orders of magnitude; six is beyond them and still far above the float
resolution of time (1e-16 |t|), where the stepper itself stops (step size underflow)."""

TYPICAL_BAND = 1e-3
"""Steps shorter than this share of the typical step are not counted in it (nor collapsed
unless below `COLLAPSE_RATIO`): a scene's phases differ by up to a few decades (flight
and stance, a stiff leg loaded), a singular approach by many more."""

COLLAPSE_STEPS = 100
"""Collapsed steps in a row (with no event) that make a collapse: a sharp but passing
feature of the field (a near-singular pose passed at speed) takes tens of short steps,
a singular one takes them without end."""


class CollapseWatch:
    """Watches the accepted steps of one run for a collapse (module doc).

    Attributes:
        typical: the reference step (s, a decade; 0 before any step): the largest median
            of the accepted steps so far.
        collapsed: collapsed steps in a row since the last event.
    """

    def __init__(self):
        self._decades: dict[int, int] = {}  # floor(log10 h) -> accepted steps
        self._n = 0
        self.typical = 0.0
        self.collapsed = 0

    def new_mode(self) -> None:
        """An event: the count of collapsed steps restarts."""
        self.collapsed = 0

    def after_step(self, h: float, clipped: bool) -> bool:
        """Record an accepted step of ``h`` (s), ``clipped`` if a breakpoint or the final
        time cut it short; whether the run has collapsed."""
        if clipped or not h > 0.0:
            return False
        if h < COLLAPSE_RATIO * self.typical:
            self.collapsed += 1
            return self.collapsed >= COLLAPSE_STEPS
        self.collapsed = 0
        if h < TYPICAL_BAND * self.typical:
            return False
        decade = math.floor(math.log10(h))
        self._decades[decade] = self._decades.get(decade, 0) + 1
        self._n += 1
        seen = 0
        for d in sorted(self._decades):  # the median's decade (its lower end)
            seen += self._decades[d]
            if 2 * seen >= self._n:
                self.typical = max(self.typical, 10.0**d)
                break
        return False
