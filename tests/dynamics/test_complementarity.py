"""Tests of contactdiff.dynamics.complementarity: the contact complementarity problem.

Reference values are derived by hand in comments; the property tests check
the conditions and the physics (energy, signs) directly, never the solver's
own output.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from contactdiff.dynamics.complementarity import ContactRows, LCPSolution, impact_rhs, solve_contact_lcp
from contactdiff.errors import InvalidInputError, SolverError

METHODS = ("auto", "enumerate", "pivot", "nnls")
PROPS = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
seeds = st.integers(0, 2**32 - 1)


# --------------------------------------------------------------------------
# helpers


def solve_tol(G, x, b):
    """Tolerances ``(on x, on w)`` for a solver's answer to a closed-form problem.

    The closed forms are exact; the solver's x solves a set's equalities in floating
    point (Cholesky or LU, the pivoting method's row operations, NNLS's QR), which is
    backward stable: its forward error is at most about c n eps cond(G) |x| and the
    residual of w = G x + b about c n eps (|G| |x| + |b|) (Higham, Accuracy and
    Stability of Numerical Algorithms, ch. 7 and 10), with c a small constant (4 here)
    and eps = 2.2e-16. A fixed 1e-15 is one to four ulps of these O(1) answers: it
    holds only for the last bits of today's LAPACK and scipy."""
    n = G.shape[0]
    gmax, xmax, bmax = np.abs(G).max(), max(1.0, np.abs(x).max()), np.abs(b).max()
    c_n_eps = 4 * n * np.finfo(float).eps
    return c_n_eps * np.linalg.cond(G) * xmax, c_n_eps * np.linalg.cond(G) * (gmax * xmax + bmax)


def random_system(rng, sizes, extra_dof=2):
    """Random M = R R^T + c I and A with at least as many dofs as rows."""
    rows = ContactRows.from_sizes(sizes)
    m = rows.n_rows
    nv = m + extra_dof
    R = rng.normal(size=(nv, nv))
    M = R @ R.T + rng.uniform(0.1, 2.0) * np.eye(nv)
    A = rng.normal(size=(m, nv))
    return M, A, rows


def delassus(M, A):
    G = A @ np.linalg.solve(M, A.T)
    return 0.5 * (G + G.T)


def kinetic(M, v):
    return 0.5 * v @ M @ v


def make_approaching(A, v, rows, resting=()):
    """Flip normal rows so every contact approaches (A_n v <= 0); make the
    contacts in `resting` have A_n v = 0 exactly up to rounding."""
    A = A.copy()
    for k, i in enumerate(rows.normal):
        if k in resting:
            A[i] -= (A[i] @ v) / (v @ v) * v
        elif A[i] @ v > 0:
            A[i] = -A[i]
    return A


def assert_valid(sol: LCPSolution, G, b, rows: ContactRows, tol=1e-8):
    """Check the LCP conditions independently of the solver's residual."""
    x, w = sol.x, sol.w
    np.testing.assert_allclose(w, G @ x + b, atol=1e-12 * (1 + np.abs(b).max()))
    scale = np.abs(b).max() + np.abs(G).max() * np.abs(x).max() + 1e-300
    S = set(sol.active)
    T = set(sol.tangential_only)
    for k in range(rows.n_contacts):
        n, t = rows.normal[k], list(rows.tangential[k])
        assert x[n] >= 0.0, f"contact {k} pulls: x_n = {x[n]}"
        assert abs(x[n] * w[n]) <= tol * scale * (abs(x).max() + 1e-300)
        if k in S:
            assert abs(w[n]) <= tol * scale
            assert np.all(np.abs(w[t]) <= tol * scale)
        elif k in T:
            assert x[n] == 0.0 and w[n] >= -tol * scale
            assert np.all(np.abs(w[t]) <= tol * scale)
        else:
            assert x[n] == 0.0 and np.all(x[t] == 0.0)
            assert w[n] >= -tol * scale


def impact(M, A, rows, v, e, **kw):
    """Solve an impact; return the solution, v+ and A v-."""
    G = delassus(M, A)
    u = A @ v
    b = impact_rhs(u, e, rows)
    sol = solve_contact_lcp(G, b, rows, **kw)
    assert_valid(sol, G, b, rows)
    v_plus = v + np.linalg.solve(M, A.T @ sol.x)
    return sol, v_plus, u


# --------------------------------------------------------------------------
# hand-derived cases


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("g, b", [(2.0, -3.0), (2.0, 1.0), (0.5, 0.0), (4.0, -1e-300)])
def test_single_contact_closed_form(method, g, b):
    # One frictionless contact: x = max(0, -b/g), w = g x + b.
    sol = solve_contact_lcp(np.array([[g]]), np.array([b]), ContactRows.from_sizes([1]), method=method)
    x = max(0.0, -b / g)
    x_tol, w_tol = solve_tol(np.array([[g]]), np.array([x]), np.array([b]))
    assert sol.x[0] == pytest.approx(x, abs=x_tol)
    assert sol.w[0] == pytest.approx(g * x + b, abs=w_tol)
    assert sol.active == ((0,) if x > 0 else ())
    assert sol.residual <= 4 * np.finfo(float).eps  # scaled residual, c n eps (solve_tol)


@pytest.mark.parametrize("method", METHODS)
def test_decoupled_contacts(method):
    # Diagonal G: each contact alone. x_k = max(0, -b_k / G_kk):
    # x = (2/2, 0, 1/1) = (1, 0, 1); w = (0, 3, 0).
    G = np.diag([2.0, 4.0, 1.0])
    b = np.array([-2.0, 3.0, -1.0])
    sol = solve_contact_lcp(G, b, ContactRows.from_sizes([1, 1, 1]), method=method)
    x_tol, w_tol = solve_tol(G, np.array([1.0, 0.0, 1.0]), b)
    np.testing.assert_allclose(sol.x, [1.0, 0.0, 1.0], rtol=0, atol=x_tol)
    np.testing.assert_allclose(sol.w, [0.0, 3.0, 0.0], rtol=0, atol=w_tol)
    assert sol.active == (0, 2)


@pytest.mark.parametrize("method", METHODS)
def test_coupled_two_contacts_one_active(method):
    # G = [[2, 1], [1, 2]], b = (-4, -1): both contacts approach.
    # Both active: x = -G^-1 b = -(1/3) [[2, -1], [-1, 2]] (-4, -1)
    #            = -(1/3) (-7, 2) = (7/3, -2/3): x_2 < 0, invalid.
    # Only 1: x_1 = 4/2 = 2, w_2 = 1 * 2 - 1 = 1 >= 0: valid.
    # Only 2: x_2 = 1/2, w_1 = 1 * 1/2 - 4 < 0: invalid. None: w_1 = -4: invalid.
    # So x = (2, 0), w = (0, 1): contact 2 approached but the impulse at
    # contact 1 lifts it.
    G = np.array([[2.0, 1.0], [1.0, 2.0]])
    b = np.array([-4.0, -1.0])
    sol = solve_contact_lcp(G, b, ContactRows.from_sizes([1, 1]), method=method)
    x_tol, w_tol = solve_tol(G, np.array([2.0, 0.0]), b)
    np.testing.assert_allclose(sol.x, [2.0, 0.0], rtol=0, atol=x_tol)
    np.testing.assert_allclose(sol.w, [0.0, 1.0], rtol=0, atol=w_tol)
    assert sol.active == (0,)


def test_sticking_contact_decoupled():
    # G = 2 I (3 rows), b = (-2, 1, -4): active, x = -b/2 = (1, -0.5, 2):
    # the tangential impulse has a free sign.
    rows = ContactRows.from_sizes([3])
    sol = solve_contact_lcp(2.0 * np.eye(3), np.array([-2.0, 1.0, -4.0]), rows)
    x_tol, w_tol = solve_tol(2.0 * np.eye(3), np.array([1.0, -0.5, 2.0]), np.array([-2.0, 1.0, -4.0]))
    np.testing.assert_allclose(sol.x, [1.0, -0.5, 2.0], rtol=0, atol=x_tol)
    np.testing.assert_allclose(sol.w, 0.0, atol=w_tol)
    # Separating (b_n > 0): inactive, no tangential impulse, w = b.
    sol = solve_contact_lcp(2.0 * np.eye(3), np.array([1.0, 5.0, -4.0]), rows)
    assert sol.active == ()
    np.testing.assert_array_equal(sol.x, 0.0)
    np.testing.assert_array_equal(sol.w, [1.0, 5.0, -4.0])


def test_acceleration_level_resting_mass():
    # Point mass m on the ground (row A = [1], height), gravity g:
    # a_free = -g, b = A a_free + drift = -g, G = 1/m -> lambda = m g.
    m, g = 3.0, 9.81
    rows = ContactRows.from_sizes([1])
    sol = solve_contact_lcp(np.array([[1 / m]]), np.array([-g]), rows)
    assert sol.x[0] == pytest.approx(m * g, abs=solve_tol(np.array([[1 / m]]), np.array([m * g]), np.array([-g]))[0])
    assert sol.active == (0,)
    # An upward push stronger than gravity: a_free = F/m - g > 0 -> no force.
    sol = solve_contact_lcp(np.array([[1 / m]]), np.array([40.0 / m - g]), rows)
    assert sol.x[0] == 0.0 and sol.active == ()


def test_impact_rhs_by_hand():
    rows = ContactRows.from_sizes([1, 3])  # normal rows 0, 1; tangential 2, 3
    u = np.array([-1.0, 0.5, 2.0, -3.0])
    # Per contact e = (0.5, 1): b = (1.5 * -1, 2 * 0.5, 2, -3).
    np.testing.assert_allclose(impact_rhs(u, [0.5, 1.0], rows), [-1.5, 1.0, 2.0, -3.0])
    np.testing.assert_allclose(impact_rhs(u, 0.0, rows), u)
    # Per row: only the normal rows' entries (0.5, 1.0) count.
    np.testing.assert_allclose(impact_rhs(u, [0.5, 1.0, 0.3, 0.2], rows), [-1.5, 1.0, 2.0, -3.0])


def test_contact_rows_layout():
    rows = ContactRows.from_sizes([1, 3, 2])
    assert rows.normal == (0, 1, 4)
    assert rows.tangential == ((), (2, 3), (5,))
    assert rows.n_contacts == 3 and rows.n_rows == 6 and not rows.frictionless
    np.testing.assert_array_equal(rows.rows_of([2, 0]), [4, 5, 0])
    # Any partition of the rows is accepted, e.g. normal rows first.
    rows = ContactRows(normal=(0, 1), tangential=((2, 3), ()))
    assert rows.n_rows == 4


def test_no_contacts():
    sol = solve_contact_lcp(np.zeros((0, 0)), np.zeros(0), ContactRows.from_sizes([]))
    assert sol.x.shape == (0,) and sol.active == ()


# --------------------------------------------------------------------------
# impact law properties, frictionless


@PROPS
@given(seed=seeds, n=st.integers(1, 4), e=st.floats(0.0, 1.0))
def test_impact_uniform_restitution(seed, n, e):
    # Uniform e, any v- (contacts may separate): the energy change is
    # ½ (1 - e) x^T (A v-) = -(1 - e) / (2 (1 + e)) x^T G x <= 0.
    rng = np.random.default_rng(seed)
    M, A, rows = random_system(rng, [1] * n)
    v = rng.normal(size=M.shape[0])
    sol, v_plus, u = impact(M, A, rows, v, e)
    ke0, ke1 = kinetic(M, v), kinetic(M, v_plus)
    assert ke1 <= ke0 * (1 + 1e-10) + 1e-14
    u_plus = A @ v_plus
    for k in sol.active:  # Newton's law on the contacts that took part
        assert u_plus[k] == pytest.approx(-e * u[k], abs=1e-8 * (1 + np.abs(u).max()))


@PROPS
@given(
    seed=seeds,
    n=st.integers(1, 4),
    e=st.lists(st.floats(0.0, 1.0), min_size=4, max_size=4),
    resting=st.sets(st.integers(0, 3), max_size=2),
)
def test_impact_per_contact_restitution_approaching(seed, n, e, resting):
    # Every contact approaching or at rest (A_n v- <= 0), its own e_k:
    # dKE = ½ sum_k (1 - e_k) x_k (A_k v-) <= 0, post-impact normal velocity
    # A_k v+ = w_k - e_k A_k v- >= 0 for all, and impulses never pull.
    rng = np.random.default_rng(seed)
    M, A, rows = random_system(rng, [1] * n)
    v = rng.normal(size=M.shape[0])
    A = make_approaching(A, v, rows, resting={k for k in resting if k < n})
    e = np.array(e[:n])
    sol, v_plus, u = impact(M, A, rows, v, e)
    assert np.all(sol.x >= 0.0)
    ke0 = kinetic(M, v)
    assert kinetic(M, v_plus) <= ke0 * (1 + 1e-10) + 1e-14
    u_plus = A @ v_plus
    assert np.all(u_plus >= -1e-9 * (1 + np.abs(u).max()))


@PROPS
@given(seed=seeds, n=st.integers(1, 4))
def test_plastic_impact_zeroes_normal_velocity(seed, n):
    # e = 0: A_k v+ = 0 on contacts in S, >= 0 on all (any v-), energy
    # change -½ x^T G x <= 0.
    rng = np.random.default_rng(seed)
    M, A, rows = random_system(rng, [1] * n)
    v = rng.normal(size=M.shape[0])
    sol, v_plus, u = impact(M, A, rows, v, 0.0)
    u_plus = A @ v_plus
    atol = 1e-9 * (1 + np.abs(u).max())
    assert np.all(np.abs(u_plus[list(sol.active)]) <= atol)
    assert np.all(u_plus >= -atol)
    assert kinetic(M, v_plus) <= kinetic(M, v) * (1 + 1e-10) + 1e-14


@PROPS
@given(seed=seeds)
def test_elastic_single_contact_keeps_energy(seed):
    rng = np.random.default_rng(seed)
    M, A, rows = random_system(rng, [1])
    v = rng.normal(size=M.shape[0])
    sol, v_plus, u = impact(M, A, rows, v, 1.0)
    assert kinetic(M, v_plus) == pytest.approx(kinetic(M, v), rel=1e-10)
    # Closed form: A v+ = -A v- if approaching, unchanged otherwise.
    assert (A @ v_plus)[0] == pytest.approx(-u[0] if u[0] < 0 else u[0], rel=1e-9, abs=1e-12)


@PROPS
@given(seed=seeds, n=st.integers(2, 4))
def test_elastic_orthogonal_contacts_keep_energy(seed, n):
    # Rows orthogonal in the M^-1 metric: with M = L L^T and A = D Q^T L^T
    # (Q orthonormal columns), A M^-1 A^T = D^2 is diagonal: independent contacts.
    rng = np.random.default_rng(seed)
    nv = n + 2
    R = rng.normal(size=(nv, nv))
    M = R @ R.T + np.eye(nv)
    L = np.linalg.cholesky(M)
    Q, _ = np.linalg.qr(rng.normal(size=(nv, n)))
    A = np.diag(rng.uniform(0.5, 2.0, size=n)) @ Q.T @ L.T
    rows = ContactRows.from_sizes([1] * n)
    v = rng.normal(size=nv)
    sol, v_plus, u = impact(M, A, rows, v, 1.0)
    np.testing.assert_allclose(np.abs(delassus(M, A) - np.diag(np.diag(delassus(M, A)))).max(), 0, atol=1e-12)
    assert kinetic(M, v_plus) == pytest.approx(kinetic(M, v), rel=1e-10)
    np.testing.assert_allclose(A @ v_plus, np.abs(u), rtol=1e-9, atol=1e-12)


def test_mixed_restitution_separating_contact_can_gain_energy():
    # Documented property of Newton's law, not a solver fault. G = A A^T
    # (M = I) = [[1, -0.9], [-0.9, 1]], A v- = (0.1, -1): contact 1 separates,
    # e = (0, 1). b = (0.1, -2); both active:
    # x = -G^-1 b = -(1/0.19) [[1, 0.9], [0.9, 1]] (0.1, -2) = (1.7, 1.91) / 0.19 > 0.
    # dKE = ½ sum (1 - e_k) x_k u_k = ½ * (1.7 / 0.19) * 0.1 = 0.085 / 0.19 > 0.
    G = np.array([[1.0, -0.9], [-0.9, 1.0]])
    A = np.linalg.cholesky(G)  # A A^T = G
    rows = ContactRows.from_sizes([1, 1])
    v = np.linalg.solve(A, [0.1, -1.0])
    sol, v_plus, _ = impact(np.eye(2), A, rows, v, [0.0, 1.0])
    np.testing.assert_allclose(sol.x, np.array([1.7, 1.91]) / 0.19, rtol=1e-12)
    assert kinetic(np.eye(2), v_plus) - kinetic(np.eye(2), v) == pytest.approx(0.085 / 0.19, rel=1e-12)


# --------------------------------------------------------------------------
# sticking rows


@PROPS
@given(seed=seeds, sizes=st.lists(st.sampled_from([1, 2, 3]), min_size=1, max_size=4))
def test_sticking_plastic_impact(seed, sizes):
    # e = 0 with sticking rows: on every row x_i w_i = 0, so x^T G x = -x^T b
    # = -x^T A v-, and dKE = x^T A v- + ½ x^T G x = -½ x^T G x <= 0. Contacts
    # in S (and tangential-only ones) have zero tangential velocity after.
    rng = np.random.default_rng(seed)
    M, A, rows = random_system(rng, sizes)
    v = rng.normal(size=M.shape[0])
    sol, v_plus, u = impact(M, A, rows, v, 0.0, on_infeasible="relax")
    u_plus = A @ v_plus
    atol = 1e-9 * (1 + np.abs(u).max())
    for k in sol.active + sol.tangential_only:
        assert np.all(np.abs(u_plus[list(rows.tangential[k])]) <= atol)
    for k in sol.active:
        assert abs(u_plus[rows.normal[k]]) <= atol
    assert np.all(u_plus[list(rows.normal)] >= -atol)
    assert kinetic(M, v_plus) <= kinetic(M, v) * (1 + 1e-10) + 1e-14


@PROPS
@given(
    seed=seeds,
    sizes=st.lists(st.sampled_from([1, 3]), min_size=1, max_size=4),
    e=st.floats(0.0, 1.0),
)
def test_sticking_impact_valid_or_named_error(seed, sizes, e):
    # Without relaxation: either a solution that satisfies every condition
    # (tangential velocity of active contacts stopped, normal velocity
    # -e A_n v-) or a SolverError, never a silent bad answer.
    rng = np.random.default_rng(seed)
    M, A, rows = random_system(rng, sizes)
    v = rng.normal(size=M.shape[0])
    A = make_approaching(A, v, rows)
    try:
        sol, v_plus, u = impact(M, A, rows, v, e)
    except SolverError as exc:
        assert "no valid active set" in str(exc)
        return
    u_plus = A @ v_plus
    atol = 1e-9 * (1 + np.abs(u).max())
    for k in sol.active:
        assert np.all(np.abs(u_plus[list(rows.tangential[k])]) <= atol)
        assert u_plus[rows.normal[k]] == pytest.approx(-e * u[rows.normal[k]], abs=atol)
    assert np.all(u_plus[list(rows.normal)] >= -atol)


def test_sticking_infeasible_raises_then_relaxes():
    # Planar sticking contact, G = [[1, 0.9], [0.9, 1]], b = (-0.1, -2).
    # Inactive: w_n = -0.1 < 0, invalid. Active: G^-1 b = (1/0.19)(1.7, -1.91),
    # x_n = -1.7/0.19 < 0, invalid: stopping the slip would pull. No solution.
    # Relaxed (tangential-only): x_n = 0, x_t = -b_t / G_tt = 2,
    # w_n = 0.9 * 2 - 0.1 = 1.7 >= 0, w_t = 0.
    G = np.array([[1.0, 0.9], [0.9, 1.0]])
    b = np.array([-0.1, -2.0])
    rows = ContactRows.from_sizes([2])
    with pytest.raises(SolverError, match=r"2x2 .*b = \[-0.1 -2. \].*best scaled residual"):
        solve_contact_lcp(G, b, rows)
    sol = solve_contact_lcp(G, b, rows, on_infeasible="relax")
    assert sol.active == () and sol.tangential_only == (0,) and sol.method == "relaxed"
    x_tol, w_tol = solve_tol(G, np.array([0.0, 2.0]), b)
    np.testing.assert_allclose(sol.x, [0.0, 2.0], rtol=0, atol=x_tol)
    np.testing.assert_allclose(sol.w, [1.7, 0.0], rtol=0, atol=w_tol)


def test_sticking_elastic_impact_can_gain_energy():
    # Kane's paradox (documented property of Newton's law with sticking).
    # M = I, A A^T = G = [[1, -0.9], [-0.9, 1]] (planar sticking contact),
    # A v- = (-1, 1), e = 1: b = (-2, 1); G^-1 b = (1/0.19)(-1.1, -0.8), so
    # x = (1.1, 0.8)/0.19 (x_n > 0: valid). A v+ = (1, 0), and
    # dKE = ½ x^T (A v- + A v+) = ½ (x_n * 0 + x_t * 1) = 0.4 / 0.19 > 0.
    G = np.array([[1.0, -0.9], [-0.9, 1.0]])
    A = np.linalg.cholesky(G)
    rows = ContactRows.from_sizes([2])
    v = np.linalg.solve(A, [-1.0, 1.0])
    sol, v_plus, _ = impact(np.eye(2), A, rows, v, 1.0)
    np.testing.assert_allclose(sol.x, np.array([1.1, 0.8]) / 0.19, rtol=1e-12)
    np.testing.assert_allclose(A @ v_plus, [1.0, 0.0], atol=1e-12)
    assert kinetic(np.eye(2), v_plus) - kinetic(np.eye(2), v) == pytest.approx(0.4 / 0.19, rel=1e-12)


# --------------------------------------------------------------------------
# methods agree


@PROPS
@given(seed=seeds, n=st.integers(1, 8))
def test_methods_agree_frictionless(seed, n):
    # Positive definite G, frictionless rows: the solution is unique.
    rng = np.random.default_rng(seed)
    M, A, rows = random_system(rng, [1] * n)
    G = delassus(M, A)
    b = rng.normal(size=n) * rng.uniform(0.1, 10.0)
    sols = [solve_contact_lcp(G, b, rows, method=m) for m in METHODS]
    for sol in sols:
        assert_valid(sol, G, b, rows)
    for sol in sols[1:]:
        np.testing.assert_allclose(sol.x, sols[0].x, rtol=1e-8, atol=1e-10 * np.abs(sols[0].x).max())
        assert sol.active == sols[0].active or np.abs(sol.x - sols[0].x).max() < 1e-10


@PROPS
@given(seed=seeds, n=st.integers(2, 6), rank=st.integers(1, 5))
def test_methods_agree_singular_frictionless(seed, n, rank):
    # G = B B^T of rank < n (redundant rows): x need not be unique, but
    # w = G x + b is (the minimisers of ½ x^T G x + b^T x over x >= 0 share
    # G x). Take b = B c + d with d >= 0 off the range so a solution exists.
    rng = np.random.default_rng(seed)
    rank = min(rank, n - 1)
    B = rng.normal(size=(n, rank))
    G = B @ B.T
    b = B @ rng.normal(size=rank)
    rows = ContactRows.from_sizes([1] * n)
    sols = [solve_contact_lcp(G, b, rows, method=m) for m in METHODS]
    for sol in sols:
        assert_valid(sol, G, b, rows, tol=1e-7)
        np.testing.assert_allclose(sol.w, sols[0].w, atol=1e-7 * (1 + np.abs(b).max()))


# --------------------------------------------------------------------------
# singular G


@pytest.mark.parametrize("method", METHODS)
def test_duplicate_rows_share_the_impulse(method):
    # Two contacts with the same Jacobian row a (M = I, |a|^2 = 2): G = 2 [[1, 1], [1, 1]].
    # b = (-1, -1): every x >= 0 with x_1 + x_2 = 1/2 solves it; the
    # minimum-norm one in the largest active set is (1/4, 1/4).
    a = np.array([1.0, -1.0, 0.0])
    A = np.vstack([a, a])
    G = A @ A.T
    rows = ContactRows.from_sizes([1, 1])
    sol = solve_contact_lcp(G, np.array([-1.0, -1.0]), rows, method=method)
    assert_valid(sol, G, np.array([-1.0, -1.0]), rows)
    assert sol.x.sum() == pytest.approx(0.5, rel=1e-12)
    if method in ("auto", "enumerate"):
        np.testing.assert_allclose(sol.x, [0.25, 0.25], rtol=1e-12)


@pytest.mark.parametrize("method", METHODS)
def test_duplicate_rows_different_restitution(method):
    # G = [[1, 1], [1, 1]], b = (-1, -2). Both active: x_1 + x_2 = 1 and = 2,
    # inconsistent. Only 2: x_2 = 2, w_1 = 2 - 1 = 1 >= 0. Only 1: w_2 = 1 - 2 < 0.
    G = np.ones((2, 2))
    b = np.array([-1.0, -2.0])
    sol = solve_contact_lcp(G, b, ContactRows.from_sizes([1, 1]), method=method)
    np.testing.assert_allclose(sol.x, [0.0, 2.0], atol=1e-12)
    np.testing.assert_allclose(sol.w, [1.0, 0.0], atol=1e-12)


def test_four_coplanar_feet_min_norm_with_sign():
    # Body with 3 dofs (heave, roll, pitch; M = I), four frictionless feet at
    # the corners of the unit square; foot row = (1, r_x - 1/2, r_y - 1/2).
    # G = B B^T has rank 3. b = -B f with f = (1, 0.4, 0.4). w = B (B^T x - f)
    # is 0 for x >= 0 with B^T x = f (total 1, centre of pressure (0.9, 0.9)),
    # and w is unique, so every solution has B^T x = f.
    # Minimum-norm: x_p = 1/4 + (0.4, 0.4).(r - c) = (-0.15, 0.25, 0.25, 0.65),
    # negative at foot (0, 0). Null space d = (1, -1, -1, 1)/2, d ⟂ x_p; x_p + t d
    # >= 0 needs 0.3 <= t <= 0.5: all of these solve the LCP. The smallest
    # norm is t = 0.3: x = (0, 0.1, 0.1, 0.8), what the documented rule
    # (largest active set, min-norm with x_n >= 0) of auto/enumerate returns.
    feet = np.array([[0, 0], [1, 0], [0, 1], [1, 1]], dtype=float)
    B = np.column_stack([np.ones(4), feet - 0.5])
    G = B @ B.T
    f = np.array([1.0, 0.4, 0.4])
    b = -B @ f
    rows = ContactRows.from_sizes([1] * 4)
    for method in METHODS:
        sol = solve_contact_lcp(G, b, rows, method=method)
        assert_valid(sol, G, b, rows)
        np.testing.assert_allclose(B.T @ sol.x, f, atol=1e-12)
        if method in ("auto", "enumerate"):
            np.testing.assert_allclose(sol.x, [0.0, 0.1, 0.1, 0.8], atol=1e-12)


def test_ill_conditioned_but_definite():
    # G = Q diag(1, 1e-3, 1e-13) Q^T with q_3 = (1, 1, 1)/sqrt(3): definite,
    # cond 1e13, its smallest eigenvalue below the min-norm cutoff (1e-12
    # relative). b = -0.1 q_3 - G (1, 2, 3): the LCP solution is all active,
    # x = 1e12 q_3 + (1, 2, 3) > 0, w = 0. The min-norm solve drops q_3 and
    # leaves w = -0.1 q_3 < 0; the solver must fall back to the plain solve.
    q3 = np.ones(3) / np.sqrt(3.0)
    Q, _ = np.linalg.qr(np.column_stack([q3, [1.0, -1.0, 0.0], [1.0, 1.0, -2.0]]))
    Q = Q[:, [1, 2, 0]]  # columns: two others, then ±q_3
    G = Q @ np.diag([1.0, 1e-3, 1e-13]) @ Q.T
    G = 0.5 * (G + G.T)
    b = -0.1 * q3 - G @ np.array([1.0, 2.0, 3.0])
    rows = ContactRows.from_sizes([1, 1, 1])
    for method in METHODS:
        sol = solve_contact_lcp(G, b, rows, method=method)
        assert_valid(sol, G, b, rows)
        assert sol.active == (0, 1, 2)
        # x is accurate to about cond(G) * eps relative along q_3.
        np.testing.assert_allclose(sol.x, 1e12 * q3 + [1.0, 2.0, 3.0], rtol=1e-2)


def rigid_box(mass=2.0, inertia=(0.1, 0.2, 0.25), half=(0.3, 0.2), height=0.1):
    """A free rigid body (v, omega coordinates, M = diag(m, m, m, I)) with four
    sticking feet at (±a, ±c, -h); foot rows (d, r × d) for d = z, x, y."""
    M = np.diag([mass] * 3 + list(inertia))
    rows_list = []
    for sx in (-1, 1):
        for sy in (-1, 1):
            r = np.array([sx * half[0], sy * half[1], -height])
            for d in np.eye(3)[[2, 0, 1]]:
                rows_list.append(np.concatenate([d, np.cross(r, d)]))
    return M, np.array(rows_list), ContactRows.from_sizes([3] * 4)


def test_four_sticking_feet_flat_drop():
    # Body falling flat, v- = (0, 0, -1), no rotation, e = 0: all feet land,
    # the body stops (v+ = 0; A is 12x6 of rank 6 so A v+ = 0 forces v+ = 0).
    # The impulses solving A^T x = -M v- form an affine set; its minimum-norm
    # point lies in range(A): x = A y with y = (0, 0, m/4, 0, 0, 0), i.e.
    # m/4 = 0.5 on each normal row and 0 tangentially.
    M, A, rows = rigid_box()
    G = delassus(M, A)
    assert np.linalg.matrix_rank(G) == 6
    v = np.array([0.0, 0.0, -1.0, 0.0, 0.0, 0.0])
    sol, v_plus, _ = impact(M, A, rows, v, 0.0)
    assert sol.active == (0, 1, 2, 3)
    np.testing.assert_allclose(v_plus, 0.0, atol=1e-12)
    expected = np.zeros(12)
    expected[list(rows.normal)] = 0.5
    np.testing.assert_allclose(sol.x, expected, atol=1e-12)


@PROPS
@given(seed=seeds)
def test_four_sticking_feet_random_landing(seed):
    # Singular G (12 rows, rank 6) with random landing velocities.
    rng = np.random.default_rng(seed)
    M, A, rows = rigid_box()
    v = np.concatenate([rng.normal(size=2), [-1.0 - rng.uniform()], 0.5 * rng.normal(size=3)])
    sol, v_plus, u = impact(M, A, rows, v, 0.0, on_infeasible="relax")
    u_plus = A @ v_plus
    atol = 1e-9 * (1 + np.abs(u).max())
    assert sol.active  # something must stop the fall
    for k in sol.active:
        np.testing.assert_allclose(u_plus[rows.rows_of([k])], 0.0, atol=atol)
    assert np.all(u_plus[list(rows.normal)] >= -atol)
    assert kinetic(M, v_plus) <= kinetic(M, v) * (1 + 1e-10) + 1e-14


# --------------------------------------------------------------------------
# errors


def test_no_valid_active_set_raises():
    # G = 0 with an approaching contact: nothing can stop it.
    with pytest.raises(SolverError, match=r"1x1 .*b = \[-1\.\].*best scaled residual"):
        solve_contact_lcp(np.zeros((1, 1)), np.array([-1.0]), ContactRows.from_sizes([1]))


_R2 = ContactRows.from_sizes([1, 1])
_G2 = np.eye(2)
_b2 = np.array([-1.0, 1.0])


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"G": np.eye(3)}, r"shape \(3, 3\); expected \(2, 2\)"),
        ({"G": np.ones(2)}, r"shape \(2,\)"),
        ({"G": np.array([[1.0, np.nan], [np.nan, 1.0]])}, r"G\[0, 1\] is nan"),
        ({"b": np.array([-1.0, np.inf])}, r"b\[1\] is inf"),
        ({"b": np.ones(3)}, r"b has shape \(3,\)"),
        ({"b": np.array([1 + 2j, 0])}, r"real numbers"),
        ({"G": [["a", "b"], ["c", "d"]]}, r"real numbers"),
        ({"G": np.array([[1.0, 0.5], [0.0, 1.0]])}, r"not symmetric: G\[0, 1\] = 0.5"),
        ({"G": np.array([[-1.0, 0.0], [0.0, 1.0]])}, r"G\[0, 0\] = -1.0 is negative"),
        ({"method": "lemke"}, r"'lemke' is not known; valid: auto, enumerate, pivot, nnls"),
        ({"tol": 0.0}, r"tol is 0.0"),
        ({"tol": float("nan")}, r"tol is nan"),
        ({"on_infeasible": "ignore"}, r"on_infeasible is 'ignore'"),
        ({"rows": (0, 1)}, r"rows must be a ContactRows"),
        (
            {"rows": ContactRows.from_sizes([3]), "G": np.eye(3), "b": np.ones(3), "method": "nnls"},
            r"method='nnls' needs frictionless rows",
        ),
    ],
)
def test_bad_inputs(kwargs, match):
    args = {"G": _G2, "b": _b2, "rows": _R2} | kwargs
    G, b, rows = args.pop("G"), args.pop("b"), args.pop("rows")
    with pytest.raises(InvalidInputError, match=match):
        solve_contact_lcp(G, b, rows, **args)


@pytest.mark.parametrize(
    "make, match",
    [
        (lambda: ContactRows.from_sizes([1, 4]), r"size of contact 1 is 4; valid: 1, 2, 3"),
        (lambda: ContactRows.from_sizes([0]), r"size of contact 0 is 0"),
        (lambda: ContactRows.from_sizes([True]), r"size of contact 0 is True"),
        (lambda: ContactRows((0, 0), ((), ())), r"each once"),
        (lambda: ContactRows((0, 2), ((), ())), r"rows must be 0..1"),
        (lambda: ContactRows((0,), ((), ())), r"1 normal rows but 2 tangential groups"),
        (lambda: ContactRows((-1,), ((),)), r"row index -1"),
    ],
)
def test_bad_rows(make, match):
    with pytest.raises(InvalidInputError, match=match):
        make()


@pytest.mark.parametrize(
    "e, match",
    [
        (1.5, r"restitution of contact 0 is 1.5; valid: 0 <= e <= 1"),
        ([0.5, -0.1], r"restitution of contact 1 is -0.1"),
        ([0.5, 0.5, 0.5], r"restitution has shape \(3,\)"),
        (float("nan"), r"restitution of contact 0 is nan"),
    ],
)
def test_bad_restitution(e, match):
    with pytest.raises(InvalidInputError, match=match):
        impact_rhs(np.zeros(2), e, _R2)


def test_bad_velocity_for_rhs():
    with pytest.raises(InvalidInputError, match=r"A_v_minus\[0\] is nan"):
        impact_rhs(np.array([np.nan, 0.0]), 0.5, _R2)
    with pytest.raises(InvalidInputError, match=r"A_v_minus has shape \(3,\)"):
        impact_rhs(np.zeros(3), 0.5, _R2)


def test_errors_are_contactdiff_errors():
    from contactdiff.errors import ContactDiffError

    assert issubclass(InvalidInputError, ContactDiffError)
    assert issubclass(SolverError, ContactDiffError)
