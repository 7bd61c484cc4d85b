"""The slip directions of a frictional impact's sliding contacts: the nonlinear part of
`contactdiff.dynamics.frictional_impact`.

A sliding contact's tangential impulse is ``-μ Λ_N s`` with ``s`` the unit direction of
its post-impact slip, itself a result of the impact: in 3-D an angle ``θ`` per sliding
contact to solve for, ``g(θ) = wrap(atan2(u+_T(θ)) - θ) = 0``. The map ``θ -> u+_T``
and its Jacobian are evaluated for a whole batch of angles at once (`SlipMap`, in
`contactdiff.dynamics.slip_map`: one stacked linear solve). One slider: every root of
the cross form below from a closed form (a quartic's roots on the unit circle,
`contactdiff.dynamics.slip_circle`), each polished by Newton; where that form gives no
answer, ``g`` scanned around the circle and beside
the poles of ``Λ_N`` (closed form), each sign change bisected and polished (Newton),
and the sign changes of the cross form below polished too (a slip that vanishes at one
direction is a root of that form only). Several: the cross form
``f_k = s_k x u+_T,k = ||u+_T,k|| sin g_k``, smooth on the torus (``g`` jumps by
2π and, where a slip is small, turns so fast that a root is a needle a grid
misses), solved by Newton's method with a backtracking line search run at once
from every local minimum of ``max|f|`` on a grid (infeasible points ranked
last; the grid's points solved as low-rank updates of one factorisation,
`contactdiff.dynamics.slip_lowrank`), the pre-impact slip, a rough solution of the whole law (a projected
fixed point) and the frictionless slip (from these three alone where a bound proves the
map from slip angles to the slips' angles a contraction, so that it has one root, and
Newton converges from one of them: `LowRankSolve.slip_contraction`); roots with a slip against ``s``
(``g = π``, also roots of ``f``) are dropped. Of two copies of one root (2π apart, or
found from two starts) the first is tried, and the other after it where Newton stopped
the first short of convergence and the other is closer. A mixin of the solver's problem
class (its state: ``G``, ``u``, ``mu``, ``tol``, the candidate's layout and
evaluation methods).
"""

from __future__ import annotations

import functools
import math
import operator
from collections.abc import Iterator
from typing import TYPE_CHECKING

import numpy as np

from .slip_circle import cross_form_roots, slip_coefficients
from .slip_map import SLIP_ZERO, CandidateEval, SlipMap, wrap_angle

__all__ = ["SLIP_ZERO", "CandidateEval", "SlipDirections", "SlipMap", "project_cone"]  # the map's names, former path

if TYPE_CHECKING:
    from .lcp_problem import ContactRows

# Newton on the slip angles of the spatial sliding contacts of a candidate.
_NEWTON_MAX_ITER = 40
_NEWTON_ATOL = 1e-13  # rad, on wrap(atan2(u+_T) - θ)
_NEWTON_LOOSE = 1e-8
_NEWTON_MAX_STEP = 0.5 * np.pi
_NEWTON_STALL = 8  # iterations without halving the best max|g|: the start is dropped
_LINE_SEARCH = 0.5 ** np.arange(6)  # step fractions tried, largest first
# Scan of the slip angle of one spatial slider; grid and starts for several.
_SCAN_POINTS = 144
_BISECT = 12  # halvings of a scan interval: 2π/144/2^12 ~ 1e-5 rad, then Newton
_GRID_POINTS = {2: 48, 3: 20}  # per axis; more sliders: _GRID_BUDGET in all
_GRID_BUDGET = 20000
_GRID_STARTS = 48
_FP_SWEEPS = 1000  # until a relative change of 1e-14; a cap, most touchdowns converge in far fewer
# a bound of the slip-angle map's Lipschitz constant below this (`LowRankSolve.slip_contraction`)
# proves one root (below 1 does; the margin covers the bound's round-off, ~1e-10 relative)
_CONTRACTION_MAX = 0.9
_FP_CREEP_AFTER = 50  # sweeps after which a creep below _FP_CREEP of the iterate per sweep stops them
_FP_CREEP = 1e-10
_FP_CYCLE = 8  # iterates kept to recognise a cycle in round-off (periods 2 to 5 seen on face landings)
_POLE_GAP = 1e-9  # rad: scan points beside a pole of one slider's Λ_N
_DUPLICATE = 1e-8  # rad: two roots closer than this are one

#: One spatial slider: its roots from the closed form of `contactdiff.dynamics.slip_circle`
#: where it answers (else, and with False, by the scan of `SlipDirections.roots_1d`).
ONE_SLIDER_CLOSED_FORM = True


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


@functools.lru_cache(maxsize=8)
def _torus_grid(ns: int) -> tuple[int, np.ndarray]:
    """Points per axis and the offsets (per_axis**ns, ns) of the grid on the torus of
    ``ns`` slip angles, last angle fastest; formed once per ``ns`` (read-only)."""
    per_axis = _GRID_POINTS.get(ns, max(4, int(_GRID_BUDGET ** (1.0 / ns))))
    axis = 2.0 * np.pi * np.arange(per_axis) / per_axis
    offsets = np.stack(np.meshgrid(*([axis] * ns), indexing="ij"), axis=-1).reshape(-1, ns)
    offsets.flags.writeable = False
    return per_axis, offsets


def _run_starts(mask: np.ndarray) -> np.ndarray:
    """The first element of each run of True in a cyclic boolean array (element 0 if all)."""
    starts = mask & ~np.roll(mask, 1)
    if mask.all():
        starts = np.zeros_like(mask)
        starts[0] = True
    return starts


class SlipDirections:
    """Slip-direction search of a candidate (module doc)."""

    if TYPE_CHECKING:  # the candidate's state it borrows (set by its subclass), for the type checker only
        G: np.ndarray
        u: np.ndarray
        rows: ContactRows
        e: np.ndarray
        mu: np.ndarray
        tol: float
        n: int
        m: int
        normal: np.ndarray
        tang: tuple[np.ndarray, ...]
        _fp: tuple[np.ndarray, np.ndarray] | None
        _grids: dict[tuple[int, ...], tuple]

        def evaluate(self, states, dirs, lay) -> CandidateEval:
            """The candidate at the given states and slip directions (the subclass's)."""

    def slip_roots(self, states, dirs, spatial, lay, fmap: SlipMap | None = None) -> Iterator[np.ndarray]:
        """Slip angles θ with g(θ) = 0, nearest the pre-impact slip directions first
        (Euclidean distance of the wrapped angle differences).

        One spatial slider: the cross form's roots in closed form (`circle_roots`),
        polished by Newton; where the closed form gives no answer (`slip_circle`: a
        badly conditioned candidate, or a slip zero or along its direction at every
        angle), g is scanned on a grid of _SCAN_POINTS angles from
        the pre-impact slip direction, each sign change is bisected and polished
        by Newton, which rejects the wrap jumps (g = ±π) and the poles (Λ_N
        infinite): all roots that the grid separates. Near a small post-impact
        slip the direction turns fast (|dg/dθ| ~ 1e3 seen), so a steep sign
        change is not taken for a jump; the cross form's sign changes are polished
        too (`cross_roots`). Of two copies of one root the first is tried, and the
        other after it where the first is not converged and the other is closer.
        Several: `newton` on the cross form from
        the pre-impact slip, from the post-impact slip of an approximate solution
        of the whole law (`fixed_point`), from the frictionless post-impact
        slip, and from the local minima of max|f| on a grid on the torus (one
        start per basin rather than the best points, which cluster), at most
        _GRID_STARTS of them, those where the law's other inequalities hold and
        the slips are along their directions first. The grid is skipped where the
        map from the slip angles to the slips' angles is proved a contraction (one
        root) and Newton from the first three starts converges.
        """
        if fmap is None:  # the candidate's cross-form map, unless the caller formed it
            fmap = SlipMap(self, states, dirs, spatial, lay, cross=True)
        pre = np.array([np.arctan2(self.u[self.tang[k][1]], self.u[self.tang[k][0]]) for k in spatial])
        closed_form = self.circle_roots(fmap) if len(spatial) == 1 and ONE_SLIDER_CLOSED_FORM else None
        if closed_form is not None:
            roots = closed_form
        elif len(spatial) == 1:
            roots = self.roots_1d(SlipMap(self, states, dirs, spatial, lay, cross=False), float(pre[0]))
            # a slip that vanishes at one direction (the impulse on the cone's edge, the
            # contact at rest after it) is no root of the angle form, whose angle is
            # undefined there, but one of the cross form s × u+_T (`cross_roots`)
            roots += self.cross_roots(fmap, float(pre[0]))
        else:
            roots = self.roots_nd(fmap, states, dirs, spatial, lay, pre)
        # of two copies of one root (found from two brackets, or 2π apart) the first is
        # tried; a copy closer to zero follows it where the first stopped short of
        # convergence (a bracket of a wrap jump may walk to a neighbouring root and stop
        # after its few iterations), for the case that the law's check rejects the first
        groups: list[list[tuple[np.ndarray, float]]] = []
        firsts = np.empty((len(roots), len(spatial)))  # each group's first copy
        for theta, merit in roots:
            gaps = np.abs(wrap_angle(theta - firsts[: len(groups)])).max(axis=1) if groups else np.zeros(0)
            if not (gaps < _DUPLICATE).any():
                firsts[len(groups)] = theta
                groups.append([(theta, merit)])
                continue
            twin = groups[int(np.argmax(gaps < _DUPLICATE))]
            if twin[-1][1] > _NEWTON_ATOL and merit < twin[-1][1]:
                twin.append((theta, merit))
        groups.sort(key=lambda g: float(np.linalg.norm(wrap_angle(g[0][0] - pre))))
        for group in groups:
            for theta, _ in group:
                yield theta

    def roots_nd(self, fmap, states, dirs, spatial, lay, pre) -> list[tuple[np.ndarray, float]]:
        """Several spatial sliders: Newton on the cross form from the starts of `slip_roots`."""
        starts = [pre]
        ups = self.fixed_point()[1]
        starts.append(np.array([np.arctan2(ups[self.tang[k][1]], ups[self.tang[k][0]]) for k in spatial]))
        free = self.evaluate(states, dirs, lay)  # sliders without their friction columns
        starts.append(np.array([np.arctan2(free.up[self.tang[k][1]], free.up[self.tang[k][0]]) for k in spatial]))
        # where the slip angles' map is a contraction its one root is found from any start:
        # the grid is needed only if Newton from these starts does not converge
        low = fmap.low_rank()
        if low.usable and low.slip_contraction(self.u, fmap.GB0, fmap.GT, fmap.T) <= _CONTRACTION_MAX:
            roots = self.newton(fmap, np.array(starts))
            if any(merit <= _NEWTON_ATOL for _, merit in roots):
                return roots
        per_axis, grid, turns = self.grid_turns(fmap, spatial, pre)
        ns = len(spatial)
        # the grid only ranks Newton's starts: its points solved as low-rank updates of
        # one factorisation (`contactdiff.dynamics.slip_lowrank`), the roots then by the direct path
        f, _, feas, _, vscale = fmap(grid, jac=False, turns=turns, low_rank=True)
        merit = np.abs(f).max(axis=1) / vscale + np.where(feas, 0.0, 1.0)
        merit = np.where(np.isfinite(merit), merit, np.inf).reshape((per_axis,) * ns)
        local = np.isfinite(merit)
        for ax in range(ns):
            for sh in (1, -1):
                local &= merit <= np.roll(merit, sh, axis=ax)
        idx = np.flatnonzero(local.ravel())
        idx = idx[np.argsort(merit.ravel()[idx], kind="stable")][:_GRID_STARTS]
        starts.extend(grid[idx])
        return self.newton(fmap, np.array(starts))

    def grid_turns(self, fmap, spatial, pre) -> tuple[int, np.ndarray, tuple]:
        """The torus grid of the sliders ``spatial`` from their pre-impact slip angles
        ``pre`` (points per axis, the angles) and its `SlipMap.turns`, formed once per
        set of sliders in a problem: its candidates with the same sliders (a face's
        corners sticking or open around them) share them."""
        key = tuple(spatial)
        if key not in self._grids:
            per_axis, offsets = _torus_grid(len(spatial))
            grid = pre + offsets
            self._grids[key] = (per_axis, grid, fmap.turns(grid))
        return self._grids[key]

    def circle_roots(self, fmap) -> list[tuple[np.ndarray, float]] | None:
        """One spatial slider: every root of the cross form, from the closed form of
        `contactdiff.dynamics.slip_circle` (a quartic's roots on the unit circle), each
        polished by Newton on the cross form (``fmap``, a cross-form `SlipMap`); None where the
        closed form gives no answer (the scan is then used)."""
        coefficients = slip_coefficients(fmap)
        if coefficients is None:
            return None
        starts = cross_form_roots(coefficients[0])
        if starts is None:
            return None
        if not starts.size:
            return []
        return self.newton(fmap, starts[:, None])

    def cross_roots(self, fmap, pre: float) -> list[tuple[np.ndarray, float]]:
        """One spatial slider: the sign changes of the cross form ``s × u+_T`` over the
        scan, each polished by Newton. Those Newton keeps (slip along ``s``, or zero) are
        roots of the law: with the slip along ``s`` they are the angle form's roots again
        (`slip_roots` keeps one copy), with a slip that vanishes they are roots the angle
        form has not. Which of the two a root is need not be decided: the zero of the slip
        is found only to the accuracy of the angle (``|du+_T/dθ| δθ``, above `SLIP_ZERO`
        of the velocity scale where the slip turns slowly), and the candidate's check
        judges the law either way."""
        th = pre + 2.0 * np.pi * np.arange(_SCAN_POINTS + 1) / _SCAN_POINTS
        f = fmap(th[:, None], jac=False)[0][:, 0]
        fin = np.isfinite(f[:-1]) & np.isfinite(f[1:])
        ch = np.flatnonzero(fin & (f[:-1] * f[1:] < 0.0))
        if not ch.size:
            return []
        starts = 0.5 * (th[ch] + th[ch + 1])
        return self.newton(fmap, starts[:, None], max_iter=_NEWTON_MAX_ITER)

    def roots_1d(self, fmap, pre: float) -> list[tuple[np.ndarray, float]]:
        """The slip angles of one spatial slider: the circle scanned, each sign change
        bisected (_BISECT halvings, all at once) and polished by Newton."""
        th = pre + 2.0 * np.pi * np.arange(_SCAN_POINTS + 1) / _SCAN_POINTS
        # a root next to a pole: no sign change over their interval, so the scan
        # is also split just beside each pole
        poles = pre + np.mod(fmap.poles() - pre, 2.0 * np.pi)
        th = np.unique(
            np.concatenate([th, np.clip(np.concatenate([poles - _POLE_GAP, poles + _POLE_GAP]), th[0], th[-1])])
        )
        scan = fmap(th[:, None], jac=False)
        gs, feasible = scan[0][:, 0], scan[2][:-1]
        g0, g1 = gs[:-1], gs[1:]
        fin = np.isfinite(g0) & np.isfinite(g1)
        on = fin & (np.abs(g0) <= _NEWTON_LOOSE)  # on a grid point (e.g. the pre-impact slip kept)
        ch = np.flatnonzero(fin & ~on & (g0 * g1 < 0.0))  # a root, a wrap jump (g = ±π) or a pole
        lo, hi, glo = th[ch], th[ch + 1], g0[ch]
        for _ in range(_BISECT if ch.size else 0):  # all brackets at once
            mid = 0.5 * (lo + hi)
            gm = fmap(mid[:, None], jac=False)[0][:, 0]
            left = np.sign(gm) == np.sign(glo)  # the sign change is in [mid, hi]
            lo, glo, hi = np.where(left, mid, lo), np.where(left, gm, glo), np.where(left, hi, mid)
        # a run of grid points all on a root is a plateau (the slip is zero whatever its
        # direction: the other contacts hold it): the direction then only sets the friction
        # impulse, so one point per run of those where the law's other conditions hold
        # (else per run of the plateau) stands for it
        roots = list(th[:-1][_run_starts(on & feasible) if (on & feasible).any() else _run_starts(on)])
        roots += list(0.5 * (lo + hi))
        if not roots:
            return []
        # a pole or a jump is not a root: Newton rejects it
        return self.newton(fmap, np.array(roots)[:, None], max_iter=6)

    def fixed_point(self) -> tuple[np.ndarray, np.ndarray]:
        """Row impulses and post-impact row velocities ``(Λ, u+)`` of an approximate
        solution of the law, by projected Gauss-Seidel on De Saxce's modified velocity
        (a start and a guess only).

        Contact by contact, ``Λ_k <- P_K(Λ_k - ρ_k ŵ_k)`` with ``K`` the cone
        ``||Λ_T|| <= μ Λ_N``, ``ŵ = u+`` plus ``e u-_N + μ ||u+_T||`` on the
        normal row and ``ρ_k = 1 / max diag G_kk``. Its fixed points are the
        solutions of the law; it need not converge (at most _FP_SWEEPS sweeps: on the
        ANYmal trot's touchdowns 100 left sticking feet with a residual slip, 1000 do not).
        Where the iterates fall into a cycle in round-off (an iterate equal, bit for bit,
        to one of the last _FP_CYCLE: often, on a face's corners), the sweeps stop there
        with the iterate they would have reached at the cap. After _FP_CREEP_AFTER sweeps
        they also stop where the iterate creeps by less than _FP_CREEP of its size per
        sweep (a face's corners, whose singular G the sweeps approach at ~1e-11 a sweep:
        900 more sweeps moved the iterate by 1e-7 of its size at most, and no contact's
        guessed state, on the impacts of ten real cube tosses, whose thresholds are 1e-6).
        """
        if self._fp is not None:
            return self._fp
        lam = np.zeros(self.m)
        blocks = self.rows.contact_rows
        # each contact's rows of G, restitution term, step and cone, formed once (a sweep
        # repeats them up to _FP_SWEEPS times; the arithmetic of a sweep is unchanged)
        sweep = []
        for k in range(self.n):
            r, t, mu = blocks[k], self.tang[k], self.mu[k]
            friction = float(mu) if t.size and mu > 0.0 and mu < np.inf else None
            dg = float(self.G[r[:, None], r].diagonal().max())
            at = slice(int(r[0]), int(r[-1]) + 1) if np.array_equal(r, np.arange(r[0], r[-1] + 1)) else r
            sweep.append(
                (
                    at,
                    self.u[r],
                    self.G[r],
                    self.e[k] * self.u[self.normal[k]],
                    friction,
                    t.size and mu > 0.0,
                    dg,
                    mu if t.size else 0.0,
                )
            )
        recent = [lam.copy()]  # the iterates after the last sweeps (L_0 first), at most _FP_CYCLE
        # their values as tuples of floats, to compare: == on floats is np.array_equal's
        # test element by element (0.0 equals -0.0, NaN nothing), at a tenth of its cost
        recent_values = [tuple(lam.tolist())]
        old_values = recent_values[0]
        for done in range(1, _FP_SWEEPS + 1):
            for at_rows, u_r, G_r, restitution, friction, coulomb, dg, cone in sweep:
                w = u_r + G_r @ lam
                if coulomb:
                    wt = w[1:]  # the norm as np.linalg.norm forms it (the BLAS dot, then sqrt)
                    w[0] += restitution + (friction * math.sqrt(wt.dot(wt)) if friction is not None else 0.0)
                else:
                    w[0] += restitution
                x = lam[at_rows] - w / dg if dg > 0.0 else lam[at_rows]
                if cone == np.inf:
                    lam[at_rows] = project_cone(x, cone)
                    continue
                # `project_cone` inlined, its arithmetic unchanged (a sweep is mostly call overhead)
                xt = x[1:]
                xn, xt_norm = float(x[0]), math.sqrt(xt.dot(xt))
                if xn >= 0.0 and xt_norm <= cone * xn:
                    lam[at_rows] = x
                elif cone * xt_norm <= -xn:
                    lam[at_rows] = 0.0
                else:
                    n2 = (xn + cone * xt_norm) / (1.0 + cone * cone)
                    xt *= cone * n2 / xt_norm
                    x[0] = n2
                    lam[at_rows] = x
            values = tuple(lam.tolist())
            if math.isfinite(sum(values)):  # every element finite: Python's max is numpy's
                change, size = max(map(abs, map(operator.sub, values, old_values))), max(map(abs, values))
            else:
                change, size = float(np.abs(lam - np.array(old_values)).max()), float(np.abs(lam).max())
            if change <= 1e-14 * max(size, 1e-300):
                break
            if done >= _FP_CREEP_AFTER and change <= _FP_CREEP * size:
                break  # a creep far below what the guess and the starts can tell
            old_values = values
            # a cycle in round-off: the iterate equals one p sweeps back, bit for bit. A
            # sweep is a function of the iterate alone, so the iterates repeat with period p
            # from there, and the stop test, failed at every step of one period, fails
            # forever: the loop would end at the cap, on the iterate of its phase there
            period = next((p for p in range(1, len(recent) + 1) if recent_values[-p] == values), None)
            if period is not None:
                phase = (_FP_SWEEPS - done) % period
                lam = recent[phase - period] if phase else lam
                break
            recent.append(lam.copy())
            recent_values.append(values)
            if len(recent) > _FP_CYCLE:
                del recent[0], recent_values[0]
        self._fp = (lam, self.u + self.G @ lam)
        return self._fp

    def newton(self, fmap, theta0: np.ndarray, max_iter: int = _NEWTON_MAX_ITER) -> list[tuple[np.ndarray, float]]:
        """Newton's method on f from each row of theta0 (all at once), with steps
        capped at _NEWTON_MAX_STEP and a backtracking line search on ||f|| (the
        largest fraction in _LINE_SEARCH that decreases it, else the smallest).
        A start gives its iterate once max|f| <= _NEWTON_ATOL (relative to f's
        scale) or its step is below round-off, else its best iterate if max|f|
        <= _NEWTON_LOOSE (round-off of a small slip: the candidate's residual
        check decides), else nothing; and nothing if a slip points against its
        direction (a root of the cross form that is not one of the law). Each
        root comes with its max|f| (relative to f's scale)."""
        theta = np.array(theta0, dtype=float)
        P, ns = theta.shape
        best_f = np.full(P, np.inf)
        last_gain = np.zeros(P, dtype=int)  # iteration of the last halving of best_f
        best = theta.copy()
        active = np.ones(P, dtype=bool)
        done = np.zeros(P, dtype=bool)
        for it in range(max_iter + 1):
            ia = np.flatnonzero(active)
            if not ia.size:
                break
            f, J, _, aligned, scale = fmap(theta[ia], jac=it < max_iter)
            fmax = np.abs(f).max(axis=1) / scale
            fmax = np.where(np.isfinite(fmax) & aligned, fmax, np.inf)
            better = fmax < best_f[ia]
            last_gain[ia[fmax < 0.5 * best_f[ia]]] = it
            best_f[ia[better]] = fmax[better]
            best[ia[better]] = theta[ia[better]]
            conv = fmax <= _NEWTON_ATOL
            done[ia[conv]] = True
            live = ~conv & np.isfinite(np.abs(f).max(axis=1)) & (it - last_gain[ia] <= _NEWTON_STALL)
            active[ia[~live]] = False
            if it == max_iter:
                break
            ia, f, J = ia[live], f[live], J[live]
            if not ia.size:
                break
            try:
                step = -np.linalg.solve(J, f[..., None])[..., 0]
            except np.linalg.LinAlgError:
                step = -(np.linalg.pinv(J) @ f[..., None])[..., 0]
            big = np.abs(step).max(axis=1)
            fin = np.isfinite(big)
            active[ia[~fin]] = False
            ia, f, step, big = ia[fin], f[fin], step[fin], big[fin]
            tiny = big <= _NEWTON_ATOL * (1.0 + np.abs(theta[ia]).max(axis=1))  # at round-off
            active[ia[tiny]] = False
            ia, f, step, big = ia[~tiny], f[~tiny], step[~tiny], big[~tiny]
            if not ia.size:
                break
            step *= np.minimum(1.0, _NEWTON_MAX_STEP / np.maximum(big, 1e-300))[:, None]
            trial = theta[ia][:, None, :] + _LINE_SEARCH[None, :, None] * step[:, None, :]
            ft = fmap(trial.reshape(-1, ns), jac=False)[0].reshape(ia.size, _LINE_SEARCH.size, ns)
            nt = np.linalg.norm(ft, axis=2)
            nt = np.where(np.isfinite(nt), nt, np.inf)
            dec = nt < np.linalg.norm(f, axis=1)[:, None]
            pick = np.where(dec.any(axis=1), dec.argmax(axis=1), _LINE_SEARCH.size - 1)
            theta[ia] = trial[np.arange(ia.size), pick]
        out = [(theta[i], float(best_f[i])) for i in range(P) if done[i]]
        out += [(best[i], float(best_f[i])) for i in range(P) if not done[i] and best_f[i] <= _NEWTON_LOOSE]
        return out
