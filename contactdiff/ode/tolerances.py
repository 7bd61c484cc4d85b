"""A stepper's error tolerances, checked: the state's relative and absolute ones, and
the flow Jacobian's absolute one per row and per column (the norms they enter are in
`contactdiff.ode.step_control`; what each means is in `contactdiff.ode.base.Stepper`'s
arguments)."""

from __future__ import annotations

import numpy as np

from ..errors import InvalidInputError, check_number
from .step_control import _EPS

RTOL_FLOOR = 100 * _EPS
"""Smallest relative tolerance a stepper takes (100 eps): below it the error estimate
is round-off."""


def checked_rtol(rtol) -> float:
    """``rtol`` as a float, refused below `RTOL_FLOOR` or not finite."""
    rtol = check_number("stepper", "rtol", rtol)
    if rtol < RTOL_FLOOR:
        raise InvalidInputError(f"rtol must be >= 100*eps = {RTOL_FLOOR:.3g}, got {rtol!r}")
    return rtol


def checked_atol(atol, n: int) -> float | np.ndarray:
    """``atol`` as a float, or (n,) per entry of the state ``(δq, δv)``; positive and finite."""
    atol_arr = np.array(atol, dtype=float)
    if atol_arr.shape not in ((), (n,)):
        raise InvalidInputError(f"atol must be a scalar or have shape ({n},), got shape {atol_arr.shape}")
    if not (np.isfinite(atol_arr).all() and (atol_arr > 0).all()):
        raise InvalidInputError(f"atol must be positive and finite, got {atol!r}")
    return float(atol_arr) if atol_arr.ndim == 0 else atol_arr


def variational_row_atol(atol: float | np.ndarray, variational_atol, n: int) -> float | np.ndarray:
    """The flow Jacobian's absolute tolerance: a float, or (n, 1) per row; the state's
    ``atol`` (checked) when ``variational_atol`` is None."""
    if variational_atol is None:
        return atol if np.ndim(atol) == 0 else np.asarray(atol)[:, None]
    va = np.array(variational_atol, dtype=float)
    if va.shape not in ((), (n,)):
        raise InvalidInputError(f"variational_atol must be a scalar or have shape ({n},), got shape {va.shape}")
    if not (np.isfinite(va).all() and (va > 0).all()):
        raise InvalidInputError(f"variational_atol must be positive and finite, got {variational_atol!r}")
    return float(va) if va.ndim == 0 else va[:, None]


def column_scaled_atol(row_atol: float | np.ndarray, column_scale, m: int) -> np.ndarray:
    """``row_atol`` divided by each column's typical perturbation ``column_scale`` ((m,),
    positive and finite): (rows, m), CVODES' ``atolS = atol / pbar``."""
    pbar = np.array(column_scale, dtype=float)
    if pbar.shape != (m,) or not (np.isfinite(pbar).all() and (pbar > 0).all()):
        raise InvalidInputError(
            f"variational_column_scale must be {m} positive finite numbers (one per "
            f"column of variational), got {column_scale!r}"
        )
    return np.reshape(row_atol, (-1, 1)) / pbar[None, :]


__all__ = ["RTOL_FLOOR", "checked_rtol", "checked_atol", "column_scaled_atol", "variational_row_atol"]
