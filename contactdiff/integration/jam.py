"""A slip that jams: a slip's stop on the boundary of Painlevé's paradox.

A contact slipping with Coulomb friction whose own block
``g = A_n M^-1 (A_n - μ s^T A_T)^T`` (`contactdiff.dynamics.slip`) falls to zero while
its normal force pushes meets a *dynamic jam* (Génot and Brogliato, "New results on
Painlevé paradoxes", Eur. J. Mech. A/Solids 18, 1999): the normal force ``λ_N = b / g``
grows without bound, and so does the friction that decelerates the slip; the impulse
``∫ λ_N dt`` of ``g`` falling linearly to zero would be infinite, so the slip stops no
later than ``g`` reaches zero. The motion cannot go on sliding into ``g < 0`` (there the
sliding problem has no solution or two). In 3-D ``g`` depends on the slip direction
``s``, which turns fast as the slip slows (the anisotropic stop, docs/results/bench.md,
"The cause"), so a slip can reach ``g = 0`` by turning into a direction of the paradox
in its last microseconds.

No step follows the slip to its stop: the normal force there is unbounded, the steps
shrink to round-off, and the stepper raises `PainleveError` naming the contact. Where
that contact slips in the mode, pushes, and its slip speed falls fast enough to end
within a collapsed step (`jammed_slip`), the loop ends the slip at the last
accepted state: a slip → stick event of that contact, whose reset removes the slip left
M-orthogonally (the reset of every stop, `contactdiff.integration.friction_events`), and
the mode after it is chosen as at any stop. Elsewhere the error stands: Painlevé's
paradox proper has no continuation in a rigid model.

The jam's time is that of the last accepted step, within the time the slip had left at
its deceleration there; the event carries `NonSmooth.PAINLEVE_JAM` with those numbers:
its saltation is that of a stop at that state, not a derivative through the jam.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import OutsideDomainError, PainleveError
from ..ode.step_collapse import COLLAPSE_RATIO
from .friction_events import stop_guard
from .guards import Guard, GuardKind


@dataclass(frozen=True)
class Jam:
    """A slip that jams: its stop guard, its contact's scene index, the time it had left at
    its deceleration (s) and its speed (m/s) at the last accepted state."""

    guard: Guard
    index: int
    time_left: float
    speed: float

    def remark(self, names) -> str:
        """What the event's `NonSmooth.PAINLEVE_JAM` says (``names``: the scene's contact names)."""
        return (
            f"the slip of {names[self.index]} jammed (Painlevé: its normal force grew "
            f"without bound as it stopped); stopped {self.time_left:.3g} s early at a speed of "
            f"{self.speed:.3g} m/s, which the reset removed"
        )


def jammed_slip(dyn, t: float, q: np.ndarray, v: np.ndarray, mode, typical: float, exc: PainleveError) -> Jam | None:
    """The `Jam` of the slip that jams at the accepted state ``(t, q, v)`` of ``mode``
    (contact keys), or None where ``exc`` (raised by a step from that state) is not a jam
    (module doc).

    ``typical``: the run's typical step (s, `contactdiff.ode.step_collapse.CollapseWatch`).
    The slip jams where the time it has left at its deceleration is shorter than a
    collapsed step (`COLLAPSE_RATIO` of ``typical``): its stop is then within the time the
    run resolves, and the impulse the reset applies is the rest of the jam's, which a
    normal force growing without bound delivers in that time. A slip the stepper cannot
    follow with more time left is not stopping: Painlevé's paradox itself.
    """
    index = exc.contact
    if index is None or dyn.sliding_key(index) not in mode:
        return None
    key = dyn.sliding_key(index)
    try:
        sol = dyn.solve(q, v, t, mode)
    except OutsideDomainError:
        return None
    normal = float(sol.normal_forces()[list(mode).index(key)])
    rate = float(stop_guard(dyn, q, v, key) @ np.concatenate([v, sol.ddq]))  # updates dyn.kin at (q, v)
    speed = float(np.linalg.norm(dyn.contact(key).full.rows(dyn.kin)[1:] @ v))
    if normal <= 0.0 or rate >= 0.0:
        return None
    time_left = speed / -rate
    if time_left > COLLAPSE_RATIO * typical:
        return None
    return Jam(Guard(GuardKind.STOP, key), index, time_left, speed)


def jam_or_raise(dyn, stepper, mode, typical: float, exc: PainleveError, step_back: bool = False) -> Jam:
    """The `Jam` of the slip that ``exc`` met from the stepper's state (`jammed_slip`);
    ``exc`` itself, raised, where it is not a jam. ``step_back``: ``exc`` came from the
    dense output of the step just accepted (its extra stages crossed the jam, so the step
    went past it, and there is no interpolant to cut it back with): the stepper goes back
    to the step's start first."""
    if step_back:
        stepper.restart(stepper.t_old, stepper.q_old, stepper.v_old, phi=stepper.phi_old)
    jam = jammed_slip(dyn, stepper.t, stepper.q, stepper.v, mode, typical, exc)
    if jam is None:
        raise exc
    return jam
