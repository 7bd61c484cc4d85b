"""The slip search's blocked products (`contactdiff.dynamics.slip_map`): the same
values as numpy's whole products, at every block boundary.

Each element of a product is a sum of ``k`` terms; two correct evaluations of it
differ by at most about ``k`` roundings of the sum of the terms' magnitudes,
``k eps (|X| |Y|)_ij``. The tolerance is 4 times that bound (the order of the terms
and a fused multiply-add may differ between BLAS kernels), not an exact comparison.
"""

from __future__ import annotations

import numpy as np
import pytest

from contactdiff.dynamics.slip_map import _ONE_THREAD, _congruence, _thin_matmul

EPS = np.finfo(float).eps


def _bound(X: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """4 k eps (|X| |Y|): the round-off allowance of each element (module doc)."""
    return 4.0 * X.shape[-1] * EPS * (np.abs(X) @ np.abs(Y))


@pytest.mark.parametrize("k,n", [(4, 12), (2, 3), (3, 2)])
@pytest.mark.parametrize("extra", [0, 1, 2, 3])
def test_thin_matmul_rows_match_the_whole_product(k, n, extra):
    """Long X (rows split): sizes just past a block boundary, including one that would
    leave a last block of a single row (merged into the one before)."""
    rng = np.random.default_rng(7)
    step = _ONE_THREAD // (k * n)
    m = 3 * step + extra
    X, Y = rng.standard_normal((m, k)), rng.standard_normal((k, n))
    got = _thin_matmul(X, Y)
    assert got.shape == (m, n)
    assert np.all(np.abs(got - X @ Y) <= _bound(X, Y))


@pytest.mark.parametrize("extra", [0, 1, 5])
def test_thin_matmul_columns_match_the_whole_product(extra):
    """Long Y (columns split): a (12, 2) block times a (2, P) grid of angles."""
    rng = np.random.default_rng(8)
    step = _ONE_THREAD // (2 * 12)
    P = 2 * step + extra
    X, Y = rng.standard_normal((12, 2)), rng.standard_normal((2, P))
    got = _thin_matmul(X, Y)
    assert got.shape == (12, P)
    assert np.all(np.abs(got - X @ Y) <= _bound(X, Y))


@pytest.mark.parametrize("p,r", [(4, 3), (6, 4), (3, 1), (2, 2)])
def test_congruence_matches_the_stacked_product(p, r):
    """``Uᵀ K[i] U`` for a long stack equals the stacked product of each matrix:
    the bound applied twice (``Uᵀ K`` then times ``U``, ``U`` orthonormal columns)."""
    rng = np.random.default_rng(9)
    U = np.linalg.qr(rng.standard_normal((p, r)))[0]
    K = rng.standard_normal((20000, p, p))
    got = _congruence(U, K)
    ref = U.T @ K @ U
    assert got.shape == (len(K), r, r)
    bound = 8.0 * p * EPS * (np.abs(U.T) @ np.abs(K) @ np.abs(U))
    assert np.all(np.abs(got - ref) <= bound)
