"""``method="auto"`` in a run: the chooser (`contactdiff.ode.method_choice.MethodChooser`),
its probes of a mode's stiffness, and the switches from one stepper to another."""

from __future__ import annotations

from ..ode.factory import make_stepper
from ..ode.method_choice import EXPLICIT, MethodChooser, field_probe


class AutoMethod:
    """The method chooser of one run and what it did.

    Args:
        dyn: the run's `ModeDynamics` (the probes solve the mode with it).
        group: the configuration's Lie group (`contactdiff.ode.factory.PinocchioGroup`).
        notes: the run's notes (a switch adds one, the first ``max_notes`` of them).
        max_notes: how many switches are noted.

    Attributes:
        chooser: the `MethodChooser`, made at the run's start (`start`).
        retired: the steppers a switch replaced (for the run's statistics).
        switches: ``(t, method)`` of every switch.
        n_probe_evaluations: the probes' mode solves (they bypass the mode fields' counters).
    """

    def __init__(self, dyn, group, notes: list[str], max_notes: int):
        self.dyn, self.group, self.notes, self.max_notes = dyn, group, notes, max_notes
        self.chooser: MethodChooser | None = None
        self.retired: list = []
        self.switches: list[tuple[float, str]] = []
        self.n_probe_evaluations = 0

    def probe(self, mode):
        """``ρ`` of ``mode`` at a state, for the chooser (difference quotients of the mode's
        accelerations)."""

        def accel(t, q, v):
            self.n_probe_evaluations += 1
            return self.dyn.solve(q, v, t, mode).ddq

        return field_probe(accel, self.group)

    def start(self, mode) -> None:
        """The chooser, probing ``mode`` first."""
        self.chooser = MethodChooser(self.probe(mode))

    def switch(self, stepper, method: str, field, sensitive: bool, stepper_options: dict):
        """A stepper of ``method`` that continues from ``stepper``'s current point: a restart
        without a jump (state and flow Jacobian carried over, the step size as a first guess)."""
        assert self.chooser is not None  # only a started chooser asks for a switch
        self.retired.append(stepper)
        self.switches.append((stepper.t, method))
        if len(self.switches) <= self.max_notes:
            why = "explicit steps limited by stability" if method != EXPLICIT else "steps resolve the fastest motion"
            self.notes.append(
                f"method auto: {method} from t = {stepper.t:.12g} ({why}: "
                f"h = {stepper.h_abs:.3g} s, spectral radius {self.chooser.rho:.3g} /s)"
            )
        return make_stepper(
            method,
            field.accel,
            self.group,
            stepper.t,
            stepper.q,
            stepper.v,
            jac=field.jac,
            first_step=stepper.h_abs,
            variational=stepper.phi if sensitive else None,
            **stepper_options,
        )
