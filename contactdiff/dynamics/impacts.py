"""Impacts and the choice of the next contact mode.

Impact law (Newton restitution per contact, with complementarity): all contacts
closed at the instant take part; the impulses ``Λ`` (N s) solve the contact
complementarity problem of `contactdiff.dynamics.complementarity` with ``v+ = v- + M^-1 A^T Λ`` and
post-impact normal velocities ``w_k = A_k v+ + e_k A_k v- >= 0``,
``Λ_k w_k = 0``. Tangential rows of sticking contacts stop the tangential
velocity (plastic); restitution acts on normal rows only.

Mode choice (force-level complementarity): among the closed contacts whose
normal velocity is zero, the next mode is the active set ``S`` of the
acceleration-level problem: contacts in ``S`` have normal force >= 0 and zero
row acceleration, the others a non-negative normal acceleration.

Sliding: with sticking rows the mode choice may have no solution (holding a
contact's tangents would need a pulling normal force, releasing it lets it
sink: a Painleve-type inconsistency of infinite friction). Coulomb friction
carries no tangential force at zero normal force, so the fewest sticking
contacts needed are then made to *slide*: they keep their normal row only
(keys of `contactdiff.dynamics.mode`), and frictionless rows always have a
solution. A sliding contact stays sliding until its normal force vanishes
(the integrator's ``slip`` event makes the same choice at a lift-off).

Impacts keep the infinite-friction limit where sticking has no solution
(`solve_contact_lcp`'s ``on_infeasible="relax"``): the contact's slip is
stopped by a tangential impulse with no normal one, which may lift it. Sliding
there instead would leave its slip speed (measured up to 0.56 m/s on ANYmal's
trot) to persist, frictionless, through its whole stance.
Contacts are given as keys throughout (see `contactdiff.dynamics.mode`).

Coulomb friction: when a closed contact has a finite coefficient ``μ``, the
impact is the frictional law of `contactdiff.dynamics.frictional_impact`
(Newton restitution on the normal rows, Coulomb's cone on the tangential
impulse, maximal dissipation on the post-impact slip) over every closed
contact, each with all its rows (a slipping one too); each contact ends open,
sticking or sliding (``ImpactResult.states``).
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ..errors import PainleveError, SolverError
from .complementarity import ContactRows, impact_rhs, solve_contact_lcp
from .frictional_impact import ContactState, solve_frictional_impact
from .mode import ModeDynamics


@dataclass
class ImpactResult:
    """Outcome of one impact.

    Attributes:
        v_plus: post-impact velocity (nv,).
        impulses: normal impulse of each participating contact (N s), in ``contacts`` order.
        row_impulses: impulses of all rows (normal and tangential).
        contacts: keys of the participating (closed) contacts.
        normal_speeds_before, normal_speeds_after: ``A_n v-`` and ``A_n v+`` per contact (m/s).
        restitution: the coefficient used for each contact (0 where Zeno ended a bounce
            or where the contact was not approaching).
        active: positions in ``contacts`` of the contacts whose rows carry impulse
            (the complementarity problem's active set).
        tangential_only: positions in ``contacts`` of the sticking contacts in the
            relaxed infinite-friction state: tangential impulse only, slip stopped,
            normal impulse zero (module doc).
        rows: the row layout of ``contacts`` (`ContactRows`).
        states: with Coulomb friction, the `ContactState` of each contact (None
            otherwise); ``contacts`` then holds every contact with all its rows.
        slide_directions: with Coulomb friction, each sliding contact's unit slip
            direction (tangent coordinates; zeros otherwise).
        friction: with Coulomb friction, each contact's coefficient (inf sticking, 0
            frictionless).
    """

    v_plus: np.ndarray
    impulses: np.ndarray
    row_impulses: np.ndarray
    contacts: tuple[int, ...]
    normal_speeds_before: np.ndarray
    normal_speeds_after: np.ndarray
    restitution: np.ndarray
    active: tuple[int, ...] = ()
    rows: ContactRows | None = None
    tangential_only: tuple[int, ...] = ()
    states: tuple[ContactState, ...] | None = None
    slide_directions: tuple[np.ndarray, ...] = ()
    friction: np.ndarray | None = None


def _rows(dyn: ModeDynamics, contacts: Sequence[int]):
    """Stacked rows of ``contacts`` at the kinematics' current state, and their layout."""
    bound = [dyn.contact(k) for k in contacts]
    A = np.vstack([c.rows(dyn.kin) for c in bound])
    return A, ContactRows.from_sizes([c.n_rows for c in bound])


def _solve_sliding_where_needed(
    dyn: ModeDynamics, keys: tuple[int, ...], G: np.ndarray, b: np.ndarray, rows: ContactRows
):
    """Solve the contact problem of ``keys``; if no sticking solution exists, with
    the fewest sticking contacts sliding (module doc).

    Returns:
        ``(solution, keys)``: the solution (on the kept rows: a sliding contact's
        normal row only) and the keys with the sliding contacts' keys substituted.
    """
    try:
        return solve_contact_lcp(G, b, rows), keys
    except SolverError:
        pass
    sticking = [k for k in range(len(keys)) if len(rows.tangential[k])]
    for size in range(1, len(sticking) + 1):
        for group in itertools.combinations(sticking, size):
            kept = np.concatenate(
                [rows.rows_of([k])[:1] if k in group else rows.rows_of([k]) for k in range(len(keys))]
            )
            sub = ContactRows.from_sizes([1 if k in group else 1 + len(rows.tangential[k]) for k in range(len(keys))])
            try:
                solution = solve_contact_lcp(G[np.ix_(kept, kept)], b[kept], sub)
            except SolverError:
                continue
            slid = tuple(dyn.sliding_key(dyn.contact_index(key)) if k in group else key for k, key in enumerate(keys))
            return solution, slid
    raise SolverError(
        f"no solution for contacts {keys}, even with every sticking one sliding "
        f"(Delassus matrix {G.tolist()}, b {b.tolist()})"
    )


def resolve_impact(
    dyn: ModeDynamics,
    q: np.ndarray,
    v_minus: np.ndarray,
    contacts: Sequence[int],
    restitution: Sequence[float] | None = None,
) -> ImpactResult:
    """Apply the impact law at configuration ``q`` to the closed ``contacts``.

    Args:
        dyn: the scene's `ModeDynamics` (its kinematics cache is reused).
        q: configuration at the impact.
        v_minus: velocity just before (nv,).
        contacts: keys of the closed contacts (all take part; a sliding contact
            with its normal row only).
        restitution: coefficient per contact overriding the scene's (e.g. 0 to end a
            Zeno sequence); ``None`` uses each contact's own.
    """
    contacts = tuple(contacts)
    dyn.kin.update(q, v_minus)
    coulomb = any(dyn.contact(k).spec.coulomb for k in contacts)
    if coulomb:  # every contact takes part with all its rows (module doc)
        contacts = tuple(dyn.contact_index(k) if dyn.contact(k).spec.coulomb else k for k in contacts)
    A, rows = _rows(dyn, contacts)
    e = (
        np.array([dyn.contact(k).restitution for k in contacts])
        if restitution is None
        else np.array(restitution, dtype=float)
    )
    MinvAT = pin.computeMinverse(dyn.model, dyn.data, q) @ A.T
    Av = A @ v_minus
    G = A @ MinvAT
    normal = list(rows.normal)
    if coulomb:
        mu = np.array([dyn.contact(k).mu for k in contacts])
        solution = solve_frictional_impact(0.5 * (G + G.T), Av, rows, e, mu)
        v_plus = v_minus + MinvAT @ solution.impulses
        active = tuple(k for k, state in enumerate(solution.states) if state is not ContactState.OPEN)
        return ImpactResult(
            v_plus,
            solution.impulses[normal].copy(),
            solution.impulses,
            contacts,
            Av[normal],
            (A @ v_plus)[normal],
            solution.restitution,
            active,
            rows,
            (),
            solution.states,
            solution.slide_directions,
            mu,
        )
    # Restitution restores compression only: a closed contact that is not approaching
    # takes part plastically (with its own e, Newton's law could add energy).
    e[Av[normal] >= 0.0] = 0.0
    lcp = solve_contact_lcp(G, impact_rhs(Av, e, rows), rows, on_infeasible="relax")
    v_plus = v_minus + MinvAT @ lcp.x
    return ImpactResult(
        v_plus,
        lcp.x[normal].copy(),
        lcp.x,
        contacts,
        Av[normal],
        (A @ v_plus)[normal],
        e,
        lcp.active,
        rows,
        lcp.tangential_only,
    )


def choose_mode(
    dyn: ModeDynamics, q: np.ndarray, v: np.ndarray, t: float, candidates: Sequence[int]
) -> tuple[int, ...]:
    """Active set among the closed, non-separating ``candidates`` (acceleration-level LCP).

    Args:
        dyn: the scene's `ModeDynamics` (its kinematics cache is moved to ``(q, v)``).
        q: configuration (nq,).
        v: velocity (nv,), tangent space.
        t: time (s), for time-dependent efforts.
        candidates: keys of the contacts that may stay active; a sticking key may be
            turned into its sliding key when no sticking solution exists (module doc).

    Returns:
        Sorted keys of the contacts that stay active (normal force >= 0).
    """
    candidates = tuple(sorted(candidates))
    if not candidates:
        return ()
    a_free = dyn.solve(q, v, t, ()).ddq  # also updates the kinematics at (q, v)
    A, rows = _rows(dyn, candidates)
    drift = np.concatenate([dyn.contact(k).drift(dyn.kin) for k in candidates])
    G = A @ pin.computeMinverse(dyn.model, dyn.data, q) @ A.T
    solution, keys = _solve_sliding_where_needed(dyn, candidates, G, A @ a_free + drift, rows)
    return tuple(sorted(keys[k] for k in solution.active))


#: A normal force above -PULL_SHARE of a mode's largest is round-off, not a pull.
PULL_SHARE = 1e-9

#: A released contact accelerating downwards by less than this share of |gravity|
#: (round-off of the mode solve) is not sinking.
ACCEL_TOL = 1e-9


def _sliding_set(dyn: ModeDynamics, q, v, t, staying) -> tuple[int, ...] | None:
    """``staying`` (sorted) where one of them slides with Coulomb friction and the set's
    own solve, its friction included, pushes at every contact (none below `PULL_SHARE`
    of the largest force); None otherwise. `choose_mode`'s problem holds a sliding
    contact's normal row alone, without its friction: a sliding face whose friction
    moment loads its trailing corners (a couple tipping a cube forward onto the corner
    behind it) looked to it like a face that lets them go."""
    if not any(dyn.is_sliding(k) for k in staying):
        return None
    mode = tuple(sorted(staying))
    try:
        normal = dyn.solve(q, v, t, mode).normal_forces()
    except (PainleveError, SolverError):
        return None
    return mode if normal.min() >= -PULL_SHARE * max(float(normal.max()), 0.0) else None


def liftoff_mode(
    dyn: ModeDynamics,
    q: np.ndarray,
    v: np.ndarray,
    t: float,
    mode: Sequence[int],
    releasing: Sequence[int],
    resting: Sequence[int] = (),
) -> tuple[int, ...]:
    """The mode after the normal forces of ``releasing`` (keys of ``mode``) reach zero.

    The releasing contacts leave, unless a sticking one would then sink: at zero
    normal speed its normal acceleration in the new mode is negative beyond
    round-off, because the tangential force it carried pressed it down. That one
    slides instead (module doc): its normal row stays, its tangents go.
    ``resting`` (keys) are closed contacts outside ``mode`` at zero normal speed (a
    face's corner released earlier, held at zero gap by the releasing contacts):
    they are candidates of the new mode with the staying ones, so that one the
    release would let sink bears at once instead of being caught below the ground.
    """
    staying = [k for k in mode if k not in releasing] + list(resting)
    new_mode = _sliding_set(dyn, q, v, t, staying) or choose_mode(dyn, q, v, t, staying)
    released = [k for k in releasing if dyn.contact(k).sticking]
    if not released:
        return new_mode
    ddq = dyn.solve(q, v, t, new_mode).ddq  # also moves the kinematics to (q, v)
    tol = ACCEL_TOL * max(1.0, float(np.linalg.norm(dyn.model.gravity.linear)))
    sinking = [k for k in released if dyn.contact(k).rows(dyn.kin)[0] @ ddq + dyn.contact(k).drift(dyn.kin)[0] < -tol]
    if not sinking:
        return new_mode
    return choose_mode(dyn, q, v, t, staying + [dyn.sliding_key(k) for k in sinking])
