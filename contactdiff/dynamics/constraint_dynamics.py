"""Pinocchio's constraint dynamics for modes of sticking point contacts on the ground.

When every active contact of a mode is a sticking contact of one frame against
the ground with all three rows (normal and two tangents: a point that can move
in 3-D), the mode's KKT system is Pinocchio's 3-D rigid-contact problem, and
``pin.constraintDynamics`` with ``computeConstraintDynamicsDerivatives`` solve
it and differentiate it in C++ — about ten times faster than assembling the
rows, drifts and Hessians in Python. `ModeDynamics` uses this path for such
modes (the usual stance of a quadruped) and its own for the others
(frictionless rows, planar models, contacts between two frames, round contacts).

Conventions: Pinocchio's contact force ``f`` of a 3-D LOCAL_WORLD_ALIGNED
contact is in world axes at the frame origin, acting on the robot
(``M ddq = tau - nle + J^T f``). The rows of a `BoundContact` are its world
directions ``D`` (normal first), so its row forces are ``lam = D f``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pinocchio as pin

# mu = 0: no proximal regularisation, the exact KKT solution from one Cholesky
# factorisation (max_iter 1); accuracy only governs the (unused) iterations.
_SETTINGS = pin.ProximalSettings(1e-12, 0.0, 1)


def eligible(contacts: Sequence) -> bool:
    """Whether Pinocchio's 3-D contact dynamics represents this set of bound contacts.

    A round contact (radius > 0) is not: its rolling point is not fixed in the frame,
    while Pinocchio's contacts hold frame-fixed points."""
    return bool(contacts) and all(
        c.sticking and c.against_fid is None and c.n_rows == 3 and not c.radius for c in contacts
    )


class RigidContactMode:
    """One mode's constraint models and ``pinocchio.Data`` (built once per mode)."""

    def __init__(self, model: pin.Model, contacts: Sequence):
        self.model = model
        self.models = pin.StdVec_RigidConstraintModel()
        self.datas = pin.StdVec_RigidConstraintData()
        for c in contacts:
            frame = model.frames[c.fid]
            cm = pin.RigidConstraintModel(
                pin.ContactType.CONTACT_3D, model, frame.parentJoint, frame.placement, pin.LOCAL_WORLD_ALIGNED
            )
            self.models.append(cm)
            self.datas.append(cm.createData())
        self.data = model.createData()
        pin.initConstraintDynamics(model, self.data, self.models, self.datas)
        n = 3 * len(contacts)
        # world force components -> row forces, block diagonal of each contact's D
        self.rotation = np.zeros((n, n))
        for k, c in enumerate(contacts):
            self.rotation[3 * k : 3 * k + 3, 3 * k : 3 * k + 3] = c.directions

    def accelerations(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray) -> np.ndarray | None:
        """``ddq``, or None when Pinocchio's factorisation fails (redundant contacts), so
        that the caller falls back to least squares; the contact forces stay in
        ``data.lambda_c`` (world axes) until the next call."""
        try:
            ddq = pin.constraintDynamics(self.model, self.data, q, v, tau, self.models, self.datas, _SETTINGS)
        except RuntimeError:
            return None
        # a failed factorisation leaves non-finite accelerations (the forces enter them):
        # one dot product checks them all (an overflow to inf falls back too, harmlessly)
        return ddq if math.isfinite(ddq @ ddq) else None

    def solve(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """``(ddq, row forces)``, or None as `accelerations`."""
        ddq = self.accelerations(q, v, tau)
        return None if ddq is None else (ddq, self.rotation @ self.data.lambda_c)

    def derivatives(self, dtau_dq: np.ndarray, dtau_dv: np.ndarray):
        """Derivatives at the state of the last `solve`, efforts' own derivatives included:
        ``(ddq_dq, ddq_dv, forces_dq, forces_dv, ddq_dtau, forces_dtau)`` in the tangent
        space, the last two the responses to a generalised force (row forces)."""
        ddq_dq, ddq_dv, ddq_dtau, lam_dq, lam_dv, lam_dtau = pin.computeConstraintDynamicsDerivatives(
            self.model, self.data, self.models, self.datas, _SETTINGS
        )
        R = self.rotation
        forces_dtau = R @ lam_dtau
        return (
            ddq_dq + ddq_dtau @ dtau_dq,
            ddq_dv + ddq_dtau @ dtau_dv,
            R @ lam_dq + forces_dtau @ dtau_dq,
            R @ lam_dv + forces_dtau @ dtau_dv,
            ddq_dtau,
            forces_dtau,
        )
