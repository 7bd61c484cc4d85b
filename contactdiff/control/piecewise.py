"""A function of the gait phase that is one polynomial between breakpoints, as a table.

A clock-driven schedule made of polynomial pieces (smooth steps, spline
pieces, their products) is, between consecutive breakpoints, one polynomial of
known degree. `PiecewisePolynomial` interpolates such a function once, at
``degree + 1`` Chebyshev points of each piece, which reproduces it to
round-off, and then evaluates it with one small matrix product: a dozen
Python-level evaluations of the formulas become one table lookup.
"""

from __future__ import annotations

import bisect
from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InvalidInputError


class PiecewisePolynomial:
    """Values ``f(phi)`` (m,) for ``phi`` in [0, 1) of a vector function that is one
    polynomial of degree at most ``degree`` on each piece between consecutive breakpoints.

    Args:
        breaks: sorted breakpoint phases in [0, 1), the first 0 (pieces ``[b_i, b_i+1)``,
            the last up to 1).
        sample: ``sample(phis) -> (len(phis), m)``, the function at many phases at once.
        degree: the largest degree of a piece.

    Attributes:
        starts: the pieces' first phases (a list: the evaluation bisects it).
    """

    def __init__(self, breaks: ArrayLike, sample: Callable[[np.ndarray], np.ndarray], degree: int):
        breaks = np.asarray(breaks, dtype=float)
        if (
            breaks.ndim != 1
            or not breaks.size
            or breaks[0] != 0.0
            or np.any(np.diff(breaks) <= 0.0)
            or breaks[-1] >= 1.0
        ):
            raise InvalidInputError(f"breaks must rise strictly from 0 to below 1, got {breaks!r}")
        n = degree + 1
        nodes = np.cos(np.pi * (np.arange(n) + 0.5) / n)  # Chebyshev: a well-conditioned interpolation
        vandermonde_inv = np.linalg.inv(np.vander(nodes, n, increasing=True))
        ends = np.append(breaks, 1.0)
        widths = np.diff(ends)
        phis = breaks[:, None] + widths[:, None] * (nodes[None, :] + 1.0) / 2.0
        values = np.asarray(sample(phis.ravel()), dtype=float).reshape(len(breaks), n, -1)
        # monomial coefficients in x in [-1, 1] across each piece
        self.table = np.einsum("ij,pjk->pik", vandermonde_inv, values)
        self.starts, self._widths = breaks.tolist(), widths.tolist()
        self._exponents = np.arange(n, dtype=float)
        self.degree = degree
        self.condition = float(np.linalg.cond(np.vander(nodes, n, increasing=True), np.inf))
        """Condition number (inf-norm) of the interpolation: values are reproduced to
        about ``condition * (degree + 1) * eps`` times their size."""

    def __call__(self, phi: float) -> np.ndarray:
        """The function at phase ``phi`` in [0, 1)."""
        i = bisect.bisect_right(self.starts, phi) - 1  # a list: on an array each probe is a numpy scalar
        x = 2.0 * (phi - self.starts[i]) / self._widths[i] - 1.0
        return np.power(x, self._exponents) @ self.table[i]
