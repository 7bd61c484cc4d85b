"""Impacts and the choice of the next contact mode.

Impact law (Newton restitution per contact, with complementarity): all contacts
closed at the instant take part; the impulses ``Λ`` (N s) solve the contact
complementarity problem of `contactdiff.lcp` with ``v+ = v- + M^-1 A^T Λ`` and
post-impact normal velocities ``w_k = A_k v+ + e_k A_k v- >= 0``,
``Λ_k w_k = 0``. Tangential rows of sticking contacts stop the tangential
velocity (plastic); restitution acts on normal rows only.

Mode choice (force-level complementarity): among the closed contacts whose
normal velocity is zero, the next mode is the active set ``S`` of the
acceleration-level problem: contacts in ``S`` have normal force >= 0 and zero
row acceleration, the others a non-negative normal acceleration.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from .dynamics import ModeDynamics
from .lcp import ContactRows, impact_rhs, solve_contact_lcp


@dataclass
class ImpactResult:
    """Outcome of one impact.

    Attributes:
        v_plus: post-impact velocity (nv,).
        impulses: normal impulse of each participating contact (N s), in ``contacts`` order.
        row_impulses: impulses of all rows (normal and tangential).
        contacts: indices of the participating (closed) contacts.
        normal_speeds_before, normal_speeds_after: ``A_n v-`` and ``A_n v+`` per contact (m/s).
        restitution: the coefficient used for each contact (0 where Zeno ended a bounce
            or where the contact was not approaching).
        active: positions in ``contacts`` of the contacts whose rows carry impulse
            (the complementarity problem's active set).
        rows: the row layout of ``contacts`` (`ContactRows`).
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


def _rows(dyn: ModeDynamics, contacts: Sequence[int]):
    """Stacked rows of ``contacts`` at the kinematics' current state, and their layout."""
    bound = [dyn.scene.contacts[i] for i in contacts]
    A = np.vstack([c.rows(dyn.kin) for c in bound])
    return A, ContactRows.from_sizes([c.n_rows for c in bound])


def resolve_impact(dyn: ModeDynamics, q: np.ndarray, v_minus: np.ndarray, contacts: Sequence[int],
                   restitution: Sequence[float] | None = None) -> ImpactResult:
    """Apply the impact law at configuration ``q`` to the closed ``contacts``.

    Args:
        dyn: the scene's `ModeDynamics` (its kinematics cache is reused).
        q: configuration at the impact.
        v_minus: velocity just before (nv,).
        contacts: indices of the closed contacts (all take part).
        restitution: coefficient per contact overriding the scene's (e.g. 0 to end a
            Zeno sequence); ``None`` uses each contact's own.
    """
    contacts = tuple(contacts)
    model = dyn.model
    dyn.kin.update(q, v_minus)
    A, rows = _rows(dyn, contacts)
    e = np.array([dyn.scene.contacts[i].restitution for i in contacts]) if restitution is None \
        else np.array(restitution, dtype=float)
    MinvAT = pin.computeMinverse(model, dyn.data, q) @ A.T
    Av = A @ v_minus
    # Restitution restores compression only: a closed contact that is not approaching
    # takes part plastically (with its own e, Newton's law could add energy).
    e[Av[list(rows.normal)] >= 0.0] = 0.0
    solution = solve_contact_lcp(A @ MinvAT, impact_rhs(Av, e, rows), rows, on_infeasible="relax")
    v_plus = v_minus + MinvAT @ solution.x
    normal = list(rows.normal)
    return ImpactResult(v_plus, solution.x[normal].copy(), solution.x, contacts, Av[normal],
                        (A @ v_plus)[normal], e, solution.active, rows)


def choose_mode(dyn: ModeDynamics, q: np.ndarray, v: np.ndarray, t: float,
                candidates: Sequence[int]) -> tuple[int, ...]:
    """Active set among the closed, non-separating ``candidates`` (acceleration-level LCP).

    Returns:
        Sorted contact indices that stay active (normal force >= 0).
    """
    candidates = tuple(sorted(candidates))
    if not candidates:
        return ()
    a_free = dyn.solve(q, v, t, ()).ddq  # also updates the kinematics at (q, v)
    A, rows = _rows(dyn, candidates)
    drift = np.concatenate([dyn.scene.contacts[i].drift(dyn.kin) for i in candidates])
    G = A @ pin.computeMinverse(dyn.model, dyn.data, q) @ A.T
    solution = solve_contact_lcp(G, A @ a_free + drift, rows, on_infeasible="relax")
    return tuple(candidates[k] for k in solution.active)
