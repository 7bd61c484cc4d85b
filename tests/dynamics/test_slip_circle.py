"""The one-slider closed form of the slip search (`contactdiff.dynamics.slip_circle`)
against the general path it replaces (the candidate's direct solve, and the scan of
`contactdiff.dynamics.friction_slip`).

The closed form is the Sherman-Morrison identity about a base angle where the
candidate's matrix is as well conditioned as the circle allows; the direct solve is an
LU factorisation at each angle. Both are backward stable, so ``V(θ) / D(θ)`` and the
direct ``u+_T(θ)`` differ by a small multiple of ``eps · cond(Kb) · cond(K(θ))``
relative to the velocity scale: on a cube's corners (edge 0.1 m, 0.37 kg, μ = 0.18)
``K(θ) = K0 + O(μ)`` with ``cond(K0) < 1e2`` (`test_slip_lowrank`), below 1e-13, and
1e-12 relative to the velocity scale is asserted.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_frictional_impact import random_problem
from test_slip_lowrank import EDGE, FACE, _cube_problem

from contactdiff.dynamics import friction_slip
from contactdiff.dynamics.frictional_impact import ContactState, solve_frictional_impact
from contactdiff.dynamics.slip_circle import cross_form_roots, slip_coefficients
from contactdiff.dynamics.slip_map import SlipMap

SLIDE, STICK, OPEN = ContactState.SLIDE, ContactState.STICK, ContactState.OPEN


@pytest.mark.parametrize(
    "corners,states",
    [
        (FACE, (SLIDE, OPEN, OPEN, OPEN)),  # dependent rows: the compatible-impulse solve
        (FACE, (SLIDE, STICK, OPEN, OPEN)),
        (EDGE, (SLIDE, STICK)),  # independent rows: the plain solve
        (FACE[:1], (SLIDE,)),
    ],
)
def test_slip_times_denominator_equals_the_direct_solve(corners, states):
    """At 200 random angles, 5 random cubes each: ``V(θ) / D(θ)`` of the closed form
    equals the candidate's directly solved ``u+_T(θ)``, and ``z_c(θ) D(θ)`` is the same
    at every angle (``zb[c]``, module doc), to 1e-12 of the velocity and impulse scales
    (module doc of this test)."""
    rng = np.random.default_rng(7)
    for _ in range(5):
        prob = _cube_problem(rng, corners)
        lay = prob.layout(states)
        fmap = SlipMap(prob, states, {}, [0], lay, cross=True)
        coefficients = slip_coefficients(fmap)
        assert coefficients is not None
        V, dd = coefficients
        theta = rng.uniform(-np.pi, np.pi, 200)
        trig = np.stack([np.ones_like(theta), np.cos(theta), np.sin(theta)])  # (3, 200)
        D = dd @ trig
        *_, z, zc, up, lam_max = fmap._impulses(theta[:, None])
        vscale = prob.bmax + prob.gmax * lam_max.max()
        assert np.all(np.abs((V @ trig / D).T - up[:, prob.tang[0]]) <= 1e-12 * vscale)
        zcD = zc[:, 0] * D
        assert np.all(np.abs(zcD - zcD[0]) <= 1e-12 * np.abs(z).max())


def test_quartic_roots_are_the_cross_form_roots():
    """The angles `cross_form_roots` returns (unpolished) make ``cos θ V_y - sin θ V_x``
    vanish to 1e-9 of the coefficients' scale (the companion matrix's eigenvalues are
    backward stable: a few eps of the scale at a simple root, up to ``sqrt(eps)`` at a
    close pair), and a scan of that form on 1e5 angles (step 6.3e-5 rad) finds no sign
    change they miss: each within 1e-4 rad of a returned root."""
    rng = np.random.default_rng(3)
    th = np.linspace(-np.pi, np.pi, 100_001)
    for _ in range(200):
        V = rng.standard_normal((2, 3))
        alpha, beta, gamma = V.T
        roots = cross_form_roots(V)
        assert roots is not None

        def F(t):
            V = alpha[:, None] + beta[:, None] * np.cos(t) + gamma[:, None] * np.sin(t)
            return np.cos(t) * V[1] - np.sin(t) * V[0]

        scale = np.abs(V).max()
        assert np.all(np.abs(F(roots)) <= 1e-9 * scale)
        f = F(th)
        for i in np.flatnonzero(np.sign(f[:-1]) != np.sign(f[1:])):
            gaps = np.abs((roots - th[i] + np.pi) % (2 * np.pi) - np.pi)
            assert gaps.min() <= 1e-4


def test_flat_cross_form_has_no_answer():
    """A slip along its direction at every angle (``V(θ) = (cos θ, sin θ)``: ``F ≡ 0``)
    and a slip zero at every angle give no answer (the scan is used)."""
    assert cross_form_roots(np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])) is None
    assert cross_form_roots(np.zeros((2, 3))) is None


def test_a_slip_held_at_zero_has_no_closed_form():
    """A face's corner sliding while two others stick: the sticking corners fix the cube's
    motion in the plane (two points held), so the slider's slip is zero whatever its
    direction; `slip_coefficients` gives no answer (``V`` at round-off of the velocity
    scale, `FLAT_TOL`) and the scan's plateau rule is used."""
    rng = np.random.default_rng(9)
    for _ in range(5):
        prob = _cube_problem(rng, FACE)
        states = (SLIDE, STICK, STICK, OPEN)
        fmap = SlipMap(prob, states, {}, [0], prob.layout(states), cross=True)
        assert slip_coefficients(fmap) is None


@pytest.mark.parametrize("seed", range(2))
def test_solutions_equal_the_scan_path(monkeypatch, seed):
    """On 100 random problems (1-3 spatial contacts, random Delassus, μ in [0.05, 1], e
    in [0, 1]): the solver with the closed form and with the scan returns the same
    contact states, and the same impulses to 1e-12 relative, unless the scan's root
    was accepted short of round-off (its residual above 1e-12: Newton on the angle form
    stops within the law's tolerance, 1e-9), where the closed form's is at least as
    accurate (its residual no larger)."""
    rng = np.random.default_rng(100 + seed)
    for _ in range(100):
        n = int(rng.integers(1, 4))
        _, A, G, v, rows = random_problem(rng, n, 3)
        u = A @ v
        e, mu = rng.uniform(0, 1, n), rng.uniform(0.05, 1.0, n)
        monkeypatch.setattr(friction_slip, "ONE_SLIDER_CLOSED_FORM", False)
        scan = solve_frictional_impact(G, u, rows, e, mu)
        monkeypatch.setattr(friction_slip, "ONE_SLIDER_CLOSED_FORM", True)
        closed = solve_frictional_impact(G, u, rows, e, mu)
        assert closed.states == scan.states
        gap = np.abs(closed.impulses - scan.impulses).max() / np.abs(scan.impulses).max()
        if scan.residual <= 1e-12:
            assert gap <= 1e-12
        else:
            assert closed.residual <= scan.residual
