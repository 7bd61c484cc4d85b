"""What the hybrid loop reports of its run: the `Trajectory` with its statistics, the errors
that end a run with the run so far on them (`StepCollapseError`, `StepBudgetError`), and the
near-grazing misses (a note each, or `GrazingError`).

`LoopReports` is a mixin of `contactdiff.integration.hybrid_loop.HybridLoop`: it reads the
loop's state, declared below for the type checker (it exists at run time through
`HybridLoop` only).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..errors import GrazingError, StepBudgetError, StepCollapseError
from ..ode.step_budget import budget_message
from ..ode.step_collapse import COLLAPSE_RATIO, COLLAPSE_STEPS
from .guards import NearMiss
from .options import OnGrazing
from .trajectory import RunStats, Termination, Trajectory

if TYPE_CHECKING:
    from ..model.scene import Scene
    from ..ode.method_choice import MethodChooser
    from .mode_field import ModeField
    from .options import SimulateOptions
    from .parameter_jumps import ParameterJumps
    from .samples import SampleRecorder
    from .trajectory import Event, Segment

MAX_NOTES = 10
"""Notes written for the first method switches of ``method="auto"`` and the first
near-grazing misses (all are counted in the statistics)."""


class LoopReports:
    """The loop's records and reports (module doc)."""

    if TYPE_CHECKING:  # the state it reads of HybridLoop (set there), for the type checker only
        scene: Scene
        t0: float
        t_final: float
        options: SimulateOptions
        names: list[str]
        events: list[Event]
        segments: list[Segment]
        notes: list[str]
        fields: list[ModeField]
        retired: list
        switches: list[tuple[float, str]]
        chooser: MethodChooser | None
        max_drift: float
        n_projections: int
        n_near_misses: int
        n_probe_evaluations: int
        n_state: int
        jumps: ParameterJumps | None
        recorder: SampleRecorder

        def _mode_names(self, mode) -> tuple[str, ...]: ...

    def _collapse(self, stepper, mode, h: float, typical: float, underflow: str | None = None):
        """Raise `StepCollapseError` (`contactdiff.ode.step_collapse`) at the stepper's
        point; ``underflow``: the stepper's own underflow message, where the steps shrank to
        the resolution of time before the count of short steps was reached."""
        names = self._mode_names(mode)
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
            self._trajectory(stepper, Termination.STEP_COLLAPSE),
            stepper.t,
            names,
            h,
        )

    def _over_budget(self, stepper, mode, steps: int, needed: float, reference: float):
        """Raise `StepBudgetError` (`contactdiff.ode.step_budget`) at the stepper's point."""
        names = self._mode_names(mode)
        raise StepBudgetError(
            budget_message(self.options.max_steps, self.t_final, stepper.t, names, steps, needed, reference),
            self._trajectory(stepper, Termination.MAX_STEPS),
            stepper.t,
            names,
            reference,
            needed,
        )

    def _trajectory(self, stepper, termination: Termination) -> Trajectory:
        steppers = self.retired + [stepper]
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
            method_switches=[[t, m] for t, m in self.switches],
            stiffness_probes=self.chooser.n_probes if self.chooser else 0,
            probe_evaluations=self.n_probe_evaluations,
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
