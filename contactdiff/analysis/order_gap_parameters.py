"""How the order gap moves with the model's parameters.

The order gap's outcome (`contactdiff.analysis.order_gap`) is

    outcome = ‖v_ij - v_ji‖_M / ‖v_sim - v-‖_M,       ‖x‖_M = sqrt(xᵀ M(q; p) x),

at a fixed event state ``(q, v-)``. Each velocity is a chain of impacts at ``q``:
order ``(i, j)`` is ``v_ij = Δ_j(Δ_i(v-))`` (the second only if that contact still
approaches), so ``dv_ij/dp = ∂_v Δ_j · ∂Δ_i/∂p + ∂Δ_j/∂p``, each impact's
parameter derivative ``∂Δ/∂p`` at fixed velocity (`impact_parameter_jacobian`:
inertias and armature through M, the restitution, the Coulomb coefficient of a
contact that slides through the impact; a group's column sums its members') and its velocity derivative
``∂_v Δ`` the velocity block of `impact_reset_jacobian`, with the impacts'
complementarity states held. The metric moves too:
``d(xᵀ M x)/dp = 2 xᵀ M dx/dp + xᵀ (∂M/∂p) x``, with ``(∂M/∂p) x =
-impulse_forces(q, x)`` (`contactdiff.dynamics.parameter_forces`).

Where the two orders agree (a decoupled robot) the outcome is 0 and, as a norm
at 0, has no derivative: `order_gap_gradient` says so instead of returning one.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike

from ..dynamics.impacts import resolve_impact
from ..dynamics.mode import ModeDynamics
from ..dynamics.parameter_forces import ParameterForces
from ..errors import InvalidInputError
from ..integration.sensitivity import impact_parameter_jacobian, impact_reset_jacobian
from ..model.parameters import resolve
from ..model.scene import Scene
from .order_gap import OrderGap, _index, landings, order_gap

ZERO_GAP = 1e-12
"""An outcome below this (relative) is the decoupled case: its norm has no derivative."""


@dataclass
class OrderGapGradient:
    """The order gap and its derivatives with respect to scene parameters.

    Attributes:
        gap: the `OrderGap` at the nominal parameters.
        parameter_names: the parameters, in column order.
        outcome: ``d outcome / dp`` (p,), per unit of each parameter.
        outcome_abs: ``d ‖v_ij - v_ji‖_M / dp`` (p,).
        v_after: per order, ``dv_order/dp`` (nv × p).
        v_simultaneous: ``dv_sim/dp`` (nv × p).
    """

    gap: OrderGap
    parameter_names: tuple[str, ...]
    outcome: np.ndarray
    outcome_abs: np.ndarray
    v_after: dict
    v_simultaneous: np.ndarray

    def to_dict(self) -> dict:
        """JSON-ready data."""
        return {
            "parameter_names": list(self.parameter_names),
            "outcome": self.gap.outcome,
            "d_outcome": self.outcome.tolist(),
            "d_outcome_abs": self.outcome_abs.tolist(),
            "d_v_after": {" > ".join(k): m.tolist() for k, m in self.v_after.items()},
            "d_v_simultaneous": self.v_simultaneous.tolist(),
        }


def order_gap_gradient(
    scene: Scene,
    q: ArrayLike,
    v_minus: ArrayLike,
    contacts: Sequence = (0, 1),
    parameters: Sequence[str] = (),
    *,
    mode: Sequence = (),
    t: float = 0.0,
) -> OrderGapGradient:
    """`order_gap` at ``(q, v-)`` and the derivatives of its outcome with respect to
    ``parameters`` (module doc). Arguments as `order_gap` (no horizon).

    Raises:
        InvalidInputError: as `order_gap`; unknown parameters (the message lists the
            valid ones); an outcome of 0 (decoupled), where the norm has no derivative.
    """

    gap = order_gap(scene, q, v_minus, contacts, mode=mode, t=t)
    names = [parameters] if isinstance(parameters, str) else list(parameters)
    params = resolve(scene, names)
    if gap.outcome <= ZERO_GAP:
        raise InvalidInputError(
            f"order_gap_gradient: the two orders agree (outcome {gap.outcome:.3g}): a norm "
            "at 0 has no derivative (the robot is decoupled there)"
        )
    q, v_minus = gap.q, gap.v_minus
    dyn = ModeDynamics(scene)
    forces = ParameterForces(scene, params)
    columns: dict[int, list[int]] = {}  # scene index -> the restitution columns that set it
    for col, par in enumerate(params):
        if par.field == "restitution":
            for member in par.members:
                columns.setdefault(member, []).append(col)
    nv = scene.nv
    i, j = (_index(scene, c) for c in contacts)
    before = tuple(sorted(_index(scene, c) for c in mode))

    def reset_parameters(impact, v_before):
        live = {i: columns[i] for i in map(dyn.contact_index, impact.contacts) if i in columns}
        return impact_parameter_jacobian(dyn, q, v_before, impact, forces, live, forces.friction_columns)[nv:]

    d_after = {}
    for order in ((i, j), (j, i)):
        dv = np.zeros((nv, len(params)))
        for v, step in landings(dyn, t, q, v_minus, before, order):
            dv = impact_reset_jacobian(dyn, q, v, step.impact)[nv:, nv:] @ dv + reset_parameters(step.impact, v)
        d_after[tuple(scene.contact_names[k] for k in order)] = dv
    whole = resolve_impact(dyn, q, v_minus, sorted(set(before) | {i, j}))
    d_sim = reset_parameters(whole, v_minus)

    M = pin.crba(scene.model, scene.robot.new_data(), q)

    def norm_and_gradient(x, dx):
        size = float(np.sqrt(max(x @ M @ x, 0.0)))
        d_square = 2.0 * (x @ M) @ dx - x @ forces.impulse_forces(q, x)
        return size, d_square / (2.0 * size)

    a, b = gap.v_after.values()
    da, db = d_after.values()
    top, d_top = norm_and_gradient(a - b, da - db)
    jump, d_jump = norm_and_gradient(gap.v_simultaneous - v_minus, d_sim)
    d_outcome = (d_top * jump - top * d_jump) / jump**2
    return OrderGapGradient(
        gap=gap,
        parameter_names=tuple(names),
        outcome=d_outcome,
        outcome_abs=d_top,
        v_after=d_after,
        v_simultaneous=d_sim,
    )


__all__ = ["OrderGapGradient", "order_gap_gradient", "ZERO_GAP"]
