"""Keeping a state on the constraint manifold of a contact mode, M-orthogonally.

Active contacts are held at the acceleration level, so their gaps and row
velocities drift by the integration error. These functions move a state back:
the configuration onto ``gap = 0`` by Gauss–Newton along the M-weighted
pseudo-inverse of the normal rows, the velocity onto ``A v = 0`` by removing the
row velocities M-orthogonally (the least change of kinetic energy), and, for a
flow Jacobian, the derivative of that map on the manifold.

Every function works in the tangent space (``q ⊕ dq``) and uses the kinematics
cache and Pinocchio data of ``dyn`` (a `ModeDynamics`); contacts are keys of
`contactdiff.dynamics.mode`.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

CLOSE_TOL = 1e-15
"""m: Gauss–Newton stops once every gap is this small."""
CLOSE_ITERATIONS = 10


def weighted_pinv(dyn, q: np.ndarray, A: np.ndarray) -> np.ndarray:
    """``M^-1 A^T (A M^-1 A^T)^+``: the M-orthogonal (minimum kinetic energy)
    pseudo-inverse of the rows ``A`` at ``q``; redundant rows are allowed."""
    MinvAT = pin.computeMinverse(dyn.model, dyn.data, q) @ A.T
    return MinvAT @ np.linalg.pinv(A @ MinvAT)


def mode_rows(dyn, mode) -> np.ndarray:
    """Stacked constraint rows of ``mode`` at the kinematics' current configuration."""
    return np.vstack([dyn.contact(k).rows(dyn.kin) for k in mode])


def close(dyn, q: np.ndarray, contacts) -> np.ndarray:
    """Project ``q`` M-orthogonally onto ``gap = 0`` of ``contacts`` (keys; Gauss–Newton)."""
    if not contacts:
        return q
    kin, zero = dyn.kin, np.zeros(dyn.model.nv)
    for _ in range(CLOSE_ITERATIONS):
        kin.update(q, zero)
        gaps = np.array([dyn.contact(k).gap(kin) for k in contacts])
        if np.max(np.abs(gaps)) <= CLOSE_TOL:
            break
        A = np.vstack([dyn.contact(k).rows(kin)[0] for k in contacts])
        q = pin.integrate(dyn.model, q, -weighted_pinv(dyn, q, A) @ gaps)
    return q


def held_velocity(dyn, q: np.ndarray, v: np.ndarray, mode) -> np.ndarray:
    """``v`` with the row velocities of ``mode`` removed M-orthogonally (the least
    kinetic-energy change that holds every contact of the mode)."""
    if not mode:
        return v
    dyn.kin.update(q, v)
    A = mode_rows(dyn, mode)
    return v - weighted_pinv(dyn, q, A) @ (A @ v)


def held_velocity_jacobian(dyn, q: np.ndarray, v: np.ndarray, mode) -> np.ndarray:
    """Derivative (2nv × 2nv, tangent space) of the map ``(q, v) -> (q, v - P A(q) v)``
    that holds the rows of ``mode`` (`held_velocity`), at a ``(q, v)`` that it holds
    (``A v = 0``): ``[[I, 0], [-P d(A v)/dq, I - P A]]``, ``P`` the M-weighted
    pseudo-inverse of the rows. At such a point the term of ``dP/dq`` vanishes, as
    it multiplies ``A v``."""
    nv = dyn.model.nv
    kin = dyn.kin
    kin.update(q, v, derivatives=True)
    A = mode_rows(dyn, mode)
    pinv = weighted_pinv(dyn, q, A)
    dAv = np.vstack([dyn.contact(k).rows_velocity_dq(kin) for k in mode])
    D = np.eye(2 * nv)
    D[nv:, nv:] -= pinv @ A
    D[nv:, :nv] -= pinv @ dAv
    return D


def project_state(dyn, q: np.ndarray, v: np.ndarray, mode, jacobian: bool = False):
    """``(q, v)`` moved onto the manifold of ``mode``: ``q`` onto ``gap = 0``, ``v``
    onto ``A v = 0``, both M-orthogonally.

    Returns:
        ``(q, v, D)``, with ``D`` (2nv × 2nv) the derivative of the map
        ``(q, v) -> (q - P a(q), v - P A(q) v)`` on the manifold when ``jacobian``
        (``D @ phi`` is the projected flow Jacobian), else None.
    """
    q = close(dyn, q, list(mode))
    kin = dyn.kin
    kin.update(q, v)
    A = mode_rows(dyn, mode)
    pinv = weighted_pinv(dyn, q, A)
    v = v - pinv @ (A @ v)
    if not jacobian:
        return q, v, None
    return q, v, projection_jacobian(dyn, q, v, mode)


def projection_jacobian(dyn, q: np.ndarray, v: np.ndarray, mode) -> np.ndarray:
    """``D`` (2nv × 2nv, tangent space) of `project_state` at a ``(q, v)`` on the manifold of
    ``mode``: `held_velocity_jacobian` with ``I - P_N A_N`` on the configuration block
    (``A_N`` the normal rows). ``D`` is the identity for the empty mode."""
    nv = dyn.model.nv
    if not mode:
        return np.eye(2 * nv)
    D = held_velocity_jacobian(dyn, q, v, mode)
    A = mode_rows(dyn, mode)
    normal = [0] + list(np.cumsum([dyn.contact(k).n_rows for k in mode])[:-1])
    D[:nv, :nv] -= weighted_pinv(dyn, q, A[normal]) @ A[normal]
    return D
