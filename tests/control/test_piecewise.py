"""`PiecewisePolynomial` against functions whose pieces are known polynomials."""

from __future__ import annotations

import numpy as np
import pytest

from contactdiff.control.piecewise import PiecewisePolynomial
from contactdiff.errors import InvalidInputError

BREAKS = np.array([0.0, 0.1, 0.35, 0.6, 0.9])


def _kinked(phis):
    """Two columns, each one polynomial of degree <= 5 between BREAKS: a quintic smooth
    step over [0.1, 0.35] (its third derivative jumps at both ends) and a cubic in
    (phi - 0.6) switched on at 0.6."""
    phis = np.asarray(phis, dtype=float)
    u = np.clip((phis - 0.1) / 0.25, 0.0, 1.0)
    step = u**3 * (10.0 - 15.0 * u + 6.0 * u**2)
    cubic = np.where(phis >= 0.6, 3.0 * (phis - 0.6) ** 3 - (phis - 0.6), 0.0)
    return np.stack([step, cubic], axis=1)


def test_reproduces_a_piecewise_polynomial_to_round_off():
    table = PiecewisePolynomial(BREAKS, _kinked, degree=5)
    phis = np.random.default_rng(1).uniform(0.0, 1.0, 2000)
    got = np.array([table(p) for p in phis])
    # interpolation by the inverse Vandermonde: at most condition x (degree + 1) x eps
    # times the values' size (1 here)
    bound = table.condition * 6 * np.finfo(float).eps
    np.testing.assert_allclose(got, _kinked(phis), rtol=0, atol=bound)
    np.testing.assert_allclose(table(0.6), [1.0, 0.0], rtol=0, atol=bound)  # a breakpoint itself


def test_a_kink_inside_a_piece_is_not_reproduced():
    """The table is exact only where the breakpoints are complete: without 0.35 the
    smooth step's end falls inside a piece and the interpolant misses it by far more
    than round-off (a check that the first test could fail)."""
    table = PiecewisePolynomial(np.delete(BREAKS, 2), _kinked, degree=5)
    phis = np.linspace(0.1, 0.6, 501)
    error = np.max(np.abs(np.array([table(p) for p in phis]) - _kinked(phis)))
    assert error > 1e-6


@pytest.mark.parametrize("breaks", [[0.1, 0.5], [0.0, 0.5, 0.5], [0.0, 1.0], [[0.0]]])
def test_bad_breaks_are_named(breaks):
    with pytest.raises(InvalidInputError, match="breaks"):
        PiecewisePolynomial(breaks, _kinked, degree=5)
