"""Guard crossings over one step: detection, root location and grouping.

Small pure helpers in the style of scipy's ``_ivp`` event code. Guards are
scalar functions of time along the dense output of an accepted step; a crossing
is always *downward* (a touchdown gap or a normal force going from >= 0 to < 0),
so a reset never re-triggers its own event: right after an event the guard is
at zero moving up, which is not a downward crossing.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
from scipy.optimize import brentq

from ..errors import InvalidInputError

_EPS = np.finfo(float).eps


def hermite_minimum(g0: float, d0: float, g1: float, d1: float, h: float) -> tuple[float, float]:
    """Minimum of the cubic Hermite interpolant of a guard over one step.

    Args:
        g0: guard value at the step start (the guard's unit, e.g. m for a gap).
        d0: its time derivative at the step start (unit/s, e.g. m/s).
        g1: guard value at the step end.
        d1: its time derivative at the step end.
        h: step length (s).

    Returns:
        ``(s, value)``: normalised time ``s`` in [0, 1] of the minimum and the
        interpolant's value there. Detects a guard dipping below zero and coming
        back within one step (a double crossing) from end-point data alone.
    """
    # Python floats: this runs for every open contact after every step, and numpy
    # scalars cost several times as much per operation
    g0, d0, g1, d1, h = float(g0), float(d0), float(g1), float(d1), float(h)
    # p(s) = g0 + h d0 s + c2 s^2 + c3 s^3 on s in [0, 1]
    c2 = 3 * (g1 - g0) - h * (2 * d0 + d1)
    c3 = -2 * (g1 - g0) + h * (d0 + d1)
    best = (0.0, g0) if g0 <= g1 else (1.0, g1)
    # p'(s) = 3 c3 s^2 + 2 c2 s + h d0: its real roots in (0, 1)
    for s in _quadratic_roots(3 * c3, 2 * c2, h * d0):
        if 0.0 < s < 1.0:
            value = g0 + h * d0 * s + c2 * s * s + c3 * s**3
            if value < best[1]:
                best = (s, value)
    return best


def _quadratic_roots(a: float, b: float, c: float) -> list[float]:
    """Real roots of ``a x^2 + b x + c`` (a linear or constant one allowed), computed
    without cancellation (the root of larger magnitude first, then c / (a x1))."""
    if a == 0.0:
        return [-c / b] if b != 0.0 else []
    disc = b * b - 4.0 * a * c
    if disc < 0.0:
        return []
    big = -0.5 * (b + math.copysign(math.sqrt(disc), b))
    if big == 0.0:  # b = c = 0: double root at 0
        return [0.0]
    return [big / a, c / big]


def locate_crossing(
    guard: Callable[[float], float], t_a: float, t_b: float, g_a: float | None = None, g_b: float | None = None
) -> float:
    """Time of the downward zero crossing of ``guard`` in ``[t_a, t_b]``.

    Requires ``guard(t_a) > 0 >= guard(t_b)``. Brent's method to full double
    precision in time: ``|t - t*| <= 4 eps max(1, |t|)``.
    """
    g_a = guard(t_a) if g_a is None else g_a
    g_b = guard(t_b) if g_b is None else g_b
    if g_b == 0.0:
        return t_b
    if not (g_a > 0.0 > g_b):
        raise InvalidInputError(f"no bracket: guard({t_a!r}) = {g_a!r}, guard({t_b!r}) = {g_b!r}")
    xtol = 4 * _EPS * max(1.0, abs(t_a), abs(t_b))
    # the values given may be the step's own (its ends' states), the guard's the dense
    # output's, which differ from them by round-off: where they do not bracket, the
    # crossing is at the end whose value round-off put on the other side
    f_a, f_b = guard(t_a), guard(t_b)
    if f_a <= 0.0:
        return t_a
    if f_b >= 0.0:
        return t_b
    ends = {t_a: f_a, t_b: f_b}  # (brentq evaluates the ends again)
    return float(brentq(lambda t: ends[t] if t in ends else guard(t), t_a, t_b, xtol=xtol, rtol=4 * _EPS, maxiter=200))


def simultaneous_group(roots: Sequence[tuple[float, object]], tol: float) -> tuple[float, list]:
    """The earliest crossing time and every guard whose root lies within ``tol`` of it.

    Args:
        roots: ``(time, guard_id)`` pairs.
        tol: simultaneity tolerance (s).
    """
    t_first = min(t for t, _ in roots)
    return t_first, [g for t, g in sorted(roots, key=lambda r: r[0]) if t - t_first <= tol]
