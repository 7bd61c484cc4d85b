"""Residuals of a simulated configuration against a measured one, on the configuration manifold.

For every sample the residual has one row per velocity coordinate of the model
(``nv``), joint by joint:

* a **free-flyer** joint (a floating base, an object): the position error
  ``p_sim − p_data`` (m, world frame) times `ResidualWeights.position`, then the
  orientation error ``log(R_dataᵀ R_sim)`` (rad, a rotation vector in the
  measured body's frame) times `ResidualWeights.orientation`;
* every other joint: Pinocchio's ``difference(q_data, q_sim)`` on that joint
  (rad for a revolute joint, m for a prismatic one, a rotation vector for a
  spherical one) times `ResidualWeights.joint`.

The weights turn each kind into a common unit of the least-squares cost:
``position`` is per metre, ``orientation`` and ``joint`` per radian (or per
metre for prismatic joints); all three default to 1. The derivative of the residual in the
simulated configuration's tangent space (Pinocchio's local convention,
``q ⊕ δ``) is exact: ``[R_sim 0]`` for the position rows (a local step moves
the origin by ``R_sim δ_lin``), ``[0 Jlog3(R_dataᵀ R_sim)]`` for the
orientation rows, and ``dDifference`` for the other joints.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ..errors import InvalidInputError


@dataclass(frozen=True)
class ResidualWeights:
    """What one unit of each residual kind counts in the cost (see the module doc).

    Attributes:
        position: per metre of a free body's position error (1/m).
        orientation: per radian of a free body's orientation error (1/rad).
        joint: per radian (revolute) or metre (prismatic) of another joint's error.
    """

    position: float = 1.0
    orientation: float = 1.0
    joint: float = 1.0

    def __post_init__(self):
        for name in ("position", "orientation", "joint"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and np.isfinite(value) and value >= 0.0):
                raise InvalidInputError(f"ResidualWeights: {name} must be a finite number >= 0, got {value!r}")


class PoseResidual:
    """The residual rows of one model's configuration against a measured one (module doc).

    Args:
        model: the Pinocchio model whose configurations are compared.
        weights: the `ResidualWeights`.
    """

    def __init__(self, model: pin.Model, weights: ResidualWeights = ResidualWeights()):
        self.model = model
        self.weights = weights
        self._free = [(j.idx_q, j.idx_v) for j in model.joints[1:] if j.shortname() == "JointModelFreeFlyer"]
        scale = np.full(model.nv, weights.joint)
        for _, iv in self._free:
            scale[iv : iv + 3] = weights.position
            scale[iv + 3 : iv + 6] = weights.orientation
        self.scale = scale

    def residual(self, q_sim: np.ndarray, q_data: np.ndarray) -> np.ndarray:
        """The weighted residual (nv,) of the configuration ``q_sim`` against ``q_data``."""
        r = (
            pin.difference(self.model, q_data, q_sim)
            if len(self._free) < len(self.model.joints) - 1
            else np.zeros(self.model.nv)
        )
        for iq, iv in self._free:
            r[iv : iv + 3] = q_sim[iq : iq + 3] - q_data[iq : iq + 3]
            r[iv + 3 : iv + 6] = pin.log3(_rotation(q_data, iq).T @ _rotation(q_sim, iq))
        return self.scale * r

    def jacobian(self, q_sim: np.ndarray, q_data: np.ndarray) -> np.ndarray:
        """The derivative (nv × nv) of `residual` in ``q_sim``'s tangent space (local steps)."""
        J = (
            pin.dDifference(self.model, q_data, q_sim, pin.ARG1)
            if len(self._free) < len(self.model.joints) - 1
            else np.zeros((self.model.nv, self.model.nv))
        )
        for iq, iv in self._free:
            J[iv : iv + 6, :] = 0.0
            J[iv : iv + 3, iv : iv + 3] = _rotation(q_sim, iq)
            J[iv + 3 : iv + 6, iv + 3 : iv + 6] = pin.Jlog3(_rotation(q_data, iq).T @ _rotation(q_sim, iq))
        return self.scale[:, None] * J


def _rotation(q: np.ndarray, iq: int) -> np.ndarray:
    """The rotation of the free-flyer whose configuration starts at ``iq`` (``[x y z qx qy qz qw]``)."""
    return pin.Quaternion(q[iq + 6], *q[iq + 3 : iq + 6]).normalized().matrix()


__all__ = ["PoseResidual", "ResidualWeights"]
