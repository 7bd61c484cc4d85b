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

from ..dynamics.impacts import ImpactResult, choose_mode, resolve_impact
from ..dynamics.mode import ModeDynamics
from ..errors import SolverError
from ..model.scene import Scene
from .guard_gradients import force_time_rate, gap_gradient, liftoff_guard
from .reset_jacobians import VanishingSlipError, impact_parameter_jacobian, impact_reset_jacobian

__all__ = [  # the reset Jacobians' and the guards' former path
    "ORDER_TOL",
    "SimultaneousSaltation",
    "Touchdown",
    "VanishingSlipError",
    "force_time_rate",
    "gap_gradient",
    "impact_parameter_jacobian",
    "impact_reset_jacobian",
    "liftoff_guard",
    "liftoff_saltation",
    "saltation",
    "saltation_matrices",
    "simultaneous_saltation",
    "touchdown",
    "vector_field",
]

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
