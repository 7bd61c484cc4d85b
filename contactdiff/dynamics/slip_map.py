"""The map from a frictional impact candidate's slip angles to its impulses and
post-impact velocities (`SlipMap`), for a batch of angles at once, and the thin
products it is built of; the search for its roots is
`contactdiff.dynamics.friction_slip`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .slip_lowrank import LowRankSolve

# OpenBLAS's gemm runs on one thread up to this many multiply-adds (its SMP_THRESHOLD_MIN
# 65536 times GEMM_MULTITHREAD_THRESHOLD 4)
_ONE_THREAD = 65536 * 4

# A post-impact slip below this share of the velocity scale has no direction.
SLIP_ZERO = 1e-14


def wrap_angle(a: np.ndarray) -> np.ndarray:
    """Angles (rad) wrapped into [-π, π)."""
    return (a + np.pi) % (2.0 * np.pi) - np.pi


def _thin_matmul(X: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """``X @ Y`` (2-D) in blocks of rows of ``X`` (or columns of ``Y``, whichever is
    longer) of at most `_ONE_THREAD` multiply-adds each: the slip search's products are
    thin (a few columns) and long (a grid of thousands of angles), and OpenBLAS runs a
    larger product on every core, whose start-up costs more than the product (the
    search ran 1.6 times slower with it on two busy cores). Each element is the same
    sum as in the whole product. Blocks have at least two rows (columns): numpy takes
    a vector kernel for one."""
    m, k = X.shape
    n = Y.shape[1]
    if m * k * n <= _ONE_THREAD or min(m, k, n) < 2:
        return X @ Y
    if m >= n:
        step = max(2, _ONE_THREAD // (k * n))
        cuts = list(range(0, m, step))
        if m - cuts[-1] < 2:
            cuts.pop()
        return np.concatenate([X[a:b] @ Y for a, b in zip(cuts, cuts[1:] + [m])], axis=0)
    step = max(2, _ONE_THREAD // (k * m))
    cuts = list(range(0, n, step))
    if n - cuts[-1] < 2:
        cuts.pop()
    return np.concatenate([X @ Y[:, a:b] for a, b in zip(cuts, cuts[1:] + [n])], axis=1)


def _congruence(U: np.ndarray, K: np.ndarray) -> np.ndarray:
    """``Uᵀ K[i] U`` for a stack ``K`` (P, p, p), ``U`` (p, r): the stacked product
    computed as two products of all P matrices at once (one BLAS call each, not one
    per matrix), each element the same sum over the same terms; with ``r = 1`` (where
    numpy takes vector kernels) or one matrix, the stacked product itself."""
    P, p, _ = K.shape
    r = U.shape[1]
    if r < 2 or P < 2:
        return U.T @ K @ U
    left = _thin_matmul(K.transpose(0, 2, 1).reshape(P * p, p), U).reshape(P, p, r)  # (Uᵀ K[i])ᵀ
    left = np.ascontiguousarray(left.transpose(0, 2, 1))
    return _thin_matmul(left.reshape(P * r, p), U).reshape(P, r, r)


def _solve_stack(K: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """``K[i] x[i] = rhs[i]`` for a stack; least squares (pseudo-inverse) if one is singular."""
    try:
        return np.linalg.solve(K, rhs)
    except np.linalg.LinAlgError:
        return np.linalg.pinv(K) @ rhs


class SlipMap:
    """``θ -> g(θ)`` of one candidate's spatial sliders, for a batch of angles.

    With the friction columns of the sliders left out, ``Λ = B0 z`` and the
    candidate's equations are ``K0 z = r``; slider ``k`` adds ``-μ_k Λ_N,k s_k``
    on its tangential rows, so column ``c_k`` of ``G B`` gains
    ``a_k(θ) = -μ_k G[:, T_k] s_k``. Then ``K(θ) z = r``,
    ``u+ = u + G B0 z + Σ_k a_k z_ck`` and, differentiating,
    ``dz/dθ_k = -K^-1 (da_k z_ck)[eq]``, ``du+/dθ_k = G B(θ) dz/dθ_k + da_k z_ck``.
    With dependent equality rows (``prob.redundant``) every solve is the
    compatible-impulse one, ``z = U (Uᵀ K U)⁻¹ Uᵀ r`` with ``U`` a basis of the
    range of ``G[eq, eq]`` (`contactdiff.dynamics.redundant`), as the candidate's
    own evaluation.
    """

    def __init__(self, prob, states, dirs, spatial, lay, cross: bool):
        self.cross = cross
        cols_n, cols_t, eq, _ = lay
        self.prob, self.eq = prob, eq
        self.GB0 = prob.G @ prob.build_B(states, dirs, lay)
        self.K0 = self.GB0[eq]
        self.r = -prob.b[eq]
        self.c = np.array([cols_n[k] for k in spatial], dtype=np.intp)
        self.T = [prob.tang[k] for k in spatial]
        self.GT = [-prob.mu[k] * prob.G[:, prob.tang[k]] for k in spatial]
        self.mu_s = np.array([prob.mu[k] for k in spatial])
        # inequalities of the law that a root must also satisfy (for ranking starts)
        self.closed = np.array(list(cols_n.values()), dtype=np.intp)
        self.stick = [(cols_n[k], cols_t[k], prob.mu[k]) for k in cols_t if prob.mu[k] < np.inf]
        self.open_k = np.array([k for k in range(prob.n) if k not in cols_n], dtype=np.intp)
        self.U = prob.equality_basis(eq)
        self._low_rank: LowRankSolve | None = None  # formed at the first low-rank evaluation

    def _solve(self, K: np.ndarray, rhs: np.ndarray) -> np.ndarray:
        """``K[i] x[i] = rhs[i]`` for a stack, by the compatible-impulse principle when the
        equality rows are dependent (class doc)."""
        U = self.U
        if U is None:
            return _solve_stack(K, rhs)
        return U @ _solve_stack(_congruence(U, K), U.T @ rhs)

    def _solve_r(self, K: np.ndarray) -> np.ndarray:
        """``K[i] z[i] = r`` for a stack (P, p, p) with one right-hand side: `_solve`
        with ``Uᵀ r`` formed once for all matrices (P, p, 1)."""
        U, P = self.U, K.shape[0]
        if U is None:
            return _solve_stack(K, np.broadcast_to(self.r, (P, self.r.size))[..., None])
        Ur = U.T @ self.r[:, None]
        return U @ _solve_stack(_congruence(U, K), np.broadcast_to(Ur, (P,) + Ur.shape))

    def turns(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
        """``cos θ``, ``sin θ`` (P, ns) and the friction columns ``a_k(θ)`` (m, P) of
        each slider at angles ``theta`` (P, ns): what `__call__` forms first. They
        depend on the sliders and the angles only, not on the rest of the candidate, so
        a problem forms them once per set of sliders for its grid (`grid_turns`)."""
        cs, sn = np.cos(theta), np.sin(theta)
        a = [_thin_matmul(self.GT[j], np.stack([cs[:, j], sn[:, j]])) for j in range(theta.shape[1])]
        return cs, sn, a

    def low_rank(self) -> LowRankSolve:
        """The candidate's low-rank solve (`contactdiff.dynamics.slip_lowrank`), formed once."""
        if self._low_rank is None:
            self._low_rank = LowRankSolve(self.K0, self.r, self.U, self.c, [g[self.eq] for g in self.GT], _thin_matmul)
        return self._low_rank

    def _impulses(self, theta: np.ndarray, turns=None, low_rank: bool = False):
        """At angles ``theta`` (P, ns): `turns`, the candidate's matrices ``K(θ)``
        (P, p, p; None by the low-rank path), unknowns ``z`` (P, p) and those of the
        sliders' normal impulses ``zc`` (P, ns), post-impact row velocities ``u+`` (P, m)
        and the impulse scale (P,): the largest ``|z|`` or slider's ``μ |Λ_N|``. With
        ``low_rank``, ``z`` by `contactdiff.dynamics.slip_lowrank` where ``K0`` is well
        conditioned (equal to the direct solve's up to round-off)."""
        P, ns = theta.shape
        cs, sn, a = self.turns(theta) if turns is None else turns  # a: (m, P) each
        if low_rank and self.low_rank().usable:
            K = None
            z = self.low_rank().solve(cs, sn)
        else:
            K = np.repeat(self.K0[None], P, axis=0)
            for j in range(ns):
                K[:, :, self.c[j]] += a[j][self.eq].T
            z = self._solve_r(K)[..., 0]
        zc = z[:, self.c]
        up = self.prob.u + _thin_matmul(z, self.GB0.T)
        for j in range(ns):
            up += a[j].T * zc[:, j, None]
        lam_max = np.maximum(np.abs(z).max(axis=1, initial=0.0), (np.abs(zc) * self.mu_s).max(axis=1))
        return cs, sn, a, K, z, zc, up, lam_max

    def violating(self, theta: np.ndarray, rel: float) -> np.ndarray:
        """At angles ``theta`` (P, ns): where the candidate's impulses are finite and
        break one of the law's inequalities (`feasible`) by more than ``rel`` of their
        scale (P,), a negative normal impulse by ``rel`` of the largest impulse, say.
        With ``rel`` far above the candidate check's tolerance such a point fails that
        check whatever the round-off of the two evaluations: the solver skips it."""
        *_, z, _, up, lam_max = self._impulses(theta)
        ok = np.isfinite(z).all(axis=1) & np.isfinite(up).all(axis=1) & np.isfinite(lam_max)
        return ok & ~self.feasible(z, up, lam_max, self.prob.bmax + self.prob.gmax * lam_max, rel)

    def __call__(self, theta: np.ndarray, jac: bool = True, turns=None, low_rank: bool = False):
        """For angles ``theta`` of shape (P, ns): the residual f (P, ns), its
        Jacobian (P, ns, ns) or None, the feasibility of the law's other
        conditions (P,), whether every slip is along (not against) its ``s``
        (P,) and the scale of f (P,). With ``cross``, ``f_k = s_k x u+_T,k``
        (smooth; scale: the velocity scale), else ``f_k = g_k`` (scale 1).
        ``turns``: `turns` of ``theta`` if already formed; ``low_rank`` (without
        ``jac``): the unknowns by the low-rank path (`_impulses`)."""
        P, ns = theta.shape
        cs, sn, a, K, z, zc, up, lam_max = self._impulses(theta, turns, low_rank and not jac)
        vscale = self.prob.bmax + self.prob.gmax * lam_max
        v = np.stack([up[:, t] for t in self.T], axis=1)  # (P, ns, 2)
        r2 = (v * v).sum(axis=2)
        moving = np.sqrt(r2) > SLIP_ZERO * vscale[:, None]
        if self.cross:
            f = cs * v[..., 1] - sn * v[..., 0]
            aligned = ((cs * v[..., 0] + sn * v[..., 1] > 0.0) | ~moving).all(axis=1)
        else:
            f = np.where(moving, wrap_angle(np.arctan2(v[..., 1], v[..., 0]) - theta), 0.0)
            aligned = np.ones(P, dtype=bool)
            vscale = np.ones(P)
        ok = np.isfinite(f).all(axis=1) & np.isfinite(z).all(axis=1)
        feas = ok & self.feasible(z, up, lam_max, self.prob.bmax + self.prob.gmax * lam_max)
        if not jac:
            return f, None, feas, aligned, vscale
        GB = np.repeat(self.GB0[None], P, axis=0)
        for j in range(ns):
            GB[:, :, self.c[j]] += a[j].T
        rhs = np.empty((P, self.r.size, ns))
        da = []
        for j in range(ns):
            da.append(_thin_matmul(self.GT[j], np.stack([-sn[:, j], cs[:, j]])))
            rhs[:, :, j] = da[j][self.eq].T * zc[:, j, None]
        dup = GB @ -self._solve(K, rhs)
        for j in range(ns):
            dup[:, :, j] += da[j].T * zc[:, j, None]
        J = np.zeros((P, ns, ns)) if self.cross else np.repeat(-np.eye(ns)[None], P, axis=0)
        with np.errstate(invalid="ignore", divide="ignore"):
            for i in range(ns):
                dv = dup[:, self.T[i], :]  # (P, 2, ns)
                if self.cross:  # d(c v1 - s v0) = c dv1 - s dv0 - (s v1 + c v0) dθ_i
                    J[:, i, :] = cs[:, i, None] * dv[:, 1] - sn[:, i, None] * dv[:, 0]
                    J[:, i, i] -= sn[:, i] * v[:, i, 1] + cs[:, i] * v[:, i, 0]
                    continue
                row = (v[:, i, 0, None] * dv[:, 1] - v[:, i, 1, None] * dv[:, 0]) / r2[:, i, None]
                J[:, i, :] += np.where(moving[:, i, None], row, 0.0)
                J[:, i, i] = np.where(moving[:, i], J[:, i, i], 1.0)  # no direction: any θ is consistent
        return f, J, feas, aligned, vscale

    def poles(self) -> np.ndarray:
        """One slider: the angles where ``K(θ)`` is singular (``Λ_N`` infinite).
        Only column ``c`` depends on θ, linearly in ``s``, so
        ``det K = α + β cos θ + γ sin θ``: fitted at 0, π/2, π and solved."""
        K = np.repeat(self.K0[None], 3, axis=0)
        K[:, :, self.c[0]] += (self.GT[0] @ np.array([[1.0, 0.0, -1.0], [0.0, 1.0, 0.0]]))[self.eq].T
        if self.U is not None:
            K = self.U.T @ K @ self.U
        d0, d1, d2 = np.linalg.det(K)
        al, be = 0.5 * (d0 + d2), 0.5 * (d0 - d2)
        rad = float(np.hypot(be, d1 - al))
        if not rad > abs(al):
            return np.zeros(0)
        phi, w = np.arctan2(d1 - al, be), np.arccos(-al / rad)
        return np.array([phi - w, phi + w])

    def feasible(self, z, up, lam_max, vscale, rel=1e-6):
        """Λ_N >= 0 of closed contacts, the cone of sticking ones, w_N >= 0 of open ones."""
        ok = (z[:, self.closed] >= -rel * lam_max[:, None]).all(axis=1)
        for c, cs, mu in self.stick:
            ok &= np.linalg.norm(z[:, cs], axis=1) <= mu * z[:, c] + rel * lam_max
        if self.open_k.size:
            pr = self.prob
            w = up[:, pr.normal[self.open_k]] + pr.e[self.open_k] * pr.u[pr.normal[self.open_k]]
            ok &= (w >= -rel * vscale[:, None]).all(axis=1)
        return ok


@dataclass
class CandidateEval:
    """One candidate of a frictional impact at given slip states and directions: its
    impulses ``lam`` (N s) and post-impact velocity ``up``, the unknowns ``z`` of its
    linear system (``lam = B z``) and that system's matrix ``K`` (None without unknowns)."""

    lam: np.ndarray
    up: np.ndarray
    z: np.ndarray
    K: np.ndarray | None
