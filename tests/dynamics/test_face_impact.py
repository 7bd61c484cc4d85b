"""A face of a box landing flat with Coulomb friction: four corners' impulses on rows of
rank 3 (normal) or 6 (with sticking tangents), chosen by the compatible-impulse
principle (`contactdiff.dynamics.redundant`).

The rigid body is written here in numpy alone (world-frame twist ``(v, ω)`` about the
centre of mass, ``M = diag(m I, I_c)``), independent of the library's model building.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from contactdiff.dynamics.frictional_impact import ContactState, solve_frictional_impact
from contactdiff.dynamics.lcp_problem import ContactRows
from contactdiff.dynamics.redundant import gram_range_basis


def face_problem(half, mass, yaw, twist):
    """``(G, u, M⁻¹Aᵀ)`` of a box's bottom corners flat on the ground (rows: normal z,
    tangents x, y per corner) for the pre-impact twist ``(v, ω)`` (world axes)."""
    a, b, c = half
    inertia = mass / 3 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])
    cy, sy = np.cos(yaw), np.sin(yaw)
    R = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
    I_world = R @ inertia @ R.T
    M_inv = np.zeros((6, 6))
    M_inv[:3, :3] = np.eye(3) / mass
    M_inv[3:, 3:] = np.linalg.inv(I_world)
    rows = []
    for sx in (1, -1):
        for s_y in (1, -1):
            r = R @ np.array([sx * a, s_y * b, -c])
            for d in (np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])):
                rows.append(np.r_[d, np.cross(r, d)])  # d · (v + ω × r)
    A = np.array(rows)
    return A @ M_inv @ A.T, A @ twist, M_inv @ A.T


ROWS = ContactRows.from_sizes([3, 3, 3, 3])


def assert_in_cones_without_gain(out, rows, G, u, mu, e, scale):
    """Every contact's normal impulse pushes and its tangential one lies in its cone, to
    1e-12 of ``scale`` (the solver's residual, ~1e-15 of the impulses); no kinetic
    energy is gained when ``e`` = 0."""
    lam = out.impulses
    for n, t in zip(rows.normal, rows.tangential):
        assert lam[n] >= -1e-12 * scale
        assert np.linalg.norm(lam[list(t)]) <= mu * lam[n] + 1e-12 * scale
    if e == 0.0:
        assert out.energy_change <= 1e-12 * scale * (np.abs(u).max() + np.abs(G).max() * scale)


@pytest.mark.parametrize("u_slide", [0.5, 2.5])
def test_box_lands_flat_sticking_or_sliding(u_slide):
    """Landing flat at vertical speed w with horizontal speed u along x, not turning:
    Newton's restitution gives every corner e w upward, so the box does not turn and
    ``Σ Λ_N = m (1 + e) w``; Coulomb then stops the slip if ``u <= μ (1 + e) w``
    (sticking) and otherwise takes ``μ Σ Λ_N`` of it: ``v_x+ = max(0, u - μ (1 + e) w)``.
    The friction's moment, ``c`` below the centre, is balanced by loads shifted forward:
    ``Σ x_i Λ_N,i = c m (u - v_x+)``; the principle splits them evenly left/right."""
    half, mass, mu, e, w = (0.15, 0.1, 0.05), 2.0, 0.3, 0.5, 2.0
    twist = np.r_[u_slide, 0.0, -w, 0.0, 0.0, 0.0]
    G, u, MinvAT = face_problem(half, mass, 0.0, twist)
    out = solve_frictional_impact(G, u, ROWS, e, mu)
    v_plus = twist + MinvAT @ out.impulses
    vx = max(0.0, u_slide - mu * (1 + e) * w)
    np.testing.assert_allclose(v_plus, [vx, 0.0, e * w, 0.0, 0.0, 0.0], atol=1e-12 * w)
    normal = out.impulses[list(ROWS.normal)]
    assert normal.sum() == pytest.approx(mass * (1 + e) * w, rel=1e-12)
    x = np.array([1, 1, -1, -1]) * half[0]
    assert normal @ x == pytest.approx(half[2] * mass * (u_slide - vx), rel=1e-12)
    np.testing.assert_allclose(normal[[0, 2]], normal[[1, 3]], rtol=1e-12)  # left = right
    expected = ContactState.STICK if vx == 0.0 else ContactState.SLIDE
    assert out.states == (expected,) * 4


# 15 examples: each face landing that slides enumerates up to 81 state candidates with
# slip-direction searches on a 4-torus (about a second each)
@settings(max_examples=15, deadline=None)
@given(
    yaw=st.floats(-3.0, 3.0),
    mu=st.floats(0.05, 1.0),
    e=st.sampled_from([0.0, 0.0, 0.3, 1.0]),
    vx=st.floats(-3.0, 3.0),
    vy=st.floats(-3.0, 3.0),
    vz=st.floats(-3.0, -0.2),
    wx=st.floats(-1.0, 1.0),
    wy=st.floats(-1.0, 1.0),
    wz=st.floats(-5.0, 5.0),
)
def test_face_impact_properties(yaw, mu, e, vx, vy, vz, wx, wy, wz):
    """Any face landing: normal impulses push (>= 0), tangential ones in their cones,
    kinetic energy not gained when e = 0, and the impulses on the candidate's
    equality rows (normals of closed corners, tangents of sticking ones) lie in the
    range of those rows (the principle; vacuous when they are independent).
    Tolerances: the solver's scaled residual ~1e-15 of impulses O(1)."""
    half, mass = (0.15, 0.1, 0.05), 2.0
    twist = np.r_[vx, vy, vz, wx, wy, wz]
    G, u, _ = face_problem(half, mass, yaw, twist)
    out = solve_frictional_impact(G, u, ROWS, e, mu)
    lam = out.impulses
    scale = max(1.0, np.abs(lam).max())
    assert_in_cones_without_gain(out, ROWS, G, u, mu, e, scale)
    eq = [ROWS.normal[k] for k, s in enumerate(out.states) if s is not ContactState.OPEN]
    eq += [i for k, s in enumerate(out.states) if s is ContactState.STICK for i in ROWS.tangential[k]]
    U = gram_range_basis(G[np.ix_(eq, eq)]) if eq else None
    if U is not None:
        z = lam[eq]
        np.testing.assert_allclose(z - U @ (U.T @ z), 0.0, atol=1e-10 * scale)


@settings(max_examples=30, deadline=None)
@given(
    mu=st.floats(0.05, 0.5),
    e=st.sampled_from([0.0, 0.125, 0.5]),
    slip=st.floats(-1e-3, 1e-3),
    twist_x=st.floats(-0.05, 0.05),
    approach=st.floats(1e-10, 1e-2),
    spin=st.floats(-0.05, 0.05),
)
def test_edge_landings_with_small_slips_always_resolve(mu, e, slip, twist_x, approach, spin):
    """Two corners of one edge (six rows of rank 5) landing with unequal approach speeds
    and a small slip: where the compatible split of the sticking impulses would leave one
    corner's cone, that corner ends on its cone's edge with zero slip (a sliding state
    whose slip vanishes); the law must always have its solution found, with impulses in
    the cones, pushing, and no energy gained for e = 0 (a measured toss stopped on such
    an edge). Tolerances: the solver's scaled residual, ~1e-15 of O(1e-3) impulses."""
    half, mass = (0.0524, 0.0524, 0.0524), 0.37
    twist = np.r_[0.0, slip, -approach, twist_x, 0.0, spin]
    G6, u6, _ = face_problem(half, mass, 0.0, twist)
    rows = list(range(6))  # corners (+a, +b) and (+a, -b): the +x edge
    G, u = G6[np.ix_(rows, rows)], u6[rows]
    edge = ContactRows.from_sizes([3, 3])
    out = solve_frictional_impact(G, u, edge, e, mu)
    scale = max(1e-300, np.abs(out.impulses).max(initial=0.0))
    assert_in_cones_without_gain(out, edge, G, u, mu, e, scale)


# An edge of the measured cube (edge 0.1048 m, 0.37 kg, 8.1e-4 kg m²; μ 0.18, e 0.125) at
# an impact of a simulated toss: Delassus matrix and pre-impact row velocities (normal,
# two tangents per corner), one corner resting (-3e-10 m/s), the other landing at
# 1.6 mm/s, both slipping at 0.5 mm/s.
TOSS_EDGE_G = np.array(
    [
        [
            9.482357023690358,
            -3.7871698741600905,
            2.939251724554659,
            -4.076951618284953,
            -3.7871698741600914,
            2.9392517245546586,
        ],
        [
            -3.7871698741600905,
            8.64109658688724,
            3.283779690462117,
            3.787169874160091,
            3.5439631395058218,
            -3.2837796904621146,
        ],
        [
            2.939251724554659,
            3.283779690462117,
            10.323617460493479,
            -2.9392517245546586,
            -3.2837796904621177,
            1.8614422658995842,
        ],
        [
            -4.076951618284953,
            3.787169874160091,
            -2.9392517245546586,
            9.48235702369036,
            3.7871698741600923,
            -2.939251724554658,
        ],
        [
            -3.7871698741600914,
            3.5439631395058218,
            -3.2837796904621177,
            3.7871698741600923,
            8.641096586887242,
            3.2837796904621173,
        ],
        [
            2.9392517245546586,
            -3.2837796904621146,
            1.8614422658995842,
            -2.939251724554658,
            3.2837796904621173,
            10.323617460493477,
        ],
    ]
)
TOSS_EDGE_U = np.array(
    [
        -3.0357459173411053e-10,
        -0.0003824994508052044,
        0.00029686076704244543,
        -0.0015824350380069575,
        -0.0003537351918833055,
        0.0003339229668981115,
    ]
)


def test_an_edge_stopped_with_one_corner_on_its_cone_resolves():
    """The compatible split of the two corners' sticking impulses would leave the resting
    corner's cone, so that corner slides with its impulse on the cone's edge and a slip
    that vanishes (the direction search's angle form has no root there, its cross form
    has): both corners end with zero slip, the landing one bouncing at e times its speed.
    Tolerances: the solver's residual, ~1e-15 of the velocity scale (1e-3 m/s here)."""
    edge = ContactRows.from_sizes([3, 3])
    out = solve_frictional_impact(TOSS_EDGE_G, TOSS_EDGE_U, edge, 0.125, 0.18)
    lam, up = out.impulses, out.u_plus
    assert out.states[1] is ContactState.STICK
    np.testing.assert_allclose(up[[1, 2, 4, 5]], 0.0, atol=1e-14)  # no slip at either corner
    assert up[3] == pytest.approx(-0.125 * TOSS_EDGE_U[3], rel=1e-9)
    assert np.linalg.norm(lam[1:3]) == pytest.approx(0.18 * lam[0], rel=1e-9)  # on the cone
    assert np.linalg.norm(lam[4:6]) <= 0.18 * lam[3]
