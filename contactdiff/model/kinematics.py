"""Per-state kinematics cache shared by contacts and efforts.

One `Kinematics` object owns a ``pinocchio.Data`` and holds, for the state
``(q, v)`` of its last `update`, frame positions, Jacobians and classical
accelerations (all in the LOCAL_WORLD_ALIGNED frame: world axes, at the frame
origin) and, when asked, their derivatives; for round contacts, also the
frames' angular velocities' Jacobians, angular accelerations and their
derivatives (LOCAL_WORLD_ALIGNED too: world axes). Each quantity is computed once per
update, however many contacts or springs use the frame, and only when first
asked for: a mode whose efforts and contacts need no frame kinematics (joint
springs, contacts handled by Pinocchio's constraint dynamics) pays for none.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ..errors import InvalidInputError

LWA = pin.LOCAL_WORLD_ALIGNED


def _matrix(x: np.ndarray, rows: int) -> np.ndarray:
    """Pinocchio returns an (r × 1) matrix as a 1-D array when nv = 1; restore the shape."""
    return x.reshape(rows, -1)


class Kinematics:
    """Frame kinematics at one state ``(q, v)`` with zero joint acceleration.

    Call `update` first; derivative getters need ``update(..., derivatives=True)``.
    Every derivative with respect to ``q`` is taken in the tangent space
    (column ``k`` = perturbation ``q ⊕ ε e_k``).
    """

    def __init__(self, model: pin.Model):
        self.model = model
        self.data = model.createData()
        self._zero = np.zeros(model.nv)
        self._cache: dict = {}
        # the state of the last `update`; None before the first (nothing is read before it)
        self.q: np.ndarray = None  # type: ignore[assignment]  # set by the first update
        self.v: np.ndarray = None  # type: ignore[assignment]  # set by the first update
        self.has_derivatives = False
        self._fresh = self._fresh_derivatives = False

    def update(self, q: np.ndarray, v: np.ndarray, derivatives: bool = False) -> None:
        """Move the cache to the state ``(q, v)`` (joint acceleration 0).

        Nothing is computed here: placements and Jacobians on first use, their
        derivatives on first use of a derivative getter. ``q`` and ``v`` are
        copied, so the caller may reuse its buffers.
        """
        self.q, self.v, self.has_derivatives = np.array(q, dtype=float), np.array(v, dtype=float), derivatives
        self._fresh = self._fresh_jacobians = self._fresh_derivatives = False
        self._cache.clear()

    def _kinematics(self) -> pin.Data:
        """Placements, velocities and classical accelerations (a gap, a gap rate, a drift
        need no Jacobian: the guards evaluate gaps along every located event)."""
        if not self._fresh:
            m, d = self.model, self.data
            pin.forwardKinematics(m, d, self.q, self.v, self._zero)  # a = 0: classical acc = drift
            pin.updateFramePlacements(m, d)
            self._fresh = True
        return self.data

    def _jacobian_data(self) -> pin.Data:
        """`_kinematics` and the joint Jacobians (from the same forward pass)."""
        if not self._fresh_jacobians:
            pin.computeJointJacobians(self.model, self._kinematics())
            self._fresh_jacobians = True
        return self.data

    def _derivative_data(self) -> pin.Data:
        if not self.has_derivatives:
            raise InvalidInputError("Kinematics.update(..., derivatives=True) must come first")
        if not self._fresh_derivatives:
            m, d = self.model, self._jacobian_data()
            pin.computeForwardKinematicsDerivatives(m, d, self.q, self.v, self._zero)
            pin.computeJointKinematicHessians(m, d, self.q)
            self._fresh_derivatives = True
        return self.data

    def _memo(self, key, compute):
        value = self._cache.get(key)
        if value is None:
            value = self._cache[key] = compute()
        return value

    def position(self, fid: int) -> np.ndarray:
        """World position of frame ``fid`` (3,)."""
        return self._kinematics().oMf[fid].translation

    def jacobian(self, fid: int) -> np.ndarray:
        """Linear LWA Jacobian of the frame origin, d p / d q (3 × nv)."""
        return self._memo(
            ("J", fid), lambda: _matrix(pin.getFrameJacobian(self.model, self._jacobian_data(), fid, LWA), 6)[:3].copy()
        )

    def velocity(self, fid: int) -> np.ndarray:
        """World velocity of the frame origin (3,) (from the forward pass with ``v``: no
        Jacobian needed)."""
        return pin.getFrameVelocity(self.model, self._kinematics(), fid, LWA).linear

    def classical_acceleration(self, fid: int) -> np.ndarray:
        """Classical acceleration of the frame origin at zero joint acceleration: ``J̇ v`` (3,)."""
        return self._memo(
            ("a", fid),
            lambda: pin.getFrameClassicalAcceleration(self.model, self._kinematics(), fid, LWA).linear.copy(),
        )

    def velocity_derivative(self, fid: int) -> np.ndarray:
        """d(J v)/dq of the frame origin velocity at fixed ``v`` (3 × nv)."""
        frame = self.model.frames[fid]
        return self._memo(
            ("dv", fid),
            lambda: _matrix(
                pin.getPointVelocityDerivatives(
                    self.model, self._derivative_data(), frame.parentJoint, frame.placement, LWA
                )[0],
                3,
            ).copy(),
        )

    def acceleration_derivatives(self, fid: int) -> tuple[np.ndarray, np.ndarray]:
        """d(J̇ v)/dq and d(J̇ v)/dv of the classical acceleration at zero joint acceleration."""
        frame = self.model.frames[fid]

        def compute():
            _, dq, dv, _ = pin.getPointClassicAccelerationDerivatives(
                self.model, self._derivative_data(), frame.parentJoint, frame.placement, LWA
            )
            return _matrix(dq, 3).copy(), _matrix(dv, 3).copy()

        return self._memo(("da", fid), compute)

    def hessian(self, fid: int) -> np.ndarray:
        """Kinematic Hessian of the frame origin: ``H[c, j, k] = d J[c, j] / d q_k`` (3 × nv × nv)."""

        def compute():
            H = pin.getFrameKinematicHessian(self.model, self._derivative_data(), fid, LWA)
            # Pinocchio returns column-major memory flagged as C order (notes, pitfall 4).
            return H.ravel(order="C").reshape(H.shape, order="F")[:3].copy()

        return self._memo(("H", fid), compute)

    # -- angular terms (round contacts: `contactdiff.model.contacts`) ------------------
    def angular_jacobian(self, fid: int) -> np.ndarray:
        """Angular LWA Jacobian of the frame, ``ω = J_ω v`` in world axes (3 × nv)."""
        return self._memo(
            ("Jw", fid),
            lambda: _matrix(pin.getFrameJacobian(self.model, self._jacobian_data(), fid, LWA), 6)[3:].copy(),
        )

    def angular_acceleration(self, fid: int) -> np.ndarray:
        """Angular acceleration of the frame at zero joint acceleration, ``J̇_ω v`` (3,),
        world axes (the classical and the spatial acceleration share it)."""
        return self._memo(
            ("aw", fid),
            lambda: pin.getFrameClassicalAcceleration(self.model, self._kinematics(), fid, LWA).angular.copy(),
        )

    def angular_derivatives(self, fid: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``d ω/dq`` at fixed ``v``, ``d α/dq`` and ``d α/dv`` at zero joint acceleration
        (each 3 × nv), ``ω`` and ``α`` the frame's angular velocity and acceleration in
        world axes. (The angular rows of Pinocchio's LWA frame derivatives match finite
        differences; their linear rows do not, hence the point derivatives above.)"""

        def compute():
            dv_dq, da_dq, da_dv, _ = pin.getFrameAccelerationDerivatives(self.model, self._derivative_data(), fid, LWA)
            return tuple(_matrix(x, 6)[3:].copy() for x in (dv_dq, da_dq, da_dv))

        return self._memo(("dw", fid), compute)

    def angular_hessian(self, fid: int) -> np.ndarray:
        """Kinematic Hessian of the angular Jacobian: ``H[c, j, k] = d J_ω[c, j] / d q_k``
        (3 × nv × nv)."""

        def compute():
            H = pin.getFrameKinematicHessian(self.model, self._derivative_data(), fid, LWA)
            return H.ravel(order="C").reshape(H.shape, order="F")[3:].copy()

        return self._memo(("Hw", fid), compute)
