"""The hybrid loop: flow in a mode, locate the earliest event, reset, continue.

`simulate` integrates a `Scene` event by event:

1. In mode ``J`` the stepper (`contactdiff.ode`) integrates the KKT flow of
   `contactdiff.dynamics.mode`.
2. After every accepted step each guard of the mode is checked over the step:
   the gap of every inactive contact (downward through 0, including a dip
   below 0 and back within the step, found from the cubic Hermite interpolant
   of the end-point gaps and gap rates and confirmed on the dense output) and
   the normal force of every active contact (downward through 0); a contact the
   mode holds at zero gap has its compatible load watched instead of its gap
   (`contactdiff.integration.held`).
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
6. A run at rest (an equilibrium of an autonomous scene's mode, stable, with no guard
   near) steps to ``t_final`` in one step of its linearised flow
   (`contactdiff.integration.rest`).

With ``method="auto"`` the stepper is DOP853 while its steps are limited by
accuracy and Radau IIA while they would be limited by stability
(`contactdiff.ode.method_choice`); a switch restarts the stepper at the current point
(no jump; the flow Jacobian carries over).

Admissibility: a penetrating initial state is an error; closed contacts at the
start select a consistent mode (with an impact first if they approach);
grazing touchdowns (normal speed below ``grazing_speed``) are events of kind
``grazing`` (or an error with ``on_grazing="raise"``), and so are, as notes,
near-grazing misses (a gap turning back up within ``grazing_gap`` of 0, where
the integration error cannot tell a touch from a miss); a bounce slower than
``zeno_speed`` ends the bounce sequence (the contact stays closed, event kind
``zeno``); more than ``max_events`` events raise `TooManyEventsError`, more
than ``max_steps`` steps `TooManyStepsError` (early, as `StepBudgetError`, when steady
steps project far more than the budget: `contactdiff.ode.step_budget`), and steps
that collapse by orders of magnitude with no event `StepCollapseError`
(`contactdiff.ode.step_collapse`).

`HybridLoop` is the loop itself, public and meant to be extended: a subclass
may override `HybridLoop.initial_mode` (the consistent start) and
`HybridLoop.on_event` (called after every event; returning True makes the event
terminal: the run ends just after it, with ``Termination.STOPPED``). The stride
map (`contactdiff.analysis.gait.stride`) is such a subclass. The options of a
run are one `SimulateOptions`.
"""

from __future__ import annotations

from typing import Any

from ..errors import InvalidInputError
from ..model.scene import Scene, StateInput
from .hybrid_loop import GAP_TOL, HybridLoop
from .loop_reports import MAX_NOTES
from .options import SimulateOptions
from .trajectory import Trajectory

__all__ = ["GAP_TOL", "MAX_NOTES", "HybridLoop", "simulate"]  # the loop's and its constants' former path


def simulate(
    scene: Scene,
    t_final: float,
    q0: StateInput | None = None,
    v0: StateInput | None = None,
    *,
    t0: float = 0.0,
    options: SimulateOptions | None = None,
    **option_values: Any,
) -> Trajectory:
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
            ``max_step``, ``sample_times``, ``progress``); see there for units and defaults.

    Returns:
        The `Trajectory`.

    Raises:
        InvalidInputError: a bad argument (the message names it and its valid range,
            or lists the valid option names).
        TooManyEventsError, TooManyStepsError: a budget ran out (the run so far
            is on the error's ``.trajectory``).
        StepCollapseError: the steps collapsed with no event in sight (a singular
            vector field); the run so far is on its ``.trajectory``.
        IntegrationError: the stepper cannot go on (step size underflow).
    """
    options = SimulateOptions() if options is None else options
    if not isinstance(options, SimulateOptions):
        raise InvalidInputError(f"simulate: options must be a SimulateOptions, got {options!r}")
    if option_values:
        options = options.replace(**option_values)
    return HybridLoop(scene, t0, t_final, q0, v0, options).run()
