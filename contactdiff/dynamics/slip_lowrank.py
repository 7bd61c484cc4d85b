"""A frictional-impact candidate's unknowns at many slip angles at once, as a low-rank
update of one factorisation: the fast path of the slip search's grid
(`contactdiff.dynamics.slip_map.SlipMap`).

The candidate's equations are ``K(θ) z = r`` with ``K(θ) = K0 + Σ_j g_j(θ) e_cjᵀ``:
slider ``j``'s friction adds the column ``g_j(θ) = Gt_j (cos θ_j, sin θ_j)`` (``Gt_j``
its rows ``-μ_j G[eq, T_j]``, p x 2) to column ``c_j`` (its normal impulse's unknown)
of the angle-free ``K0``. With ``W = K0⁻¹`` (or, where the equality rows are dependent,
``W = U (Uᵀ K0 U)⁻¹ Uᵀ``, the compatible-impulse solve of
`contactdiff.dynamics.redundant` with ``U`` a basis of the range of ``G[eq, eq]``), the
Sherman-Morrison-Woodbury identity gives

    z(θ) = z0 - Y(θ) S(θ)⁻¹ z0[c],   z0 = W r,   Y(θ) = [W g_j(θ)]_j,   S(θ) = I + Y(θ)[c],

and ``W g_j(θ) = (W Gt_j) (cos θ_j, sin θ_j)`` is linear in the two precomputed columns
``W Gt_j``: a point costs an ``ns x ns`` solve (``ns`` sliders) instead of a ``p x p``
one and the stacked matrices it takes. For the dependent case, ``(Uᵀ K U)⁻¹ Uᵀ`` with
``Uᵀ K U = Uᵀ K0 U + Σ_j (Uᵀ g_j)(U[c_j])`` is the same identity in the coordinates of
``U``, and multiplied by ``U`` it is the formula above.

The same identity bounds, over every angle, how far the sliders' slips turn with their
angles (`LowRankSolve.slip_contraction`): where the map from the slip angles to the
slips' angles is a contraction, the candidate has one root and the search needs no grid.

The two paths agree to round-off times the condition of ``K0`` and ``S(θ)``; the solver
takes this one only where ``K0`` (in ``U``'s coordinates) is well conditioned
(`COND_MAX`), and only to rank a grid's points as Newton's starts, whose roots the
direct path then polishes and checks.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

#: Largest condition number of ``K0`` (in ``U``'s coordinates) for which the low-rank
#: path is taken: its results then differ from the direct solve's by at most about
#: ``COND_MAX * cond(S) * eps`` relative, far below the grid's purpose (ranking starts).
COND_MAX = 1e8


#: `LowRankSolve.pulls_everywhere` answers only where ``K0`` is conditioned below this
#: and the friction's share ``σ`` of ``S(θ)`` is at most `CERTIFY_SIGMA`.
CERTIFY_COND = 1e6
CERTIFY_SIGMA = 0.5


class LowRankSolve:
    """``z(θ)`` of one candidate by the identity of the module doc.

    Args:
        K0: the angle-free matrix (p, p).
        r: the right-hand side (p,).
        U: a basis of the range of the equality rows (p, q) where they are dependent,
            else None.
        c: the sliders' normal-impulse columns (ns,).
        Gt: each slider's friction rows on the equations, ``-μ G[eq, T]`` (p, 2).
        matmul: the product of two matrices (the slip search's, which keeps OpenBLAS
            on one thread for its long thin products).

    ``usable`` is False where ``K0`` is singular or worse conditioned than `COND_MAX`:
    then `solve` must not be called.
    """

    def __init__(self, K0, r, U, c, Gt: list[np.ndarray], matmul: Callable[[np.ndarray, np.ndarray], np.ndarray]):
        self.matmul = matmul
        K = K0 if U is None else U.T @ K0 @ U
        self.cond = float(np.linalg.cond(K)) if K.size and np.isfinite(K).all() else np.inf
        self.usable = self.cond < COND_MAX
        if not self.usable:
            return
        inv = np.linalg.inv(K)
        W = inv if U is None else U @ inv @ U.T
        self.z0 = W @ r
        self.c = c
        WG = [W @ g for g in Gt]  # (p, 2) each: W g_j(θ) = WG_j (cos θ_j, sin θ_j)
        # S(θ) = I + cos θ_j WG_j[c_i, 0] + sin θ_j WG_j[c_i, 1] (row i, column j), and
        # Y(θ) β = [cos θ ∘ β, sin θ ∘ β] @ WGᵀ with the columns of all WG_j in that order
        self.S_cos = np.stack([wg[c, 0] for wg in WG], axis=1)
        self.S_sin = np.stack([wg[c, 1] for wg in WG], axis=1)
        self.WGt = np.concatenate([np.stack([wg[:, 0] for wg in WG]), np.stack([wg[:, 1] for wg in WG])])

    def solve(self, cs: np.ndarray, sn: np.ndarray) -> np.ndarray:
        """The unknowns ``z`` (P, p) at angles with cosines ``cs`` and sines ``sn`` (P, ns)."""
        P, ns = cs.shape
        S = cs[:, None, :] * self.S_cos + sn[:, None, :] * self.S_sin + np.eye(ns)  # (P, ns, ns)
        rhs = np.broadcast_to(self.z0[self.c], (P, ns))[..., None]
        try:
            beta = np.linalg.solve(S, rhs)[..., 0]
        except np.linalg.LinAlgError:  # a pole on a grid point: the least-squares answer there
            beta = (np.linalg.pinv(S) @ rhs)[..., 0]
        return self.z0 - self.matmul(np.concatenate([cs * beta, sn * beta], axis=1), self.WGt)

    def pulls_everywhere(self, closed: np.ndarray, mu_max: float, rel: float) -> bool:
        """Whether, at every slip angle of the sliders, a contact of the candidate pulls
        by more than ``rel`` of the impulses' scale: some normal-impulse unknown among
        ``closed`` (columns of ``z``) is below ``-rel · L`` for every ``θ``, with ``L`` a
        bound of the largest impulse (``max |z|``, or a slider's ``μ |Λ_N|``, ``μ`` up to
        ``mu_max``) over all angles. Then no slip direction satisfies the law.

        The bound, from the module doc's identity: each entry of ``W g_j(θ)`` is
        ``cos θ_j a + sin θ_j b``, at most ``N_ij = ||(a, b)||`` in size (``WG_j``'s row
        ``i``), so ``|S(θ) - I| <= N[c]`` entry by entry; with ``β = z0[c] - (S - I) β``
        that gives ``|β| <= (I - N[c])⁻¹ |z0[c]|`` (a nonnegative inverse while the
        spectral norm ``σ`` of ``N[c]`` is below 1), and ``|z_i(θ) - z0_i| <= N_i · |β|``.
        Only where ``σ <= CERTIFY_SIGMA`` and ``cond(K0) <= CERTIFY_COND`` (otherwise
        False): ``K(θ)`` is then conditioned below ``CERTIFY_COND (1 + σ) / (1 - σ) =
        3e6``, so the candidate's own evaluation of ``z`` is within about
        ``3e6 · p · eps < 1e-8`` of its scale of the exact one, far inside a ``rel`` of
        1e-6."""
        if not self.cond <= CERTIFY_COND:
            return False
        cos_part, sin_part = self._WG_parts()
        N = np.sqrt(cos_part**2 + sin_part**2)  # (p, ns)
        Nc = N[self.c]
        sigma = float(np.linalg.norm(Nc, 2)) if np.isfinite(Nc).all() else np.inf
        if not sigma <= CERTIFY_SIGMA:
            return False
        beta = np.linalg.solve(np.eye(len(self.c)) - Nc, np.abs(self.z0[self.c]))
        spread = N @ beta
        scale = float((np.abs(self.z0) + spread).max()) * max(1.0, mu_max)
        return bool(np.any(self.z0[closed] + spread[closed] < -rel * scale))

    def slip_contraction(self, u: np.ndarray, GB0: np.ndarray, GT: list[np.ndarray], T: list[np.ndarray]) -> float:
        """A bound ``L`` of the Lipschitz constant (max-norm, over every slip angle) of the
        map from the sliders' slip angles to the angles of their post-impact slips, inf
        where none is found. Where ``L < 1`` that map is a contraction: the candidate's
        slip-angle equations have exactly one root (a fixed point of the map).

        Args:
            u: pre-impact row velocities (m,).
            GB0: ``G B0``, the rows' response to the unknowns without the sliders'
                friction columns (m, p).
            GT: each slider's friction rows ``-μ G[:, T]`` (m, 2).
            T: each slider's tangential rows.

        The bound, from the module doc's identity: ``z_c(θ) = β(θ)``, so the post-impact
        velocities are ``u+(θ) = u_free + Σ_j H_j s_j β_j`` with ``u_free = u + G B0 z0``
        (the frictionless sliders'), ``H_j = GT_j - G B0 W Gt_j`` and ``s_j = (cos θ_j,
        sin θ_j)``. With ``N`` and ``|β| <= b = (I - N[c])⁻¹ |z0[c]|`` as in
        `pulls_everywhere` (valid while ``σ < 1``), slider ``k``'s slip ``v_k`` is within
        ``R_k = Σ_j h_kj b_j`` of its frictionless one (``h_kj = ||H_j[T_k]||₂``), and
        ``∂β/∂θ_i = -S⁻¹ (W Gt_i)[c] s_i' β_i`` with ``|S⁻¹| <= (I - N[c])⁻¹`` entry by
        entry (Neumann series) gives ``|∂v_k/∂θ_i| <= D_ki = h_ki b_i + Σ_j h_kj ((I -
        N[c])⁻¹ N[c, i])_j b_i``. Where ``|v_k^free| > R_k`` the slip never vanishes and its
        angle moves by at most ``D_ki / (|v_k^free| - R_k)`` per radian of ``θ_i``: ``L``
        is the largest row sum. Only where ``σ <= CERTIFY_SIGMA`` and ``cond(K0) <=
        CERTIFY_COND`` (as `pulls_everywhere`), else inf."""
        if not self.cond <= CERTIFY_COND:
            return np.inf
        cos_part, sin_part = self._WG_parts()
        N = np.sqrt(cos_part**2 + sin_part**2)  # (p, ns)
        Nc = N[self.c]
        sigma = float(np.linalg.norm(Nc, 2)) if np.isfinite(Nc).all() else np.inf
        if not sigma <= CERTIFY_SIGMA:
            return np.inf
        ns = len(self.c)
        inv = np.linalg.inv(np.eye(ns) - Nc)
        b = inv @ np.abs(self.z0[self.c])
        dbeta = (inv @ Nc) * b[None, :]  # column i: the bound of |∂β/∂θ_i|
        u_free = u + GB0 @ self.z0
        bound = 0.0
        for k in range(ns):
            h = np.array(
                [
                    np.linalg.norm(GT[j][T[k]] - GB0[T[k]] @ np.column_stack([cos_part[:, j], sin_part[:, j]]), 2)
                    for j in range(ns)
                ]
            )
            slip = float(np.linalg.norm(u_free[T[k]])) - float(h @ b)
            if not slip > 0.0:
                return np.inf
            bound = max(bound, float((h * b + h @ dbeta).sum()) / slip)
        return bound if np.isfinite(bound) else np.inf

    def _WG_parts(self) -> tuple[np.ndarray, np.ndarray]:
        """The columns ``WG_j[:, 0]`` and ``WG_j[:, 1]`` of every slider, (p, ns) each."""
        ns = self.S_cos.shape[1]
        return self.WGt[:ns].T, self.WGt[ns:].T
