"""Tests of contactdiff.dynamics.frictional_impact: impacts with Coulomb friction.

Reference values are closed forms derived by hand in the docstrings (a point
mass, a planar rod, the rod embedded in 3-D); the property tests check the
conditions of the law and the physics (energy, signs) directly from ``G``,
``u-`` and the returned impulses, never the solver's own residual.

Energy in the row metric: with ``v+ = v- + M^-1 A^T Λ`` and ``u- = A v-``,
``T+ - T- = ½ (v- + M^-1 A^T Λ)^T M (v- + M^-1 A^T Λ) - ½ v-^T M v-
= Λ^T A v- + ½ Λ^T A M^-1 A^T Λ = Λ^T u- + ½ Λ^T G Λ``; the property tests also
compute it from ``M`` and ``v±`` directly.

Tolerances: the random problems have cond(G) <= ~1e6 and O(1) data; the
solver accepts a scaled residual of 1e-9, so checks use 1e-8 relative to each
case's impulse and velocity scales.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from impact_law import approaching_e, check_law

from contactdiff.dynamics.complementarity import ContactRows, impact_rhs, solve_contact_lcp
from contactdiff.dynamics.frictional_impact import (
    ContactState,
    EnergyGainError,
    solve_frictional_impact,
)
from contactdiff.errors import InvalidInputError, SolverError

OPEN, STICK, SLIDE = ContactState.OPEN, ContactState.STICK, ContactState.SLIDE
# derandomized: the solver's search for spatial slip directions is not proved
# complete (module doc), so a random draw could fail a run at random.
PROPS = settings(max_examples=40, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
seeds = st.integers(0, 2**32 - 1)


# --------------------------------------------------------------------------
# helpers


def random_problem(rng, n, dim, extra_dof=2):
    """Random SPD M = R R^T + c I, full-rank A (n contacts, normal then
    ``dim - 1`` tangential rows each), an approaching pre-impact velocity."""
    rows = ContactRows.from_sizes([dim] * n)
    m = rows.n_rows
    nv = m + extra_dof
    R = rng.normal(size=(nv, nv))
    M = R @ R.T + rng.uniform(0.1, 2.0) * np.eye(nv)
    A = rng.normal(size=(m, nv))
    v = rng.normal(size=nv)
    for i in rows.normal:  # every contact approaches
        if A[i] @ v > 0:
            A[i] = -A[i]
    G = A @ np.linalg.solve(M, A.T)
    return M, A, 0.5 * (G + G.T), v, rows


# --------------------------------------------------------------------------
# 1. a point mass hitting the ground obliquely


@pytest.mark.parametrize("e", [0.0, 0.5, 1.0])
@pytest.mark.parametrize("angle", [0.0, 0.7, 2.5, -2.0])
def test_point_mass_spatial(e, angle):
    """Point mass m, rows (n, t1, t2), G = I/m, u- = (v_n, v_t) with v_n < 0.

    The normal row is decoupled: Λ_N = m (1 + e) |v_n| whatever the tangent does.
    Stick needs Λ_T = -m v_t in the cone: |v_t| <= μ (1 + e) |v_n|. Otherwise
    slide: Λ_T = -μ Λ_N ŝ and u+_T = v_t - μ (1 + e) |v_n| ŝ, which has ŝ's
    direction iff ŝ = v̂_t (then |u+_T| = |v_t| - μ (1 + e) |v_n| > 0)."""
    m, mu, v_n = 2.0, 0.4, -1.5
    G = np.eye(3) / m
    rows = ContactRows.from_sizes([3])
    d = np.array([np.cos(angle), np.sin(angle)])
    limit = mu * (1 + e) * abs(v_n)
    for speed in (0.0, 0.3 * limit, 0.99 * limit, 1.01 * limit, 3 * limit + 0.1):
        u = np.array([v_n, *(speed * d)])
        out = solve_frictional_impact(G, u, rows, e, mu)
        lam_n = m * (1 + e) * abs(v_n)
        if speed <= limit:
            assert out.states == (STICK,)
            np.testing.assert_allclose(out.impulses, [lam_n, *(-m * speed * d)], rtol=1e-13, atol=1e-14)
            np.testing.assert_allclose(out.u_plus, [-e * v_n, 0, 0], atol=1e-14)
        else:
            assert out.states == (SLIDE,)
            np.testing.assert_allclose(out.slide_directions[0], d, atol=1e-12)
            np.testing.assert_allclose(out.u_plus, [-e * v_n, *((speed - limit) * d)], atol=1e-12)
            np.testing.assert_allclose(out.impulses, [lam_n, *(-mu * lam_n * d)], atol=1e-12)
            assert out.method == "enumerate-newton"
        check_law(out, G, u, rows, np.array([e]), np.array([mu]))
        assert out.energy_change <= 1e-12 and not out.energy_gain


@pytest.mark.parametrize("e", [0.0, 0.7])
@pytest.mark.parametrize("v_t", [0.0, 0.5, -0.5, 1.0, -3.0])
def test_point_mass_planar(e, v_t):
    """The planar case (one tangential row): stick iff |v_t| <= μ (1 + e) |v_n|,
    else u+_T = v_t - μ (1 + e) |v_n| sign(v_t)."""
    m, mu, v_n = 0.5, 0.6, -1.0
    G = np.eye(2) / m
    rows = ContactRows.from_sizes([2])
    limit = mu * (1 + e) * abs(v_n)
    out = solve_frictional_impact(G, [v_n, v_t], rows, e, mu)
    if abs(v_t) <= limit:
        assert out.states == (STICK,)
        np.testing.assert_allclose(out.u_plus, [-e * v_n, 0.0], atol=1e-14)
    else:
        assert out.states == (SLIDE,)
        np.testing.assert_allclose(out.slide_directions[0], [np.sign(v_t)])
        np.testing.assert_allclose(out.u_plus, [-e * v_n, v_t - limit * np.sign(v_t)], atol=1e-14)
        assert out.method == "enumerate"


def test_first_guess_skips_the_enumeration_and_a_wrong_one_falls_back(monkeypatch):
    """The candidate of the approximate solution is tried first: on the point mass
    (decoupled rows, a unique solution) it is the answer, one candidate tried; a
    wrong first guess only costs candidates, the answer is the same (the closed
    forms of `test_point_mass_spatial`)."""
    from contactdiff.dynamics import frictional_impact

    m, mu, v_n, e = 2.0, 0.4, -1.5, 0.5
    G, rows = np.eye(3) / m, ContactRows.from_sizes([3])
    limit = mu * (1 + e) * abs(v_n)
    d = np.array([np.cos(0.7), np.sin(0.7)])
    cases = [(0.5 * limit, STICK), (2.0 * limit, SLIDE)]
    for speed, state in cases:
        out = solve_frictional_impact(G, [v_n, *(speed * d)], rows, e, mu)
        assert out.states == (state,) and out.candidates == 1
    monkeypatch.setattr(frictional_impact._Impact, "predicted", lambda self: ((OPEN,), ()))
    for speed, state in cases:
        out = solve_frictional_impact(G, [v_n, *(speed * d)], rows, e, mu)
        assert out.states == (state,) and out.candidates > 1
        lam_n = m * (1 + e) * abs(v_n)
        expected_t = -m * speed * d if state is STICK else -mu * lam_n * d
        np.testing.assert_allclose(out.impulses, [lam_n, *expected_t], rtol=1e-12, atol=1e-14)


def test_point_mass_separating_is_open():
    """A contact that separates (v_n > 0) takes no impulse, whatever its slip."""
    out = solve_frictional_impact(np.eye(3), [0.5, 1.0, -2.0], ContactRows.from_sizes([3]), 1.0, 1.0)
    assert out.states == (OPEN,)
    np.testing.assert_array_equal(out.impulses, 0.0)
    assert out.restitution[0] == 0.0  # not approaching: e = 0 (as resolve_impact)


# --------------------------------------------------------------------------
# 2. a planar rod: tangential velocity coupled with rotation


def rod(m=2.0, length=1.0, phi=np.pi / 6):
    """Thin rod, COM at the origin, lower end r = -(L/2)(cos φ, sin φ) on the ground.

    Coordinates (v_x, v_z, ω), M = diag(m, m, I) with I = m L^2 / 12. The contact
    point moves with v + ω e_y x r; in the x-z plane (e_y x r) = (r_z, -r_x) with
    the right-handed rotation about +y, so the rows are n = (0, 1, -r_x),
    t = (1, 0, r_z). Then G = A M^-1 A^T has
    a = G_nn = 1/m + r_x^2/I, c = G_tt = 1/m + r_z^2/I, g = G_nt = -r_x r_z / I."""
    inertia = m * length**2 / 12
    rx, rz = -0.5 * length * np.cos(phi), -0.5 * length * np.sin(phi)
    A = np.array([[0.0, 1.0, -rx], [1.0, 0.0, rz]])
    M = np.diag([m, m, inertia])
    a, c, g = 1 / m + rx**2 / inertia, 1 / m + rz**2 / inertia, -rx * rz / inertia
    return M, A, a, c, g


@pytest.mark.parametrize("e", [0.0, 0.5])
def test_rod_threshold_and_slide_closed_form(e):
    """Planar rod, one contact, u- = (u_n, u_t), u_n < 0, p = (1 + e) u_n.

    Stick: Λ = -G^-1 (p, u_t), i.e. Λ_N = -(c p - g u_t)/D, Λ_T = -(a u_t - g p)/D,
    D = a c - g^2. |Λ_T| <= μ Λ_N is two linear inequalities in u_t; with
    a ± μ g > 0 it reads u_lo <= u_t <= u_hi,
    u_lo = p (g + μ c)/(a + μ g), u_hi = p (g - μ c)/(a - μ g).
    Slide with sign σ: Λ_T = -μ σ Λ_N, the normal row gives
    Λ_N = -p / (a - μ σ g), and u+_T = u_t + Λ_N (g - μ σ c), valid iff σ u+_T > 0:
    σ = +1 above u_hi, σ = -1 below u_lo (u+_T = u_t - u_hi resp. u_t - u_lo)."""
    M, A, a, c, g = rod()
    G = A @ np.linalg.solve(M, A.T)
    np.testing.assert_allclose(G, [[a, g], [g, c]], rtol=1e-14)
    assert abs(g) > 0.3 * a  # strongly coupled
    mu, u_n = 0.5, -1.0
    p = (1 + e) * u_n
    lo, hi = p * (g + mu * c) / (a + mu * g), p * (g - mu * c) / (a - mu * g)
    assert 0 < lo < hi  # with this coupling a contact with no pre-impact slip slides
    rows = ContactRows.from_sizes([2])
    for u_t in (lo - 1.0, 0.0, lo - 1e-6, lo + 1e-6, 0.5 * (lo + hi), hi - 1e-6, hi + 1e-6, hi + 2.0):
        u = np.array([u_n, u_t])
        out = solve_frictional_impact(G, u, rows, e, mu)
        if lo <= u_t <= hi:
            D = a * c - g * g
            assert out.states == (STICK,)
            np.testing.assert_allclose(out.impulses, [-(c * p - g * u_t) / D, -(a * u_t - g * p) / D], rtol=1e-12)
            np.testing.assert_allclose(out.u_plus, [-e * u_n, 0.0], atol=1e-13)
        else:
            sigma = 1.0 if u_t > hi else -1.0
            lam_n = -p / (a - mu * sigma * g)
            assert out.states == (SLIDE,)
            assert out.slide_directions[0][0] == sigma
            np.testing.assert_allclose(out.impulses, [lam_n, -mu * sigma * lam_n], rtol=1e-12)
            np.testing.assert_allclose(out.u_plus, [-e * u_n, u_t - (hi if sigma > 0 else lo)], atol=1e-12)
        # the body: v+ = v- + M^-1 A^T Λ moves the contact point at u+
        v_minus = np.linalg.lstsq(A, u, rcond=None)[0] + np.array([0.0, 0.0, 0.0])
        v_plus = v_minus + np.linalg.solve(M, A.T @ out.impulses)
        np.testing.assert_allclose(A @ v_plus, out.u_plus, atol=1e-12)
        assert out.energy_change <= 1e-12 or e > 0


def test_rod_in_space_matches_planar():
    """The rod as a 3-D body (v, ω, M = diag(m, m, m, Ix, I, Iz)), rows (z, x, y) at
    r = (r_x, 0, r_z): v + ω x r = (v_x + ω_y r_z, v_y + ω_z r_x - ω_x r_z, v_z - ω_y r_x).
    The (z, x) block of G is the planar rod's and y is decoupled from both, so a
    slip along x only keeps the planar solution with zero y components: the 2-D
    direction solve (Newton) must find the planar slide."""
    m, length, phi = 2.0, 1.0, np.pi / 6
    inertia = m * length**2 / 12
    rx, rz = -0.5 * length * np.cos(phi), -0.5 * length * np.sin(phi)
    A = np.array([[0, 0, 1, 0, -rx, 0], [1, 0, 0, 0, rz, 0], [0, 1, 0, -rz, 0, rx]], dtype=float)
    M = np.diag([m, m, m, 0.01, inertia, inertia])
    G = A @ np.linalg.solve(M, A.T)
    G = 0.5 * (G + G.T)
    _, _, a, c, g = rod()
    mu, e, u_n = 0.5, 0.0, -1.0
    p = (1 + e) * u_n
    lo, hi = p * (g + mu * c) / (a + mu * g), p * (g - mu * c) / (a - mu * g)
    for u_t in (lo - 0.5, hi + 0.5, 0.5 * (lo + hi)):
        out = solve_frictional_impact(G, [u_n, u_t, 0.0], ContactRows.from_sizes([3]), e, mu)
        if lo <= u_t <= hi:
            assert out.states == (STICK,)
            np.testing.assert_allclose(out.u_plus, 0.0, atol=1e-13)
        else:
            sigma = 1.0 if u_t > hi else -1.0
            lam_n = -p / (a - mu * sigma * g)
            assert out.states == (SLIDE,)
            np.testing.assert_allclose(out.slide_directions[0], [sigma, 0.0], atol=1e-12)
            np.testing.assert_allclose(out.impulses, [lam_n, -mu * sigma * lam_n, 0.0], atol=1e-12)
            np.testing.assert_allclose(out.u_plus, [0.0, u_t - (hi if sigma > 0 else lo), 0.0], atol=1e-12)


def test_rod_kane_energy_gain_is_flagged():
    """Kane's paradox with the rod, e = 1, μ = 0.5, u- = (-1, 0.5): sticking (u_t is
    inside [u_lo, u_hi] = [0.326, 1.115] for p = -2) with
    ΔT = ½ Λ^T (u- + u+) = -½ [(1 - e^2) u_n^2 h11 + 2 u_n u_t h12 + u_t^2 h22],
    H = G^-1 (from Λ = -H ((1 + e) u_n, u_t) and u- + u+ = ((1 - e) u_n, u_t)).
    Here h12 = -g/D > 0, so with e = 1 and 0 < u_t < 2 h12 / h22 the energy grows."""
    M, A, a, c, g = rod()
    G = A @ np.linalg.solve(M, A.T)
    e, mu = 1.0, 0.5
    u = np.array([-1.0, 0.5])
    D = a * c - g * g
    h11, h12, h22 = c / D, -g / D, a / D
    dT = -0.5 * ((1 - e**2) * u[0] ** 2 * h11 + 2 * u[0] * u[1] * h12 + u[1] ** 2 * h22)
    assert dT > 0.1
    rows = ContactRows.from_sizes([2])
    out = solve_frictional_impact(G, u, rows, e, mu)
    assert out.states == (STICK,)
    assert out.energy_gain
    np.testing.assert_allclose(out.energy_change, dT, rtol=1e-12)
    # the same from the body: the least-energy v- with A v- = u-
    v_minus = np.linalg.solve(M, A.T @ np.linalg.solve(G, u))
    v_plus = v_minus + np.linalg.solve(M, A.T @ out.impulses)
    np.testing.assert_allclose(0.5 * v_plus @ M @ v_plus - 0.5 * v_minus @ M @ v_minus, dT, rtol=1e-12)
    with pytest.raises(EnergyGainError, match="gains kinetic energy dT = 0.12"):
        solve_frictional_impact(G, u, rows, e, mu, on_energy_gain="raise")
    # frictionless and plastic versions of the same impact lose energy
    assert not solve_frictional_impact(G, u, rows, e, 0.0).energy_gain
    assert not solve_frictional_impact(G, u, rows, 0.0, mu).energy_gain


# --------------------------------------------------------------------------
# 3. limits: μ = inf is the sticking LCP, μ = 0 the frictionless one

# the same random problems, 1-4 contacts, for both limits
LIMITS = settings(max_examples=60, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
LIMIT_PROBLEMS = given(seed=seeds, n=st.integers(1, 4), dim=st.sampled_from([2, 3]), e=st.floats(0.0, 1.0))


def limit_problem(seed, n, dim):
    """``(G, u-, rows)`` of the random problem drawn from ``seed`` (`random_problem`)."""
    _, A, G, v, rows = random_problem(np.random.default_rng(seed), n, dim)
    return G, A @ v, rows


@LIMITS
@LIMIT_PROBLEMS
def test_infinite_friction_is_the_sticking_lcp(seed, n, dim, e):
    G, u, rows = limit_problem(seed, n, dim)
    try:
        ref = solve_contact_lcp(G, impact_rhs(u, e, rows), rows, method="enumerate")
    except SolverError:
        with pytest.raises(SolverError, match="no valid state candidate"):
            solve_frictional_impact(G, u, rows, e, np.inf)
        return
    out = solve_frictional_impact(G, u, rows, e, np.inf)
    assert [k for k, s in enumerate(out.states) if s is not OPEN] == list(ref.active)
    assert all(s in (OPEN, STICK) for s in out.states)
    scale = np.abs(ref.x).max() + 1e-300
    np.testing.assert_allclose(out.impulses, ref.x, atol=1e-9 * scale)


@LIMITS
@LIMIT_PROBLEMS
def test_zero_friction_is_the_frictionless_lcp(seed, n, dim, e):
    G, u, rows = limit_problem(seed, n, dim)
    nrm = list(rows.normal)
    one = ContactRows.from_sizes([1] * n)
    ref = solve_contact_lcp(G[np.ix_(nrm, nrm)], impact_rhs(u[nrm], e, one), one)
    out = solve_frictional_impact(G, u, rows, e, 0.0)
    scale = np.abs(ref.x).max() + 1e-300
    np.testing.assert_allclose(out.impulses[nrm], ref.x, atol=1e-9 * scale)
    tang = [i for t in rows.tangential for i in t]
    assert np.all(out.impulses[tang] == 0.0)
    assert all(s is (SLIDE if k in ref.active else OPEN) for k, s in enumerate(out.states))


# --------------------------------------------------------------------------
# 4. properties on random problems


def _random_case(seed, n, dim):
    rng = np.random.default_rng(seed)
    M, A, G, v, rows = random_problem(rng, n, dim)
    mu = rng.uniform(0.0, 2.0, size=n)
    return rng, M, A, G, v, rows, mu


@PROPS
@given(seed=seeds, n=st.integers(1, 3), dim=st.sampled_from([2, 3]))
def test_plastic_law_and_energy(seed, n, dim):
    """e = 0: the law's conditions hold and T+ - T- = Λ^T u- + ½ Λ^T G Λ <= 0
    (also from M, v- and v+ = v- + M^-1 A^T Λ)."""
    _, M, A, G, v, rows, mu = _random_case(seed, n, dim)
    u = A @ v
    out = solve_frictional_impact(G, u, rows, 0.0, mu)
    e = np.zeros(n)
    check_law(out, G, u, rows, e, mu)
    lam = out.impulses
    v_plus = v + np.linalg.solve(M, A.T @ lam)
    dT = 0.5 * v_plus @ M @ v_plus - 0.5 * v @ M @ v
    scale = 0.5 * v @ M @ v + np.abs(lam).max() * np.abs(u).max()
    np.testing.assert_allclose(out.energy_change, dT, atol=1e-10 * scale)
    assert dT <= 1e-10 * scale
    assert not out.energy_gain


@PROPS
@given(seed=seeds, n=st.integers(1, 3), dim=st.sampled_from([2, 3]), e=st.floats(0.0, 1.0))
def test_restitution_law_and_energy_flag(seed, n, dim, e):
    """e in [0, 1]: the law's conditions hold; the energy flag is set exactly when
    T+ - T- > 0 beyond round-off (with e > 0 it can be: see the rod test)."""
    rng, M, A, G, v, rows, mu = _random_case(seed, n, dim)
    es = rng.uniform(0.0, 1.0, size=n) * e
    u = A @ v
    out = solve_frictional_impact(G, u, rows, es, mu)
    check_law(out, G, u, rows, approaching_e(u, rows, es), mu)
    v_plus = v + np.linalg.solve(M, A.T @ out.impulses)
    dT = 0.5 * v_plus @ M @ v_plus - 0.5 * v @ M @ v
    scale = 0.5 * v @ M @ v + np.abs(out.impulses).max() * np.abs(u).max()
    np.testing.assert_allclose(out.energy_change, dT, atol=1e-10 * scale)
    if abs(dT) > 1e-8 * scale:
        assert out.energy_gain == (dT > 0)


def test_known_search_gap():
    """Two spatial contacts sliding (an earlier search raised SolverError here):
    solved, and the law holds."""
    rng, _, A, G, v, rows, mu = _random_case(115, 2, 3)
    e = rng.uniform(0, 1, size=2)
    out = solve_frictional_impact(G, A @ v, rows, e, mu)
    check_law(out, G, A @ v, rows, approaching_e(A @ v, rows, e), mu)


def _two_slider_roots(G, u, e, mu, n_grid=400):
    """Every slip-angle pair of two spatial contacts both sliding that satisfies
    the law, by brute force independent of the solver: for each (θ1, θ2) on a
    dense grid, Λ_T,k = -μ_k Λ_N,k s_k and w_N = 0 give Λ_N from a 2x2 system;
    the grid points where the slip residual ||u+_T,k - ||u+_T,k|| s_k|| is
    smallest (with Λ_N >= 0) are polished by least squares on that residual."""
    from scipy.optimize import least_squares

    nrm, tng = [0, 3], [[1, 2], [4, 5]]
    b = u.copy()
    b[nrm] = (1 + e) * u[nrm]

    def impulses(th):  # th (P, 2) -> Λ (P, 6)
        s = np.stack([np.cos(th), np.sin(th)], axis=2)  # (P, 2, 2)
        B = np.zeros((th.shape[0], 6, 2))
        for k in range(2):
            B[:, nrm[k], k] = 1.0
            B[:, tng[k], k] = -mu[k] * s[:, k]
        z = np.linalg.solve((G @ B)[:, nrm], -b[nrm][None, :, None])
        return (B @ z)[..., 0], s

    def slip_residual(th):
        lam, s = impulses(th)
        up = u + lam @ G
        res = [up[:, t] - np.linalg.norm(up[:, t], axis=1, keepdims=True) * s[:, k] for k, t in enumerate(tng)]
        return np.concatenate(res, axis=1), lam

    ax = 2 * np.pi * np.arange(n_grid) / n_grid
    grid = np.stack(np.meshgrid(ax, ax, indexing="ij"), axis=2).reshape(-1, 2)
    res, lam = slip_residual(grid)
    merit = np.where((lam[:, nrm] >= 0).all(axis=1), np.abs(res).max(axis=1), np.inf)
    roots = []
    for i in np.argsort(merit)[:40]:
        sol = least_squares(lambda t: slip_residual(t[None])[0][0], grid[i], xtol=1e-15, ftol=1e-15, gtol=1e-15)
        r, lam = slip_residual(sol.x[None])
        vs = np.abs(b).max() + np.abs(G).max() * np.abs(lam).max()
        if np.abs(r).max() < 1e-10 * vs and (lam[0, nrm] >= 0).all():
            if not any(np.abs(np.angle(np.exp(1j * (sol.x - q)))).max() < 1e-6 for q in roots):
                roots.append(sol.x)
    return roots


def test_two_sliders_small_slip_matches_brute_force():
    """Two spatial contacts sliding, one with a small post-impact slip: its
    direction turns fast with the slip angles, so the root is a needle in the
    angle residual (an earlier search missed it). The brute-force search finds
    exactly one valid pair of slip directions; the solver returns it."""
    rng, _, A, G, v, rows, mu = _random_case(115, 2, 3)
    e = rng.uniform(0, 1, size=2)
    u = A @ v
    out = solve_frictional_impact(G, u, rows, e, mu)
    check_law(out, G, u, rows, approaching_e(u, rows, e), mu)
    assert out.states == (SLIDE, SLIDE)
    roots = _two_slider_roots(G, u, approaching_e(u, rows, e), mu)
    assert len(roots) == 1
    ref = [np.array([np.cos(t), np.sin(t)]) for t in roots[0]]
    for k in range(2):
        np.testing.assert_allclose(out.slide_directions[k], ref[k], atol=1e-9)
    np.testing.assert_allclose(
        np.arctan2(out.slide_directions[1][1], out.slide_directions[1][0]), -1.3382, atol=1e-4
    )  # the value found by a fine grid and Nelder-Mead


def test_one_slider_root_beside_a_pole_matches_brute_force():
    """One spatial contact whose slide root lies 0.008 rad from a pole of Λ_N
    (the normal row's coefficient G_NN - μ G_NT.s vanishes there): both in one
    interval of a coarse scan, with no sign change between them (an earlier scan
    missed the root and raised SolverError). Reference: Λ_N = -(1 + e) u-_N /
    (G_NN - μ G_NT.s) in closed form, the cross form s x u+_T scanned on 2e5
    angles and each sign change with a finite positive Λ_N and the slip along s
    refined by Brent's method; exactly one is valid, and the solver returns it."""
    from scipy.optimize import brentq

    rng, _, A, G, v, rows, mu = _random_case(1931, 1, 3)
    e = rng.uniform(0, 1, size=1)
    u = A @ v
    out = solve_frictional_impact(G, u, rows, e, mu)
    check_law(out, G, u, rows, approaching_e(u, rows, e), mu)
    assert out.states == (SLIDE,)

    def solve(th):
        s = np.array([np.cos(th), np.sin(th)])
        col = np.array([1.0, *(-mu[0] * s)])
        lam_n = -(1 + e[0]) * u[0] / (G[0] @ col)
        return s, lam_n, u + lam_n * (G @ col)

    def cross(th):
        s, _, up = solve(th)
        return s[0] * up[2] - s[1] * up[1]

    th = np.linspace(0.0, 2 * np.pi, 200_001)
    f = np.array([cross(t) for t in th])
    refs = []
    for i in np.flatnonzero(np.sign(f[:-1]) != np.sign(f[1:])):
        r = brentq(cross, th[i], th[i + 1], xtol=1e-15)
        s, lam_n, up = solve(r)
        if 0 < lam_n < 1e6 and s @ up[1:] > 0 and abs(cross(r)) < 1e-9:
            refs.append(s)
    assert len(refs) == 1
    np.testing.assert_allclose(out.slide_directions[0], refs[0], atol=1e-9)


# --------------------------------------------------------------------------
# 5. errors name the bad value


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(restitution=1.5), r"restitution of contact 0 is 1\.5"),
        (dict(restitution=[0.2, np.nan]), r"restitution of contact 1 is nan"),
        (dict(restitution=[0.1, 0.2, 0.3]), r"restitution has shape \(3,\)"),
        (dict(friction=-0.1), r"friction coefficient of contact 0 is -0\.1"),
        (dict(friction=[0.5, np.nan]), r"friction coefficient of contact 1 is nan"),
        (dict(friction="high"), r"friction must be an array of real numbers"),
        (dict(u_minus=[1.0, 2.0]), r"u_minus has shape \(2,\); expected \(5,\)"),
        (dict(u_minus=[-1.0, 0, 0, np.inf, 0]), r"u_minus\[3\] is inf"),
        (dict(G=np.eye(4)), r"G has shape \(4, 4\); expected \(5, 5\)"),
        (dict(G=np.eye(5) + np.triu(np.ones((5, 5)), 1)), r"G is not symmetric: G\[0, 1\] = 1\.0"),
        (dict(tol=-1.0), r"tol is -1\.0"),
        (dict(on_energy_gain="ignore"), r"on_energy_gain is 'ignore'"),
        (dict(rows=(0, 1)), r"rows must be a ContactRows; got tuple"),
    ],
)
def test_bad_input_names_the_value(kwargs, match):
    args = dict(
        G=np.eye(5),
        u_minus=[-1.0, 0.1, 0.2, -1.0, 0.3],
        rows=ContactRows.from_sizes([3, 2]),
        restitution=0.5,
        friction=0.5,
    )
    args.update(kwargs)
    with pytest.raises(InvalidInputError, match=match):
        solve_frictional_impact(args.pop("G"), args.pop("u_minus"), args.pop("rows"), **args)


def test_too_many_contacts():
    rows = ContactRows.from_sizes([1] * 9)
    with pytest.raises(InvalidInputError, match="at most 8 contacts; got 9"):
        solve_frictional_impact(np.eye(9), -np.ones(9), rows, 0.0, 0.5)


def test_no_solution_names_the_best_candidate():
    """G = 0 (a row no impulse can move): closed, w_N = u-_N = -1 != 0 whatever
    Λ_N; open, it penetrates. No candidate is valid; both have residual 1."""
    with pytest.raises(SolverError, match=r"best scaled residual 1 with states \{0: slide\}"):
        solve_frictional_impact(np.zeros((1, 1)), [-1.0], ContactRows.from_sizes([1]), 0.0, 0.0)


def test_no_contacts():
    out = solve_frictional_impact(np.zeros((0, 0)), np.zeros(0), ContactRows((), ()), 0.5, 0.5)
    assert out.states == () and out.impulses.shape == (0,)


def test_mixed_rows_frictionless_and_sticking_contacts():
    """Decoupled G = I: contact 0 frictionless (1 row), contact 1 μ = inf (3 rows),
    contact 2 μ = 0.5 spatial. Each is the point mass of test 1 with m = 1."""
    rows = ContactRows.from_sizes([1, 3, 3])
    u = np.array([-1.0, -2.0, 5.0, 5.0, -1.0, 3.0, 0.0])
    out = solve_frictional_impact(np.eye(7), u, rows, 0.0, [0.3, np.inf, 0.5])
    assert out.states == (SLIDE, STICK, SLIDE)
    np.testing.assert_allclose(out.impulses, [1.0, 2.0, -5.0, -5.0, 1.0, -0.5, 0.0], atol=1e-12)
    np.testing.assert_allclose(out.u_plus[[5, 6]], [2.5, 0.0], atol=1e-12)
