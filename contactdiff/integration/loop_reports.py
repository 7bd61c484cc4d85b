"""What the hybrid loop reports of its run: the `Trajectory` with its statistics, the errors
that end a run with the run so far on them (`StepCollapseError`, `StepBudgetError`), and the
near-grazing misses (a note each, or `GrazingError`).

`LoopReports` is an object the loop (`contactdiff.integration.hybrid_loop.HybridLoop`) holds
as ``reports``, given its inputs explicitly: the run's description, the record lists the loop
appends to, and two functions of the loop's state (a mode's names, the stiffness probes run).
It keeps the run's counts that the loop adds to (drift, projections, probe evaluations) and
counts the near-grazing misses itself.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

from ..errors import GrazingError, StepBudgetError, StepCollapseError
from ..ode.step_budget import budget_message
from ..ode.step_collapse import COLLAPSE_RATIO, COLLAPSE_STEPS
from .guards import NearMiss
from .options import OnGrazing
from .trajectory import RunStats, Termination, Trajectory

if TYPE_CHECKING:
    from ..model.scene import Scene
    from .auto_method import AutoMethod
    from .mode_field import ModeField
    from .options import SimulateOptions
    from .parameter_jumps import ParameterJumps
    from .samples import SampleRecorder
    from .trajectory import Event, Segment

MAX_NOTES = 10
"""Notes written for the first method switches of ``method="auto"`` and the first
near-grazing misses (all are counted in the statistics)."""


class LoopReports:
    """The loop's records and reports (module doc).

    Args:
        scene: the run's `Scene` (its name, start state and model).
        t0: start time (s).
        t_final: final time (s).
        options: the run's `SimulateOptions`.
        n_state: the flow Jacobian's state columns (2nv with ``options.jacobian``, else 0).
        jumps: the parameters' blocks at events (`ParameterJumps`), or None.
        recorder: the run's `SampleRecorder`.
        events: the run's events, a list the loop appends to (the same object).
        segments: its segments, likewise.
        notes: its notes, likewise (the near-grazing misses add theirs).
        fields: the mode fields of the modes visited, likewise (their evaluation counts).
        auto: ``method="auto"``'s chooser and what it did (`AutoMethod`: the steppers it
            replaced, its switches, its probes and their mode solves).
        mode_names: the names of a mode's active contacts (a mode: its contact keys).

    Attributes:
        max_drift: largest active-gap drift found (m; the loop raises it).
        n_projections: projections onto the constraint manifold (the loop counts them).
        n_near_misses: near-grazing misses (`near_misses` counts them).
    """

    def __init__(
        self,
        scene: Scene,
        t0: float,
        t_final: float,
        options: SimulateOptions,
        n_state: int,
        jumps: ParameterJumps | None,
        recorder: SampleRecorder,
        events: list[Event],
        segments: list[Segment],
        notes: list[str],
        fields: list[ModeField],
        auto: AutoMethod,
        mode_names: Callable[[tuple[int, ...]], tuple[str, ...]],
    ):
        self.scene, self.t0, self.t_final, self.options = scene, t0, t_final, options
        self.names = scene.contact_names
        self.n_state, self.jumps, self.recorder = n_state, jumps, recorder
        self.events, self.segments, self.notes, self.fields = events, segments, notes, fields
        self.auto, self.mode_names = auto, mode_names
        self.max_drift = 0.0
        self.n_projections = 0
        self.n_near_misses = 0

    def collapse(self, stepper, mode, h: float, typical: float, underflow: str | None = None):
        """Raise `StepCollapseError` (`contactdiff.ode.step_collapse`) at the stepper's
        point; ``underflow``: the stepper's own underflow message, where the steps shrank to
        the resolution of time before the count of short steps was reached."""
        names = self.mode_names(mode)
        how = (
            f"the step shrank to the resolution of time ({underflow})"
            if underflow
            else f"{COLLAPSE_STEPS} steps in a row shorter than {COLLAPSE_RATIO:g} of the run's typical step "
            f"(~{typical:.3g} s), the last {h:.3g} s"
        )
        raise StepCollapseError(
            f"step size collapsed at t = {stepper.t:.12g} s in mode ({', '.join(names) or 'free flight'}): "
            f"{how}, with no event; the vector field is singular or nearly "
            "so here (a mechanism reaching a singular pose with its contacts held, e.g. a leg folded flat, "
            "or a force that blows up in finite time)",
            self.trajectory(stepper, Termination.STEP_COLLAPSE),
            stepper.t,
            names,
            h,
        )

    def over_budget(self, stepper, mode, steps: int, needed: float, reference: float):
        """Raise `StepBudgetError` (`contactdiff.ode.step_budget`) at the stepper's point."""
        names = self.mode_names(mode)
        raise StepBudgetError(
            budget_message(self.options.max_steps, self.t_final, stepper.t, names, steps, needed, reference),
            self.trajectory(stepper, Termination.MAX_STEPS),
            stepper.t,
            names,
            reference,
            needed,
        )

    def trajectory(self, stepper, termination: Termination) -> Trajectory:
        """The run so far as a `Trajectory` ending at the stepper's point, with ``termination``
        and the run's statistics (every stepper's and mode field's counts)."""
        steppers = self.auto.retired + [stepper]
        by_method: dict[str, int] = {}
        for st in steppers:
            by_method[st.method] = by_method.get(st.method, 0) + st.n_steps
        stats = RunStats(
            steps=sum(st.n_steps for st in steppers),
            rejected_steps=sum(st.n_rejected for st in steppers),
            dynamics_evaluations=sum(f.n_solve for f in self.fields),
            stepper_evaluations=sum(st.n_accel for st in steppers),
            jacobian_evaluations=sum(st.n_jac for st in steppers),
            derivative_evaluations=sum(f.n_derivatives for f in self.fields),
            events=len(self.events),
            projections=self.n_projections,
            method=self.options.method,
            steps_by_method=by_method,
            method_switches=[[t, m] for t, m in self.auto.switches],
            stiffness_probes=self.auto.chooser.n_probes if self.auto.chooser else 0,
            probe_evaluations=self.auto.n_probe_evaluations,
            near_grazing_misses=self.n_near_misses,
        )
        return Trajectory(
            scene_name=self.scene.name,
            t0=self.t0,
            q0=self.scene.q0.copy(),
            v0=self.scene.v0.copy(),
            t=stepper.t,
            q=stepper.q.copy(),
            v=stepper.v.copy(),
            events=self.events,
            segments=self.segments,
            stats=stats,
            max_drift=self.max_drift,
            termination=termination,
            notes=self.notes,
            dense=self.options.dense,
            jacobian=stepper.phi[:, : self.n_state].copy() if self.options.jacobian else None,
            parameter_jacobian=stepper.phi[:, self.n_state :].copy() if self.jumps else None,
            parameter_names=tuple(self.options.parameters),
            samples=self.recorder.samples(self.scene.model.nq, self.scene.nv),
        )

    # -- detection ------------------------------------------------------------------
    def near_misses(self, misses: list[NearMiss], t_event: float) -> None:
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
            message = (
                f"near-grazing of {self.names[i]} at t = {t:.12g}: its gap came down to {gap:.3g} m "
                f"(within grazing_gap {band:.3g} m) with zero normal speed and rose again"
            )
            if self.options.on_grazing is OnGrazing.RAISE:
                raise GrazingError(
                    message + "; whether it touches is below the integration error: "
                    "tighten rtol/atol, or lower grazing_gap to accept the miss"
                )
            self.n_near_misses += 1
            if self.n_near_misses <= MAX_NOTES:
                self.notes.append(message + "; counted as a miss (no touchdown)")
