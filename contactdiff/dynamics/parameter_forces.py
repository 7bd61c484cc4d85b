"""How model parameters enter the equations of motion and of impact, as generalised forces.

The dynamics of a mode balance generalised forces at fixed ``(q, v, ddq)``:

    f(q, v, ddq, t; p) = tau(q, v, t; p) - RNEA(q, v, ddq; p) + A^T lam = 0,

with RNEA Pinocchio's inverse dynamics (inertia, Coriolis, gravity, armature). A
parameter ``p`` that does not change the constraint rows ``A`` or their drift
moves the solution as a generalised force ``∂f/∂p`` would: ``∂ddq/∂p =
(∂ddq/∂tau) ∂f/∂p`` and ``∂lam/∂p = (∂lam/∂tau) ∂f/∂p``, with the mode's own
operators ``∂ddq/∂tau`` (``M^-1`` in flight, the constrained inverse mass in
contact) and ``∂lam/∂tau``. `ParameterForces.forces` gives ``∂f/∂p`` (nv × p):

* a body's mass, centre of mass (m, link frame) and inertia about it (kg m²):
  ``-Y(q, v, ddq) ∂π/∂p``, with ``Y`` Pinocchio's joint-torque regressor and ``π``
  the body's ten dynamic parameters (its inertia about the joint frame's
  origin: the parallel-axis theorem's chain rule);
* a joint's armature: ``-ddq_j`` on its coordinate;
* gravity (m/s², world): ``-g(q; e_k)``, the generalised gravity of a unit
  gravity along axis k (gravity enters RNEA linearly);
* through the efforts, ``∂tau/∂p`` (`Scene.tau_parameter_derivatives`): their own
  parameters (springs, gains, ...), and the model's where an effort is computed
  from the model when bound (the trot controller's feed-forward holds the
  weight: it moves with the masses, centres of mass and gravity);
* a contact's restitution and offset: zero (they act at events only);
* a contact's friction coefficient ``μ`` (``contact:NAME:friction``, or a group's):
  where the contact slides, its friction force ``-μ λ_N s`` moves by
  ``-λ_N A_T^T s`` per unit of ``μ`` at fixed ``λ_N`` (`ParameterForces.mode_forces`,
  which needs the mode's forces and slip directions); the mode's own response
  ``∂ddq/∂tau`` (with the sliding force rows ``F = A_n - μ s^T A_T``) then carries the
  change of ``λ_N`` it causes. Zero where it sticks or is open.

At an impact the balance is ``A^T Λ - M(q; p) (v+ - v-) = 0``;
`ParameterForces.impulse_forces` gives its ``∂/∂p`` at fixed velocities,
``-∂(M dv)/∂p`` (inertias and armature only; forces of finite size do no work
in an instant).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from ..model.kinematics import Kinematics
from ..model.parameter_types import Parameter, ParameterKind
from ..model.scene import Scene

_INERTIA_FIELDS = ("ixx", "ixy", "iyy", "ixz", "iyz", "izz")  # Pinocchio's order of the six
_RNEA_COLUMNS = 4  # bodies + inertial columns up to which RNEA differences beat the regressor
_AXES = {"x": 0, "y": 1, "z": 2}


def _parallel_axis(c: np.ndarray) -> np.ndarray:
    """``|c|² I - c cᵀ`` in Pinocchio's order of six (the inertia of a unit point mass at c)."""
    S = (c @ c) * np.eye(3) - np.outer(c, c)
    return S[[0, 0, 1, 0, 1, 2], [0, 1, 1, 2, 2, 2]]


def dynamic_parameter_derivative(inertia: pin.Inertia, field: str) -> np.ndarray:
    """``∂π/∂p`` (10,) of a body's dynamic parameters ``π`` (Pinocchio's
    ``Inertia.toDynamicParameters`` order: m, m c, inertia about the frame's origin) with
    respect to one of its named parameters ``field`` (``mass``, ``com_x|y|z``,
    ``ixx|ixy|ixz|iyy|iyz|izz`` about the centre of mass), at ``inertia``."""
    m, c = float(inertia.mass), np.array(inertia.lever)
    out = np.zeros(10)
    if field == "mass":
        out[0], out[1:4], out[4:] = 1.0, c, _parallel_axis(c)
    elif field.startswith("com_"):
        k = _AXES[field[-1]]
        e = np.zeros(3)
        e[k] = 1.0
        dS = 2.0 * c[k] * np.eye(3) - np.outer(e, c) - np.outer(c, e)  # ∂(|c|² I - c cᵀ)/∂c_k
        out[1 + k] = m
        out[4:] = m * dS[[0, 0, 1, 0, 1, 2], [0, 1, 1, 2, 2, 2]]
    else:
        out[4 + _INERTIA_FIELDS.index(field)] = 1.0  # a symmetric pair (ixy = iyx) is one parameter
    return out


class ParameterForces:
    """``∂f/∂p`` of the force balance and of the impact balance (module doc) for a list of
    a scene's parameters (from `contactdiff.model.parameters`), column by column.

    Args:
        scene: the scene (its model holds the parameters' current values).
        parameters: the parameters, in column order.
    """

    def __init__(self, scene: Scene, parameters: Sequence[Parameter]):
        self.scene, self.parameters = scene, list(parameters)
        model = scene.model
        self.model, self.nv, self.p = model, model.nv, len(self.parameters)
        self._data = model.createData()
        inertial: list[tuple[int, int, np.ndarray]] = []  # (column, joint, ∂π/∂p)
        self._armature: list[tuple[int, int]] = []  # (column, tangent index)
        self._gravity: list[tuple[int, pin.Model, pin.Data]] = []  # (column, unit-gravity model, data)
        # columns the efforts depend on: their own, and the model's where an effort is computed
        # from the model when bound (`model_parameter_derivatives`, the trot's feed-forward)
        self._efforts: list[int] = []
        self.friction_columns: dict[int, list[int]] = {}
        """Scene index of each contact -> the columns of the friction parameters that set its μ."""
        model_dependent = any(hasattr(e, "model_parameter_derivatives") for e in scene.efforts)
        for col, par in enumerate(self.parameters):
            kind = par.kind
            if kind is ParameterKind.BODY:
                inertial.append((col, par.joint, dynamic_parameter_derivative(model.inertias[par.joint], par.field)))
            elif kind is ParameterKind.JOINT:
                self._armature.append((col, model.joints[model.getJointId(par.target)].idx_v))
            elif kind is ParameterKind.SCENE:
                unit = model.copy()
                g = np.zeros(3)
                g[_AXES[par.field[-1]]] = 1.0
                unit.gravity = pin.Motion(g, np.zeros(3))
                self._gravity.append((col, unit, unit.createData()))
            contact = kind in (ParameterKind.CONTACT, ParameterKind.GROUP)
            if contact and par.field == "friction":
                for i in par.members:
                    self.friction_columns.setdefault(i, []).append(col)
            if not contact and (
                kind not in (ParameterKind.BODY, ParameterKind.JOINT, ParameterKind.SCENE) or model_dependent
            ):
                self._efforts.append(col)
        self._effort_parameters = [self.parameters[k] for k in self._efforts]
        # ∂π/∂p of the inertial columns as one matrix (10 per body × their count): one product
        # with the regressor gives them all
        self._inertial_columns = [col for col, _, _ in inertial]
        self._dpi = np.zeros((10 * (model.njoints - 1), len(inertial)))
        for k, (_, j, dpi) in enumerate(inertial):
            self._dpi[10 * (j - 1) : 10 * j, k] = dpi
        # a few inertial columns: RNEA is linear in the inertias, so a column is the difference
        # of two RNEA calls on models holding only its body (π + ∂π/∂p against π), a few µs
        # each, where the regressor computes every body's ten columns
        self._by_rnea = None
        bodies = sorted({j for _, j, _ in inertial})
        if inertial and len(bodies) + len(inertial) <= _RNEA_COLUMNS:

            def alone(j, pi):
                m = model.copy()
                for k in range(1, m.njoints):
                    m.inertias[k] = pin.Inertia.Zero()
                m.inertias[j] = pin.Inertia.FromDynamicParameters(pi)
                m.armature[:] = 0.0
                return m, m.createData()

            own = {j: model.inertias[j].toDynamicParameters() for j in bodies}
            self._by_rnea = (
                {j: alone(j, own[j]) for j in bodies},
                [(col, j, *alone(j, own[j] + dpi)) for col, j, dpi in inertial],
            )
        self._still = model.copy()  # no gravity: the regressor of M dv alone
        self._still.gravity = pin.Motion.Zero()
        self._still_data = self._still.createData()

    def forces(self, kin: Kinematics, q: np.ndarray, v: np.ndarray, ddq: np.ndarray, t: float) -> np.ndarray:
        """``∂f/∂p`` (nv × p) at ``(q, v, ddq)`` and time ``t`` (s); ``kin`` at ``(q, v)``."""
        out = np.zeros((self.nv, self.p))
        if self._by_rnea is not None:
            reference, columns = self._by_rnea
            base = {j: pin.rnea(m, d, q, v, ddq) for j, (m, d) in reference.items()}
            for col, j, m, d in columns:
                out[:, col] = base[j] - pin.rnea(m, d, q, v, ddq)
        elif self._inertial_columns:
            # (nv, 10 bodies); the binding returns a flat array when nv = 1
            Y = np.reshape(pin.computeJointTorqueRegressor(self.model, self._data, q, v, ddq), (self.nv, -1))
            out[:, self._inertial_columns] = -(Y @ self._dpi)
        for col, iv in self._armature:
            out[iv, col] = -ddq[iv]
        for col, unit, data in self._gravity:
            out[:, col] = -pin.computeGeneralizedGravity(unit, data, q)
        if self._efforts:
            out[:, self._efforts] += self.scene.tau_parameter_derivatives(kin, t, self._effort_parameters)
        return out

    def mode_forces(self, dyn, sol, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        """`forces` of ``sol`` (a `ModeSolution` of ``dyn``, a `ModeDynamics` of the
        scene, just solved at ``(q, v, t)``) plus the sliding contacts' friction columns:
        ``-λ_N A_T^T s`` for each parameter that sets a sliding contact's ``μ`` (module
        doc). ``dyn``'s kinematics must be at ``(q, v)``."""
        out = self.forces(dyn.kin, q, v, sol.ddq, t)
        if self.friction_columns:
            for key, rows in zip(sol.active, sol.row_slices):
                if not dyn.is_sliding(key) or not dyn.contact(key).slips:
                    continue
                index = dyn.contact_index(key)
                cols = self.friction_columns.get(index)
                if cols:
                    A_T = dyn.contact(key).full.rows(dyn.kin)[1:]
                    s = dyn.slip_direction(index, A_T @ v, jacobian=False)[0]
                    out[:, cols] -= (sol.forces[rows.start] * (A_T.T @ s))[:, None]
        return out

    def impulse_forces(self, q: np.ndarray, dv: np.ndarray) -> np.ndarray:
        """``-∂(M(q) dv)/∂p`` (nv × p) of an impact's balance, ``dv = v+ - v-`` (m/s, rad/s)."""
        out = np.zeros((self.nv, self.p))
        if self._inertial_columns:
            Y = np.reshape(
                pin.computeJointTorqueRegressor(self._still, self._still_data, q, np.zeros(self.nv), dv), (self.nv, -1)
            )
            out[:, self._inertial_columns] = -(Y @ self._dpi)
        for col, iv in self._armature:
            out[iv, col] = -dv[iv]
        return out


__all__ = ["ParameterForces", "dynamic_parameter_derivative"]
