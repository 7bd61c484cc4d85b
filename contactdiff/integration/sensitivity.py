"""Saltation matrices: how a perturbation crosses an event (docs/design.md §2).

At an event with guard ``h`` and reset ``R`` a tangent perturbation ``δx`` just
before becomes ``Ξ δx`` just after, with

    Ξ = DR + (F+(R x) - DR F-(x)) Dh / (Dh F-(x)),

``F-``/``F+`` the vector fields ``(v, ddq)`` of the modes before and after.
Touchdowns and bounces have ``h = a_i(q)``, ``Dh = [A_i, 0]`` and the impact
reset ``R = (q, v+(q, v-))`` whose derivative includes ``∂(Δ(q) v)/∂q``;
lift-offs have ``h = λ_i`` and ``R = identity`` (``Ξ = I`` for a frictionless
contact, whose force is continuous there).

At a simultaneous touchdown of contacts ``K`` the saltation matrix of every
order of ``K`` is the product of single-contact saltations taken at the same
point; the paper's theorem says that for limbs decoupled through the body all
of them equal ``DR_K + Σ_k S_k``. `simultaneous_saltation` computes them and
says whether they agree.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from ..dynamics.friction_slip import SLIP_ZERO
from ..dynamics.frictional_impact import ContactState
from ..dynamics.impacts import ImpactResult, choose_mode, resolve_impact
from ..dynamics.mode import ModeDynamics
from ..dynamics.parameter_forces import ParameterForces
from ..dynamics.redundant import range_basis
from ..errors import SolverError
from ..model.scene import Scene

ORDER_TOL = 1e-8
"""Relative agreement (max-norm) below which the saltation matrices of all orders
at a simultaneous event count as equal: round-off in a saltation matrix is about
1e-14 relative, while a coupled model differs at O(1)."""


def vector_field(dyn: ModeDynamics, q: np.ndarray, v: np.ndarray, t: float, mode: Sequence[int]) -> np.ndarray:
    """``F = (v, ddq)`` of ``mode`` at ``(q, v, t)`` in the tangent space (2nv,)."""
    return np.concatenate([v, dyn.solve(q, v, t, tuple(mode)).ddq])


def saltation(DR: np.ndarray, Dh: np.ndarray, F_minus: np.ndarray, F_plus: np.ndarray, h_t: float = 0.0) -> np.ndarray:
    """``Ξ = DR + (F+ - DR F-) Dh / (Dh F- + h_t)`` (2nv × 2nv); ``h_t`` is the guard's
    explicit time rate (a contact force under time-dependent efforts)."""
    rate = float(Dh @ F_minus) + h_t
    return DR + np.outer(F_plus - DR @ F_minus, Dh) / rate


def force_time_rate(dyn: ModeDynamics, q: np.ndarray, v: np.ndarray, t: float, mode: Sequence[int], row: int) -> float:
    """``∂lam_row/∂t`` at fixed state (N/s): the forces are affine in the efforts, so
    it is the forces' response to ``d tau/dt`` alone (exact up to round-off; zero for
    an autonomous scene)."""
    dyn.kin.update(q, v)
    tau_t = dyn.scene.tau_time_derivative(dyn.kin, t)
    if not np.any(tau_t):
        return 0.0
    tau = dyn.scene.tau(dyn.kin, t)
    mode = tuple(mode)
    return float(dyn.solve(q, v, t, mode, tau=tau + tau_t).forces[row] - dyn.solve(q, v, t, mode, tau=tau).forces[row])


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


def gap_gradient(dyn: ModeDynamics, q: np.ndarray, contact: int) -> np.ndarray:
    """``Dh = [A_i, 0]`` of the touchdown guard of ``contact`` (2nv,)."""
    dyn.kin.update(q, np.zeros(dyn.model.nv))
    return np.concatenate([dyn.contact(contact).rows(dyn.kin)[0], np.zeros(dyn.model.nv)])


@dataclass
class Touchdown:
    """One single-contact (or simultaneous-reset) touchdown and its saltation matrix."""

    saltation: np.ndarray
    v_plus: np.ndarray
    mode_after: tuple[int, ...]
    impact: ImpactResult


def touchdown(
    dyn: ModeDynamics,
    t: float,
    q: np.ndarray,
    v_minus: np.ndarray,
    mode: Sequence[int],
    contacts: Sequence[int],
    restitution=None,
    guard: int | None = None,
) -> Touchdown:
    """Impact of ``contacts`` closing on ``mode`` and the saltation matrix of ``guard``'s crossing.

    Args:
        dyn: the scene's `ModeDynamics`.
        t: event time (s).
        q: configuration at the event (nq,).
        v_minus: velocity just before (nv,), tangent space.
        mode: active contacts before.
        contacts: contacts that close at this instant (all take part in the impact
            together with ``mode``).
        restitution: per-contact override over ``sorted(mode ∪ contacts)``.
        guard: the contact whose gap is the guard (default: the only one of ``contacts``).
    """
    mode = tuple(mode)
    closed = sorted(set(mode) | set(contacts))
    impact = resolve_impact(dyn, q, v_minus, closed, restitution)
    scale = max(1.0, float(np.max(np.abs(impact.normal_speeds_before))))
    staying = [i for i, s in zip(closed, impact.normal_speeds_after) if s <= 1e-12 * scale]
    mode_after = choose_mode(dyn, q, impact.v_plus, t, staying)
    DR = impact_reset_jacobian(dyn, q, v_minus, impact)
    guard = contacts[0] if guard is None else guard
    Dh = gap_gradient(dyn, q, guard)
    F_minus = vector_field(dyn, q, v_minus, t, mode)
    F_plus = vector_field(dyn, q, impact.v_plus, t, mode_after)
    return Touchdown(saltation(DR, Dh, F_minus, F_plus), impact.v_plus, mode_after, impact)


def liftoff_guard(
    dyn: ModeDynamics, t: float, q: np.ndarray, v: np.ndarray, mode: Sequence[int], contact: int
) -> tuple[np.ndarray, np.ndarray, float]:
    """The lift-off guard of ``contact`` (a key of ``mode``), its normal force:
    ``(Dh, F-, h_t)`` with ``Dh`` its gradient (2nv,), ``F-`` the field of ``mode``
    and ``h_t`` its explicit time rate (`force_time_rate`)."""
    mode = tuple(mode)
    sol, der = dyn.solve(q, v, t, mode, derivatives=True)
    row = sol.row_slices[mode.index(contact)].start
    Dh = np.concatenate([der.forces_dq[row], der.forces_dv[row]])
    return Dh, np.concatenate([v, sol.ddq]), force_time_rate(dyn, q, v, t, mode, row)


def liftoff_saltation(
    dyn: ModeDynamics,
    t: float,
    q: np.ndarray,
    v: np.ndarray,
    mode: Sequence[int],
    contact: int,
    mode_after: Sequence[int],
    guard=None,
) -> np.ndarray:
    """Saltation matrix of the lift-off of ``contact`` (guard: its normal force, reset:
    identity); ``guard`` is its `liftoff_guard` if already computed."""
    Dh, F_minus, h_t = liftoff_guard(dyn, t, q, v, mode, contact) if guard is None else guard
    F_plus = vector_field(dyn, q, v, t, mode_after)
    return saltation(np.eye(len(F_minus)), Dh, F_minus, F_plus, h_t)


@dataclass
class SimultaneousSaltation:
    """Saltation matrices at a simultaneous touchdown.

    Attributes:
        orders: saltation matrix of each order of the activating contacts (keys
            are tuples of contact indices, first to land first).
        paper: ``DR_K + Σ_k S_k`` of the paper (simultaneous reset plus one
            correction per contact).
        differentiable: all orders and the paper's matrix agree within ``tol``.
        spread: largest relative max-norm difference between any two of them (with
            ``complete`` False, between the two orders that first disagreed: a lower bound).
        tol: the tolerance used.
        complete: every order and the paper's matrix were formed (False when a
            verdict-only call stopped at the first two orders that disagree).
        unresolved: the orders whose sequence of single-contact impacts has no solution
            the impact law's search finds (`SolverError` message by order): such an
            event is not called differentiable, since its orders cannot be compared.
        corrections: for each landing contact k, the pieces of its term
            ``S_k = jump_k Dh_k / rate_k``: ``(jump_k, rate_k)`` with ``jump_k =
            F_{J∪k}(q, v+_k) - DR_k F_J(q, v-)`` and ``rate_k = Dh_k F_J(q, v-)`` (for a
            guard that also depends on parameters, `contactdiff.integration.parameter_jumps`).
    """

    orders: dict = field(default_factory=dict)
    paper: np.ndarray | None = None
    differentiable: bool = True
    spread: float = 0.0
    tol: float = ORDER_TOL
    corrections: dict = field(default_factory=dict)
    complete: bool = True
    unresolved: dict = field(default_factory=dict)

    @property
    def matrix(self) -> np.ndarray:
        """The matrix used for the flow Jacobian: the paper's (equal to every order's when
        differentiable), else, where it could not be formed, the first order's."""
        if self.paper is not None:
            return self.paper
        if self.orders:
            return next(iter(self.orders.values()))
        raise SolverError(
            "no landing order of the simultaneous touchdown could be resolved: " + "; ".join(self.unresolved.values())
        )


def simultaneous_saltation(
    dyn: ModeDynamics,
    t: float,
    q: np.ndarray,
    v_minus: np.ndarray,
    mode: Sequence[int],
    contacts: Sequence[int],
    restitution=None,
    tol: float = ORDER_TOL,
    verdict_only: bool = False,
) -> SimultaneousSaltation:
    """Saltation matrices of every order of the simultaneous touchdown of ``contacts``.

    For an order ``(k1, k2, ...)``: ``k1`` lands alone on ``mode`` at ``(q, v-)``,
    then ``k2`` on the resulting mode and velocity at the same ``q``, and so on; a
    later contact already separating after the earlier impacts does not land. The
    order's matrix is the product of the single-contact saltation matrices.
    The paper's ``DR_K + Σ_k S_k`` uses the simultaneous reset ``R_K`` and
    ``S_k = (F_{J∪k}(q, v+_k) - DR_k F_J(q, v-)) Dh_k / (Dh_k F_J(q, v-))``.

    Args:
        dyn: the scene's `ModeDynamics`.
        t: event time (s).
        q: configuration at the event (nq,), with the ``contacts`` closed.
        v_minus: velocity just before (nv,), tangent space.
        mode: contact keys active before.
        contacts: indices of the contacts landing together.
        restitution: optional per-contact override, a mapping from contact index to e.
        tol: agreement tolerance (relative, max-norm) below which all orders count as
            equal (``differentiable``).
        verdict_only: stop at the first order that disagrees with the first one (a
            face of k corners has k! orders; a plain run needs only the verdict).

    Returns:
        A `SimultaneousSaltation`: every order's matrix, the paper's, their spread.
    """
    mode, contacts = tuple(mode), tuple(contacts)
    override = dict(restitution or {})

    def e_for(closed):
        if not override:
            return None
        return [override.get(i, dyn.contact(i).restitution) for i in closed]

    result = SimultaneousSaltation(tol=tol)
    for order in itertools.permutations(contacts):
        Xi, v, current = np.eye(2 * dyn.model.nv), v_minus, mode
        try:
            for k in order:
                dyn.kin.update(q, v)
                if dyn.contact(k).rows(dyn.kin)[0] @ v >= 0.0:
                    continue  # already separating after the earlier impacts: it does not land
                step = touchdown(dyn, t, q, v, current, [k], e_for(sorted(set(current) | {k})), guard=k)
                Xi, v, current = step.saltation @ Xi, step.v_plus, step.mode_after
        except SolverError as exc:  # this order's hypothetical impacts: noted, not fatal to the run
            result.unresolved[order] = str(exc)
            result.differentiable = False
            if verdict_only:
                result.complete = False
                return result
            continue
        result.orders[order] = Xi
        if verdict_only and len(result.orders) > 1:
            first = next(iter(result.orders.values()))
            gap = float(np.max(np.abs(Xi - first))) / max(1.0, float(np.max(np.abs(first))), float(np.max(np.abs(Xi))))
            if gap > tol:
                result.spread, result.differentiable, result.complete = gap, False, False
                return result
    # the paper's formula around the simultaneous reset
    closed = sorted(set(mode) | set(contacts))
    try:
        whole = resolve_impact(dyn, q, v_minus, closed, e_for(closed))
        paper = impact_reset_jacobian(dyn, q, v_minus, whole)
        F_minus = vector_field(dyn, q, v_minus, t, mode)
        for k in contacts:
            single = touchdown(dyn, t, q, v_minus, mode, [k], e_for(sorted(set(mode) | {k})), guard=k)
            DR_k = impact_reset_jacobian(dyn, q, v_minus, single.impact)
            Dh = gap_gradient(dyn, q, k)
            F_plus = vector_field(dyn, q, single.v_plus, t, single.mode_after)
            jump, rate = result.corrections[k] = (F_plus - DR_k @ F_minus, float(Dh @ F_minus))
            paper = paper + np.outer(jump, Dh) / rate
        result.paper = paper
    except SolverError as exc:  # a contact's single landing has no solution found: no paper matrix
        result.unresolved[("paper",)] = str(exc)
        result.differentiable, result.corrections = False, {}
    mats = list(result.orders.values()) + ([result.paper] if result.paper is not None else [])
    if len(mats) > 1:
        scale = max(1.0, max(float(np.max(np.abs(m))) for m in mats))
        result.spread = max(float(np.max(np.abs(a - b))) for a, b in itertools.combinations(mats, 2)) / scale
    result.differentiable = result.spread <= tol and not result.unresolved
    return result


def saltation_matrices(
    scene: Scene,
    q: np.ndarray,
    v_minus: np.ndarray,
    contacts: Sequence[int | str],
    mode: Sequence[int | str] = (),
    t: float = 0.0,
    tol: float = ORDER_TOL,
) -> SimultaneousSaltation:
    """Public entry: saltation matrices of every landing order of ``contacts`` at ``(q, v-)``.

    Args:
        scene: the scene.
        q: configuration (nq,) with the ``contacts`` closed.
        v_minus: velocity just before (nv,), tangent space.
        contacts: contacts (indices or names) landing together.
        mode: contacts active before (indices or names).
        t: time (s), for time-dependent efforts.
        tol: agreement tolerance (relative).
    """

    def index(c):
        return scene.contact_index(c) if isinstance(c, str) else int(c)

    return simultaneous_saltation(
        ModeDynamics(scene),
        t,
        np.asarray(q, float),
        np.asarray(v_minus, float),
        [index(c) for c in mode],
        [index(c) for c in contacts],
        tol=tol,
    )
