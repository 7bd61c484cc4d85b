"""The impact reset's Jacobians: ``DR`` in the state (`impact_reset_jacobian`) and ``∂R/∂p`` in
the parameters (`impact_parameter_jacobian`), from the impact law's equations differentiated
with the contacts' complementarity states held fixed; a slip that vanishes after the impact has
no derivative (`VanishingSlipError`).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ..dynamics.friction_slip import SLIP_ZERO
from ..dynamics.frictional_impact import ContactState
from ..dynamics.impacts import ImpactResult
from ..dynamics.mode import ModeDynamics
from ..dynamics.parameter_forces import ParameterForces
from ..dynamics.redundant import range_basis
from ..errors import SolverError


class VanishingSlipError(SolverError):
    """A contact the impact leaves sliding has no slip after it (its impulse on its cone's edge
    with a slip below `SLIP_ZERO` of the velocity scale): a stick/slip threshold, where the
    slip direction, and so the reset, has no derivative."""


def impact_reset_jacobian(
    dyn: ModeDynamics, q: np.ndarray, v_minus: np.ndarray, impact: ImpactResult, hold_vanishing: bool = False
) -> np.ndarray:
    """``DR`` of the impact reset ``(q, v-) -> (q, v+)`` (2nv × 2nv), tangent space.

    Differentiates the equations of the rows that carry impulse, with the
    complementarity states held fixed: ``M (v+ - v-) = A^T Λ``, and on an
    active contact ``A_n v+ = -e A_n v-``, ``A_t v+ = 0``; on a tangential-only
    contact (the relaxed infinite-friction state) ``A_t v+ = 0`` with ``Λ_n = 0``.
    A contact sliding with Coulomb friction (``impact.states``) holds its normal row
    only, and its tangential impulse ``-μ Λ_N s`` follows ``s = u+_T / ||u+_T||``:
    its force column is ``F = A_n - μ s^T A_T``, and ``δs = (I - s s^T) δu+_T / ||u+_T||``
    moves ``v+`` through ``-μ Λ_N A_T^T δs`` (a planar slip keeps its sign, ``δs = 0``).
    A sliding contact whose slip vanishes after the impact (`VanishingSlipError`) has no
    derivative there; with ``hold_vanishing`` its direction is held (a one-sided derivative).
    Dependent held rows (a face's corners) keep the impulses in the range of the rows, as
    the impact law (`contactdiff.dynamics.redundant`): with sliding corners the velocity
    depends on the corners' shares, which least squares would not give.
    """
    model, nv = dyn.model, dyn.model.nv
    held = sorted(set(impact.active) | set(impact.tangential_only))
    DR = np.eye(2 * nv)
    if not held:
        return DR
    kin = dyn.kin
    kin.update(q, v_minus, derivatives=True)
    v_plus = impact.v_plus
    M = pin.crba(model, dyn.data, q)
    M = np.triu(M) + np.triu(M, 1).T
    dMdv_dq = pin.computeRNEADerivatives(model, dyn.data, q, np.zeros(nv), v_plus - v_minus)[
        0
    ] - pin.computeGeneralizedGravityDerivatives(model, dyn.data, q)
    rhs_q = -dMdv_dq
    K_vv = M.copy()
    A_rows, F_rows, con_q, e_rows, held_rows = [], [], [], [], []
    for k in held:
        c = dyn.contact(impact.contacts[k])
        # a tangential-only contact keeps its tangential rows only; its normal impulse is 0
        kept = slice(0, c.n_rows) if k in impact.active else slice(1, c.n_rows)
        e_k = impact.restitution[k] if k in impact.active else 0.0
        assert impact.rows is not None  # set by every impact with held contacts
        impulses = impact.row_impulses[impact.rows.rows_of([k])]
        rhs_q += c.rows_transpose_dq(kin, impulses)
        rows = c.rows(kin)
        e_block = np.zeros(c.n_rows)
        e_block[0] = e_k
        constraint_q = -c.rows_times_dq(kin, v_plus) - e_block[:, None] * c.rows_times_dq(kin, v_minus)
        force_rows = rows[kept]
        if _slides_with_friction(impact, k, c):
            kept = slice(0, 1)
            assert impact.friction is not None  # set with the contact states
            mu, s = impact.friction[k], impact.slide_directions[k]
            force_rows = (rows[0] - mu * s @ rows[1:])[None, :]
            u_T = rows[1:] @ v_plus
            speed = float(np.linalg.norm(u_T))
            vanishing = len(s) == 2 and _slip_vanishes(speed, v_minus)
            if vanishing and not hold_vanishing:
                raise VanishingSlipError(
                    f"contact {impact.contacts[k]} slides with a slip of {speed:.2e} m/s after "
                    "the impact: a stick/slip threshold, where the reset has no derivative"
                )
            if len(s) == 2 and not vanishing:  # δs through the post-impact slip velocity
                D = (np.eye(2) - np.outer(s, s)) / speed
                coef = mu * impulses[0] * rows[1:].T @ D
                K_vv += coef @ rows[1:]
                rhs_q -= coef @ c.rows_times_dq(kin, v_plus)[1:]
        A_rows.append(rows[kept])
        F_rows.append(force_rows)
        con_q.append(constraint_q[kept])
        e_rows.append(e_block[kept])
        held_rows.append((c, kept, impulses[kept]))
    A, F, E = np.vstack(A_rows), np.vstack(F_rows), np.diag(np.concatenate(e_rows))
    C_q = np.vstack(con_q)
    U = range_basis(A)
    if U is not None:
        # dependent rows (a face's corners): the impulses stay in range(A) as the impact law's
        # (contactdiff.dynamics.redundant), δΛ = U δy + (I - U Uᵀ) d(A w)/dq δq, w = A⁺ Λ
        w = np.linalg.lstsq(A, np.concatenate([lam for _, _, lam in held_rows]), rcond=None)[0]
        turn = np.vstack([c.rows_times_dq(kin, w)[kept] for c, kept, _ in held_rows])
        turn -= U @ (U.T @ turn)
        rhs_q = rhs_q + F.T @ turn
        F_held, A, C_q, EA = F.T @ U, U.T @ A, U.T @ C_q, U.T @ E @ A
    else:
        F_held, EA = F.T, E @ A
    m = A.shape[0]
    K = np.block([[K_vv, -F_held], [A, np.zeros((m, m))]])
    rhs = np.block([[rhs_q, M], [C_q, -EA]])
    X = np.linalg.lstsq(K, rhs, rcond=None)[0] if np.linalg.matrix_rank(K) < nv + m else np.linalg.solve(K, rhs)
    DR[nv:, :nv] = X[:nv, :nv]
    DR[nv:, nv:] = X[:nv, nv:]
    return DR


def _slip_vanishes(speed: float, v_minus: np.ndarray) -> bool:
    """Whether a post-impact slip speed (m/s) is below `SLIP_ZERO` of the velocity scale: no direction."""
    return not speed > SLIP_ZERO * max(1.0, float(np.max(np.abs(v_minus))))


def _slides_with_friction(impact: ImpactResult, k: int, contact) -> bool:
    """Whether contact ``k`` of ``impact`` slides with finite friction on tangential rows."""
    return (
        impact.states is not None
        and impact.states[k] is ContactState.SLIDE
        and contact.n_rows > 1
        and impact.friction is not None  # set with the states
        and 0.0 < impact.friction[k] < np.inf
        and bool(np.any(impact.slide_directions[k]))
    )


def impact_parameter_jacobian(
    dyn: ModeDynamics,
    q: np.ndarray,
    v_minus: np.ndarray,
    impact: ImpactResult,
    forces: ParameterForces,
    restitution_columns: dict,
    friction_columns: dict | None = None,
) -> np.ndarray:
    """``∂R/∂p`` of the impact reset at fixed ``(q, v-)`` (2nv × p; zero ``q`` rows).

    The same equations as `impact_reset_jacobian`, differentiated in the parameters:
    ``K_vv δv+ - F^T δΛ = -∂(M (v+ - v-))/∂p`` (`ParameterForces.impulse_forces`) and, on an
    active contact whose restitution is parameter column ``c``
    (``restitution_columns[i] = c``, or a list of columns, by scene index ``i``, for the
    contacts whose coefficient the impact used as it is), ``A_n δv+ = -δe A_n v-``. A contact sliding
    with Coulomb friction holds its normal row only, its force column is
    ``F = A_n - μ s^T A_T`` and ``K_vv = M + μ Λ_N A_T^T D A_T`` (the turn of ``s``,
    ``D = ds/du+_T``); its coefficient's columns (``friction_columns[i]``, by scene index) get the
    force ``-Λ_N A_T^T s`` (the tangential impulse's ``∂/∂μ`` at fixed ``Λ_N`` and
    ``s``). A sticking contact's impulse does not depend on ``μ`` while it sticks.
    Dependent rows (a face's corners) keep ``δΛ`` in the range of the held rows, as the
    impact law's impulses (`contactdiff.dynamics.redundant`).
    """
    nv = dyn.model.nv
    out = np.zeros((2 * nv, forces.p))
    held = sorted(set(impact.active) | set(impact.tangential_only))
    if not held:
        return out
    kin = dyn.kin
    kin.update(q, v_minus)
    M = pin.crba(dyn.model, dyn.data, q)
    M = np.triu(M) + np.triu(M, 1).T
    K_vv = M.copy()
    rhs_v = forces.impulse_forces(q, impact.v_plus - v_minus)
    A_rows, F_rows, e_rhs = [], [], []
    friction_columns = friction_columns or {}
    for k in held:
        key = impact.contacts[k]
        index = dyn.contact_index(key)  # the columns are by scene index: a key may be a sliding one
        c = dyn.contact(key)
        rows = c.rows(kin) if k in impact.active else c.rows(kin)[1:]
        force_rows = rows
        if k in impact.active and _slides_with_friction(impact, k, c):
            full = rows
            rows = force_rows = full[:1]
            assert impact.friction is not None and impact.rows is not None  # set with the contact states
            mu, s = impact.friction[k], impact.slide_directions[k]
            lam_n = float(impact.row_impulses[impact.rows.rows_of([k])][0])
            force_rows = (full[0] - mu * s @ full[1:])[None, :]
            u_T = full[1:] @ impact.v_plus
            speed = float(np.linalg.norm(u_T))
            # a vanishing slip (`VanishingSlipError`, flagged by the reset's Jacobian): direction held
            if len(s) == 2 and not _slip_vanishes(speed, v_minus):
                D = (np.eye(2) - np.outer(s, s)) / speed  # δs through the post-impact slip velocity
                K_vv += mu * lam_n * full[1:].T @ D @ full[1:]
            for col in _as_list(friction_columns.get(index)):
                rhs_v[:, col] -= lam_n * full[1:].T @ s
        block = np.zeros((rows.shape[0], forces.p))
        if k in impact.active and impact.normal_speeds_before[k] < 0.0:
            for col in _as_list(restitution_columns.get(index)):
                block[0, col] -= float(rows[0] @ v_minus)
        A_rows.append(rows)
        F_rows.append(force_rows)
        e_rhs.append(block)
    A, F = np.vstack(A_rows), np.vstack(F_rows)
    U = range_basis(A)
    if U is None:
        U = np.eye(A.shape[0])
    r = U.shape[1]
    K = np.block([[K_vv, -F.T @ U], [U.T @ A, np.zeros((r, r))]])
    rhs = np.vstack([rhs_v, U.T @ np.vstack(e_rhs)])
    X = np.linalg.lstsq(K, rhs, rcond=None)[0] if np.linalg.matrix_rank(K) < nv + r else np.linalg.solve(K, rhs)
    out[nv:] = X[:nv]
    return out


def _as_list(columns) -> list[int]:
    """A column, a list of columns, or None, as a list."""
    if columns is None:
        return []
    return [int(columns)] if isinstance(columns, (int, np.integer)) else list(columns)
