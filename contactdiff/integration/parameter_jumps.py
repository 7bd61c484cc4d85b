"""How the parameter columns of a flow Jacobian cross events.

With parameters ``p`` the loop propagates the augmented state ``(x, p)``, ``p' = 0``:
the flow Jacobian's last columns are ``∂x/∂p`` (tangent space), forced in each mode
by ``∂F/∂p`` (`contactdiff.dynamics.parameter_forces`). At an event with guard ``h(x, p)``
and reset ``R(x, p)`` the augmented saltation matrix's parameter block is

    Ξ_p = ∂R/∂p + (F+ - DR F-) (∂h/∂p) / (Dh F- + h_t),

so that ``∂x+/∂p = Ξ ∂x-/∂p + Ξ_p`` and the event time moves by
``∂t/∂p = -(Dh ∂x-/∂p + ∂h/∂p) / (Dh F- + h_t)``. What depends on parameters:

* a touchdown's guard, the gap ``n · p(q) - offset``: ``∂h/∂offset = -1``;
* a lift-off's guard, the normal force: ``∂λ/∂p`` of the mode (inertias, gravity,
  efforts);
* an impact's reset: ``∂v+/∂p`` through ``M`` (inertias, armature), the
  restitution and the friction coefficient of a contact that slides through the
  impact (`contactdiff.integration.sensitivity.impact_parameter_jacobian`);
* a stick → slip guard, the cone margin ``h = μ λ_N - ||λ_T||``: ``∂h/∂μ = λ_N`` at
  fixed state, plus the sticking forces' ``∂λ/∂p`` (`contactdiff.integration.friction_events`);
  a slip → stick guard, the slip velocity, depends on no parameter;
* the projection back onto the constraints, ``q - P a(q)``: ``+P`` on an offset.

A group parameter (``group:GROUP:field``) moves every member's coefficient by the
same amount: each member contributes its term to the group's column.

A lift-off's reset is the identity, so ``Ξ_p`` there is the guard term alone (zero
when the field does not jump).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..dynamics.impacts import ImpactResult
from ..dynamics.mode import ModeDynamics
from ..dynamics.parameter_forces import ParameterForces
from ..model.parameter_types import ParameterKind
from .projection import mode_rows, weighted_pinv
from .sensitivity import impact_parameter_jacobian


class ParameterJumps:
    """The parameter blocks of a run's events (module doc), for a list of a scene's
    parameters (`contactdiff.model.parameters`, in column order).

    Attributes:
        forces: the `ParameterForces` of the flows.
        p: number of parameters.
        scale: typical size of each parameter (its absolute value, 1 where it is 0),
            the error control's ``variational_column_scale``.
    """

    def __init__(self, dyn: ModeDynamics, parameters: Sequence):
        self.dyn, self.parameters = dyn, list(parameters)
        self.p = len(self.parameters)
        self.forces = ParameterForces(dyn.scene, self.parameters)
        scene = dyn.scene
        # scene index of a contact -> the columns of the parameters that set its offset,
        # restitution (a contact's own, its group's)
        self.offset_columns: dict[int, list[int]] = {}
        self.restitution_columns: dict[int, list[int]] = {}
        for col, par in enumerate(self.parameters):
            if par.kind in (ParameterKind.CONTACT, ParameterKind.GROUP) and par.field != "friction":
                target = self.offset_columns if par.field == "offset" else self.restitution_columns
                for i in par.members:
                    target.setdefault(i, []).append(col)
        specs = scene.contact_specs
        values = np.array(
            [
                max(abs(float(getattr(specs[i], par.field))) for i in par.members)
                if par.members
                else abs(float(scene.parameter_values([par.name])[0]))
                for par in self.parameters
            ]
        )
        self.scale = np.where(values > 0.0, values, 1.0)

    def gap_guard(self, contact: int) -> np.ndarray:
        """``∂h/∂p`` (p,) of the touchdown guard of scene contact ``contact``."""
        h_p = np.zeros(self.p)
        for col in self.offset_columns.get(contact, ()):
            h_p[col] -= 1.0
        return h_p

    def force_guard(self, q: np.ndarray, v: np.ndarray, t: float, mode: Sequence[int], key: int) -> np.ndarray:
        """``∂λ/∂p`` (p,) of the normal force of contact key ``key`` in ``mode`` at ``(q, v, t)``."""
        mode = tuple(mode)
        sol, der = self.dyn.solve(q, v, t, mode, derivatives=True)
        row = sol.row_slices[mode.index(key)].start
        return der.forces_dtau[row] @ self.forces.mode_forces(self.dyn, sol, q, v, t)

    def impact(self, q: np.ndarray, v_minus: np.ndarray, impact: ImpactResult, live: Sequence[int]) -> np.ndarray:
        """``∂R/∂p`` (2nv × p) of ``impact``; ``live``: the contact keys whose own
        restitution the impact used (not ended by the Zeno rule)."""
        live_indices = {self.dyn.contact_index(k) for k in live}
        columns = {i: cols for i, cols in self.restitution_columns.items() if i in live_indices}
        return impact_parameter_jacobian(
            self.dyn, q, v_minus, impact, self.forces, columns, self.forces.friction_columns
        )

    def projection(self, q: np.ndarray, mode: Sequence[int]) -> np.ndarray:
        """``∂/∂p`` (2nv × p) of the projection ``(q - P a(q), ...)`` onto ``mode``'s
        constraints at fixed state: ``P``'s column of each offset's contact."""
        out = np.zeros((2 * self.dyn.model.nv, self.p))
        cols = [(j, c) for j, k in enumerate(mode) for c in self.offset_columns.get(self.dyn.contact_index(k), ())]
        if not cols:
            return out
        self.dyn.kin.update(q, np.zeros(self.dyn.model.nv))
        A = mode_rows(self.dyn, mode)
        normal = [0] + list(np.cumsum([self.dyn.contact(k).n_rows for k in mode])[:-1])
        P = weighted_pinv(self.dyn, q, A[normal])
        for j, col in cols:
            out[: self.dyn.model.nv, col] += P[:, j]
        return out

    @staticmethod
    def saltation(
        R_p: np.ndarray | None,
        h_p: np.ndarray,
        DR: np.ndarray | None,
        F_minus: np.ndarray,
        F_plus: np.ndarray,
        rate: float,
    ) -> np.ndarray:
        """``Ξ_p = ∂R/∂p + (F+ - DR F-) ∂h/∂p / rate`` (2nv × p); ``R_p``/``DR`` None: identity reset."""
        jump = F_plus - (F_minus if DR is None else DR @ F_minus)
        out = np.outer(jump, h_p) / rate
        return out if R_p is None else out + R_p


__all__ = ["ParameterJumps"]
