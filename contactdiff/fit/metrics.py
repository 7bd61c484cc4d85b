"""How far a simulated pose trajectory is from a measured one: the published cube-toss metrics.

Both metrics compare two trajectories sampled at the same times and average
over the samples (uniform sampling makes that the time average):

* `position_error`: mean over samples of ``‖p_sim − p_data‖`` (m), optionally
  as a percentage of a length (the cube's edge, as ContactNets and Acosta, Yang
  and Posa report it);
* `rotation_error`: mean over samples of the angle of the relative rotation
  ``R_dataᵀ R_sim`` (degrees), ``2 acos |⟨q_sim, q_data⟩|`` for unit quaternions.

Quaternions are ``[qx qy qz qw]`` (Pinocchio's order, as the free-flyer's
configuration holds them); ``q`` and ``−q`` are the same rotation.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InvalidInputError


def _pair(name: str, simulated, measured, width: int) -> tuple[np.ndarray, np.ndarray]:
    a, b = np.asarray(simulated, dtype=float), np.asarray(measured, dtype=float)
    if a.ndim != 2 or a.shape[1] != width or a.shape != b.shape or len(a) == 0:
        raise InvalidInputError(
            f"{name}: expected two (n, {width}) arrays of the same shape with n >= 1, got {a.shape} and {b.shape}"
        )
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        raise InvalidInputError(f"{name}: the trajectories hold non-finite values")
    return a, b


def position_errors(simulated: ArrayLike, measured: ArrayLike) -> np.ndarray:
    """``‖p_sim − p_data‖`` at each sample (m), from two ``(n, 3)`` position arrays."""
    a, b = _pair("position_errors", simulated, measured, 3)
    return np.linalg.norm(a - b, axis=1)


def position_error(simulated: ArrayLike, measured: ArrayLike, scale: float | None = None) -> float:
    """The time average of ``‖p_sim − p_data‖``: in m, or in percent of ``scale`` (m) when given."""
    mean = float(np.mean(position_errors(simulated, measured)))
    if scale is None:
        return mean
    if not (np.isfinite(scale) and scale > 0.0):
        raise InvalidInputError(f"position_error: scale must be a length > 0 (m), got {scale!r}")
    return 100.0 * mean / scale


def rotation_errors(simulated: ArrayLike, measured: ArrayLike) -> np.ndarray:
    """The angle between the two orientations at each sample (degrees), from ``(n, 4)``
    quaternion arrays ``[qx qy qz qw]`` (normalised here; a zero quaternion is refused)."""
    a, b = _pair("rotation_errors", simulated, measured, 4)
    na, nb = np.linalg.norm(a, axis=1), np.linalg.norm(b, axis=1)
    if np.any(na < 1e-12) or np.any(nb < 1e-12):
        raise InvalidInputError("rotation_errors: a quaternion of zero norm")
    a, b = a / na[:, None], b / nb[:, None]
    # the relative rotation conj(a) b: scalar part cos(θ/2), vector part of norm |sin(θ/2)|;
    # atan2 of the two keeps small angles exact where acos of a cosine near 1 loses them
    cosine = np.abs(np.sum(a * b, axis=1))
    vector = a[:, 3:] * b[:, :3] - b[:, 3:] * a[:, :3] - np.cross(a[:, :3], b[:, :3])
    sine = np.linalg.norm(vector, axis=1)
    return np.degrees(2.0 * np.arctan2(sine, cosine))


def rotation_error(simulated: ArrayLike, measured: ArrayLike) -> float:
    """The time average of the angle between the orientations (degrees)."""
    return float(np.mean(rotation_errors(simulated, measured)))


__all__ = ["position_error", "position_errors", "rotation_error", "rotation_errors"]
