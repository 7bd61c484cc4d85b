"""The slip search's low-rank path (`contactdiff.dynamics.slip_lowrank`) against the
direct solve it replaces on the grid (`SlipMap._impulses`), on a rigid cube's corners.

Both paths solve the same linear system: the direct one by an LU factorisation of
``K(θ)`` (in ``U``'s coordinates where rows are dependent), the low-rank one by the
Sherman-Morrison-Woodbury identity on the factorised angle-free ``K0``. Each is
backward stable, so they differ by at most a small multiple of
``eps · cond(K0) · cond(S(θ))`` relative to ``z``. On a cube (edge 0.1 m, 0.37 kg) with
μ = 0.18 the friction columns are a fraction μ of the normal ones, ``S(θ) = I + O(μ)``
is well conditioned at every angle, and ``cond(K0)`` (a Delassus block of the cube's
corners) is below 1e2: the bound is below 1e-13, and 1e-12 relative is asserted.
"""

from __future__ import annotations

import numpy as np
import pytest

from contactdiff.dynamics.frictional_impact import ContactState, _Impact
from contactdiff.dynamics.lcp_problem import ContactRows
from contactdiff.dynamics.slip_lowrank import LowRankSolve
from contactdiff.dynamics.slip_map import SlipMap, _thin_matmul

SLIDE, STICK, OPEN = ContactState.SLIDE, ContactState.STICK, ContactState.OPEN
HALF = 0.05  # m, half the edge
FACE = [np.array([sx * HALF, sy * HALF, -HALF]) for sx in (-1, 1) for sy in (-1, 1)]  # from the centre
EDGE = FACE[:2]


def _cube_problem(rng, corners, slide: float | None = None) -> _Impact:
    """A frictional impact of a cube (randomly turned inertia) on the given corners
    (positions from its centre, world axes), each with a normal row (z) and two
    tangential rows (x, y); G = A M⁻¹ Aᵀ with the rows ``[d, r × d]`` acting on
    (v, ω); a random velocity moving the cube down at 2 m/s (with ``slide``: sliding at
    that speed in a random direction, turning at a tenth of the random rates)."""
    mass = 0.37
    q, _ = np.linalg.qr(rng.standard_normal((3, 3)))
    inertia = q @ np.diag(mass * (2 * HALF) ** 2 / 6 * (1 + 0.2 * rng.random(3))) @ q.T
    m_inv = np.zeros((6, 6))
    m_inv[:3, :3] = np.eye(3) / mass
    m_inv[3:, 3:] = np.linalg.inv(inertia)
    A = np.array([np.concatenate([d, np.cross(r, d)]) for r in corners for d in np.eye(3)[[2, 0, 1]]])
    G = A @ m_inv @ A.T
    v = rng.standard_normal(6)
    v[2] = -2.0
    if slide is not None:
        heading = rng.uniform(-np.pi, np.pi)
        v[:2] = slide * np.array([np.cos(heading), np.sin(heading)])
        v[3:] *= 0.1
    u = A @ v
    rows = ContactRows.from_sizes([3] * len(corners))
    e = np.where(u[list(rows.normal)] < 0.0, 0.125, 0.0)
    return _Impact(0.5 * (G + G.T), u, rows, e, np.full(len(corners), 0.18), 1e-9)


@pytest.mark.parametrize(
    "corners,states",
    [
        (FACE, (SLIDE, SLIDE, SLIDE, SLIDE)),  # dependent rows: the compatible-impulse solve
        (FACE, (SLIDE, STICK, SLIDE, OPEN)),
        (FACE, (STICK, SLIDE, SLIDE, SLIDE)),
        (FACE, (SLIDE, OPEN, OPEN, OPEN)),
        (EDGE, (SLIDE, SLIDE)),  # independent rows: the plain solve
        (EDGE, (SLIDE, STICK)),
    ],
)
def test_low_rank_unknowns_equal_the_direct_solve(corners, states):
    """At 500 random angles of the sliders, 5 random cubes each: the unknowns of both
    paths agree to 1e-12 relative (module doc), and the low-rank path is taken."""
    rng = np.random.default_rng(11)
    spatial = [k for k, s in enumerate(states) if s is SLIDE]
    for _ in range(5):
        prob = _cube_problem(rng, corners)
        lay = prob.layout(states)
        fmap = SlipMap(prob, states, {}, spatial, lay, cross=True)
        theta = rng.uniform(-np.pi, np.pi, (500, len(spatial)))
        direct = fmap._impulses(theta)[4]
        low = fmap._impulses(theta, low_rank=True)[4]
        assert fmap._low_rank is not None and fmap._low_rank.usable
        scale = np.abs(direct).max(axis=1, keepdims=True)
        assert np.all(np.abs(low - direct) <= 1e-12 * scale)


def test_grid_merit_equal_on_both_paths():
    """What the grid gives Newton (residual, feasibility, scale) is the same by both
    paths: the residual to 1e-12 of its scale, feasibility identical (no grid point of
    these problems lies within round-off of an inequality's bound)."""
    rng = np.random.default_rng(12)
    states = (SLIDE, SLIDE, SLIDE, SLIDE)
    prob = _cube_problem(rng, FACE)
    fmap = SlipMap(prob, states, {}, [0, 1, 2, 3], prob.layout(states), cross=True)
    theta = rng.uniform(-np.pi, np.pi, (2000, 4))
    f, _, feas, _, scale = fmap(theta, jac=False)
    f_low, _, feas_low, _, scale_low = fmap(theta, jac=False, low_rank=True)
    assert np.all(np.abs(f_low - f) <= 1e-12 * scale[:, None])
    assert np.allclose(scale_low, scale, rtol=1e-12, atol=0.0)
    assert np.array_equal(feas_low, feas)


@pytest.mark.parametrize("K0", [np.zeros((3, 3)), np.diag([1.0, 1.0, 1e-12]), np.full((2, 2), np.nan)])
def test_singular_or_ill_conditioned_K0_is_not_used(K0):
    """A singular, ill-conditioned (cond 1e12 > COND_MAX) or non-finite ``K0`` leaves
    the low-rank path unusable: the direct solve is taken instead."""
    p = K0.shape[0]
    solve = LowRankSolve(K0, np.ones(p), None, np.array([0]), [np.ones((p, 2))], _thin_matmul)
    assert not solve.usable


def _edge_bounce(slide: float) -> _Impact:
    """The face's edge at x = -HALF hits the board at 1 m/s while the opposite edge rests
    on it (zero normal speed), the level cube sliding at ``slide`` m/s towards the
    hitting edge (along -x): a face event of the tosses."""
    mass = 0.37
    m_inv = np.zeros((6, 6))
    m_inv[:3, :3] = np.eye(3) / mass
    m_inv[3:, 3:] = np.eye(3) / (mass * (2 * HALF) ** 2 / 6)
    A = np.array([np.concatenate([d, np.cross(r, d)]) for r in FACE for d in np.eye(3)[[2, 0, 1]]])
    G = A @ m_inv @ A.T
    # a corner's normal speed vz + (ω × r)_z = vz + ωx ry - ωy rx: -1 at rx = -HALF and 0
    # at rx = +HALF for vz = -1/2, ωy = -1 / (2 HALF)
    u = A @ np.array([-slide, 0.0, -0.5, 0.0, -0.5 / HALF, 0.0])
    rows = ContactRows.from_sizes([3] * 4)
    e = np.where(u[list(rows.normal)] < -1e-12, 0.125, 0.0)
    return _Impact(0.5 * (G + G.T), u, rows, e, np.full(4, 0.18), 1e-9)


def _pulls_on_a_grid(prob: _Impact, states, spatial, per_axis: int) -> bool:
    """Brute force by the direct solve: at every point of a grid of the sliders' angles
    some closed contact pulls by more than 1e-6 of the largest impulse."""
    fmap = SlipMap(prob, states, {}, spatial, prob.layout(states), cross=True)
    axes = np.meshgrid(*([2 * np.pi * np.arange(per_axis) / per_axis] * len(spatial)), indexing="ij")
    theta = np.stack([a.ravel() for a in axes], axis=1)
    *_, z, _, _, lam_max = fmap._impulses(theta)
    return bool(np.all((z[:, fmap.closed] < -1e-6 * lam_max[:, None]).any(axis=1)))


@pytest.mark.parametrize("slide", [0.3, 1.0, 3.0])
def test_a_face_whose_sticking_corners_pull_is_certified_without_a_search(slide):
    """On the edge bounce (`_edge_bounce`) each of the 14 candidates with all four
    corners closed, some sliding and some sticking, makes a corner pull: a sticking
    corner stops its slip, and that tangential impulse at the board, below the centre,
    tips the cube about the hitting edge and lifts the resting one, which equal
    compliant supports would then have to hold down. The certificate holds for each
    (and the grid by the direct solve agrees: a pull at every point); it does not hold
    for the four sliding corners, the solver's answer."""
    prob = _edge_bounce(slide)
    certified = []
    for states, sliding in prob.candidates():
        if any(s is OPEN for s in states) or not sliding:
            continue
        if prob.pulls_everywhere(states, {}, list(sliding), prob.layout(states)):
            certified.append(states)
            assert _pulls_on_a_grid(prob, states, list(sliding), 12 if len(sliding) < 4 else 6)
    assert len(certified) == 14 and (SLIDE,) * 4 not in certified
    assert prob.solve().states == (SLIDE,) * 4


@pytest.mark.parametrize("corners", [FACE, EDGE, FACE[:3]])
def test_certificate_never_holds_where_a_grid_point_is_feasible(corners):
    """On random cube impacts, every candidate with sliders: where the certificate
    holds, the direct solve finds a pulling contact at every grid point (it is a bound,
    so the converse need not hold)."""
    rng = np.random.default_rng(14)
    checked = 0
    for _ in range(4):
        prob = _cube_problem(rng, corners)
        for states, sliding in prob.candidates():
            if not sliding:
                continue
            if prob.pulls_everywhere(states, {}, list(sliding), prob.layout(states)):
                checked += 1
                assert _pulls_on_a_grid(prob, states, list(sliding), 12 if len(sliding) < 4 else 6)
    assert checked > 0


def _slip_angles(fmap, theta: np.ndarray) -> np.ndarray:
    """The angles of the sliders' post-impact slips at slip angles ``theta`` (P, ns), by
    the candidate's direct solve."""
    up = fmap._impulses(theta)[6]
    return np.stack([np.arctan2(up[:, t[1]], up[:, t[0]]) for t in fmap.T], axis=1)


@pytest.mark.parametrize(
    "corners,states",
    [
        (FACE, (SLIDE, SLIDE, SLIDE, SLIDE)),  # dependent rows
        (FACE, (SLIDE, STICK, SLIDE, OPEN)),
        (EDGE, (SLIDE, SLIDE)),  # independent rows
    ],
)
def test_slip_contraction_bounds_the_slip_angles_derivative(corners, states):
    """Where `LowRankSolve.slip_contraction` gives a bound ``L``, the map from the
    sliders' angles to their slips' angles changes by at most ``L`` per radian in the
    max-norm: at 300 random angles, each row sum of its Jacobian by central differences
    (step 1e-6 rad: truncation ~1e-12 and round-off ~1e-10 relative, covered by 1e-6
    of L) is at most ``L``; and over 300 random pairs of angles the change of the slips'
    angles (wrapped) is at most ``L`` times the largest change of the sliders' angles.
    Cubes moving down at 2 m/s and sliding at 10 m/s (`_cube_problem`; the bound is about
    0.25 on a face, above 1 at 3 m/s): at least one per case is checked."""
    rng = np.random.default_rng(21)
    spatial = [k for k, s in enumerate(states) if s is SLIDE]
    checked = 0
    for _ in range(8):
        prob = _cube_problem(rng, corners, slide=10.0)
        fmap = SlipMap(prob, states, {}, spatial, prob.layout(states), cross=True)
        low = fmap.low_rank()
        L = low.slip_contraction(prob.u, fmap.GB0, fmap.GT, fmap.T) if low.usable else np.inf
        if not L < 1.0:
            continue
        checked += 1
        ns, h = len(spatial), 1e-6
        theta = rng.uniform(-np.pi, np.pi, (300, ns))
        jac = np.zeros((300, ns, ns))
        for i in range(ns):
            step = np.zeros(ns)
            step[i] = h
            diff = _slip_angles(fmap, theta + step) - _slip_angles(fmap, theta - step)
            jac[:, :, i] = ((diff + np.pi) % (2 * np.pi) - np.pi) / (2 * h)
        assert np.abs(jac).sum(axis=2).max() <= L * (1 + 1e-6)
        other = rng.uniform(-np.pi, np.pi, (300, ns))
        moved = (_slip_angles(fmap, theta) - _slip_angles(fmap, other) + np.pi) % (2 * np.pi) - np.pi
        apart = np.abs((theta - other + np.pi) % (2 * np.pi) - np.pi).max(axis=1)
        assert np.all(np.abs(moved).max(axis=1) <= L * apart * (1 + 1e-9) + 1e-12)
    assert checked >= 1


@pytest.mark.parametrize("corners", [FACE, EDGE])
def test_contraction_skips_the_grid_with_the_same_answer(monkeypatch, corners):
    """With the contraction's proof of one root the grid is skipped (Newton from the
    pre-impact, approximate and frictionless slips); the solver's answer on 10 random
    cubes landing on a face or an edge (`_cube_problem`, every corner closed) is the
    same as with the grid: the same states and impulses to 1e-12 relative (both are one
    root polished by Newton to 1e-13 of the cross form's scale). Cubes moving down at 2
    m/s and sliding at 10 m/s (the proof holds) and at 1 m/s (it does not on a face)."""
    from contactdiff.dynamics import friction_slip
    from contactdiff.dynamics.frictional_impact import solve_frictional_impact

    rng = np.random.default_rng(5)
    skipped = 0
    for slide in [10.0] * 5 + [1.0] * 5:
        prob = _cube_problem(rng, corners, slide)
        args = (prob.G, prob.u, prob.rows, 0.125, prob.mu)
        monkeypatch.setattr(friction_slip, "_CONTRACTION_MAX", -1.0)
        grid = solve_frictional_impact(*args)
        monkeypatch.setattr(friction_slip, "_CONTRACTION_MAX", 0.9)
        calls = []
        monkeypatch.setattr(friction_slip.SlipDirections, "grid_turns", lambda *a: calls.append(a) or 1 / 0)
        try:
            fast = solve_frictional_impact(*args)
        except ZeroDivisionError:  # the grid was needed: no proof for this cube
            monkeypatch.undo()
            continue
        monkeypatch.undo()
        skipped += 1
        assert fast.states == grid.states
        assert np.abs(fast.impulses - grid.impulses).max() <= 1e-12 * np.abs(grid.impulses).max()
    assert skipped >= 1
