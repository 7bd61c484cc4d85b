"""Guards of a mode over one accepted step: which crossed, when, and near misses.

The guards of mode ``J`` are the gap of every open contact (downward through 0)
and the normal force of every closed one (downward through 0); with Coulomb
friction also the cone margin ``μ λ_N - ||λ_T||`` of every sticking contact
(stick → slip) and the slip velocity along its direction of every slipping one
(slip → stick, `contactdiff.dynamics.slip`), minus the compatible load of a
contact the mode holds at zero gap, which has no gap guard, and the distance outside the
cone of the sticking force of a slip the mode holds at zero, which has no stop to fire
(both `contactdiff.integration.held`).
After each
accepted step every guard is checked over the step: a gap that ends below 0, or
that dips below it and back within the step (found from the cubic Hermite
interpolant of the end-point gaps and gap rates, and confirmed on the step's
dense output), and a force-level or slip guard that ends below 0, or that dips
below it and back within the step: where its values at both ends lie within
`NEAR_FRACTION` of its scale, its rates along the flow are formed at both ends
(`GuardFinder._rates`) and its Hermite interpolant is searched as a gap's. Each
crossing is located on the dense output with Brent's method to full precision in
time. A gap that comes down to within the grazing band with zero normal speed and
rises again is a near-grazing miss: the integration error cannot tell whether it
touched.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

import numpy as np
import pinocchio as pin
from scipy.optimize import minimize_scalar

from ..ode.crossings import hermite_minimum, locate_crossing
from .options import SimulateOptions

DIP_FRACTION = 0.5
"""A step is searched for a dip when its Hermite minimum is below this share of the end gaps."""

PULL_TOL = 1e-9
"""A normal force below -PULL_TOL times the largest of its mode's at a step's start
(beyond the solve's round-off, ~1e-15 of the forces) pulls already: its guard fires
at the step's start whatever its value at the step's end. A mode chosen at an event
or at t0 may start so (the compatible load of a face's corner, `dynamics/redundant`,
is negative where another split of the same forces is not), and the force may come
back above zero within the first step (a step grown long on a motion of constant
acceleration): judged at the step's end only, the corner would have pulled unseen."""


NEAR_FRACTION = 0.1
"""A force, cone, stop, bearing or grip guard whose values at both ends of a step are positive
is modelled over the step only where the smaller lies within this share of its scale (a normal
force or a held load: the scene's weight, or the mode's largest normal force at the step's ends
if larger; a cone margin: its cone's size ``μ λ_N``; a slip speed: the larger of its two ends).
Its rates there cost a mode solve per end, paid only near a threshold: a guard that ends a step
far above it would have to fall by most of its scale and come back within the step (the state's
own error control makes that a step over a fast change of the efforts, as a push's pulse on a
body at rest: there ``max_step`` must resolve the efforts' time scale)."""

RATE_STEP = 1e-6
"""The guards' rates along the flow, ``Dh F + h_t``, are the forward difference of their values
over this share of the step (`GuardFinder._rates`): the difference's error moves the Hermite
model by ~RATE_STEP of the guard's change over the step, its round-off by ~eps / RATE_STEP of
its scale, both far below a dip the model must see."""


class GuardKind(Enum):
    """What a guard watches."""

    GAP = "gap"
    """the gap of an open contact"""
    FORCE = "force"
    """the normal force of a closed contact"""
    CONE = "cone"
    """the friction cone margin ``μ λ_N - ||λ_T||`` of a sticking contact with finite ``μ``"""
    STOP = "stop"
    """the slip velocity of a slipping contact along its slip direction"""
    BEAR = "bear"
    """minus the compatible load of a contact the mode holds at zero gap, in the set of the
    mode and it (`contactdiff.integration.held`): it fires as that load turns to pushing"""
    GRIP = "grip"
    """minus the cone margin ``||λ_T|| - μ λ_N`` of the sticking force of a slipping contact
    whose slip the mode holds at zero, in the mode with it sticking
    (`contactdiff.integration.held`): it fires as that force comes back inside the cone"""


@dataclass(frozen=True)
class Guard:
    """A guard: its kind and its contact (scene index for a gap, contact key otherwise)."""

    kind: GuardKind
    contact: int


@dataclass(frozen=True)
class NearMiss:
    """A gap that came down to ``gap`` (m, within ``band``) at ``t`` (s) and rose again."""

    t: float
    contact: int
    gap: float
    band: float


def mode_guards(dyn, mode) -> list[Guard]:
    """The force-level and slip guards of ``mode``: a normal force per contact, a cone
    margin per sticking contact with Coulomb friction, a slip velocity per slipping one."""
    guards = [Guard(GuardKind.FORCE, key) for key in mode]
    for key in mode:
        contact = dyn.contact(key)
        if contact.slips:
            guards.append(Guard(GuardKind.STOP, key))
        elif contact.holds_cone:
            guards.append(Guard(GuardKind.CONE, key))
    return guards


class _Below(Exception):
    """A guard search found a point below its threshold: ``args = (s, value)``."""


class GuardFinder:
    """Finds the guards of a mode that one accepted step crossed.

    Args:
        scene: the scene (its contacts and kinematics cache).
        dyn: the scene's `ModeDynamics` (contact keys of a mode).
        options: the run's `SimulateOptions` (tolerances, grazing band).
        gap_tol: gap (m) below which a contact counts as closed.
    """

    def __init__(self, scene, dyn, options: SimulateOptions, gap_tol: float):
        self.scene, self.dyn, self.options, self.gap_tol = scene, dyn, options, gap_tol
        self.kin = scene.kinematics
        self.contacts = scene.contacts
        self._rate_points: dict = {}
        """The guards' rates (`_rates`) at the last step's ends, by field and point."""
        # N: the scale of a normal force (NEAR_FRACTION); 0 without gravity
        self.weight = pin.computeTotalMass(scene.model) * float(np.linalg.norm(scene.model.gravity.linear))
        self.from_rest: set[int] = set()
        """Keys of the slips the events started from rest whose speed has stayed within the
        slip-speed floor since (`restart_from_rest` at an event, `keep_resting` after each step)."""

    def crossings(self, stepper, dense, field, mode, start, end) -> tuple[list[tuple[float, Guard]], list[NearMiss]]:
        """The guards the last step of ``stepper`` crossed, and its near-grazing misses.

        Args:
            stepper: the stepper after an accepted step ``[t_old, t]``.
            dense: that step's dense output.
            field: the mode's vector field (its guard values on the dense output).
            mode: the contact keys of the mode.
            start: ``(gaps, gap rates, guard values)`` at the step start: gaps (m)
                and gap rates (m/s) of every scene contact, the values of the
                field's own guards (``field.guard_values``).
            end: the same at the step end.

        Returns:
            ``(crossings, misses)``: each crossing as ``(t, Guard)`` located to full
            precision in time; the misses in the step (gaps that came down within
            the grazing band with zero normal speed and rose again).
        """
        t_a, t_b = stepper.t_old, stepper.t
        gaps0, rates0, values0 = start
        gaps1, rates1, values1 = end
        found = []
        misses = []
        # a contact the mode holds at zero gap has no gap guard: its gap is the others'
        # drift (its compatible load is watched instead, `contactdiff.integration.held`)
        skipped = set(self.dyn.contacts_of(mode)) | set(getattr(field, "held", ()))
        for i, contact in enumerate(self.contacts):
            if i in skipped:
                continue

            def gap(t, i=i):
                qt, _ = dense(t)
                self.kin.update(qt, np.zeros(self.scene.nv))
                return self.contacts[i].gap(self.kin)

            t_lo, g_lo = t_a, gaps0[i]
            if gaps1[i] < 0.0:
                t_hi, g_hi = t_b, gaps1[i]
            else:
                s, low = hermite_minimum(gaps0[i], rates0[i], gaps1[i], rates1[i], t_b - t_a)
                # an interior minimum that comes close to the ground relative to the end
                # gaps may dip below it: the cubic from end-point data alone can miss a
                # shallow dip, so search the step's own dense output for its minimum
                dip = 0.0 < s < 1.0 and low < DIP_FRACTION * min(gaps0[i], gaps1[i])
                # a gap that turns upward within the step, perhaps just above the ground
                turning = gaps0[i] > self.gap_tol and rates0[i] < 0.0 <= rates1[i]
                band = self.grazing_band(stepper.q) if turning else 0.0
                if not (dip or (turning and min(low, gaps1[i]) <= 2.0 * band)):
                    continue
                t_hi, g_hi = self._lowest(gap, t_a, t_b, stop_below=0.0)
                if g_hi >= 0.0:
                    if turning and g_hi <= band:
                        misses.append(NearMiss(t_hi, i, g_hi, band))
                    continue
            if g_lo <= self.gap_tol:
                # the contact has just opened (bounce or lift-off): its gap starts at 0
                # going up; a new touchdown needs the gap to rise above 0 and come back
                t_peak, g_peak = self._peak(gap, t_a, t_hi, rates0[i] > self.options.grazing_speed)
                if t_peak is None:
                    # it never opened (released at an impact with no separating speed,
                    # or rising by less than the search resolves) and is sinking: it
                    # touches down where it passes below the integration error band
                    # (a shallower dip of the dense output may be its error alone)
                    # (the band at the step's start, where the contact is: the end of a long
                    # step may lie far below the ground, and rtol there would widen it)
                    shift = max(self.gap_tol, self.grazing_band(stepper.q_old)) - min(g_lo, 0.0)
                    if g_hi + shift < 0.0:
                        found.append(
                            (
                                locate_crossing(lambda t: gap(t) + shift, t_a, t_hi, g_lo + shift, g_hi + shift),
                                Guard(GuardKind.GAP, i),
                            )
                        )
                    continue
                t_lo, g_lo = t_peak, g_peak
            found.append((locate_crossing(gap, t_lo, t_hi, g_lo, g_hi), Guard(GuardKind.GAP, i)))
        floor = self.dyn.slip_speed_floor
        forces0 = [abs(values0[k]) for k, g in enumerate(field.guards) if g.kind is GuardKind.FORCE]
        pull = -PULL_TOL * max(forces0, default=0.0)
        scales = None  # each guard's scale (NEAR_FRACTION), formed where a guard ends a step near 0
        for k, guard in enumerate(field.guards):
            pulling = guard.kind is GuardKind.FORCE and values0[k] < pull
            # a slip that starts at (or is stopped within noise of) zero speed fires only once
            # its speed along its direction passes -floor: below floor its direction is noise.
            # One an event started from rest starts at round-off of either sign (`from_rest`)
            shift = 0.0
            if guard.kind is GuardKind.STOP and (
                values0[k] <= 0.0 or (guard.contact in self.from_rest and values0[k] <= floor)
            ):
                shift = floor
            if values1[k] + shift >= 0.0 and not pulling:
                low = min(values0[k], values1[k]) + shift
                if not 0.0 < low < np.inf:
                    continue
                scales = self._scales(field, values0, values1) if scales is None else scales
                if low <= NEAR_FRACTION * (scales[k] + shift):
                    t_dip = self._dip(stepper, dense, field, k, shift, values0, values1)
                    if t_dip is not None:
                        found.append((t_dip, guard))
                continue

            def value(t, k=k, shift=shift):
                qt, vt = dense(t)
                return field.guard_values(t, qt, vt)[k] + shift

            # the start's value afresh: a slip direction set since it was stored (at an event's
            # mode choice) moves the forces of the contacts it pushes on
            start = value(t_a)
            if start <= 0.0:  # already past it at the step start (a slip stopped by a reset)
                found.append((t_a, guard))
                continue
            if values1[k] + shift >= 0.0:  # a pull at the stored start that the fresh value does not see
                continue
            found.append((locate_crossing(value, t_a, t_b, start, values1[k] + shift), guard))
        return found, misses

    def _scales(self, field, values0, values1) -> np.ndarray:
        """Each guard's scale (`NEAR_FRACTION`) over a step whose ends have the guard values
        ``values0``, ``values1``: a normal force's and a held load's, the scene's weight or the
        mode's largest normal force, whichever is larger (a push that unloads every contact
        shrinks the latter with the guard itself); a cone margin's (and a held slip's), its
        cone's size ``μ λ_N``; a slip speed's, the larger of its ends (the caller adds the floor
        to one watched past ``-floor``)."""
        normal = {}
        for k, guard in enumerate(field.guards):
            if guard.kind is GuardKind.FORCE:
                normal[guard.contact] = max(abs(values0[k]), abs(values1[k]))
        largest = max([self.weight, *normal.values()])
        scales = np.empty(len(field.guards))
        for k, guard in enumerate(field.guards):
            if guard.kind in (GuardKind.CONE, GuardKind.GRIP):
                scales[k] = field.dyn.contact(guard.contact).spec.mu * normal[guard.contact]
            elif guard.kind is GuardKind.STOP:
                scales[k] = max(values0[k], values1[k])
            else:
                scales[k] = largest
        return scales

    def _dip(self, stepper, dense, field, k: int, shift: float, values0, values1) -> float | None:
        """The time (s) where guard ``k`` of ``field`` (plus ``shift``) first passes below 0
        within the last step of ``stepper``, positive at both its ends (the guards' values there
        ``values0``, ``values1``), or None: its cubic Hermite model from the end values and rates
        (`_rates`), searched on the step's dense output where the model comes within
        `DIP_FRACTION` of the end values, as a gap's."""
        t_a, t_b = stepper.t_old, stepper.t
        h0, h1 = values0[k] + shift, values1[k] + shift
        r0 = self._rates(field, t_a, stepper.q_old, stepper.v_old, t_b - t_a)[k]
        r1 = self._rates(field, t_b, stepper.q, stepper.v, t_b - t_a, values1, stepper.f)[k]
        s, low = hermite_minimum(h0, r0, h1, r1, t_b - t_a)
        if not (0.0 < s < 1.0 and low < DIP_FRACTION * min(h0, h1)):
            return None

        def value(t):
            qt, vt = dense(t)
            return field.guard_values(t, qt, vt)[k] + shift

        t_low, g_low = self._lowest(value, t_a, t_b, stop_below=0.0)
        if g_low >= 0.0:
            return None
        g_a = value(t_a)  # the dense output's start, as the crossings past a step's end
        return t_a if g_a <= 0.0 else locate_crossing(value, t_a, t_low, g_a, g_low)

    def _rates(self, field, t: float, q, v, h: float, values=None, f=None) -> np.ndarray:
        """The rates ``Dh F + h_t`` (guard unit per s) of every guard of ``field`` along its flow
        at ``(t, q, v)``: the forward difference of `ModeField.guard_values` over
        ``δ = RATE_STEP h`` (``h`` the step, s) from ``x`` to ``(t + δ, q ⊕ δ v, v + δ ddq)``.
        ``values``: the guards there, ``f``: the field ``(v, ddq)`` there, if known (a step's
        end); else solved (a step's start whose rates its previous step's end did not form).
        Kept for the next step, whose start this step's end is."""
        key = (id(field), t, q.tobytes(), v.tobytes())
        known = self._rate_points.get(key)
        if known is not None:
            return known
        if values is None:
            values = field.guard_values(t, q, v)
        if f is None:
            f = np.concatenate([v, field.dyn.solve(q, v, t, field.mode).ddq])
        nv = len(v)
        delta = max(RATE_STEP * h, 1e3 * np.finfo(float).eps * max(1.0, abs(t)))
        moved = field.guard_values(t + delta, self.scene.robot.integrate(q, delta * f[:nv]), v + delta * f[nv:])
        rates = (moved - values) / delta
        if len(self._rate_points) > 2:
            self._rate_points.clear()
        self._rate_points[key] = rates
        return rates

    def restart_from_rest(self, mode_before, mode_after, fired) -> None:
        """After an event from ``mode_before`` to ``mode_after`` (contact keys) where the
        guards ``fired``: the slips of ``mode_after`` that start from rest, those whose
        contact did not slip before (it stuck: its slip held at zero) or whose stop fired
        (its slip held at zero, then slipping on). Their slip velocity is zero by
        construction, so its sign at the first step's start is round-off (+1e-17 m/s seen):
        their stop fires only past ``-floor`` (`crossings`). With the round-off positive
        the stop was located at zero instead, where a step's dense output reversing from
        the start put it at the start itself: after every restart the same stop, and a
        run that repeated one event without advancing. A slip started from rest at an earlier
        event that this one leaves as it was (the same key on both sides, its stop not fired)
        stays from rest: its slip may still be round-off (a corner whose slip two sticking
        corners hold at zero), and its stop at round-off's sign changes would reset its
        reference at times that depend on the last bits of the state."""
        stopped = {g.contact for g in fired if g.kind is GuardKind.STOP}
        kept = {key for key in self.from_rest if key in mode_before and key not in stopped}
        self.from_rest = {
            key
            for key in mode_after
            if self.dyn.contact(key).slips and (key not in mode_before or key in stopped or key in kept)
        }

    def keep_resting(self, field, values) -> None:
        """After an accepted step whose end has the guard values ``values`` (``field.guard_values``):
        the slips from rest whose speed along their direction is still within the slip-speed
        floor stay from rest for the next step. A slip the mode holds at zero (a corner of a
        face whose other sticking corners fix the body's motion) stays at round-off for the
        whole mode, and its stop must not fire on round-off's sign changes, which depend on
        the last bits of the state (and would reset its reference there)."""
        floor = self.dyn.slip_speed_floor
        self.from_rest = {
            guard.contact
            for guard, value in zip(field.guards, values)
            if guard.kind is GuardKind.STOP and guard.contact in self.from_rest and value <= floor
        }

    def grazing_band(self, q) -> float:
        """Gap (m) within which a contact that turns back up may have touched, given
        the integration error: ``grazing_gap``, by default 10 (atol + rtol |q|_inf)."""
        if self.options.grazing_gap is not None:
            return self.options.grazing_gap
        return 10.0 * (self.options.atol + self.options.rtol * float(np.max(np.abs(q))))

    @staticmethod
    def _lowest(gap, t_a, t_b, stop_below: float = -np.inf):
        """Lowest point of ``gap`` on the dense output of one step (bounded Brent),
        searched in time relative to the step start: the bounded method's tolerance
        includes sqrt(eps) |x|, which in absolute time (t ~ 300) exceeds a short flight.

        The search stops at the first point below ``stop_below``: a caller that
        only needs a point past a sign change (a bracket) gets it without resolving
        the minimum. The time tolerance, 1e-9 of the step (or a few ulps of t),
        puts the minimum's value within ~1e-18 of the step's gap variation.
        """

        def f(s):
            value = gap(t_a + s)
            if value < stop_below:
                raise _Below(s, value)
            return value

        xatol = max(4 * np.finfo(float).eps * max(1.0, abs(t_b)), 1e-9 * (t_b - t_a))
        try:
            low = minimize_scalar(f, bounds=(0.0, t_b - t_a), method="bounded", options={"xatol": xatol})
        except _Below as below:
            s, value = below.args
            return t_a + float(s), float(value)
        return t_a + float(low.x), float(low.fun)

    def _peak(self, gap, t_a, t_b, leaving: bool = False):
        """Highest point of a gap that starts closed at ``t_a`` and is negative at ``t_b``;
        ``leaving``: its rate at ``t_a`` is above ``grazing_speed`` (a bounce).

        Returns ``(t, gap)`` there, or ``(None, None)`` if the gap never opens (rises
        above 0). A peak in (0, gap_tol] is still a real bounce that comes back: skipping
        it would leave the contact out of the mode, and it would fall through the
        ground (e.g. a ball bounce at 1.2e-6 m/s under g = 1 peaks at 7e-13 m); the
        Zeno rule ends such sequences instead.
        """
        t_peak, low = self._lowest(lambda t: -gap(t), t_a, t_b, stop_below=0.0)
        if -low > 0.0 or not leaving:
            return (t_peak, -low) if -low > 0.0 else (None, None)
        # The search's resolution is a share of the step (`_lowest`); a step grown long in
        # an exact flight (constant gravity: no error, the step growing tenfold each time up
        # to t_final) can hold a whole short flight (a bounce at 1e-6 m/s under g = 1 lasts
        # 2e-6 s) within that resolution of its start. For a contact that left with a
        # speed (not one released with none: its dense output near t_a is round-off),
        # probe the step's start on a geometric sequence of times, down to the time
        # resolution, for a point where the contact is open; the flight's peak then
        # lies before twice that time.
        resolution = 4 * np.finfo(float).eps * max(1.0, abs(t_a))
        tau = 0.5 * (t_b - t_a)
        while tau > resolution:
            if gap(t_a + tau) > 0.0:
                t_peak, low = self._lowest(lambda t: -gap(t), t_a, min(t_b, t_a + 2.0 * tau), stop_below=0.0)
                return (t_peak, -low) if -low > 0.0 else (t_a + tau, gap(t_a + tau))
            tau *= 0.5
        return None, None
