"""The clock of the trot controller (`contactdiff.control.trot_controller`, whose
notes define it): the gait phase and each leg's, the scheduled stances, touchdowns
and lift-offs, and each leg's scheduled load and PD gain scale, all functions of
time only."""

from __future__ import annotations

from typing import Protocol

from .foot_paths import smooth_step
from .legs import PAIR_A, Leg


class TrotTiming(Protocol):
    """The numbers of a `TrotController` that its clock reads (fractions of a period
    unless said)."""

    @property
    def period(self) -> float:
        """Gait period (s)."""
        ...

    @property
    def t_start(self) -> float:
        """Time (s) of the gait phase 0."""
        ...

    @property
    def duty(self) -> float:
        """Stance share of a leg's period."""
        ...

    @property
    def lag(self) -> float:
        """How far a pair's hind foot follows its front foot."""
        ...

    @property
    def transfer(self) -> float:
        """Length of each load and gain transition."""
        ...

    @property
    def liftoff_pull(self) -> float:
        """The pull at lift-off, a share of the leg's load."""
        ...

    @property
    def touchdown_load(self) -> float:
        """The load pressing a landing foot down, a share of the leg's load."""
        ...

    @property
    def release_gain(self) -> float:
        """The PD gains' scale at the scheduled lift-off."""
        ...

    @property
    def feedforward(self) -> bool:
        """Whether the scheduled load is applied (its pieces are breakpoints then)."""
        ...


def unload_window(spec: TrotTiming) -> tuple[float, float]:
    """Leg phases between which the load falls from 1 to ``-liftoff_pull``: length
    ``2 transfer``, crossing 0 at ``duty`` (where ``S(u) = 1 / (1 + liftoff_pull)``)."""
    target = 1.0 / (1.0 + spec.liftoff_pull)
    lo, hi = 0.0, 1.0
    for _ in range(60):  # bisection: S is increasing on [0, 1]
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if smooth_step(mid) < target else (lo, mid)
    start = spec.duty - 2.0 * spec.transfer * 0.5 * (lo + hi)
    return start, start + 2.0 * spec.transfer


class TrotSchedule:
    """The clock of a trot controller bound to a quadruped's ``legs`` (`Leg` list, the
    order of its feet): the phases, the scheduled events, loads and gain scales.

    Attributes:
        spec: the controller's numbers (`TrotTiming`).
        offsets: each leg's phase offset ``o`` (``psi = (phi + o) mod 1``, module notes of
            `contactdiff.control.trot_controller`).
    """

    def __init__(self, spec: TrotTiming, legs: list[Leg]):
        self.spec = spec
        c = 0.5 * (spec.duty + spec.lag)
        self.offsets = [c - (0.0 if leg.pair == PAIR_A else 0.5) - (0.0 if leg.front else spec.lag) for leg in legs]
        self._unload = unload_window(spec)  # fixed by the spec: a 60-step bisection, once

    def phase(self, t: float) -> float:
        """Gait phase ``phi`` in [0, 1) at time ``t`` (s)."""
        return ((t - self.spec.t_start) / self.spec.period) % 1.0

    def leg_phase(self, leg: int, phi: float) -> float:
        """Phase ``psi`` of leg number ``leg`` (in ``legs``) at gait phase ``phi``; 0 = its touchdown."""
        return (phi + self.offsets[leg]) % 1.0

    def scheduled_stance(self, t: float) -> list[bool]:
        """Which feet the schedule has on the ground at time ``t`` (``legs`` order)."""
        phi = self.phase(t)
        return [self.leg_phase(k, phi) < self.spec.duty for k in range(4)]

    def scheduled_touchdown(self, leg: int) -> float:
        """Gait phase of the scheduled touchdown of leg number ``leg``."""
        return (-self.offsets[leg]) % 1.0

    def scheduled_liftoff(self, leg: int) -> float:
        """Gait phase of the scheduled lift-off of leg number ``leg``."""
        return (self.spec.duty - self.offsets[leg]) % 1.0

    def load(self, psi: float) -> float:
        """Scheduled vertical load ``w`` of a leg at leg phase ``psi`` (1: its share of the
        weight before scaling; negative: a pull), with ``r = transfer``, ``d = duty`` and smooth
        steps between the levels (C² in time):

        * ``touchdown_load`` at ``psi = 0`` (rising from 0 over the last ``r`` of the swing),
          to 1 by ``psi = r``;
        * 1 until the unloading: from 1 down to ``-liftoff_pull`` over a window of length
          ``2 r``, placed so that ``w`` crosses 0 at ``psi = d`` (the scheduled lift-off);
        * from ``-liftoff_pull`` back to 0 over the next ``r``; 0 for the rest of the swing.
        """
        s = self.spec
        r, pull, tl = s.transfer, s.liftoff_pull, s.touchdown_load
        start, end = self._unload
        if psi < r:
            return tl + (1.0 - tl) * float(smooth_step(psi / r))
        if psi < start:
            return 1.0
        if psi < end:
            return 1.0 - (1.0 + pull) * float(smooth_step((psi - start) / (end - start)))
        if psi < end + r:
            return -pull * (1.0 - float(smooth_step((psi - end) / r)))
        if psi < 1.0 - r:
            return 0.0
        return tl * float(smooth_step((psi - (1.0 - r)) / r))

    def gain(self, psi: float) -> float:
        """Scale ``g`` of the PD gains of a leg at leg phase ``psi``: ``release_gain`` at the
        scheduled lift-off (``psi = duty``), back to 1 over ``transfer`` on either side
        (smooth steps)."""
        s = self.spec
        distance = abs(psi - s.duty)
        distance = min(distance, 1.0 - distance)
        if distance >= s.transfer:
            return 1.0
        return s.release_gain + (1.0 - s.release_gain) * float(smooth_step(distance / s.transfer))

    def leg_breakpoint_phases(self) -> list[float]:
        """Gait phases in [0, 1), per leg, where its load or its gain scale changes piece
        (the ends of their smooth steps, where the third derivative jumps), unsorted."""
        s = self.spec
        start, end = self._unload
        r = s.transfer
        leg_breaks = [0.0, r, start, end, end + r, 1.0 - r] if s.feedforward else []
        if s.release_gain != 1.0:
            leg_breaks += [s.duty - s.transfer, s.duty, s.duty + s.transfer]
        return [(psi - offset) % 1.0 for offset in self.offsets for psi in leg_breaks]


__all__ = ["TrotSchedule", "TrotTiming", "unload_window"]
