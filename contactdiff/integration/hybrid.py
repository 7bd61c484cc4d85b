"""The hybrid loop: flow in a mode, locate the earliest event, reset, continue.

`simulate` integrates a `Scene` event by event:

1. In mode ``J`` the stepper (`contactdiff.integration.steppers`) integrates the KKT flow of
   `contactdiff.dynamics.mode`.
2. After every accepted step each guard of the mode is checked over the step:
   the gap of every inactive contact (downward through 0, including a dip
   below 0 and back within the step, found from the cubic Hermite interpolant
   of the end-point gaps and gap rates and confirmed on the dense output) and
   the normal force of every active contact (downward through 0).
3. The earliest crossing is located on the dense output with Brent's method to
   full precision in time; guards crossing within ``simultaneous_tol`` of it
   form one simultaneous event. The stepper is cut at that time.
4. Touchdowns apply the impact law (`contactdiff.dynamics.impacts`) to every closed
   contact; the next mode follows from the force-level complementarity.
   Lift-offs change the mode without a jump. A sticking contact whose normal
   force vanishes while its release would let it sink (the tangential force it
   carried pressed it down) slides instead: event ``slip``, normal row only,
   until its normal force vanishes again (a ``lift-off``).
5. Active constraints are kept on their manifold: when the gap of an active
   contact drifts beyond ``project_tol`` the state is projected back
   (M-orthogonally) and the largest drift is reported.

With ``method="auto"`` the stepper is DOP853 while its steps are limited by
accuracy and Radau IIA while they would be limited by stability
(`contactdiff.integration.method_choice`); a switch restarts the stepper at the current point
(no jump; the flow Jacobian carries over).

Admissibility: a penetrating initial state is an error; closed contacts at the
start select a consistent mode (with an impact first if they approach);
grazing touchdowns (normal speed below ``grazing_speed``) are events of kind
``grazing`` (or an error with ``on_grazing="raise"``), and so are, as notes,
near-grazing misses (a gap turning back up within ``grazing_gap`` of 0, where
the integration error cannot tell a touch from a miss); a bounce slower than
``zeno_speed`` ends the bounce sequence (the contact stays closed, event kind
``zeno``); more than ``max_events`` events raise `TooManyEventsError`.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from scipy.optimize import minimize_scalar

from ..dynamics.mode import ModeDynamics
from ..errors import IntegrationError, InvalidInputError, StoppedRunError, TooManyStepsError, check_number
from .events import hermite_minimum, locate_crossing, simultaneous_group
from ..dynamics.impacts import choose_mode, liftoff_mode, resolve_impact
from ..model.scene import Scene, passive_note
from .sensitivity import (gap_gradient, impact_reset_jacobian, liftoff_guard, liftoff_saltation, saltation,
                          simultaneous_saltation, vector_field)
from .steppers import METHODS, PinocchioGroup, make_stepper
from .method_choice import EXPLICIT, MethodChooser, spectral_radius
from .trajectory import Event, Segment, Trajectory


class GrazingError(IntegrationError):
    """A contact closed with (nearly) zero normal speed and ``on_grazing="raise"``."""


class TooManyEventsError(StoppedRunError):
    """More than ``max_events`` events; ``.trajectory`` holds the run up to there."""


_GRAZING_MODES = ("event", "raise")
AUTO = "auto"
SIMULATE_METHODS = (AUTO,) + METHODS
"""Valid ``method`` names of `simulate`: ``"auto"`` (`contactdiff.integration.method_choice`) or a stepper."""
MAX_STEPS = 200_000
"""Default step budget of `simulate` (accepted steps)."""
RTOL_MIN = 100 * np.finfo(float).eps
"""Smallest relative tolerance: below it the steps' own round-off exceeds the tolerance."""
RTOL_MAX = 0.1
"""Largest relative tolerance: beyond it a step's error estimate no longer means anything."""
ATOL_MAX = 0.1
"""Largest absolute tolerance (m, rad, m/s): beyond it the error of a step can exceed the
sizes of the robots the tolerance guards (foot heights, link lengths)."""
_SWITCH_NOTES = 10  # notes for the first switches of method="auto" (all are in the stats)
_SPEED_TOL = 1e-12  # m/s: a post-impact normal speed below this (scaled) counts as zero
_DIP_FRACTION = 0.5  # search a step for a dip when its Hermite minimum is below this share of the end gaps


@dataclass
class _Guard:
    kind: str  # "gap" (inactive contact) or "force" (active contact)
    contact: int  # scene index for "gap", contact key (`contactdiff.dynamics.mode`) for "force"


class _Below(Exception):
    """A guard search found a point below its threshold: ``args = (s, value)``."""


class _ModeField:
    """Vector field of one mode for the stepper, remembering its last forces.

    With ``fused`` (a flow Jacobian by an explicit method) every evaluation also
    differentiates the mode: the stepper asks for the Jacobian at the very
    stage points whose accelerations it evaluated, and one solve with
    derivatives costs less than a plain solve followed by a derivative solve.
    The derivatives of the last few points are kept for `jac`.
    """

    _KEEP = 32  # points remembered: more than the stages of one step

    def __init__(self, dyn: ModeDynamics, mode: tuple[int, ...], fused: bool = False):
        self.dyn, self.mode, self.fused = dyn, mode, fused
        self.last = None
        self.n_solve = self.n_derivatives = 0
        self._derivatives: OrderedDict = OrderedDict()

    def accel(self, t, q, v):
        self.n_solve += 1
        if self.fused:
            sol, der = self._solve_with_derivatives(t, q, v)
            self._derivatives[(t, q.tobytes(), v.tobytes())] = (der.ddq_dq, der.ddq_dv)
            if len(self._derivatives) > self._KEEP:
                self._derivatives.popitem(last=False)
        else:
            sol = self.dyn.solve(q, v, t, self.mode)
        self.last = (t, q, v, sol)
        return sol.ddq

    def _solve_with_derivatives(self, t, q, v):
        self.n_derivatives += 1
        return self.dyn.solve(q, v, t, self.mode, derivatives=True)

    def jac(self, t, q, v):
        known = self._derivatives.get((t, q.tobytes(), v.tobytes()))
        if known is not None:
            return known
        _, der = self._solve_with_derivatives(t, q, v)
        return der.ddq_dq, der.ddq_dv

    def normal_forces(self, t, q, v) -> np.ndarray:
        last = self.last
        if last is not None and last[0] == t and np.array_equal(last[1], q) and np.array_equal(last[2], v):
            return last[3].normal_forces()
        return self.dyn.solve(q, v, t, self.mode).normal_forces()


def simulate(scene: Scene, t_final: float, q0=None, v0=None, *, t0: float = 0.0,
             rtol: float = 1e-8, atol: float = 1e-10, method: str = AUTO,
             jacobian: bool = False, max_events: int = 10_000, simultaneous_tol: float = 1e-9,
             zeno_speed: float = 1e-6, grazing_speed: float = 1e-9, on_grazing: str = "event",
             grazing_gap: float | None = None, project_tol: float | None = None,
             max_step: float = np.inf, max_steps: int = MAX_STEPS,
             progress: Callable[[float, int, int], None] | None = None) -> Trajectory:
    """Compute the hybrid trajectory of ``scene`` from ``t0`` to ``t_final``.

    Args:
        scene: the `Scene`.
        t_final: final time (s), > t0.
        q0, v0: initial state (arrays or joint-name mappings); default the scene's.
        t0: initial time (s).
        rtol, atol: error tolerances of each step (relative, in [`RTOL_MIN`,
            `RTOL_MAX`]; absolute in m, rad, m/s, in (0, `ATOL_MAX`]).
        method: ``"auto"`` (explicit DOP853, switching to Radau IIA while the explicit
            steps are limited by stability rather than accuracy, see
            `contactdiff.integration.method_choice`; the steps of each are in ``traj.stats``) or a
            stepper of ``steppers.METHODS`` used throughout (``"Radau"`` for stiff scenes).
        jacobian: also compute the flow Jacobian ``traj.jacobian`` (d x(t_final) /
            d x0, tangent space) and each event's saltation matrix and time gradient.
        max_events: largest number of events before `TooManyEventsError`.
        simultaneous_tol: guards crossing within this time of the first (s) form
            one simultaneous event.
        zeno_speed: a contact closing slower than this (m/s) does not bounce: the
            sequence ends and it stays closed.
        grazing_speed: a touchdown slower than this (m/s) is grazing.
        on_grazing: ``"event"`` records a grazing event and goes on; ``"raise"``
            raises `GrazingError`, also for a near-grazing miss (see ``grazing_gap``).
        grazing_gap: a contact whose gap comes down to within this distance (m) of
            0 and turns back up is a near-grazing miss: the integration error cannot
            tell whether it touched (a note, counted in ``stats["near_grazing_misses"]``,
            or `GrazingError`); default 10 (atol + rtol |q|_inf) at that step.
        project_tol: active-gap drift (m) beyond which the state is projected back
            onto the constraints; default ``atol``.
        max_step: largest step (s).
        max_steps: largest number of accepted steps before `TooManyStepsError`
            (its ``.trajectory`` holds the run so far); the default `MAX_STEPS`
            lets a quadruped trot run for two minutes of simulated time (about
            1,500 steps per second) and stops a runaway run (steps far shorter
            than the horizon: a body spinning at 1e6 rad/s needs 1e-6-s steps).
        progress: called after every accepted step as ``progress(t, events, steps)``
            (time in s, events and accepted steps so far), e.g. to draw a progress
            bar; ``None`` for none.

    Returns:
        The `Trajectory`.

    Raises:
        InvalidInputError: a bad argument (the message names it and its valid range).
        TooManyEventsError, TooManyStepsError: a budget ran out (the run so far
            is on the error's ``.trajectory``).
        IntegrationError: the stepper cannot go on (step size underflow).
    """
    run = _HybridRun(scene, t0, t_final, q0, v0, rtol=rtol, atol=atol, method=method,
                     jacobian=jacobian, max_events=max_events, simultaneous_tol=simultaneous_tol,
                     zeno_speed=zeno_speed, grazing_speed=grazing_speed, on_grazing=on_grazing,
                     grazing_gap=grazing_gap, project_tol=project_tol, max_step=max_step,
                     max_steps=max_steps, progress=progress)
    return run.run()


def _tolerance(name: str, value, low: float, high: float, *, open_low: bool = False) -> float:
    x = check_number("simulate", name, value)
    if not (low < x if open_low else low <= x) or x > high:
        interval = f"({low:g}, {high:g}]" if open_low else f"[{low:.3g}, {high:g}]"
        raise InvalidInputError(f"simulate: {name} must be in {interval}, got {value!r}")
    return x


def _count(name: str, value) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
        raise InvalidInputError(f"simulate: {name} must be an integer >= 0, got {value!r}")
    return int(value)


def _positive(name: str, value, *, allow_zero: bool = False) -> float:
    x = check_number("simulate", name, value, minimum=0.0)
    if x == 0 and not allow_zero:
        raise InvalidInputError(f"simulate: {name} must be > 0, got {value!r}")
    return x


class _HybridRun:
    def __init__(self, scene, t0, t_final, q0, v0, *, rtol, atol, method, jacobian, max_events,
                 simultaneous_tol, zeno_speed, grazing_speed, on_grazing, grazing_gap, project_tol,
                 max_step, max_steps=None, progress=None):
        if not isinstance(scene, Scene):
            raise InvalidInputError(f"scene must be a Scene (see load_scene), got {scene!r}")
        if method not in SIMULATE_METHODS:
            raise InvalidInputError(f"unknown method {method!r}; valid: {', '.join(SIMULATE_METHODS)}")
        if on_grazing not in _GRAZING_MODES:
            raise InvalidInputError(f"on_grazing must be one of {', '.join(_GRAZING_MODES)}; got {on_grazing!r}")
        self.t0 = check_number("simulate", "t0", t0)
        self.t_final = check_number("simulate", "t_final", t_final)
        if not self.t_final > self.t0:
            raise InvalidInputError(f"simulate: t_final must be after t0 = {self.t0}, got {t_final!r}")
        self.scene = scene.with_state(q0, v0) if (q0 is not None or v0 is not None) else scene
        self.rtol = _tolerance("rtol", rtol, RTOL_MIN, RTOL_MAX)
        self.atol = _tolerance("atol", atol, 0.0, ATOL_MAX, open_low=True)
        self.max_events = _count("max_events", max_events)
        self.max_steps = _count("max_steps", MAX_STEPS if max_steps is None else max_steps)
        if progress is not None and not callable(progress):
            raise InvalidInputError(f"simulate: progress must be a callable or None, got {progress!r}")
        self.progress = progress
        self.simultaneous_tol = _positive("simultaneous_tol", simultaneous_tol, allow_zero=True)
        self.zeno_speed = _positive("zeno_speed", zeno_speed, allow_zero=True)
        self.grazing_speed = _positive("grazing_speed", grazing_speed, allow_zero=True)
        self.on_grazing = on_grazing
        self.grazing_gap = None if grazing_gap is None else _positive("grazing_gap", grazing_gap, allow_zero=True)
        self.project_tol = self.atol if project_tol is None else _positive("project_tol", project_tol)
        self.method, self.max_step = method, max_step
        self.jacobian = bool(jacobian)
        self.dyn = ModeDynamics(self.scene)
        self.kin = self.scene.kinematics
        self.contacts = self.scene.contacts
        self.names = self.scene.contact_names
        self.gap_tol = 1e-12  # m: a contact with |gap| below this is closed
        self.events: list[Event] = []
        self.segments: list[Segment] = []
        self.notes: list[str] = [note] if (note := passive_note(self.scene)) else []
        self.max_drift = 0.0
        self.n_projections = 0
        self.n_near_misses = 0
        self.misses: list = []
        self.n_probe_evaluations = 0
        self.phi = None  # flow Jacobian just before the event being processed
        self.initial_saltation = None

    # -- small evaluations ------------------------------------------------------------
    def _gaps_and_rates(self, q, v) -> tuple[np.ndarray, np.ndarray]:
        self.kin.update(q, v)
        gaps = np.array([c.gap(self.kin) for c in self.contacts])
        rates = np.array([c.rows(self.kin)[0] @ v for c in self.contacts])
        return gaps, rates

    def _mode_names(self, mode) -> tuple[str, ...]:
        """Names of the contacts active (sticking or sliding) in ``mode``."""
        return tuple(self.names[i] for i in sorted(self.dyn.contacts_of(mode)))

    def _sliding_names(self, mode) -> tuple[str, ...]:
        return tuple(self.names[i] for i in sorted(self.dyn.contact_index(k) for k in mode
                                                   if self.dyn.is_sliding(k)))

    # -- start ----------------------------------------------------------------------
    def _initial_mode(self, q, v):
        """Consistent mode at t0.

        Closed contacts that approach, and closed sticking contacts that slide, take
        an impact first (restitution on the normal, tangential velocity stopped).
        Otherwise the closed, non-separating contacts choose the mode, and the tiny
        row velocities they may have (at most ``grazing_speed``) are removed.
        """
        gaps, rates = self._gaps_and_rates(q, v)
        closed = [i for i, g in enumerate(gaps) if g <= self.gap_tol]
        if not closed:
            return (), v
        self.kin.update(q, v)
        sliding = [i for i in closed if self.contacts[i].n_rows > 1
                   and np.max(np.abs(self.contacts[i].rows(self.kin)[1:] @ v)) > self.grazing_speed]
        if any(rates[i] < -self.grazing_speed for i in closed) or sliding:
            if self.jacobian:
                self.phi = np.eye(2 * self.scene.nv)
            mode, v_plus = self._impact(self.t0, q, v, (), closed, closed, initial=True)
            self.initial_saltation = self.events[-1].saltation
            return mode, v_plus
        candidates = [i for i in closed if rates[i] <= self.grazing_speed]
        mode = choose_mode(self.dyn, q, v, self.t0, candidates)
        return mode, self._held_velocity(q, v, mode)

    # -- the loop -------------------------------------------------------------------
    def run(self) -> Trajectory:
        scene = self.scene
        q, v = scene.q0.copy(), scene.v0.copy()
        mode, v = self._initial_mode(q, v)
        field = _ModeField(self.dyn, mode, fused=self.jacobian and self.method != "Radau")
        self.group = PinocchioGroup(scene.model)
        self.chooser = MethodChooser(self._probe(mode)) if self.method == AUTO else None
        stepper = make_stepper(EXPLICIT if self.chooser else self.method, field.accel, self.group, self.t0,
                               q, v, rtol=self.rtol, atol=self.atol, jac=field.jac, max_step=self.max_step,
                               t_bound=self.t_final,
                               variational=np.eye(2 * scene.nv) if self.jacobian else None)
        self.retired = []  # steppers replaced by method="auto", for the statistics
        self.switches: list[tuple[float, str]] = []
        if self.jacobian and self.initial_saltation is not None:
            stepper.restart(self.t0, q, v, phi=self.initial_saltation)
        self.fields = [field]
        segment = Segment(self.t0, self.t0, self._mode_names(mode), sliding=self._sliding_names(mode))
        self.segments.append(segment)
        gaps, rates = self._gaps_and_rates(stepper.q, stepper.v)
        forces = field.normal_forces(stepper.t, stepper.q, stepper.v)
        steps = 0
        while stepper.t < self.t_final:
            if steps == self.max_steps:
                raise TooManyStepsError(
                    f"max_steps = {self.max_steps} steps taken by t = {stepper.t:.6g} s of "
                    f"t_final = {self.t_final:g} s (last step {stepper.t - stepper.t_old:.3g} s); "
                    "raise max_steps, or look for a runaway state", self._trajectory(stepper, "max_steps"))
            stepper.step()
            steps += 1
            if self.progress is not None:
                self.progress(stepper.t, len(self.events), steps)
            h = stepper.t - stepper.t_old
            dense = stepper.dense(lazy=True)  # DOP853's extra stages only if a guard needs them
            segment.pieces.append(dense)
            gaps1, rates1 = self._gaps_and_rates(stepper.q, stepper.v)
            forces1 = field.normal_forces(stepper.t, stepper.q, stepper.v)
            crossings = self._crossings(stepper, dense, field, mode, (gaps, rates, forces),
                                        (gaps1, rates1, forces1))
            if not crossings:
                self._near_misses(np.inf)
                gaps, rates, forces = gaps1, rates1, forces1
                if mode and self._project(stepper, mode, gaps1):
                    gaps, rates = self._gaps_and_rates(stepper.q, stepper.v)
                    forces = field.normal_forces(stepper.t, stepper.q, stepper.v)
                segment.t1 = stepper.t
                if self.chooser is not None and stepper.t < self.t_final:
                    switch = self.chooser.after_step(h, stepper.q, stepper.v, stepper.t)
                    if switch:
                        stepper = self._switch(stepper, switch, field)
                continue
            t_event, fired = simultaneous_group(crossings, self.simultaneous_tol)
            self._near_misses(t_event)
            stepper.truncate(t_event)
            dense.t = segment.t1 = t_event
            self.phi = stepper.phi
            mode, v_plus = self._event(t_event, stepper.q, stepper.v, mode, fired)
            if len(self.events) > self.max_events:
                raise TooManyEventsError(
                    f"more than max_events = {self.max_events} events by t = {t_event:.17g} "
                    f"(last: {self.events[-1].kind} of {', '.join(self.events[-1].contacts)}); "
                    "raise max_events or zeno_speed", self._trajectory(stepper, "max_events"))
            q_event = self.events[-1].q
            field = _ModeField(self.dyn, mode, fused=self.jacobian and stepper.method != "Radau")
            self.fields.append(field)
            xi = self.events[-1].saltation
            stepper.restart(t_event, q_event, v_plus, accel=field.accel, jac=field.jac,
                            phi=None if xi is None else xi @ stepper.phi)
            if self.chooser is not None:
                self.chooser.new_mode(self._probe(mode))
            segment = Segment(t_event, t_event, self._mode_names(mode), sliding=self._sliding_names(mode))
            self.segments.append(segment)
            gaps, rates = self._gaps_and_rates(stepper.q, stepper.v)
            forces = field.normal_forces(stepper.t, stepper.q, stepper.v)
        return self._trajectory(stepper, "t_final")

    # -- method="auto" ----------------------------------------------------------------
    def _probe(self, mode):
        """``ρ`` of ``mode`` at a state, for `MethodChooser` (difference quotients of
        the mode's accelerations; they bypass the mode field and its counters)."""
        def accel(t, q, v):
            self.n_probe_evaluations += 1
            return self.dyn.solve(q, v, t, mode).ddq
        return lambda q, v, t: spectral_radius(accel, q, v, t, self.group)

    def _switch(self, stepper, method: str, field):
        """Continue from the stepper's current point with ``method``: a restart without a
        jump (state and flow Jacobian carried over, the step size as a first guess)."""
        self.retired.append(stepper)
        self.switches.append((stepper.t, method))
        # Radau evaluates the field at Newton iterates, where no derivative is wanted
        field.fused = self.jacobian and method != "Radau"
        rho = self.chooser.rho
        if len(self.switches) <= _SWITCH_NOTES:
            why = ("explicit steps limited by stability" if method != EXPLICIT
                   else "steps resolve the fastest motion")
            self.notes.append(f"method auto: {method} from t = {stepper.t:.12g} ({why}: "
                              f"h = {stepper.h_abs:.3g} s, spectral radius {rho:.3g} /s)")
        return make_stepper(method, field.accel, self.group, stepper.t, stepper.q, stepper.v,
                            rtol=self.rtol, atol=self.atol, jac=field.jac, max_step=self.max_step,
                            t_bound=self.t_final, first_step=stepper.h_abs,
                            variational=stepper.phi if self.jacobian else None)

    def _trajectory(self, stepper, termination) -> Trajectory:
        steppers = self.retired + [stepper]
        by_method: dict[str, int] = {}
        for st in steppers:
            by_method[st.method] = by_method.get(st.method, 0) + st.n_steps
        stats = {"steps": sum(st.n_steps for st in steppers),
                 "rejected_steps": sum(st.n_rejected for st in steppers),
                 "dynamics_evaluations": sum(f.n_solve for f in self.fields),
                 "stepper_evaluations": sum(st.n_accel for st in steppers),
                 "jacobian_evaluations": sum(st.n_jac for st in steppers),
                 "derivative_evaluations": sum(f.n_derivatives for f in self.fields),
                 "events": len(self.events), "projections": self.n_projections,
                 "method": self.method, "steps_by_method": by_method,
                 "method_switches": [[t, m] for t, m in self.switches],
                 "stiffness_probes": self.chooser.n_probes if self.chooser else 0,
                 "probe_evaluations": self.n_probe_evaluations,
                 "near_grazing_misses": self.n_near_misses}
        return Trajectory(self.scene.name, self.t0, self.scene.q0.copy(), self.scene.v0.copy(),
                          stepper.t, stepper.q.copy(), stepper.v.copy(), self.events, self.segments,
                          stats, self.max_drift, termination, self.notes,
                          stepper.phi.copy() if self.jacobian else None)

    # -- detection ------------------------------------------------------------------
    def _crossings(self, stepper, dense, field, mode, start, end) -> list[tuple[float, _Guard]]:
        t_a, t_b = stepper.t_old, stepper.t
        gaps0, rates0, forces0 = start
        gaps1, rates1, forces1 = end
        found = []
        self.misses = []  # near-grazing misses of this step: (t, contact, gap, band)
        active = self.dyn.contacts_of(mode)
        for i, contact in enumerate(self.contacts):
            if i in active:
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
                dip = 0.0 < s < 1.0 and low < _DIP_FRACTION * min(gaps0[i], gaps1[i])
                # a gap that turns upward within the step, perhaps just above the ground
                turning = gaps0[i] > self.gap_tol and rates0[i] < 0.0 <= rates1[i]
                band = self._grazing_band(stepper.q) if turning else 0.0
                if not (dip or (turning and min(low, gaps1[i]) <= 2.0 * band)):
                    continue
                t_hi, g_hi = self._lowest(gap, t_a, t_b, stop_below=0.0)
                if g_hi >= 0.0:
                    if turning and g_hi <= band:
                        self.misses.append((t_hi, i, g_hi, band))
                    continue
            if g_lo <= self.gap_tol:
                # the contact has just opened (bounce or lift-off): its gap starts at 0
                # going up; a new touchdown needs the gap to rise above 0 and come back
                t_peak, g_peak = self._peak(gap, t_a, t_hi)
                if t_peak is None:
                    # it never opened (released at an impact with no separating speed,
                    # or rising by less than the search resolves) and is sinking: it
                    # touches down where it passes below the integration error band
                    # (a shallower dip of the dense output may be its error alone)
                    shift = max(self.gap_tol, self._grazing_band(stepper.q)) - min(g_lo, 0.0)
                    if g_hi + shift < 0.0:
                        found.append((locate_crossing(lambda t: gap(t) + shift, t_a, t_hi, g_lo + shift,
                                                      g_hi + shift), _Guard("gap", i)))
                    continue
                t_lo, g_lo = t_peak, g_peak
            found.append((locate_crossing(gap, t_lo, t_hi, g_lo, g_hi), _Guard("gap", i)))
        for k, key in enumerate(mode):
            if forces1[k] >= 0.0:
                continue

            def force(t, k=k):
                qt, vt = dense(t)
                return field.normal_forces(t, qt, vt)[k]
            found.append((locate_crossing(force, t_a, t_b, forces0[k], forces1[k]), _Guard("force", key)))
        return found

    def _grazing_band(self, q) -> float:
        """Gap (m) within which a contact that turns back up may have touched, given
        the integration error: ``grazing_gap``, by default 10 (atol + rtol |q|_inf)."""
        if self.grazing_gap is not None:
            return self.grazing_gap
        return 10.0 * (self.atol + self.rtol * float(np.max(np.abs(q))))

    def _near_misses(self, t_event: float) -> None:
        """Report the near-grazing misses of the last step before ``t_event``.

        A contact came down to ``gap`` (within ``band``) with zero normal speed and
        rose again: no touchdown was found, but the integration error cannot tell
        touching from missing, and the outcome is not continuous there (a touch of
        depth d stops a normal speed of order sqrt(d)). Never silent: a note, or
        `GrazingError` with ``on_grazing="raise"``."""
        for t, i, gap, band in sorted(self.misses):
            if t >= t_event:
                break
            message = (f"near-grazing of {self.names[i]} at t = {t:.12g}: its gap came down to {gap:.3g} m "
                       f"(within grazing_gap {band:.3g} m) with zero normal speed and rose again")
            if self.on_grazing == "raise":
                raise GrazingError(message + "; whether it touches is below the integration error: "
                                   "tighten rtol/atol, or lower grazing_gap to accept the miss")
            self.n_near_misses += 1
            if self.n_near_misses <= _SWITCH_NOTES:
                self.notes.append(message + "; counted as a miss (no touchdown)")

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

    def _peak(self, gap, t_a, t_b):
        """Highest point of a gap that starts closed at ``t_a`` and is negative at ``t_b``.

        Returns ``(t, gap)`` there, or ``(None, None)`` if the gap never opens (rises
        above 0). A peak in (0, gap_tol] is still a real bounce that comes back: skipping
        it would leave the contact out of the mode, and it would fall through the
        ground (e.g. a ball bounce at 1.2e-6 m/s under g = 1 peaks at 7e-13 m); the
        Zeno rule ends such sequences instead.
        """
        t_peak, low = self._lowest(lambda t: -gap(t), t_a, t_b, stop_below=0.0)
        return (t_peak, -low) if -low > 0.0 else (None, None)

    # -- events ---------------------------------------------------------------------
    def _event(self, t, q, v, mode, fired: list[_Guard]):
        dyn = self.dyn
        touching = [g.contact for g in fired if g.kind == "gap"]
        releasing = [g.contact for g in fired if g.kind == "force"]
        if touching:
            # every contact closed at the instant takes part (DESIGN §2), also one whose
            # guard did not fire within simultaneous_tol: left out, it would start the
            # next step closed and be skipped by _crossings (no peak), i.e. penetrate
            gaps, _ = self._gaps_and_rates(q, v)
            active = dyn.contacts_of(mode)
            near = [i for i, g in enumerate(gaps) if g <= self.gap_tol and i not in active]
            closed = sorted(set(mode) | set(touching) | set(near))
            return self._impact(t, q, v, mode, closed, touching, releasing)
        # a released sticking contact that would sink (the tangential force it carried
        # pressed it down) slides instead: normal row only, until its force vanishes
        new_mode = liftoff_mode(dyn, q, v, t, mode, releasing)
        kind = "slip" if any(dyn.is_sliding(k) and k not in mode for k in new_mode) else "lift-off"
        event = Event(t, kind, self._mode_names(releasing), len(releasing) > 1, q.copy(),
                      v.copy(), v.copy(), {}, self._mode_names(mode), self._mode_names(new_mode),
                      sliding=self._sliding_names(new_mode))
        if self.jacobian:
            # guard: the normal force of the first releasing contact; with several at once
            # (a simultaneous lift-off) the saltation is the product of the single
            # lift-offs in turn (each releasing contact's guard in the mode left by the
            # earlier ones): a sticking contact's force jump is not carried by another's guard
            guard = liftoff_guard(dyn, t, q, v, mode, releasing[0])
            xi = self._liftoff_sequence(t, q, v, mode, releasing, new_mode, guard)
            self._attach_sensitivity(event, xi, *guard)
        self.events.append(event)
        return new_mode, v

    def _liftoff_sequence(self, t, q, v, mode, releasing, new_mode, first_guard) -> np.ndarray:
        """Saltation of the lift-off of ``releasing`` from ``mode``, one contact after the
        other in the given order at the same state (no jump: each force is zero there);
        ``first_guard`` is the first one's `liftoff_guard`."""
        xi, current = np.eye(2 * self.scene.nv), tuple(mode)
        for n, k in enumerate(releasing):
            slide = self.dyn.sliding_key(k) if not self.dyn.is_sliding(k) else None
            after = tuple(new_mode) if n == len(releasing) - 1 else tuple(sorted(
                [i for i in current if i != k] + ([slide] if slide in new_mode else [])))
            guard = first_guard if n == 0 else None
            xi = liftoff_saltation(self.dyn, t, q, v, current, k, after, guard) @ xi
            current = after
        return xi

    def _impact(self, t, q, v_minus, mode, closed, touching, releasing=(), initial=False):
        """Impact of the ``closed`` contacts (keys: a sliding contact takes part with its
        normal row), ``touching`` being those whose guard fired (at the start,
        ``initial``: all closed contacts, with no guard and no grazing)."""
        q = self._close(q, closed)
        self.kin.update(q, v_minus)
        speeds = {i: float(self.contacts[i].rows(self.kin)[0] @ v_minus) for i in touching}
        grazing = [] if initial else [i for i in touching if abs(speeds[i]) <= self.grazing_speed]
        if grazing and self.on_grazing == "raise":
            raise GrazingError(
                f"grazing touchdown of {', '.join(self.names[i] for i in grazing)} at t = {t:.17g}: "
                f"normal speed {max(abs(speeds[i]) for i in grazing):.3g} m/s <= grazing_speed "
                f"{self.grazing_speed:g}; the flow is not differentiable there")
        dyn = self.dyn
        e = np.array([dyn.contact(k).restitution for k in closed])
        zeno = [i for i in touching if self.contacts[i].restitution > 0 and abs(speeds[i]) < self.zeno_speed]
        for i in zeno:
            e[closed.index(i)] = 0.0
        impact = resolve_impact(dyn, q, v_minus, closed, e)
        v_plus = impact.v_plus
        scale = max(1.0, float(np.max(np.abs(impact.normal_speeds_before))))
        leaving = set(dyn.contacts_of(releasing))  # a releasing contact leaves whatever its key
        staying = [k for k, s in zip(closed, impact.normal_speeds_after)
                   if s <= _SPEED_TOL * scale and dyn.contact_index(k) not in leaving]
        # The Zeno rule for impact cascades: a closed contact that this impact would
        # lift slower than zeno_speed does not leave (with several sticking feet an
        # impact at one foot lifts another by a little, whose return lifts a third,
        # and so on, a geometric series of ever slower impacts); its separating speed
        # is removed M-orthogonally if the mode keeps it. This includes a landing
        # contact with no restitution left (plastic, or a bounce ended above) that
        # the impact law itself lifts: a sticking contact whose slip only a pulling
        # impulse could stop takes a tangential impulse alone and leaves
        # (`resolve_impact`), and if its flight brings it back slipping the same
        # way, its landings form a geometric series as well. Left to leave, it
        # would rise by (speed)² / (2 |normal acceleration|), far below what the
        # dense output resolves, and come back only through the sinking rule of
        # `_crossings`, i.e. below the ground by the grazing band, landing again
        # at sqrt(2 |acceleration| band) (ANYmal's trot: 1e-7 m, 1 cm/s). A contact
        # with restitution left bounces by its own law, ended on its approach speed.
        settling = [k for k, s, e_k in zip(closed, impact.normal_speeds_after, impact.restitution)
                    if _SPEED_TOL * scale < s < self.zeno_speed and dyn.contact_index(k) not in leaving
                    and (dyn.contact_index(k) not in touching or e_k == 0.0)]
        new_mode = choose_mode(dyn, q, v_plus, t, staying + settling)
        settled = [i for i in dyn.contacts_of(settling) if i in dyn.contacts_of(new_mode)]
        if settled:
            v_plus = self._held_velocity(q, v_plus, new_mode)
            self.notes.append(f"Zeno: impact cascade ended at t = {t:.12g}: "
                              f"{', '.join(self.names[i] for i in settled)} kept closed (lifted slower "
                              f"than zeno_speed = {self.zeno_speed:g} m/s)")
        # a landing slower than zeno_speed ends its bounces: its own restitution set to
        # zero, or, lifted by the impact law, kept closed by the rule above
        ended = sorted(set(zeno) | {i for i in settled if i in touching and abs(speeds[i]) < self.zeno_speed})
        if grazing:
            kind = "grazing"
            self.notes.append(f"grazing touchdown of {', '.join(self.names[i] for i in grazing)} at t = {t:.12g}")
        elif ended:
            kind = "zeno"
            self.notes.append(f"Zeno: bounces of {', '.join(self.names[i] for i in ended)} ended at t = {t:.12g} "
                              f"(impact speed below zeno_speed = {self.zeno_speed:g} m/s); contact kept closed")
        elif any(i in dyn.contacts_of(new_mode) for i in touching):
            kind = "touchdown"
        else:
            kind = "bounce"
        impulses = {self.names[dyn.contact_index(k)]: float(x) for k, x in zip(closed, impact.impulses)}
        event = Event(t, kind, self._mode_names(touching), len(touching) > 1, q.copy(),
                      v_minus.copy(), v_plus.copy(), impulses, self._mode_names(mode),
                      self._mode_names(new_mode), {self.names[i]: s for i, s in speeds.items()},
                      sliding=self._sliding_names(new_mode))
        event.differentiable = not (grazing or settled)  # the cascade rule's cut-off is not smooth
        if self.jacobian and initial:
            # no guard at t0: perturbations keep the start time, only the reset acts
            event.saltation = impact_reset_jacobian(self.dyn, q, v_minus, impact)
            event.time_gradient = np.zeros(2 * self.scene.nv)
        elif self.jacobian:
            F_minus = vector_field(self.dyn, q, v_minus, t, mode)
            guard = min(touching, key=lambda i: speeds[i])
            Dh = gap_gradient(self.dyn, q, guard)
            if len(touching) > 1:
                override = {i: e[closed.index(i)] for i in closed}
                sim = simultaneous_saltation(self.dyn, t, q, v_minus, mode, touching, override)
                xi = sim.matrix
                event.differentiable = event.differentiable and sim.differentiable
                event.saltation_orders = {tuple(self.names[i] for i in k): m for k, m in sim.orders.items()}
                if not sim.differentiable:
                    self.notes.append(
                        f"not differentiable at t = {t:.12g}: the landing orders of "
                        f"{', '.join(self.names[i] for i in touching)} give saltation matrices "
                        f"differing by {sim.spread:.2e} (relative)")
            else:
                DR = impact_reset_jacobian(self.dyn, q, v_minus, impact)
                xi = saltation(DR, Dh, F_minus, vector_field(self.dyn, q, v_plus, t, new_mode))
            self._attach_sensitivity(event, xi, Dh, F_minus)
        self.events.append(event)
        return new_mode, v_plus

    def _attach_sensitivity(self, event: Event, xi: np.ndarray, Dh: np.ndarray, F_minus: np.ndarray,
                            h_t: float = 0.0) -> None:
        """Saltation matrix and event-time gradient ``-Dh Φ- / (Dh F- + h_t)`` (implicit
        functions; ``h_t`` the guard's explicit time rate)."""
        event.saltation = xi
        event.time_gradient = -(Dh @ self.phi) / (float(Dh @ F_minus) + h_t)

    # -- constraint manifold ----------------------------------------------------------
    def _close(self, q, contacts):
        """Project ``q`` M-orthogonally onto ``gap = 0`` of ``contacts`` (keys; Gauss–Newton)."""
        if not contacts:
            return q
        model, zero = self.scene.model, np.zeros(self.scene.nv)
        for _ in range(10):
            self.kin.update(q, zero)
            gaps = np.array([self.dyn.contact(k).gap(self.kin) for k in contacts])
            if np.max(np.abs(gaps)) <= 1e-15:
                break
            A = np.vstack([self.dyn.contact(k).rows(self.kin)[0] for k in contacts])
            q = pin.integrate(model, q, -self._weighted_pinv(q, A) @ gaps)
        return q

    def _mode_rows(self, mode) -> np.ndarray:
        """Stacked constraint rows of ``mode`` at the kinematics' current configuration."""
        return np.vstack([self.dyn.contact(k).rows(self.kin) for k in mode])

    def _held_velocity(self, q, v, mode) -> np.ndarray:
        """``v`` with the row velocities of ``mode`` removed M-orthogonally (the least
        kinetic-energy change that holds every contact of the mode)."""
        if not mode:
            return v
        self.kin.update(q, v)
        A = self._mode_rows(mode)
        return v - self._weighted_pinv(q, A) @ (A @ v)

    def _weighted_pinv(self, q, A) -> np.ndarray:
        """``M^-1 A^T (A M^-1 A^T)^+``: the M-orthogonal (minimum kinetic energy)
        pseudo-inverse of the rows ``A`` at ``q``; redundant rows are allowed."""
        MinvAT = pin.computeMinverse(self.scene.model, self.dyn.data, q) @ A.T
        return MinvAT @ np.linalg.pinv(A @ MinvAT)

    def _project(self, stepper, mode, gaps) -> bool:
        drift = max(abs(gaps[i]) for i in self.dyn.contacts_of(mode))
        self.max_drift = max(self.max_drift, drift)
        if drift <= self.project_tol:
            return False
        q = self._close(stepper.q, list(mode))
        self.kin.update(q, stepper.v)
        A = self._mode_rows(mode)
        pinv = self._weighted_pinv(q, A)
        v = stepper.v - pinv @ (A @ stepper.v)
        phi = None
        if self.jacobian:
            # derivative of the projection (q, v) -> (q - P a(q), v - P A(q) v) on the manifold
            nv = self.scene.nv
            self.kin.update(q, v, derivatives=True)
            normal = [0] + list(np.cumsum([self.dyn.contact(k).n_rows for k in mode])[:-1])
            dAv = np.vstack([self.dyn.contact(k).rows_velocity_dq(self.kin) for k in mode])
            D = np.eye(2 * nv)
            D[:nv, :nv] -= self._weighted_pinv(q, A[normal]) @ A[normal]
            D[nv:, nv:] -= pinv @ A
            D[nv:, :nv] -= pinv @ dAv
            phi = D @ stepper.phi
        stepper.restart(stepper.t, q, v, phi=phi)
        self.n_projections += 1
        return True
