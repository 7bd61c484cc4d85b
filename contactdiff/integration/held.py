"""Contacts held at zero gap by a mode, and the event where one bears again; slips
held at zero by a mode, and the event where one sticks again.

A contact outside the mode whose gap is closed and whose rows add no rank to the
mode's (a face's corner released when its compatible load asked it to pull, while
three others hold the face: `contactdiff.dynamics.redundant`) keeps a gap and a gap
speed of exactly zero for as long as the mode lasts. It has no gap guard: its gap
is the others' drift, and round-off of it (a few 1e-17 m) would otherwise close it
as a grazing landing. It is watched instead by the principle that released it: its
guard is the load it would carry in the *enlarged* set (the mode and it, solved by
the compatible-load rule), fired as that load turns from pulling to pushing. There
it **bears** (event kind ``bear``): a re-touch at zero speed, no impulse, the mode
with it added (Coulomb's law settled again over the enlarged set).

Its saltation matrix: the reset is the identity and the guard ``h = -λ_N`` of the
held contact in the enlarged set, so ``Ξ = I + (F+ - F-) Dh / (Dh F- + h_t)`` with
``Dh`` the gradient of that load (its derivatives by the mode's own derivative
solve, through the slip directions of sliding rows) and ``h_t`` its explicit time
rate under time-dependent efforts. Where the enlarged set's forces with the held
load at zero are the mode's (the rows of the mode independent: three corners of a
face) the field does not jump and ``Ξ = I`` up to round-off; the event time's
derivative is what moves the flow Jacobian's later columns.

Cost: one mode solve per held contact at each guard evaluation (each accepted
step's end, and the crossing search of a step that crossed); none when no contact
is held.

**Slips held at zero.** A contact that slips from rest in a mode whose other rows fix
its motion (a face's corner whose sticking force left its cone while two or three
other corners stick: its sticking rows add no rank to the mode's) keeps a slip of
exactly zero (round-off) for as long as the mode lasts, so its stop guard never fires
(`GuardFinder.keep_resting`) and it would slide on, its friction saturated, after the
push that started it is gone. It is watched instead by the principle that made it
slip (`settle_friction`: a contact at rest slips where its sticking force leaves the
cone): its guard is ``||λ_T|| - μ λ_N`` of the force it would carry sticking, in the
mode with it sticking (`held_slips`, `grip_value`), fired as that force comes back
inside the cone. There it sticks (event kind ``stick``): no jump of the state (its
slip is zero), the mode with it sticking and Coulomb's law settled again. Its
saltation matrix is ``Ξ = I + (F+ - F-) Dh / (Dh F- + h_t)`` with ``Dh``, ``h_t`` the
guard's (`grip_guard`, the cone margin's of `contactdiff.integration.friction_events.cone_guard`
with its sign turned); where the mode's rows fix the whole motion ``F+ = F-`` and
``Ξ = I``, and the event time's gradient is the guard's. Cost: one mode solve per such
slip at each guard evaluation; a rank test per slipping contact at each mode's start.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Protocol

import numpy as np

from ..dynamics.mode import ModeDynamics
from ..dynamics.redundant import row_rank
from ..errors import PainleveError, SolverError
from .friction_events import THRESHOLD_TOL, cone_guard, settle_friction
from .loop_events import LoopEvents
from .parameter_jumps import ParameterJumps
from .projection import mode_rows
from .sensitivity import liftoff_guard, saltation, vector_field
from .trajectory import EventKind, NonSmooth


def held_contacts(
    dyn: ModeDynamics,
    q: np.ndarray,
    v: np.ndarray,
    t: float,
    mode: tuple[int, ...],
    gaps: np.ndarray,
    rates: np.ndarray,
    gap_tol: float,
    speed_tol: float,
    from_rest: list | None = None,
) -> tuple[dict[int, int], dict[int, np.ndarray]]:
    """The contacts ``mode`` holds at zero gap, each with its key in the enlarged set, and
    the slip references set on ``dyn`` to find them.

    Args:
        dyn: the scene's `ModeDynamics` (its kinematics cache is moved to ``(q, v)``;
            slip references are set on ``dyn.slip_reference``: the second value returned).
        q: configuration (nq,).
        v: velocity (nv,), tangent space.
        t: time (s), for time-dependent efforts.
        mode: the contact keys of the mode.
        gaps: gap (m) of every scene contact at ``q``.
        rates: gap rate (m/s) of every scene contact at ``(q, v)``.
        gap_tol: m, a gap below it is closed (the loop passes the drift its projection
            allows: a held contact's gap is a combination of the others').
        speed_tol: m/s, a gap rate within it is zero, and a slip faster than it makes a
            Coulomb contact's key sliding.
        from_rest: if given, gets ``(scene index, mode, enlarged)`` for each held contact at
            rest that Coulomb's law makes slide in its enlarged set: ``mode`` the set whose
            sticking force set its reference (`settle_friction`), ``enlarged`` the settled
            set it bears with (`HeldEvents._held_onsets` carries its reference's angle).

    Returns:
        ``(held, references)``. ``held``, ``{scene index: key}``: the contacts whose rows
        (sticking, or sliding along its slip for a Coulomb contact slipping faster than
        ``speed_tol``) add no rank to the mode's, each with its key as Coulomb's law
        settles the enlarged set ``mode + (key,)`` (`settle_friction`: a held contact at
        rest whose sticking force there would leave its cone bears sliding; the guard
        then watches the load it would bear with). One whose enlarged set has no solution
        is left out, as is a contact without Coulomb friction that slips (its sticking
        rows would add a constraint): both keep their gap guard. ``references``,
        ``{scene index: unit vector}``: every slip reference set on
        ``dyn.slip_reference`` on the way (the last value where set twice): a held
        contact's own slip, and those Coulomb's law sets settling each enlarged set,
        which can be a contact of ``mode`` itself that sticks in ``mode`` but slips in an
        enlarged set (its entry overwritten).
    """
    references: dict[int, np.ndarray] = {}
    if not mode:
        return {}, references
    active = dyn.contacts_of(mode)
    closed = [
        i for i, (g, r) in enumerate(zip(gaps, rates)) if i not in active and g <= gap_tol and abs(r) <= speed_tol
    ]
    if not closed:
        return {}, references
    dyn.kin.update(q, v)
    A = mode_rows(dyn, mode)
    rank = row_rank(A)
    held = {}
    for i in closed:
        contact = dyn.contact(i)
        slip = contact.rows(dyn.kin)[1:] @ v
        key = i
        if len(slip) and np.max(np.abs(slip)) > speed_tol:
            if not contact.spec.coulomb:
                continue
            dyn.slip_reference[i] = references[i] = slip / np.linalg.norm(slip)
            key = dyn.sliding_key(i)
        if row_rank(np.vstack([A, dyn.contact(key).rows(dyn.kin)])) != rank:
            continue
        found: list = []
        try:  # its key as Coulomb's law settles the enlarged set, the one it would bear with
            settled, _ = settle_friction(dyn, q, v, t, enlarged(mode, key), found, references)
        except (PainleveError, SolverError):
            continue
        held[i] = next(k for k in settled if dyn.contact_index(k) == i)
        if from_rest is not None:
            from_rest.extend((index, rows, settled) for index, rows in found if index == i)
    return held, references


def held_slips(dyn: ModeDynamics, q: np.ndarray, mode) -> list[int]:
    """The slipping keys of ``mode`` whose slip the mode holds at zero (module doc): their
    contact's sticking rows add no rank to the mode's rows at ``q`` (``dyn.kin`` is moved to
    ``q`` at rest)."""
    slipping = [k for k in mode if dyn.is_sliding(k)]
    if not slipping:
        return []
    dyn.kin.update(q, np.zeros(dyn.model.nv))
    A = mode_rows(dyn, mode)
    rank = row_rank(A)
    return [k for k in slipping if row_rank(np.vstack([A, dyn.contact(dyn.contact_index(k)).rows(dyn.kin)])) == rank]


def gripped(dyn: ModeDynamics, mode, key: int) -> tuple[int, ...]:
    """The mode ``mode`` with slipping key ``key`` sticking (sorted keys)."""
    return tuple(sorted(dyn.contact_index(k) if k == key else k for k in mode))


def grip_value(dyn: ModeDynamics, q: np.ndarray, v: np.ndarray, t: float, mode, key: int) -> float:
    """The guard ``||λ_T|| - μ λ_N`` (N) of held slip ``key`` of ``mode`` at ``(q, v, t)``
    (module doc): its sticking force in the mode with it sticking, positive while that force
    lies outside the cone; +inf where that mode has no solution."""
    stuck = gripped(dyn, mode, key)
    index = dyn.contact_index(key)
    try:
        sol = dyn.solve(q, v, t, stuck)
    except (PainleveError, SolverError):
        return np.inf
    f = sol.forces[sol.row_slices[stuck.index(index)]]
    return float(np.linalg.norm(f[1:])) - dyn.contact(index).spec.mu * float(f[0])


def grip_guard(dyn: ModeDynamics, t: float, q: np.ndarray, v: np.ndarray, mode, key: int):
    """The guard of held slip ``key`` of ``mode`` (`grip_value`): ``(Dh, h_t, solved)``, its
    gradient (2nv,), its explicit time rate (N/s) and `cone_guard`'s ``solved`` in the mode
    with it sticking (for the parameters' block)."""
    Dh, _, h_t, solved, _ = cone_guard(dyn, t, q, v, gripped(dyn, mode, key), dyn.contact_index(key))
    return -Dh, -h_t, solved


def enlarged(mode, key: int) -> tuple[int, ...]:
    """The mode ``mode`` with the held contact key ``key`` added (sorted keys)."""
    return tuple(sorted((*mode, key)))


def bear_value(dyn: ModeDynamics, q: np.ndarray, v: np.ndarray, t: float, mode, key: int) -> float:
    """The bearing guard's value ``-λ_N`` (N) of held key ``key`` of ``mode`` at
    ``(q, v, t)``: minus its normal force in the enlarged set, positive while it would
    pull; +inf where that set has no solution (a sliding set Painlevé refuses), where
    it cannot bear."""
    full = enlarged(mode, key)
    try:
        sol = dyn.solve(q, v, t, full)
    except (PainleveError, SolverError):
        return np.inf
    return -float(sol.forces[sol.row_slices[full.index(key)].start])


def bear_guard(dyn: ModeDynamics, t: float, q: np.ndarray, v: np.ndarray, mode, key: int) -> tuple[np.ndarray, float]:
    """The bearing guard ``h = -λ_N`` of held key ``key`` of ``mode`` (module doc):
    ``(Dh, h_t)``, its gradient (2nv,) and its explicit time rate (N/s)."""
    Dh, _, h_t = liftoff_guard(dyn, t, q, v, enlarged(mode, key), key)
    return -Dh, -h_t


class HoldingField(Protocol):
    """What the bearing event reads of a mode's field (`contactdiff.integration.mode_field.ModeField`,
    which evaluates the bearing guards with `bear_value`): the contacts it holds."""

    held: dict[int, int]
    """``{scene index: key}`` of the held contacts (`held_contacts`)."""


class HeldEvents(LoopEvents):
    """The loop's ``bear`` events (module doc); a mixin of
    `contactdiff.integration.hybrid.HybridLoop` (its state as for
    `contactdiff.integration.event_resets`; ``fields[-1]`` is the mode's field)."""

    if TYPE_CHECKING:  # besides the state of every event mixin (LoopEvents)
        fields: Sequence[HoldingField]  # the loop's ModeField objects
        initial_saltation: np.ndarray | None

    def _held_onsets(self, t, q, v, mode, found: list, start: bool) -> None:
        """Carry the references of the held contacts at rest that `held_contacts` set at the
        start of ``mode`` (``found``: its ``from_rest`` entries) as onsets' angles
        (`FrictionEvents._onset_columns`): their ``w = ∂θ/∂`` of the flow Jacobian's columns,
        from the state at ``(t, q, v)`` (after the last event, or the start's) moved with the
        event's time, ``Ξ φ + Ξ_p + F+ ∂t`` (``∂t`` the event's time gradient; zero at the
        start, whose time is fixed). The reference acts once the contact bears with it (its
        load in the enlarged set, the bearing guard, moves with ``θ`` by a force proportional
        to that load: zero where it fires)."""
        n_cols = self.jacobians.identity().shape[1]
        dt = np.zeros(n_cols)
        if start:
            phi = self.initial_saltation if self.initial_saltation is not None else self.jacobians.identity()
        else:
            event = self.events[-1]
            if event.saltation is None or self.phi is None:
                return  # not differentiable there: the run's Jacobian ends (its note says so)
            phi = self.jacobians.after(self.phi, event)
            n = self.n_state
            if event.time_gradient is not None:
                dt[:n] = event.time_gradient
            if event.parameter_time_gradient is not None:
                dt[n:] = event.parameter_time_gradient
        moved = phi + np.outer(vector_field(self.dyn, q, v, t, mode), dt)
        for index, rows, settled in found:
            self._onset_columns(t, q, [(index, rows, v)], moved, dt, settled)

    def _bear_event(self, t, q, v, mode, bearing: list[int]):
        """The held contacts ``bearing`` (scene indices) join ``mode`` at ``(t, q, v)``: no
        jump; the mode after them settled by Coulomb's law. With several at once the
        saltation is that of the first one's guard (their loads turn positive together)."""
        dyn, mode = self.dyn, tuple(mode)
        held = self.fields[-1].held
        keys = [held[i] for i in bearing]
        new_mode, _ = settle_friction(dyn, q, v, t, tuple(sorted((*mode, *keys))))
        event = self._impulseless_event(t, EventKind.BEAR, keys, len(keys) > 1, q, v, v, mode, new_mode)
        if self.sensitive:
            Dh, h_t = bear_guard(dyn, t, q, v, mode, keys[0])
            F_minus, F_plus = vector_field(dyn, q, v, t, mode), vector_field(dyn, q, v, t, new_mode)
            xi = saltation(np.eye(2 * self.scene.nv), Dh, F_minus, F_plus, h_t)
            h_p = xi_p = None
            if self.jumps:
                h_p = -self.jumps.force_guard(q, v, t, enlarged(mode, keys[0]), keys[0])
                xi_p = ParameterJumps.saltation(None, h_p, None, F_minus, F_plus, float(Dh @ F_minus) + h_t)
            self._attach_sensitivity(event, xi, Dh, F_minus, h_t, xi_p=xi_p, h_p=h_p)
        self.events.append(event)
        return new_mode, v

    def _grip_event(self, t, q, v, mode, gripping: list[int]):
        """The held slips ``gripping`` (sliding keys of ``mode``) stick at ``(t, q, v)``: no
        jump (their slip is zero); the mode after them settled by Coulomb's law (module doc).
        With several at once the saltation is that of the first one's guard."""
        dyn, mode = self.dyn, tuple(mode)
        stuck = mode
        for key in gripping:
            stuck = gripped(dyn, stuck, key)
        new_mode, _ = settle_friction(dyn, q, v, t, stuck)
        event = self._impulseless_event(t, EventKind.STICK, gripping, len(gripping) > 1, q, v, v, mode, new_mode)
        Dh, h_t, (sol, der, rows, w) = grip_guard(dyn, t, q, v, mode, gripping[0])
        F_minus = vector_field(dyn, q, v, t, mode)
        rate = float(Dh @ F_minus) + h_t
        cone = dyn.contact(gripping[0]).spec.mu * float(sol.forces[rows.start])
        if abs(rate) <= THRESHOLD_TOL * max(abs(cone), 1e-300):  # touches the cone from outside
            event.nonsmooth[NonSmooth.FRICTION_THRESHOLD] = self._note(
                f"not differentiable at t = {t:.12g}: the sticking force of {', '.join(event.contacts)} "
                f"touches the friction cone without entering it (guard rate {rate:.3g} N/s)"
            )
        if self.sensitive:
            F_plus = vector_field(dyn, q, v, t, new_mode)
            xi = saltation(np.eye(2 * self.scene.nv), Dh, F_minus, F_plus, h_t)
            h_p = xi_p = None
            if self.jumps:
                forces = self.jumps.forces
                h_p = -(w @ der.forces_dtau[rows] @ forces.mode_forces(dyn, sol, q, v, t))
                # the cone's own size: ∂(μ λ_N)/∂μ = λ_N at fixed forces
                h_p[forces.friction_columns.get(dyn.contact_index(gripping[0]), [])] -= sol.forces[rows.start]
                xi_p = ParameterJumps.saltation(None, h_p, None, F_minus, F_plus, rate)
            self._attach_sensitivity(event, xi, Dh, F_minus, h_t, xi_p=xi_p, h_p=h_p)
        self.events.append(event)
        return new_mode, v
