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
@given(yaw=st.floats(-3.0, 3.0), mu=st.floats(0.05, 1.0), e=st.sampled_from([0.0, 0.0, 0.3, 1.0]),
       vx=st.floats(-3.0, 3.0), vy=st.floats(-3.0, 3.0), vz=st.floats(-3.0, -0.2),
       wx=st.floats(-1.0, 1.0), wy=st.floats(-1.0, 1.0), wz=st.floats(-5.0, 5.0))
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
    for k in range(4):
        n, t = ROWS.normal[k], list(ROWS.tangential[k])
        assert lam[n] >= -1e-12 * scale
        assert np.linalg.norm(lam[t]) <= mu * lam[n] + 1e-12 * scale
    if e == 0.0:
        assert out.energy_change <= 1e-12 * scale * (np.abs(u).max() + np.abs(G).max() * scale)
    eq = [ROWS.normal[k] for k, s in enumerate(out.states) if s is not ContactState.OPEN]
    eq += [i for k, s in enumerate(out.states) if s is ContactState.STICK for i in ROWS.tangential[k]]
    U = gram_range_basis(G[np.ix_(eq, eq)]) if eq else None
    if U is not None:
        z = lam[eq]
        np.testing.assert_allclose(z - U @ (U.T @ z), 0.0, atol=1e-10 * scale)
