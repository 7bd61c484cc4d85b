"""Step-size control shared by the steppers: the error norms, the step factors, the
first step and the round-off bound on a step's length.

A step's error is the RMS norm (`rms`) of its local error in the chart ``y = (xi, v)``
divided by ``atol + rtol |y|`` (scipy's norm); the flow Jacobian's is the largest such
norm over its columns (`rms_cols`, CVODES' norm for a set of sensitivities).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

_EPS = np.finfo(float).eps
_SAFETY = 0.9
_MIN_FACTOR = 0.2  # largest allowed step decrease after a rejection
_MAX_FACTOR = 10.0  # largest allowed step increase
ROUNDOFF_MARGIN = 10.0
"""A step's round-off, ``eps |y_new - y|`` (the dense output and the stages add terms the
size of the step's change), times this margin must stay within the tolerance at the
step's start, ``atol + rtol |y|`` (RMS over the components, as the error): see
`roundoff_error`."""


def _rms(x: np.ndarray) -> float:
    return math.sqrt(float(np.vdot(x, x)) / x.size)


def _rms_cols(x: np.ndarray) -> float:
    """Largest RMS over the rows of a column of ``x`` (n x m); inf if not finite."""
    err = math.sqrt(float(np.max(np.einsum("ij,ij->j", x, x))) / x.shape[0])
    return err if math.isfinite(err) else math.inf


def initial_step(
    interval: float,
    max_step: float,
    y0: np.ndarray,
    f0: np.ndarray,
    mag0: np.ndarray,
    atol: float | np.ndarray,
    rtol: float,
    error_order: int,
    field: Callable[[float, np.ndarray], np.ndarray | None],
) -> float:
    """Hairer–Nørsett–Wanner's starting step (as scipy's ``select_initial_step``), in s.

    Args:
        interval: time left to ``t_bound`` (s).
        max_step: largest step (s).
        y0: the state in its chart at the step's start (2nv,).
        f0: its derivative ``dy/dt`` there (2nv,).
        mag0: sizes that ``rtol`` is relative to, per component of ``y0``.
        atol: absolute tolerance, scalar or (2nv,).
        rtol: relative tolerance.
        error_order: the method's (local error ``O(h^(error_order + 1))``).
        field: ``field(h0, y1)``: ``dy/dt`` at ``t0 + h0`` and ``y1`` (same chart), or
            None where that trial point leaves the field's domain.
    """
    if interval == 0.0:
        return min(1.0, max_step)  # nothing to integrate; any positive value
    scale = atol + rtol * mag0
    d0 = _rms(mag0 / scale)
    d1 = _rms(f0 / scale)
    h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
    h0 = min(h0, interval)
    f1 = field(h0, y0 + h0 * f0)
    if f1 is None:  # the trial point left the field's domain: the step will shrink
        return min(h0, max_step)
    d2 = _rms((f1 - f0) / scale) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / (error_order + 1))
    return min(100 * h0, h1, interval, max_step)


def roundoff_error(y: np.ndarray, y_new: np.ndarray, mag: np.ndarray, atol: float | np.ndarray, rtol: float) -> float:
    """Round-off of a step from ``y`` to ``y_new`` (same chart) relative to the tolerance
    at its start (``mag``: the sizes ``rtol`` is relative to there), times `ROUNDOFF_MARGIN`.
    A step where this exceeds 1 is rejected; below, it caps the growth of the next step (the
    error control's choice is kept wherever it is smaller, so ordinary runs never see it).

    The error estimate of an exact step is zero (free flight under constant gravity
    is a polynomial), so without this bound such steps grow tenfold each time until
    ``t_bound``: their length, and the state's change over them, then scale with the
    final time asked for (a ball bouncing at t = 12 s in a step to t = 1e9 s). Every
    point of a step's dense output carries round-off of order eps times that change,
    which for long enough steps exceeds the tolerance where the step starts (a ball's
    bounce of 1e-6 m/s, just after a step's start, resolved in a step whose end lies
    5e17 m below the ground). The bound keeps every step's round-off below its
    tolerance, whatever the final time; it never binds on steps of ordinary length
    (with atol = 1e-10 a step would have to change a state component by ~1e4)."""
    scale = atol + rtol * mag
    return ROUNDOFF_MARGIN * _EPS * _rms((y_new - y) / scale)
