"""The slip directions of a frictional impact's sliding contacts: the nonlinear part of
`contactdiff.dynamics.frictional_impact`.

A sliding contact's tangential impulse is ``-μ Λ_N s`` with ``s`` the unit direction of
its post-impact slip, itself a result of the impact: in 3-D an angle per sliding
contact to solve for. One slider: its angle scanned around the circle, each sign
change refined (Brent) and polished (Newton). Several: Newton from the pre-impact
slip, from a rough solution of the whole law (a projected fixed point), from the
frictionless slip and from the best points of a coarse grid. A mixin of the solver's
problem class (its state: ``G``, ``u``, ``mu``, ``tol``, the candidate's layout and
evaluation methods).
"""

from __future__ import annotations

import itertools
from collections.abc import Iterator

import numpy as np
from scipy.optimize import brentq

# Newton on the slip angles of the spatial sliding contacts of a candidate.
_NEWTON_MAX_ITER = 60
_NEWTON_ATOL = 1e-13  # rad, on wrap(atan2(u+_T) - θ)
_NEWTON_LOOSE = 1e-8
_NEWTON_MAX_STEP = 0.5 * np.pi
# Scan of the slip angle of one spatial slider; grid and starts for several.
_SCAN_POINTS = 144
_GRID_BUDGET = 1500
_GRID_STARTS = 12
_FP_SWEEPS = 300

# A post-impact slip below this share of the velocity scale has no direction.
SLIP_ZERO = 1e-14


def project_cone(x: np.ndarray, mu: float) -> np.ndarray:
    """Euclidean projection of ``x = (x_N, x_T)`` onto ``||x_T|| <= mu x_N``
    (``x_N >= 0`` with free ``x_T`` if ``mu`` is inf, ``x_T = 0`` if it is 0)."""
    out = x.copy()
    if mu == np.inf:
        out[0] = max(out[0], 0.0)
        return out
    n, t = float(x[0]), float(np.linalg.norm(x[1:]))
    if n >= 0.0 and t <= mu * n:
        return out
    if mu * t <= -n:
        return np.zeros_like(x)
    n2 = (n + mu * t) / (1.0 + mu * mu)
    out[0] = n2
    out[1:] = x[1:] * (mu * n2 / t)
    return out


def _wrap(a: np.ndarray) -> np.ndarray:
    return (a + np.pi) % (2.0 * np.pi) - np.pi


class SlipDirections:
    """Slip-direction search of a candidate (module doc)."""

    def slip_roots(self, states, dirs, spatial, lay) -> Iterator[np.ndarray]:
        """Slip angles θ with g(θ) = wrap(atan2(u+_T(θ)) - θ) = 0 (see slip_residual).

        One spatial slider: g is scanned on a grid of _SCAN_POINTS angles from
        the pre-impact slip direction, each sign change is refined by Brent's
        method and polished by Newton, which rejects the wrap jumps (g = ±π)
        and the poles (Λ_N infinite): all roots that the grid separates,
        nearest the pre-impact direction first. Near a small post-impact slip
        the direction turns fast (|dg/dθ| ~ 1e3 seen), so a steep sign change
        is not taken for a jump. Several:
        Newton from the pre-impact slip, from the post-impact slip of an
        approximate solution of the whole law (`fixed_point_slip`), from the
        frictionless post-impact slip, and from the _GRID_STARTS points of a coarse grid on the torus
        with the smallest candidate residual.
        """
        pre = np.array([np.arctan2(self.u[self.tang[k][1]], self.u[self.tang[k][0]]) for k in spatial])
        if len(spatial) == 1:
            yield from self.roots_1d(states, dirs, spatial, lay, float(pre[0]))
            return
        starts = [pre]
        ups = self.fixed_point_slip()
        starts.append(np.array([np.arctan2(ups[self.tang[k][1]], ups[self.tang[k][0]]) for k in spatial]))
        free = self.evaluate(states, dirs, lay)  # sliders without their friction columns
        starts.append(np.array([np.arctan2(free.up[self.tang[k][1]], free.up[self.tang[k][0]])
                                for k in spatial]))
        ns = len(spatial)
        per_axis = max(4, int(_GRID_BUDGET ** (1.0 / ns)))
        axis = 2.0 * np.pi * np.arange(per_axis) / per_axis
        scored = []
        for offs in itertools.product(axis, repeat=ns):
            th = pre + np.array(offs)
            d = dict(dirs)
            for j, k in enumerate(spatial):
                d[k] = np.array([np.cos(th[j]), np.sin(th[j])])
            ev = self.evaluate(states, d, lay)
            r = self.residual(states, d, ev.lam, ev.up)  # ranks by all conditions, not g alone
            if np.isfinite(r):
                scored.append((r, len(scored), th))
        scored.sort(key=lambda x: (x[0], x[1]))
        starts.extend(th for _, _, th in scored[:_GRID_STARTS])
        found: list[np.ndarray] = []
        for theta0 in starts:
            theta = self.newton(states, dirs, spatial, lay, theta0)
            if theta is None or any(np.abs(_wrap(theta - f)).max() < 1e-9 for f in found):
                continue
            found.append(theta)
            yield theta

    def fixed_point_slip(self) -> np.ndarray:
        """Post-impact row velocities of an approximate solution of the law, by
        projected Gauss-Seidel on De Saxce's modified velocity (a start only).

        Contact by contact, ``Λ_k <- P_K(Λ_k - ρ_k ŵ_k)`` with ``K`` the cone
        ``||Λ_T|| <= μ Λ_N``, ``ŵ = u+`` plus ``e u-_N + μ ||u+_T||`` on the
        normal row and ``ρ_k = 1 / max diag G_kk``. Its fixed points are the
        solutions of the law; it need not converge (a few hundred sweeps).
        """
        if self._fp is not None:
            return self._fp
        lam = np.zeros(self.m)
        blocks = self.rows._rows_of  # type: ignore[attr-defined]
        for _ in range(_FP_SWEEPS):
            old = lam.copy()
            for k in range(self.n):
                r, t = blocks[k], self.tang[k]
                w = self.u[r] + self.G[r] @ lam
                mu = self.mu[k]
                if t.size and mu > 0.0:
                    w[0] += self.e[k] * self.u[self.normal[k]] + (mu * np.linalg.norm(w[1:]) if mu < np.inf else 0.0)
                else:
                    w[0] += self.e[k] * self.u[self.normal[k]]
                dg = float(self.G[r[:, None], r].diagonal().max())
                x = lam[r] - w / dg if dg > 0.0 else lam[r]
                lam[r] = project_cone(x, mu if t.size else 0.0)
            if np.abs(lam - old).max() <= 1e-14 * max(np.abs(lam).max(), 1e-300):
                break
        self._fp = self.u + self.G @ lam
        return self._fp

    def roots_1d(self, states, dirs, spatial, lay, pre: float) -> Iterator[np.ndarray]:
        """The slip angles of one spatial slider: the circle scanned, sign changes refined."""
        def g(t: float) -> float:
            return float(self.slip_residual(states, dirs, spatial, lay, np.array([t]), jac=False)[0][0])

        th = pre + 2.0 * np.pi * np.arange(_SCAN_POINTS + 1) / _SCAN_POINTS
        gs = np.array([g(t) for t in th])
        roots = []
        for i in range(_SCAN_POINTS):
            g0, g1 = gs[i], gs[i + 1]
            if not (np.isfinite(g0) and np.isfinite(g1)):
                continue
            if abs(g0) <= _NEWTON_LOOSE:  # on a grid point (e.g. the pre-impact slip kept)
                roots.append(th[i])
            elif g0 * g1 < 0.0:  # a root, a wrap jump (g = ±π) or a pole
                try:
                    r = brentq(g, th[i], th[i + 1], xtol=1e-15, maxiter=200)
                except (RuntimeError, ValueError):
                    continue
                roots.append(r)
        roots.sort(key=lambda r: abs(_wrap(np.array(r - pre))))
        found: list[float] = []
        for r in roots:
            theta = self.newton(states, dirs, spatial, lay, np.array([r]), max_iter=4)
            # a pole or a jump is not a root: Newton rejects it
            if theta is None or any(abs(_wrap(theta[0] - f)) < 1e-9 for f in found):
                continue
            found.append(float(theta[0]))
            yield theta

    def slip_residual(self, states, dirs, spatial, lay, theta, jac: bool = True):
        """g(θ) = wrap(atan2(u+_T(θ)) - θ) and its Jacobian (None if not ``jac``),
        per spatial slider."""
        d = dict(dirs)
        ds = {}
        for j, k in enumerate(spatial):
            c, s = np.cos(theta[j]), np.sin(theta[j])
            d[k] = np.array([c, s])
            ds[k] = np.array([-s, c])
        ev = self.evaluate(states, d, lay)
        ns = len(spatial)
        g = np.zeros(ns)
        J = -np.eye(ns)
        vscale = self.bmax + self.gmax * float(np.abs(ev.lam).max(initial=0.0))
        if not jac:
            for i, k in enumerate(spatial):
                ut = ev.up[self.tang[k]]
                if np.linalg.norm(ut) > SLIP_ZERO * vscale:
                    g[i] = _wrap(np.arctan2(ut[1], ut[0]) - theta[i])
            return g, None
        cols_n = lay[0]
        B = self.build_B(states, d, lay)
        eq = lay[2]
        dup = []
        for k in spatial:
            dB = np.zeros_like(B)
            dB[self.tang[k], cols_n[k]] = -self.mu[k] * ds[k]
            dK = (self.G @ dB)[eq]
            try:
                dz = -np.linalg.solve(ev.K, dK @ ev.z)
            except np.linalg.LinAlgError:
                dz = -np.linalg.lstsq(ev.K, dK @ ev.z, rcond=None)[0]
            dup.append(self.G @ (dB @ ev.z + B @ dz))
        for i, k in enumerate(spatial):
            ut = ev.up[self.tang[k]]
            r2 = float(ut @ ut)
            if np.sqrt(r2) <= SLIP_ZERO * vscale:
                J[i] = 0.0
                J[i, i] = 1.0  # no direction: any θ is consistent
                continue
            g[i] = _wrap(np.arctan2(ut[1], ut[0]) - theta[i])
            for j in range(ns):
                du = dup[j][self.tang[k]]
                J[i, j] += (ut[0] * du[1] - ut[1] * du[0]) / r2
        return g, J

    def newton(self, states, dirs, spatial, lay, theta0, max_iter=_NEWTON_MAX_ITER) -> np.ndarray | None:
        """Damped Newton on g(θ) from theta0; the iterate once max|g| <= _NEWTON_ATOL,
        else the best iterate if its max|g| <= _NEWTON_LOOSE (round-off of a
        small slip: the candidate's residual check decides), else None."""
        theta = np.array(theta0, dtype=float)
        best = (np.inf, theta)
        for _ in range(max_iter + 1):
            g, J = self.slip_residual(states, dirs, spatial, lay, theta)
            if not np.isfinite(g).all():
                break
            gmax = float(np.abs(g).max())
            if gmax <= _NEWTON_ATOL:
                return theta
            if gmax < best[0]:
                best = (gmax, theta)
            try:
                step = -np.linalg.solve(J, g)
            except np.linalg.LinAlgError:
                step = -np.linalg.lstsq(J, g, rcond=None)[0]
            big = np.abs(step).max()
            if not np.isfinite(big):
                return None
            if big > _NEWTON_MAX_STEP:
                step *= _NEWTON_MAX_STEP / big
            theta = theta + step
        return best[1] if best[0] <= _NEWTON_LOOSE else None

    # ---- checks ------------------------------------------------------------
