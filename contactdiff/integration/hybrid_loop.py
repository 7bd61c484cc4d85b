"""`HybridLoop`: the hybrid loop of one run (`contactdiff.integration.hybrid` describes it).

Its construction (the run's state), the hooks a subclass overrides (`HybridLoop.initial_mode`,
`HybridLoop.on_event`), the consistent start, the stepping with its guards and events, and
the projection onto a mode's constraints. What it records and reports (the `Trajectory`,
its statistics, the errors carrying the run so far, the notes of near misses) is
`contactdiff.integration.loop_reports`; ``method="auto"``'s chooser and switches,
`contactdiff.integration.auto_method`; what it does at an event, the event mixins
(`contactdiff.integration.loop_events`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..dynamics.impacts import choose_mode
from ..dynamics.mode import ModeDynamics
from ..errors import (
    InvalidInputError,
    PainleveError,
    StepSizeUnderflowError,
    TooManyEventsError,
    TooManyStepsError,
    check_number,
)
from ..model.scene import Scene, StateInput
from ..ode.crossings import simultaneous_group
from ..ode.dense import DenseOutput
from ..ode.factory import PinocchioGroup, make_stepper
from ..ode.method_choice import EXPLICIT
from ..ode.step_budget import BudgetWatch
from ..ode.step_collapse import CollapseWatch
from ..scenes.scene_file import passive_note
from .auto_method import AutoMethod
from .band import BandEvents
from .event_jacobians import EventJacobians
from .event_resets import EventResets
from .final_time import final_touches
from .friction_events import FrictionEvents, refuse_ambiguous_slip, settle_friction
from .guards import GuardFinder
from .held import HeldEvents, held_contacts, held_slips
from .jam import jam_or_raise
from .loop_reports import MAX_NOTES, LoopReports
from .mode_field import ModeField
from .options import AUTO, JacobianError, SimulateOptions
from .parameter_jumps import ParameterJumps
from .projection import held_velocity, project_state
from .rest import RestCheck
from .samples import SampleRecorder, check_sample_times
from .trajectory import Event, NonSmooth, Segment, Termination, Trajectory

GAP_TOL = 1e-12
"""m: a contact whose gap is below this is closed."""


class HybridLoop(EventResets, FrictionEvents, HeldEvents, BandEvents):
    """The hybrid loop of one run (described in `contactdiff.integration.hybrid`); `simulate` is
    ``HybridLoop(...).run()``.

    Args:
        scene: the `Scene`.
        t0: start time (s).
        t_final: final time (s).
        q0: initial configuration (an array or a joint-name mapping); None: the scene's.
        v0: initial velocity (an array or a joint-name mapping); None: the scene's.
        options: the `SimulateOptions`.

    Extension: override `initial_mode` and `on_event` (see there). The state a
    subclass may read: ``scene``, ``dyn`` (its `ModeDynamics`), ``kin`` (the
    scene's kinematics cache), ``contacts``, ``names``, ``options``, ``events``,
    ``segments``, ``notes``, ``t0``, ``jumps`` (the parameters' blocks at events, or
    None), and ``phi``, the flow Jacobian just before the event being processed (with
    ``options.jacobian`` or ``options.parameters``: its columns are the state's
    ``n_state``, 2nv with ``jacobian`` else 0, then the parameters'). It may set
    ``initial_saltation``, the flow Jacobian just after the start's events (from
    `initial_mode`). What it may call: `gaps_and_rates` (every contact's gap and gap
    rate at a state) and `jacobian_after` (the flow Jacobian just after an event, from
    the one before it or from the start's).
    """

    def __init__(
        self,
        scene: Scene,
        t0: float,
        t_final: float,
        q0: StateInput | None = None,
        v0: StateInput | None = None,
        options: SimulateOptions | None = None,
    ):
        if not isinstance(scene, Scene):
            raise InvalidInputError(f"scene must be a Scene (see load_scene), got {scene!r}")
        self.options = SimulateOptions() if options is None else options
        self.t0 = check_number("simulate", "t0", t0)
        self.t_final = check_number("simulate", "t_final", t_final)
        if not self.t_final > self.t0:
            raise InvalidInputError(f"simulate: t_final must be after t0 = {self.t0}, got {t_final!r}")
        self.scene = scene.with_state(q0, v0) if (q0 is not None or v0 is not None) else scene
        # a slip slower than zeno_speed is integration noise in direction (contactdiff.dynamics.slip)
        self.dyn = ModeDynamics(self.scene, slip_speed_floor=self.options.zeno_speed)
        self.kin = self.scene.kinematics
        self.contacts = self.scene.contacts
        self.names = self.scene.contact_names
        self.gap_tol = GAP_TOL
        self.guards = GuardFinder(self.scene, self.dyn, self.options, GAP_TOL)
        self.group = PinocchioGroup(self.scene.model)
        self.events: list[Event] = []
        self.segments: list[Segment] = []
        self.notes: list[str] = [note] if (note := passive_note(self.scene)) else []
        self.fields: list[ModeField] = []  # one per mode visited, for the statistics
        self.auto = AutoMethod(self.dyn, self.group, self.notes, MAX_NOTES)  # method="auto"'s chooser, if started
        self.phi = None  # flow Jacobian just before the event being processed
        self.initial_saltation = None
        self.jumps = None  # the parameters' blocks at events, with options.parameters
        # the slips from rest that follow the reference set at the last event: scene index ->
        # ∂θ/∂ of phi's columns (`ModeField`; set by `FrictionEvents`; an event keeps those in the band, `BandEvents`)
        self.onsets: dict[int, np.ndarray] = {}
        self.band_dt = None  # ∂t/∂ of the columns through an onset's θ, at an event in the band (`BandEvents`)
        # phi's columns: the state's 2nv (with options.jacobian), then the parameters'
        self.sensitive = self.options.jacobian or bool(self.options.parameters)
        self.n_state = 2 * self.scene.nv if self.options.jacobian else 0
        if self.options.parameters:
            from ..model.parameters import resolve  # the model's names import the dynamics' scene

            self.jumps = ParameterJumps(self.dyn, resolve(self.scene, self.options.parameters))
        self.jacobians = EventJacobians(self.scene.nv, self.n_state, self.jumps.p if self.jumps else 0)
        check_sample_times(self.options.sample_times, self.t0, self.t_final)
        self.recorder = SampleRecorder(self.options.sample_times, self.n_state, self.options.parameters)
        # what the run reports: its trajectory, the errors carrying it, the near-grazing misses
        self.reports = LoopReports(
            self.scene,
            self.t0,
            self.t_final,
            self.options,
            self.n_state,
            self.jumps,
            self.recorder,
            self.events,
            self.segments,
            self.notes,
            self.fields,
            self.auto,
            mode_names=self._mode_names,
        )

    def _fused(self, method: str) -> bool:
        """Whether the field differentiates the mode at every evaluation (`ModeField`): with
        derivatives, under an explicit method whose attempts use them. Radau evaluates the field
        at Newton iterates, and under ``jacobian_error="state"`` a rejected attempt's derivatives
        are never read: there the accepted stages are differentiated when the Jacobian is
        propagated (one more solve each, against the derivatives of every rejected attempt)."""
        return self.sensitive and method != "Radau" and self.options.jacobian_error is JacobianError.CONTROL

    def _field(self, mode, fused: bool, t: float, q, v) -> ModeField:
        """The field of ``mode`` from ``(t, q, v)``, watching the contacts it holds at zero gap
        (a gap within the drift the projection allows: a held contact's gap is the others')."""
        held: dict[int, int] = {}
        found: list = []  # held contacts at rest that slide in their enlarged set
        if mode:
            gaps, rates = self.gaps_and_rates(q, v)
            # it also sets slip references on self.dyn (its second value, kept there): the held
            # contacts' slips, which their bearing guards read, and the directions Coulomb's law
            # gives the mode's own sticking contacts in the enlarged sets
            held, _ = held_contacts(
                self.dyn,
                q,
                v,
                t,
                tuple(mode),
                gaps,
                rates,
                max(self.gap_tol, self.options.resolved_project_tol),
                self.options.grazing_speed,
                found if self.sensitive else None,
            )
            if found:  # their references' angles, carried as onsets' (`HeldEvents._held_onsets`)
                self._held_onsets(t, q, v, tuple(mode), found, start=not self.fields)
        return ModeField(
            self.dyn,
            mode,
            fused=fused,
            parameters=self.jumps.forces if self.jumps else None,
            held=held,
            onsets=self.onsets,
            held_slips=held_slips(self.dyn, q, tuple(mode)) if mode else None,
        )

    # -- hooks ----------------------------------------------------------------------
    def on_event(self, event: Event, mode_before: tuple[int, ...], phi_before: np.ndarray | None) -> bool:
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

    def jacobian_after(self, event: Event, phi: np.ndarray | None = None) -> np.ndarray:
        """The flow Jacobian just after ``event`` (its saltation attached) from ``phi`` just
        before it; None: the start's, ``[I, 0]`` (2nv × (2nv + p), as ``phi``'s columns)."""
        return self.jacobians.after(self.jacobians.identity() if phi is None else phi, event)

    # -- small evaluations ------------------------------------------------------------
    def gaps_and_rates(self, q, v) -> tuple[np.ndarray, np.ndarray]:
        """Every contact's gap (m) and gap rate (m/s) at ``(q, v)``, in the scene's order
        (the kinematics cache is moved to ``(q, v)``)."""
        self.kin.update(q, v)
        gaps = np.array([c.gap(self.kin) for c in self.contacts])
        rates = np.array([c.gap_rate(self.kin) for c in self.contacts])
        return gaps, rates

    def _mode_names(self, mode) -> tuple[str, ...]:
        """Names of the contacts active (sticking or sliding) in ``mode``."""
        return tuple(self.names[i] for i in sorted(self.dyn.contacts_of(mode)))

    def _sliding_names(self, mode) -> tuple[str, ...]:
        return tuple(self.names[i] for i in sorted(self.dyn.contact_index(k) for k in mode if self.dyn.is_sliding(k)))

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
        gaps, rates = self.gaps_and_rates(q, v)
        closed = [i for i, g in enumerate(gaps) if g <= self.gap_tol]
        if not closed:
            return (), v
        self.kin.update(q, v)
        slips = {i: self.contacts[i].rows(self.kin)[1:] @ v for i in closed if self.contacts[i].n_rows > 1}
        slips = {i: u for i, u in slips.items() if np.max(np.abs(u)) > self.options.grazing_speed}
        # a sliding contact with Coulomb friction slips on; with infinite friction an impact stops it
        sliding = [i for i in slips if not self.contacts[i].spec.coulomb]
        if any(rates[i] < -self.options.grazing_speed for i in closed) or sliding:
            if self.sensitive:
                self.phi = self.jacobians.identity()
            mode, v_plus = self._impact(self.t0, q, v, (), closed, closed, initial=True)
            if self.sensitive:
                self.initial_saltation = self.jacobians.after(self.jacobians.identity(), self.events[-1])
            return mode, v_plus
        candidates = [i for i in closed if rates[i] <= self.options.grazing_speed]
        for i in set(slips) & set(candidates):
            self.dyn.slip_reference[i] = slips[i] / np.linalg.norm(slips[i])
            candidates[candidates.index(i)] = self.dyn.sliding_key(i)
        mode = choose_mode(self.dyn, q, v, self.t0, candidates)
        refuse_ambiguous_slip(self.dyn, q, v, self.t0, candidates, mode)
        if any(self.contacts[self.dyn.contact_index(k)].spec.coulomb for k in mode):
            from_rest: list = []
            mode, _ = settle_friction(self.dyn, q, v, self.t0, mode, from_rest)
            if self.sensitive and from_rest:  # no guard at t0: the start's own perturbations
                start = self.jacobians.identity()
                self._onset_columns(
                    self.t0, q, [(i, m, v) for i, m in from_rest], start, np.zeros(start.shape[1]), mode
                )
        return mode, held_velocity(self.dyn, q, v, mode)

    # -- the loop -------------------------------------------------------------------
    def _stepper_options(self, field: ModeField) -> dict:
        o = self.options
        options: dict[str, Any] = dict(
            rtol=o.rtol,
            atol=o.atol,
            max_step=o.max_step,
            t_bound=self.t_final,
            variational_error_control=o.jacobian_error is JacobianError.CONTROL,
        )
        if self.sensitive:  # the parameters' forcing, and a slip onset's (`ModeField`)
            options.update(parameter_jac=field.parameter_jac)
        if self.jumps is not None:
            options.update(variational_column_scale=np.concatenate([np.ones(self.n_state), self.jumps.scale]))
        return options

    def run(self) -> Trajectory:
        """Integrate to ``t_final`` (or to a terminal event) and return the `Trajectory`."""
        options, scene = self.options, self.scene
        q, v = scene.q0.copy(), scene.v0.copy()
        mode, v = self.initial_mode(q, v)
        field = self._field(mode, self._fused(options.method), self.t0, q, v)
        if options.method == AUTO:
            self.auto.start(mode)
        stepper = make_stepper(
            EXPLICIT if options.method == AUTO else options.method,
            field.accel,
            self.group,
            self.t0,
            q,
            v,
            jac=field.jac,
            variational=self.jacobians.identity() if self.sensitive else None,
            **self._stepper_options(field),
        )
        if self.sensitive and self.initial_saltation is not None:
            stepper.restart(self.t0, q, v, phi=self.initial_saltation)
        self.fields.append(field)
        self.recorder.take(stepper)
        segment = Segment(t0=self.t0, t1=self.t0, mode=self._mode_names(mode), sliding=self._sliding_names(mode))
        self.segments.append(segment)
        gaps, rates = self.gaps_and_rates(stepper.q, stepper.v)
        forces = field.guard_values(stepper.t, stepper.q, stepper.v)
        steps = 0
        h = 0.0  # the last accepted step (s)
        watch, budget, rest = CollapseWatch(), BudgetWatch(options.max_steps), RestCheck(self)
        next_break = -np.inf  # the efforts' next breakpoint: a time a step must end on
        while stepper.t < self.t_final:
            if steps == options.max_steps:
                raise TooManyStepsError(
                    f"max_steps = {options.max_steps} steps taken by t = {stepper.t:.6g} s of "
                    f"t_final = {self.t_final:g} s (last step {h:.3g} s); "
                    "raise max_steps, or look for a runaway state",
                    self.reports.trajectory(stepper, Termination.MAX_STEPS),
                )
            if stepper.t >= next_break:
                next_break = scene.next_breakpoint(stepper.t)
            # steps end on breakpoints and sample times; also for a stepper new since the last step
            stepper.t_bound = min(self.t_final, next_break, self.recorder.next_time)
            jam = None
            try:
                stepper.step()
            except StepSizeUnderflowError as exc:  # the extreme of a collapse: said as one, with the run so far
                self.reports.collapse(stepper, mode, exc.h, watch.typical, underflow=str(exc))
            except PainleveError as exc:  # a slip that jams stops here (`contactdiff.integration.jam`)
                jam = jam_or_raise(self.dyn, stepper, mode, watch.typical, exc)
            if jam is None:
                steps += 1
                if options.progress is not None:
                    options.progress(stepper.t, len(self.events), steps)
                h = stepper.t - stepper.t_old
                dense: DenseOutput | None = stepper.dense(lazy=True)  # DOP853's extra stages only if a guard needs them
                gaps1, rates1 = self.gaps_and_rates(stepper.q, stepper.v)
                forces1 = field.guard_values(stepper.t, stepper.q, stepper.v)
                try:
                    crossings, misses = self.guards.crossings(
                        stepper, dense, field, mode, (gaps, rates, forces), (gaps1, rates1, forces1)
                    )
                except PainleveError as exc:  # the dense output's extra stages cross a jam
                    jam = jam_or_raise(self.dyn, stepper, mode, watch.typical, exc, step_back=True)
                else:
                    self.guards.keep_resting(field, forces1)  # the slips from rest still at rest
                    if options.dense:
                        segment.pieces.append(dense)
            if jam is not None:  # at the last accepted state: no step to cut back
                crossings, misses, dense = [(stepper.t, jam.guard)], [], None
            if not crossings:
                self.reports.near_misses(misses, np.inf)
                gaps, rates, forces = gaps1, rates1, forces1
                projected = mode and self._project(stepper, mode, gaps1)
                if projected:
                    gaps, rates = self.gaps_and_rates(stepper.q, stepper.v)
                if field.slipping:
                    field.advance(stepper.q, stepper.v)
                if projected or field.slipping:
                    forces = field.guard_values(stepper.t, stepper.q, stepper.v)
                segment.t1 = stepper.t
                self.recorder.take(stepper)
                clipped = stepper.t == stepper.t_bound
                if watch.after_step(h, clipped):
                    self.reports.collapse(stepper, mode, h, watch.typical)
                if projection := budget.after_step(h, clipped, self.t_final - stepper.t, steps):
                    self.reports.over_budget(stepper, mode, steps, *projection)
                # at rest: to t_final in one step, or to the next sample time (steps end on them)
                if rest.settle(stepper, field, mode, segment, min(self.t_final, self.recorder.next_time)):
                    self.recorder.take(stepper)
                chooser = self.auto.chooser
                if chooser is not None and stepper.t < self.t_final:
                    if switch := chooser.after_step(h, stepper.q, stepper.v, stepper.t):
                        field.fused = self._fused(switch)  # Radau's Newton iterates want no derivative
                        stepper = self.auto.switch(stepper, switch, field, self.sensitive, self._stepper_options(field))
                        budget.new_regime()
                continue
            watch.new_mode()
            budget.new_regime()
            t_event, fired = simultaneous_group(crossings, options.simultaneous_tol)
            self.reports.near_misses(misses, t_event)
            if dense is not None:
                stepper.truncate(t_event)
                dense.t = t_event
            segment.t1 = t_event
            self.phi = stepper.phi
            n_before, mode_before = len(self.events), tuple(mode)
            band = self._band_onsets(field, stepper.q, stepper.v)
            exact = not band or self._band_guard(band, t_event, stepper.q, stepper.v, mode, fired)
            mode, v_plus = self._event(t_event, stepper.q, stepper.v, mode, fired)
            correction = None
            if band:
                exact = exact and len(self.events) == n_before + 1
                q_after = self.events[-1].q
                correction = self._band_after(band, t_event, q_after, stepper.v, mode_before, mode, v_plus, exact)
                if correction is not None:  # recorded on the event, which `jacobians.after` applies
                    last = self.events[-1]
                    if self.options.jacobian:
                        last.reference_jump = correction[:, : self.n_state]
                    if self.jumps is not None:
                        last.parameter_reference_jump = correction[:, self.n_state :]
            self.guards.restart_from_rest(mode_before, mode, fired)
            if len(self.events) > options.max_events:
                raise TooManyEventsError(
                    f"more than max_events = {options.max_events} events by t = {t_event:.17g} "
                    f"(last: {self.events[-1].kind} of {', '.join(self.events[-1].contacts)}); "
                    "raise max_events or zeno_speed",
                    self.reports.trajectory(stepper, Termination.MAX_EVENTS),
                )
            if jam is not None:
                self.events[n_before].nonsmooth[NonSmooth.PAINLEVE_JAM] = self._note(jam.remark(self.names))
            phi_before = None if self.phi is None else self.phi.copy()
            stop = False
            for event in self.events[n_before:]:
                stop = self.on_event(event, mode_before, phi_before) or stop
            q_event = self.events[-1].q
            field = self._field(mode, self._fused(stepper.method), t_event, q_event, v_plus)
            self.fields.append(field)
            stepper.restart(
                t_event,
                q_event,
                v_plus,
                accel=field.accel,
                jac=field.jac,
                parameter_jac=field.parameter_jac if self.sensitive else None,
                phi=None if self.events[-1].saltation is None else self.jacobians.after(stepper.phi, self.events[-1]),
            )
            if self.auto.chooser is not None:
                self.auto.chooser.new_mode(self.auto.probe(mode))
            segment = Segment(t0=t_event, t1=t_event, mode=self._mode_names(mode), sliding=self._sliding_names(mode))
            self.segments.append(segment)
            self.recorder.take(stepper)  # a sample at the event's time: after it
            gaps, rates = self.gaps_and_rates(stepper.q, stepper.v)
            forces = field.guard_values(stepper.t, stepper.q, stepper.v)
            if stop:
                return self.reports.trajectory(stepper, Termination.STOPPED)
        traj = self.reports.trajectory(stepper, Termination.T_FINAL)
        if touches := final_touches(
            self.names,
            *self.gaps_and_rates(traj.q, traj.v),
            set(self.dyn.contacts_of(mode)),
            self.events,
            traj.t,
            options,
        ):
            traj.final_nonsmooth[NonSmooth.FINAL_TIME] = "; ".join(touches)
            self.notes.extend(touches)
        return traj

    # -- constraint manifold ----------------------------------------------------------
    def _project(self, stepper, mode, gaps) -> bool:
        """Project the stepper's state back onto the manifold of ``mode`` when its gap
        drift exceeds ``project_tol``; whether it did."""
        drift = max(abs(gaps[i]) for i in self.dyn.contacts_of(mode))
        self.reports.max_drift = max(self.reports.max_drift, drift)
        if drift <= self.options.resolved_project_tol:
            return False
        q, v, D = project_state(self.dyn, stepper.q, stepper.v, mode, jacobian=self.sensitive)
        phi = None if D is None else D @ stepper.phi
        if self.jumps is not None:
            assert phi is not None  # a run with parameters is sensitive: D is computed
            phi[:, self.n_state :] += self.jumps.projection(q, mode)
        stepper.restart(stepper.t, q, v, phi=phi)
        self.reports.n_projections += 1
        return True
