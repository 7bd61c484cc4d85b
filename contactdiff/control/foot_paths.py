"""The trot's foot paths and the joint reference that realises them.

Each foot follows a path in the body frame relative to its stance position,
built from quintic smooth steps (`foot_offset`; the shapes are described in
`contactdiff.control.trot_controller`); `reference_spline` solves the inverse
kinematics of those paths at equally spaced phases and returns the periodic
cubic spline through the joint angles.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
from scipy.interpolate import CubicSpline

from ..errors import InvalidInputError
from ..model.robot import Robot
from .legs import Leg

SWING_RISE = 0.3
"""Fraction of the swing over which a foot rises to its step height."""

_IK_TOL = 1e-12  # m: foot position residual of the inverse kinematics
_IK_ITERATIONS = 50


def smooth_step(u):
    """Quintic ``S(u) = 10u³ - 15u⁴ + 6u⁵``: 0 -> 1 on [0, 1] with zero slope and curvature at both ends."""
    return u**3 * (10.0 - 15.0 * u + 6.0 * u**2)


def _ramp(x, a: float, b: float):
    """``S`` from 0 at ``x = a`` to 1 at ``x = b`` (clamped outside)."""
    return smooth_step(np.clip((x - a) / (b - a), 0.0, 1.0))


def foot_offset(spec, psi):
    """Foot displacement ``(dx, dz)`` (m, base frame) from the stance pose at leg phase
    ``psi`` (a number or an array) of the `TrotController` ``spec``."""
    s = spec
    psi = np.asarray(psi, dtype=float)
    stance = psi < s.duty
    u = np.where(stance, psi / s.duty, (psi - s.duty) / (1.0 - s.duty))
    dx = np.where(stance, s.step_length * (0.5 - smooth_step(u)), s.step_length * (smooth_step(u) - 0.5))
    top, final = s.duty + SWING_RISE * (1.0 - s.duty), 1.0 - s.approach
    up = (
        s.step_height * _ramp(psi, s.duty, top)
        - (s.step_height - s.approach_height) * _ramp(psi, top, final)
        - s.approach_height * _ramp(psi, final, 1.0)
    )
    return dx, np.where(stance, 0.0, up)


def reference_spline(
    spec, robot: Robot, legs: list[Leg], offsets: list[float], q_stance: np.ndarray, n_joints: int
) -> CubicSpline:
    """The periodic cubic spline, over the gait phase, of the leg joints (legs in order,
    ``n_joints`` columns) that place each foot on its path: exact inverse kinematics at
    ``spec.samples`` equally spaced phases, leg ``k`` at leg phase ``phi + offsets[k]``."""
    n = spec.samples
    phis = np.arange(n + 1) / n
    values = np.empty((n + 1, n_joints))
    model = robot.model
    data = model.createData()
    pin.framesForwardKinematics(model, data, q_stance)
    start = 0
    for k, leg in enumerate(legs):
        fid = robot.frame_id(leg.foot)
        p0 = data.oMf[fid].translation.copy()
        cols = slice(start, start + len(leg.iq))
        start += len(leg.iq)
        q = q_stance.copy()
        dxs, dzs = foot_offset(spec, (phis[:-1] + offsets[k]) % 1.0)  # all phases at once
        for i, (dx, dz) in enumerate(zip(dxs, dzs)):
            q = _inverse_kinematics(spec, robot, q, leg, fid, p0 + np.array([float(dx), 0.0, float(dz)]), data)
            values[i, cols] = q[list(leg.iq)]
    values[-1] = values[0]
    return CubicSpline(phis, values, bc_type="periodic")


def _inverse_kinematics(spec, robot: Robot, q, leg: Leg, fid: int, target, data) -> np.ndarray:
    """Leg joints placing foot ``fid`` at ``target`` (base frame; Gauss–Newton, warm start ``q``)."""
    model = robot.model
    q = q.copy()
    iq, iv = list(leg.iq), list(leg.iv)
    for _ in range(_IK_ITERATIONS):
        pin.forwardKinematics(model, data, q)
        pin.updateFramePlacements(model, data)
        error = target - data.oMf[fid].translation
        if np.linalg.norm(error) <= _IK_TOL:
            return q
        J = pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL_WORLD_ALIGNED)[:3, iv]
        q[iq] += np.linalg.lstsq(J, error, rcond=None)[0]
    raise InvalidInputError(
        f"trot controller: foot {leg.foot!r} cannot reach {np.round(target, 4).tolist()} m (base frame) "
        f"with step_height={spec.step_height} m, step_length={spec.step_length} m "
        f"(residual {np.linalg.norm(error):.3g} m); lower them"
    )
