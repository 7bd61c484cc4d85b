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
``zeno``); more than ``max_events`` events raise `TooManyEventsError`, more
than ``max_steps`` steps `TooManyStepsError`.

`HybridLoop` is the loop itself, public and meant to be extended: a subclass
may override `HybridLoop.initial_mode` (the consistent start) and
`HybridLoop.on_event` (called after every event; returning True makes the event
terminal: the run ends just after it, with ``Termination.STOPPED``). The stride
map (`contactdiff.analysis.gait.stride`) is such a subclass. The options of a
run are one `SimulateOptions`.
"""

from __future__ import annotations

import numpy as np

from ..dynamics.impacts import choose_mode, liftoff_mode, resolve_impact
from ..dynamics.mode import ModeDynamics
from ..errors import GrazingError, InvalidInputError, TooManyEventsError, TooManyStepsError, check_number
from ..model.scene import Scene
from ..model.scene_file import passive_note
from .events import simultaneous_group
from .guards import Guard, GuardFinder, GuardKind, NearMiss
from .method_choice import EXPLICIT, MethodChooser, spectral_radius
from .mode_field import ModeField
from .options import AUTO, OnGrazing, SimulateOptions
from .parameter_jumps import ParameterJumps
from .projection import close, held_velocity, held_velocity_jacobian, project_state
from .sensitivity import (
    gap_gradient,
    impact_reset_jacobian,
    liftoff_guard,
    saltation,
    simultaneous_saltation,
    vector_field,
)
from .steppers import PinocchioGroup, make_stepper
from .trajectory import Event, NonSmooth, RunStats, Segment, Termination, Trajectory

MAX_NOTES = 10
"""Notes written for the first method switches of ``method="auto"`` and the first
near-grazing misses (all are counted in the statistics)."""
GAP_TOL = 1e-12
"""m: a contact whose gap is below this is closed."""
SPEED_TOL = 1e-12
"""m/s: a post-impact normal speed below this (scaled by the impact's speeds) counts as zero."""


def simulate(scene: Scene, t_final: float, q0=None, v0=None, *, t0: float = 0.0,
             options: SimulateOptions | None = None, **option_values) -> Trajectory:
    """Compute the hybrid trajectory of ``scene`` from ``t0`` to ``t_final``.

    Args:
        scene: the `Scene`.
        t_final: final time (s), > t0.
        q0: initial configuration: an array (nq,) or a joint-name mapping that changes
            only the named joints of the scene's; default the scene's.
        v0: initial velocity: an array (nv,), tangent space, or a joint-name mapping
            as for ``q0``; default the scene's.
        t0: initial time (s).
        options: a `SimulateOptions`; default ``SimulateOptions()``.
        **option_values: fields of `SimulateOptions` by name, on top of
            ``options`` (``rtol``, ``atol``, ``method``, ``jacobian``,
            ``max_events``, ``max_steps``, ``simultaneous_tol``, ``zeno_speed``,
            ``grazing_speed``, ``on_grazing``, ``grazing_gap``, ``project_tol``,
            ``max_step``, ``progress``); see there for units and defaults.

    Returns:
        The `Trajectory`.

    Raises:
        InvalidInputError: a bad argument (the message names it and its valid range,
            or lists the valid option names).
        TooManyEventsError, TooManyStepsError: a budget ran out (the run so far
            is on the error's ``.trajectory``).
        IntegrationError: the stepper cannot go on (step size underflow).
    """
    options = SimulateOptions() if options is None else options
    if not isinstance(options, SimulateOptions):
        raise InvalidInputError(f"simulate: options must be a SimulateOptions, got {options!r}")
    if option_values:
        options = options.replace(**option_values)
    return HybridLoop(scene, t0, t_final, q0, v0, options).run()


class HybridLoop:
    """The hybrid loop of one run (module docstring); `simulate` is ``HybridLoop(...).run()``.

    Args:
        scene: the `Scene`.
        t0, t_final: start and final time (s).
        q0, v0: initial state (arrays or joint-name mappings); None: the scene's.
        options: the `SimulateOptions`.

    Extension: override `initial_mode` and `on_event` (see there). The state a
    subclass may read: ``scene``, ``dyn`` (its `ModeDynamics`), ``kin`` (the
    scene's kinematics cache), ``contacts``, ``names``, ``options``, ``events``,
    ``segments``, ``notes``, and ``phi``, the flow Jacobian just before the event
    being processed (with ``options.jacobian`` or ``options.parameters``: its columns are
    the state's 2nv with ``jacobian``, then the parameters').
    """

    def __init__(self, scene: Scene, t0: float, t_final: float, q0=None, v0=None,
                 options: SimulateOptions | None = None):
        if not isinstance(scene, Scene):
            raise InvalidInputError(f"scene must be a Scene (see load_scene), got {scene!r}")
        self.options = SimulateOptions() if options is None else options
        self.t0 = check_number("simulate", "t0", t0)
        self.t_final = check_number("simulate", "t_final", t_final)
        if not self.t_final > self.t0:
            raise InvalidInputError(f"simulate: t_final must be after t0 = {self.t0}, got {t_final!r}")
        self.scene = scene.with_state(q0, v0) if (q0 is not None or v0 is not None) else scene
        self.dyn = ModeDynamics(self.scene)
        self.kin = self.scene.kinematics
        self.contacts = self.scene.contacts
        self.names = self.scene.contact_names
        self.gap_tol = GAP_TOL
        self.guards = GuardFinder(self.scene, self.dyn, self.options, GAP_TOL)
        self.group = PinocchioGroup(self.scene.model)
        self.chooser: MethodChooser | None = None  # method="auto" only, made at the start
        self.events: list[Event] = []
        self.segments: list[Segment] = []
        self.notes: list[str] = [note] if (note := passive_note(self.scene)) else []
        self.fields: list[ModeField] = []  # one per mode visited, for the statistics
        self.retired: list = []  # steppers replaced by method="auto", for the statistics
        self.switches: list[tuple[float, str]] = []
        self.max_drift = 0.0
        self.n_projections = 0
        self.n_near_misses = 0
        self.n_probe_evaluations = 0
        self.phi = None  # flow Jacobian just before the event being processed
        self.initial_saltation = None
        self.jumps = None  # the parameters' blocks at events, with options.parameters
        # phi's columns: the state's 2nv (with options.jacobian), then the parameters'
        self.sensitive = self.options.jacobian or bool(self.options.parameters)
        self.n_state = 2 * self.scene.nv if self.options.jacobian else 0
        if self.options.parameters:
            from ..model.parameters import resolve  # the model's names import the dynamics' scene
            self.jumps = ParameterJumps(self.dyn, resolve(self.scene, self.options.parameters))

    def _identity_phi(self) -> np.ndarray:
        """The flow Jacobian at the start: ``[I, 0]`` (2nv × (2nv + p)); without the state's
        Jacobian, the p parameter columns only (zero)."""
        n = 2 * self.scene.nv
        phi = np.zeros((n, self.n_state + (self.jumps.p if self.jumps else 0)))
        phi[:, :self.n_state] = np.eye(n, self.n_state)
        return phi

    def _field(self, mode, fused: bool) -> ModeField:
        return ModeField(self.dyn, mode, fused=fused, parameters=self.jumps.forces if self.jumps else None)

    def _jumped(self, phi: np.ndarray, event: Event) -> np.ndarray:
        """The flow Jacobian just after ``event`` from ``phi`` just before: ``Ξ phi``, plus
        ``Ξ_p`` on the parameter columns."""
        out = event.saltation @ phi
        if event.parameter_saltation is not None:
            out[:, self.n_state:] += event.parameter_saltation
        return out

    # -- hooks ----------------------------------------------------------------------
    def on_event(self, event: Event, mode_before: tuple[int, ...], phi_before) -> bool:
        """Called once for every event, in time order, after the loop has processed it
        (the state after the reset is ``event.q``, ``event.v_plus``).

        Args:
            event: the `Event`.
            mode_before: the contact keys of the mode before the event
                (`contactdiff.dynamics.mode`).
            phi_before: the flow Jacobian just before the event (None without
                ``options.jacobian``).

        Returns:
            True to end the run just after this event (a terminal event); the
            default never does.
        """
        return False

    # -- small evaluations ------------------------------------------------------------
    def _gaps_and_rates(self, q, v) -> tuple[np.ndarray, np.ndarray]:
        self.kin.update(q, v)
        gaps = np.array([c.gap(self.kin) for c in self.contacts])
        rates = np.array([c.gap_rate(self.kin) for c in self.contacts])
        return gaps, rates

    def _mode_names(self, mode) -> tuple[str, ...]:
        """Names of the contacts active (sticking or sliding) in ``mode``."""
        return tuple(self.names[i] for i in sorted(self.dyn.contacts_of(mode)))

    def _sliding_names(self, mode) -> tuple[str, ...]:
        return tuple(self.names[i] for i in sorted(self.dyn.contact_index(k) for k in mode
                                                   if self.dyn.is_sliding(k)))

    # -- start ----------------------------------------------------------------------
    def initial_mode(self, q, v):
        """Consistent mode at t0 and the velocity to start with (a hook: a subclass may
        override it and call it, as the stride map does to take the start impact's
        full saltation matrix).

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
                   and np.max(np.abs(self.contacts[i].rows(self.kin)[1:] @ v)) > self.options.grazing_speed]
        if any(rates[i] < -self.options.grazing_speed for i in closed) or sliding:
            if self.sensitive:
                self.phi = self._identity_phi()
            mode, v_plus = self._impact(self.t0, q, v, (), closed, closed, initial=True)
            if self.sensitive:
                self.initial_saltation = self._jumped(self._identity_phi(), self.events[-1])
            return mode, v_plus
        candidates = [i for i in closed if rates[i] <= self.options.grazing_speed]
        mode = choose_mode(self.dyn, q, v, self.t0, candidates)
        return mode, held_velocity(self.dyn, q, v, mode)

    # -- the loop -------------------------------------------------------------------
    def _stepper_options(self, field: ModeField) -> dict:
        o = self.options
        options = dict(rtol=o.rtol, atol=o.atol, max_step=o.max_step, t_bound=self.t_final)
        if self.jumps is not None:
            options.update(parameter_jac=field.parameter_jac, variational_column_scale=np.concatenate(
                [np.ones(self.n_state), self.jumps.scale]))
        return options

    def run(self) -> Trajectory:
        """Integrate to ``t_final`` (or to a terminal event) and return the `Trajectory`."""
        options, scene = self.options, self.scene
        q, v = scene.q0.copy(), scene.v0.copy()
        mode, v = self.initial_mode(q, v)
        field = self._field(mode, fused=self.sensitive and options.method != "Radau")
        self.chooser = MethodChooser(self._probe(mode)) if options.method == AUTO else None
        stepper = make_stepper(EXPLICIT if self.chooser else options.method, field.accel, self.group, self.t0,
                               q, v, jac=field.jac, variational=self._identity_phi() if self.sensitive else None,
                               **self._stepper_options(field))
        if self.sensitive and self.initial_saltation is not None:
            stepper.restart(self.t0, q, v, phi=self.initial_saltation)
        self.fields.append(field)
        segment = Segment(t0=self.t0, t1=self.t0, mode=self._mode_names(mode), sliding=self._sliding_names(mode))
        self.segments.append(segment)
        gaps, rates = self._gaps_and_rates(stepper.q, stepper.v)
        forces = field.normal_forces(stepper.t, stepper.q, stepper.v)
        steps = 0
        next_break = -np.inf  # the efforts' next breakpoint: a time a step must end on
        while stepper.t < self.t_final:
            if steps == options.max_steps:
                raise TooManyStepsError(
                    f"max_steps = {options.max_steps} steps taken by t = {stepper.t:.6g} s of "
                    f"t_final = {self.t_final:g} s (last step {stepper.t - stepper.t_old:.3g} s); "
                    "raise max_steps, or look for a runaway state",
                    self._trajectory(stepper, Termination.MAX_STEPS))
            if stepper.t >= next_break:
                next_break = scene.next_breakpoint(stepper.t)
            stepper.t_bound = min(self.t_final, next_break)  # also for a stepper new since the last step
            stepper.step()
            steps += 1
            if options.progress is not None:
                options.progress(stepper.t, len(self.events), steps)
            h = stepper.t - stepper.t_old
            dense = stepper.dense(lazy=True)  # DOP853's extra stages only if a guard needs them
            if options.dense:
                segment.pieces.append(dense)
            gaps1, rates1 = self._gaps_and_rates(stepper.q, stepper.v)
            forces1 = field.normal_forces(stepper.t, stepper.q, stepper.v)
            crossings, misses = self.guards.crossings(stepper, dense, field, mode, (gaps, rates, forces),
                                                      (gaps1, rates1, forces1))
            if not crossings:
                self._near_misses(misses, np.inf)
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
            t_event, fired = simultaneous_group(crossings, options.simultaneous_tol)
            self._near_misses(misses, t_event)
            stepper.truncate(t_event)
            dense.t = segment.t1 = t_event
            self.phi = stepper.phi
            n_before, mode_before = len(self.events), tuple(mode)
            mode, v_plus = self._event(t_event, stepper.q, stepper.v, mode, fired)
            if len(self.events) > options.max_events:
                raise TooManyEventsError(
                    f"more than max_events = {options.max_events} events by t = {t_event:.17g} "
                    f"(last: {self.events[-1].kind} of {', '.join(self.events[-1].contacts)}); "
                    "raise max_events or zeno_speed", self._trajectory(stepper, Termination.MAX_EVENTS))
            phi_before = None if self.phi is None else self.phi.copy()
            stop = False
            for event in self.events[n_before:]:
                stop = self.on_event(event, mode_before, phi_before) or stop
            q_event = self.events[-1].q
            field = self._field(mode, fused=self.sensitive and stepper.method != "Radau")
            self.fields.append(field)
            stepper.restart(t_event, q_event, v_plus, accel=field.accel, jac=field.jac,
                            parameter_jac=field.parameter_jac if self.jumps else None,
                            phi=None if self.events[-1].saltation is None else self._jumped(stepper.phi,
                                                                                             self.events[-1]))
            if self.chooser is not None:
                self.chooser.new_mode(self._probe(mode))
            segment = Segment(t0=t_event, t1=t_event, mode=self._mode_names(mode),
                              sliding=self._sliding_names(mode))
            self.segments.append(segment)
            gaps, rates = self._gaps_and_rates(stepper.q, stepper.v)
            forces = field.normal_forces(stepper.t, stepper.q, stepper.v)
            if stop:
                return self._trajectory(stepper, Termination.STOPPED)
        return self._trajectory(stepper, Termination.T_FINAL)

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
        field.fused = self.sensitive and method != "Radau"
        rho = self.chooser.rho
        if len(self.switches) <= MAX_NOTES:
            why = ("explicit steps limited by stability" if method != EXPLICIT
                   else "steps resolve the fastest motion")
            self.notes.append(f"method auto: {method} from t = {stepper.t:.12g} ({why}: "
                              f"h = {stepper.h_abs:.3g} s, spectral radius {rho:.3g} /s)")
        return make_stepper(method, field.accel, self.group, stepper.t, stepper.q, stepper.v,
                            jac=field.jac, first_step=stepper.h_abs,
                            variational=stepper.phi if self.sensitive else None,
                            **self._stepper_options(field))

    def _trajectory(self, stepper, termination: Termination) -> Trajectory:
        steppers = self.retired + [stepper]
        by_method: dict[str, int] = {}
        for st in steppers:
            by_method[st.method] = by_method.get(st.method, 0) + st.n_steps
        stats = RunStats(steps=sum(st.n_steps for st in steppers),
                         rejected_steps=sum(st.n_rejected for st in steppers),
                         dynamics_evaluations=sum(f.n_solve for f in self.fields),
                         stepper_evaluations=sum(st.n_accel for st in steppers),
                         jacobian_evaluations=sum(st.n_jac for st in steppers),
                         derivative_evaluations=sum(f.n_derivatives for f in self.fields),
                         events=len(self.events), projections=self.n_projections,
                         method=self.options.method, steps_by_method=by_method,
                         method_switches=[[t, m] for t, m in self.switches],
                         stiffness_probes=self.chooser.n_probes if self.chooser else 0,
                         probe_evaluations=self.n_probe_evaluations,
                         near_grazing_misses=self.n_near_misses)
        return Trajectory(scene_name=self.scene.name, t0=self.t0, q0=self.scene.q0.copy(),
                          v0=self.scene.v0.copy(), t=stepper.t, q=stepper.q.copy(), v=stepper.v.copy(),
                          events=self.events, segments=self.segments, stats=stats, max_drift=self.max_drift,
                          termination=termination, notes=self.notes, dense=self.options.dense,
                          jacobian=stepper.phi[:, :self.n_state].copy() if self.options.jacobian else None,
                          parameter_jacobian=stepper.phi[:, self.n_state:].copy() if self.jumps else None,
                          parameter_names=tuple(self.options.parameters))

    # -- detection ------------------------------------------------------------------
    def _near_misses(self, misses: list[NearMiss], t_event: float) -> None:
        """Report the near-grazing misses of the last step before ``t_event``.

        A contact came down to ``gap`` (within ``band``) with zero normal speed and
        rose again: no touchdown was found, but the integration error cannot tell
        touching from missing, and the outcome is not continuous there (a touch of
        depth d stops a normal speed of order sqrt(d)). Never silent: a note, or
        `GrazingError` with ``on_grazing="raise"``."""
        for miss in sorted(misses, key=lambda m: m.t):
            if miss.t >= t_event:
                break
            t, i, gap, band = miss.t, miss.contact, miss.gap, miss.band
            message = (f"near-grazing of {self.names[i]} at t = {t:.12g}: its gap came down to {gap:.3g} m "
                       f"(within grazing_gap {band:.3g} m) with zero normal speed and rose again")
            if self.options.on_grazing is OnGrazing.RAISE:
                raise GrazingError(message + "; whether it touches is below the integration error: "
                                   "tighten rtol/atol, or lower grazing_gap to accept the miss")
            self.n_near_misses += 1
            if self.n_near_misses <= MAX_NOTES:
                self.notes.append(message + "; counted as a miss (no touchdown)")

    # -- events ---------------------------------------------------------------------
    def _event(self, t, q, v, mode, fired: list[Guard]):
        dyn = self.dyn
        touching = [g.contact for g in fired if g.kind is GuardKind.GAP]
        releasing = [g.contact for g in fired if g.kind is GuardKind.FORCE]
        if touching:
            # every contact closed at the instant takes part (docs/design.md §2), also one whose
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
        event = Event(t=t, kind=kind, contacts=self._mode_names(releasing), simultaneous=len(releasing) > 1,
                      q=q.copy(), v_minus=v.copy(), v_plus=v.copy(), impulses={},
                      mode_before=self._mode_names(mode), mode_after=self._mode_names(new_mode),
                      sliding=self._sliding_names(new_mode))
        if self.sensitive:
            # guard: the normal force of the first releasing contact; with several at once
            # (a simultaneous lift-off) the saltation is the product of the single
            # lift-offs in turn (each releasing contact's guard in the mode left by the
            # earlier ones): a sticking contact's force jump is not carried by another's guard
            guard = liftoff_guard(dyn, t, q, v, mode, releasing[0])
            xi, xi_p = self._liftoff_sequence(t, q, v, mode, releasing, new_mode, guard)
            h_p = self.jumps.force_guard(q, v, t, mode, releasing[0]) if self.jumps else None
            self._attach_sensitivity(event, xi, *guard, xi_p=xi_p, h_p=h_p)
        self.events.append(event)
        return new_mode, v

    def _liftoff_sequence(self, t, q, v, mode, releasing, new_mode, first_guard):
        """Saltation of the lift-off of ``releasing`` from ``mode``, one contact after the
        other in the given order at the same state (no jump: each force is zero there);
        ``first_guard`` is the first one's `liftoff_guard`. Returns ``(Ξ, Ξ_p)``, the
        parameter block None without parameters."""
        n2 = 2 * self.scene.nv
        xi, current = np.eye(n2), tuple(mode)
        xi_p = np.zeros((n2, self.jumps.p)) if self.jumps else None
        for n, k in enumerate(releasing):
            slide = self.dyn.sliding_key(k) if not self.dyn.is_sliding(k) else None
            after = tuple(new_mode) if n == len(releasing) - 1 else tuple(sorted(
                [i for i in current if i != k] + ([slide] if slide in new_mode else [])))
            Dh, F_minus, h_t = first_guard if n == 0 else liftoff_guard(self.dyn, t, q, v, current, k)
            F_plus = vector_field(self.dyn, q, v, t, after)
            xi_k = saltation(np.eye(n2), Dh, F_minus, F_plus, h_t)
            xi = xi_k @ xi
            if xi_p is not None:
                h_p = self.jumps.force_guard(q, v, t, current, k)
                xi_p = xi_k @ xi_p + ParameterJumps.saltation(None, h_p, None, F_minus, F_plus,
                                                              float(Dh @ F_minus) + h_t)
            current = after
        return xi, xi_p

    def _impact(self, t, q, v_minus, mode, closed, touching, releasing=(), initial=False):
        """Impact of the ``closed`` contacts (keys: a sliding contact takes part with its
        normal row), ``touching`` being those whose guard fired (at the start,
        ``initial``: all closed contacts, with no guard and no grazing)."""
        q = close(self.dyn, q, closed)
        self.kin.update(q, v_minus)
        speeds = {i: float(self.contacts[i].rows(self.kin)[0] @ v_minus) for i in touching}
        grazing = [] if initial else [i for i in touching if abs(speeds[i]) <= self.options.grazing_speed]
        if grazing and self.options.on_grazing is OnGrazing.RAISE:
            raise GrazingError(
                f"grazing touchdown of {', '.join(self.names[i] for i in grazing)} at t = {t:.17g}: "
                f"normal speed {max(abs(speeds[i]) for i in grazing):.3g} m/s <= grazing_speed "
                f"{self.options.grazing_speed:g}; the flow is not differentiable there")
        dyn = self.dyn
        e = np.array([dyn.contact(k).restitution for k in closed])
        zeno = [i for i in touching if self.contacts[i].restitution > 0 and abs(speeds[i]) < self.options.zeno_speed]
        for i in zeno:
            e[closed.index(i)] = 0.0
        impact = resolve_impact(dyn, q, v_minus, closed, e)
        v_plus = impact.v_plus
        scale = max(1.0, float(np.max(np.abs(impact.normal_speeds_before))))
        leaving = set(dyn.contacts_of(releasing))  # a releasing contact leaves whatever its key
        staying = [k for k, s in zip(closed, impact.normal_speeds_after)
                   if s <= SPEED_TOL * scale and dyn.contact_index(k) not in leaving]
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
                    if SPEED_TOL * scale < s < self.options.zeno_speed and dyn.contact_index(k) not in leaving
                    and (dyn.contact_index(k) not in touching or e_k == 0.0)]
        new_mode = choose_mode(dyn, q, v_plus, t, staying + settling)
        settled = [i for i in dyn.contacts_of(settling) if i in dyn.contacts_of(new_mode)]
        nonsmooth = {}  # the cascade rule's cut-off and a grazing touchdown are not smooth
        if settled:
            v_plus = held_velocity(self.dyn, q, v_plus, new_mode)
            nonsmooth[NonSmooth.ZENO_CASCADE] = self._note(
                f"Zeno: impact cascade ended at t = {t:.12g}: {', '.join(self.names[i] for i in settled)} "
                f"kept closed (lifted slower than zeno_speed = {self.options.zeno_speed:g} m/s)")
        # a landing slower than zeno_speed ends its bounces: its own restitution set to
        # zero, or, lifted by the impact law, kept closed by the rule above
        ended = sorted(set(zeno) | {i for i in settled if i in touching and abs(speeds[i]) < self.options.zeno_speed})
        if grazing:
            kind = "grazing"
            nonsmooth[NonSmooth.GRAZING] = self._note(
                f"grazing touchdown of {', '.join(self.names[i] for i in grazing)} at t = {t:.12g}")
        elif ended:
            kind = "zeno"
            self.notes.append(f"Zeno: bounces of {', '.join(self.names[i] for i in ended)} ended at t = {t:.12g} "
                              f"(impact speed below zeno_speed = {self.options.zeno_speed:g} m/s); contact kept closed")
        elif any(i in dyn.contacts_of(new_mode) for i in touching):
            kind = "touchdown"
        else:
            kind = "bounce"
        impulses = {self.names[dyn.contact_index(k)]: float(x) for k, x in zip(closed, impact.impulses)}
        event = Event(t=t, kind=kind, contacts=self._mode_names(touching), simultaneous=len(touching) > 1,
                      q=q.copy(), v_minus=v_minus.copy(), v_plus=v_plus.copy(), impulses=impulses,
                      mode_before=self._mode_names(mode), mode_after=self._mode_names(new_mode),
                      normal_speeds={self.names[i]: s for i, s in speeds.items()},
                      sliding=self._sliding_names(new_mode), nonsmooth=nonsmooth)
        def reset_jacobian():
            DR = impact_reset_jacobian(self.dyn, q, v_minus, impact)
            if settled:  # the reset is the impact followed by holding the settled contacts
                DR = held_velocity_jacobian(self.dyn, q, v_plus, new_mode) @ DR
            return DR

        def reset_parameters():
            live = [k for k in closed if dyn.contact_index(k) not in zeno]
            R_p = self.jumps.impact(q, v_minus, impact, live)
            if settled:
                R_p = held_velocity_jacobian(self.dyn, q, v_plus, new_mode) @ R_p
            return R_p

        if self.sensitive and initial:
            # no guard at t0: perturbations keep the start time, only the reset acts
            event.saltation = reset_jacobian()
            if self.options.jacobian:
                event.time_gradient = np.zeros(2 * self.scene.nv)
            if self.jumps:
                event.parameter_saltation = reset_parameters()
                event.parameter_time_gradient = np.zeros(self.jumps.p)
        elif self.sensitive:
            F_minus = vector_field(self.dyn, q, v_minus, t, mode)
            guard = min(touching, key=lambda i: speeds[i])
            Dh = gap_gradient(self.dyn, q, guard)
            if len(touching) > 1:
                override = {i: e[closed.index(i)] for i in closed}
                sim = simultaneous_saltation(self.dyn, t, q, v_minus, mode, touching, override)
                xi = sim.matrix
                if self.jumps:  # the simultaneous reset plus one guard term per contact
                    xi_p = reset_parameters()
                    for k, (jump, rate) in sim.corrections.items():
                        xi_p += np.outer(jump, self.jumps.gap_guard(k)) / rate
                event.saltation_orders = {tuple(self.names[i] for i in k): m for k, m in sim.orders.items()}
                if not sim.differentiable:
                    event.nonsmooth[NonSmooth.ORDER] = self._note(
                        f"not differentiable at t = {t:.12g}: the landing orders of "
                        f"{', '.join(self.names[i] for i in touching)} give saltation matrices "
                        f"differing by {sim.spread:.2e} (relative)")
            else:
                DR = reset_jacobian()
                F_plus = vector_field(self.dyn, q, v_plus, t, new_mode)
                xi = saltation(DR, Dh, F_minus, F_plus)
                if self.jumps:
                    xi_p = ParameterJumps.saltation(reset_parameters(), self.jumps.gap_guard(guard), DR, F_minus,
                                                    F_plus, float(Dh @ F_minus))
            h_p = self.jumps.gap_guard(guard) if self.jumps else None
            self._attach_sensitivity(event, xi, Dh, F_minus, xi_p=xi_p if self.jumps else None, h_p=h_p)
        self.events.append(event)
        return new_mode, v_plus

    def _attach_sensitivity(self, event: Event, xi: np.ndarray, Dh: np.ndarray, F_minus: np.ndarray,
                            h_t: float = 0.0, xi_p: np.ndarray | None = None, h_p: np.ndarray | None = None) -> None:
        """Saltation matrix and event-time gradient ``-Dh Φ- / (Dh F- + h_t)`` (implicit
        functions; ``h_t`` the guard's explicit time rate); with parameters also their
        block ``xi_p`` and time gradient ``-(Dh Φ-_p + h_p) / (Dh F- + h_t)``."""
        n = self.n_state
        rate = float(Dh @ F_minus) + h_t
        event.saltation = xi
        if self.options.jacobian:
            event.time_gradient = -(Dh @ self.phi[:, :n]) / rate
        if self.jumps is not None:
            event.parameter_saltation = xi_p
            event.parameter_time_gradient = -(Dh @ self.phi[:, n:] + h_p) / rate

    def _note(self, text: str) -> str:
        """Add a note to the run's notes; return it (for an event's ``nonsmooth``)."""
        self.notes.append(text)
        return text

    # -- constraint manifold ----------------------------------------------------------
    def _project(self, stepper, mode, gaps) -> bool:
        """Project the stepper's state back onto the manifold of ``mode`` when its gap
        drift exceeds ``project_tol``; whether it did."""
        drift = max(abs(gaps[i]) for i in self.dyn.contacts_of(mode))
        self.max_drift = max(self.max_drift, drift)
        if drift <= self.options.resolved_project_tol:
            return False
        q, v, D = project_state(self.dyn, stepper.q, stepper.v, mode, jacobian=self.sensitive)
        phi = None if D is None else D @ stepper.phi
        if self.jumps is not None:
            phi[:, self.n_state:] += self.jumps.projection(q, mode)
        stepper.restart(stepper.t, q, v, phi=phi)
        self.n_projections += 1
        return True
