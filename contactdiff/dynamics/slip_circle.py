"""The slip angles of a frictional-impact candidate with one spatial sliding contact, in
closed form: the fast path of `contactdiff.dynamics.friction_slip`'s one-slider search.

With one spatial slider, only column ``c`` of the candidate's matrix depends on the slip
angle ``θ``, linearly in ``(cos θ, sin θ)``: ``K(θ) = Kb + Gt (cos θ - cos θb, sin θ -
sin θb) e_cᵀ`` about a base angle ``θb`` (``Gt = -μ G[eq, T]``, p x 2). With ``W = Kb⁻¹``
(or ``U (Uᵀ Kb U)⁻¹ Uᵀ`` where the equality rows are dependent, the compatible-impulse
solve of `contactdiff.dynamics.redundant`), ``zb = W r``, ``P = W Gt`` and ``h = P (cos
θb, sin θb)``, the Sherman-Morrison identity gives

    z(θ) D(θ) = zb D(θ) - (P (cos θ, sin θ) - h) zb[c],   z_c(θ) D(θ) = zb[c],
    D(θ) = 1 - h[c] + P[c] (cos θ, sin θ),

so every unknown times ``D`` is a trigonometric polynomial of degree 1, and so is the
slider's post-impact slip times ``D``: ``u+_T(θ) D(θ) = V(θ) = α + β cos θ + γ sin θ``
(``u+ = u + G B0 z + a(θ) z_c``, ``a(θ) = -μ G[:, T] (cos θ, sin θ)``). The cross form
``s × u+_T = (cos θ V_y - sin θ V_x) / D`` of the law's slip condition (``u+_T`` along
``s = (cos θ, sin θ)``) has the numerator

    F(θ) = α_y cos θ - α_x sin θ + β_y cos²θ + (γ_y - β_x) cos θ sin θ - γ_x sin²θ,

a trigonometric polynomial of degree 2: with ``x = e^{iθ}``, ``x² F`` is a polynomial of
degree 4 in ``x``, whose roots on the unit circle are every root of the cross form
(``F`` at most four; the scan of `friction_slip` finds those it brackets). They are
polished by Newton's method on the candidate's own evaluation (`SlipMap`), which drops
the slips against ``s`` (also roots of ``F``) and the poles (``D = 0``).

The base angle is where ``|det K(θ)|`` (``α_d + β_d cos θ + γ_d sin θ``, fitted at 0,
π/2, π) is largest: ``Kb`` is then as well conditioned as the circle allows. Where it is
not well conditioned (`COND_MAX`), or ``F`` vanishes at every angle (the slip is zero
whatever its direction: the other contacts hold it), the closed form gives no answer
(None) and the scan is used.
"""

from __future__ import annotations

import numpy as np

#: Largest condition number of ``Kb`` (in ``U``'s coordinates) for which the closed form
#: is used: the coefficients are then accurate to about ``COND_MAX · eps`` relative,
#: and Newton polishes the roots on the direct solve.
COND_MAX = 1e8

#: A root of the quartic within this of the unit circle (in ``|x| - 1``) is polished:
#: a double root of ``F`` (a slip tangent to its direction's circle) splits into two
#: roots ``sqrt(eps)`` away from it, far inside this; Newton rejects those that are not
#: roots.
CIRCLE_TOL = 1e-3

#: ``F`` with every coefficient below this share of the slip's coefficients' scale is
#: zero at every angle (round-off): no answer.
FLAT_TOL = 1e-10


def slip_coefficients(fmap) -> tuple[np.ndarray, np.ndarray] | None:
    """For the one spatial slider of the `SlipMap` ``fmap`` (module doc): the columns
    ``α, β, γ`` of ``V(θ) = u+_T(θ) D(θ)`` (2, 3) and the constant, cosine and sine
    coefficients of ``D(θ)`` (3,); None where ``Kb`` is not well conditioned or ``V`` is
    zero at every angle (within `FLAT_TOL` of the velocity scale: ``D`` is 1 at ``θb``)."""
    prob, eq, c = fmap.prob, fmap.eq, int(fmap.c[0])
    Gt = fmap.GT[0][eq]  # (p, 2)
    U = fmap.U
    # det K(θ) = α_d + β_d cos θ + γ_d sin θ: its largest |value| on the circle
    K3 = np.repeat(fmap.K0[None], 3, axis=0)
    K3[:, :, c] += (Gt @ np.array([[1.0, 0.0, -1.0], [0.0, 1.0, 0.0]])).T
    if U is not None:
        K3 = U.T @ K3 @ U
    d0, d1, d2 = np.linalg.det(K3)
    al, be, ga = 0.5 * (d0 + d2), 0.5 * (d0 - d2), d1 - 0.5 * (d0 + d2)
    tb = float(np.arctan2(ga, be)) + (0.0 if al >= 0.0 else np.pi)
    cb, sb = np.cos(tb), np.sin(tb)
    Kb = fmap.K0.copy()
    Kb[:, c] += Gt @ np.array([cb, sb])
    Kr = Kb if U is None else U.T @ Kb @ U
    if not (np.isfinite(Kr).all() and np.linalg.cond(Kr) < COND_MAX):
        return None
    if U is None:
        zb = np.linalg.solve(Kr, fmap.r)
        P = np.linalg.solve(Kr, Gt)
    else:
        sol = np.linalg.solve(Kr, U.T @ np.column_stack([fmap.r, Gt]))
        zb, P = U @ sol[:, 0], U @ sol[:, 1:]
    h = P @ np.array([cb, sb])
    zc = float(zb[c])
    dd = np.array([1.0 - h[c], P[c, 0], P[c, 1]])  # D(θ): constant, cos, sin
    # z D: constant, cos and sin parts (p, 3)
    Z = np.column_stack([zb * dd[0] + h * zc, zb * dd[1] - P[:, 0] * zc, zb * dd[2] - P[:, 1] * zc])
    T = fmap.T[0]
    V = np.outer(prob.u[T], dd) + fmap.GB0[T] @ Z  # (2, 3)
    V[:, 1:] += fmap.GT[0][T] * zc
    # a slip zero at every angle (other contacts hold it), to round-off of the velocities
    if not np.abs(V).max() > FLAT_TOL * (prob.bmax + prob.gmax * float(np.abs(Z).max())):
        return None
    return V, dd


def cross_form_roots(V: np.ndarray) -> np.ndarray | None:
    """The angles (rad) where ``F(θ)`` of the module doc vanishes for ``V(θ) = α + β cos θ
    + γ sin θ`` (columns of ``V``, 2 x 3), from the quartic's roots within `CIRCLE_TOL`
    of the unit circle (unpolished); None where ``F`` is zero at every angle (within
    `FLAT_TOL` of ``V``'s scale)."""
    alpha, beta, gamma = V[:, 0], V[:, 1], V[:, 2]
    a, b = alpha[1], -alpha[0]  # cos θ, sin θ
    cc, cs, ss = beta[1], gamma[1] - beta[0], -gamma[0]  # cos², cos sin, sin²
    # cos θ = (x + 1/x)/2, sin θ = (x - 1/x)/(2i): x² F, highest power first
    coef = np.array(
        [
            0.25 * (cc - ss) - 0.25j * cs,
            0.5 * a - 0.5j * b,
            0.5 * (cc + ss),
            0.5 * a + 0.5j * b,
            0.25 * (cc - ss) + 0.25j * cs,
        ]
    )
    scale = float(np.abs(V).max())
    if not np.isfinite(coef).all() or not np.abs(coef).max() > FLAT_TOL * scale:
        return None
    x = np.roots(coef)
    x = x[np.abs(np.abs(x) - 1.0) <= CIRCLE_TOL]
    return np.angle(x)
