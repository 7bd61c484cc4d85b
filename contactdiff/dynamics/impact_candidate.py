"""One candidate of the frictional impact law of `contactdiff.dynamics.frictional_impact`:
each contact's state (open, sticking, sliding) and its sliders' slip directions given,
the candidate's equalities solved for the impulses, every condition of the law checked
on them, and the solution (`FrictionalImpact`) formed. The enumeration of candidates,
and which is tried first, is `contactdiff.dynamics.frictional_impact`'s; the search
for the slip directions of its spatial sliders `contactdiff.dynamics.friction_slip`'s.
"""

from __future__ import annotations

import enum
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .friction_slip import SlipDirections
from .lcp_problem import ContactRows
from .redundant import gram_range_basis
from .slip_map import SLIP_ZERO, CandidateEval, SlipMap

# A slip root whose impulses break an inequality of the law by more than this many
# times the check's tolerance (relative to their scale) is skipped unchecked: the two
# evaluations of its impulses (the batch's and the check's own) differ by round-off,
# far below this margin (`SlipMap.violating`).
_SKIP_SHARE = 1e3


class ContactState(enum.Enum):
    """State of a contact after the impact."""

    OPEN = "open"
    STICK = "stick"
    SLIDE = "slide"


@dataclass(frozen=True, eq=False)  # arrays: no element-wise ==
class FrictionalImpact:
    """Solution of the frictional impact law.

    Attributes:
        impulses: Row impulses ``Λ`` on all rows (N s), shape ``(n_rows,)``.
        u_plus: Post-impact row velocities ``u- + G Λ``.
        states: `ContactState` of each contact.
        slide_directions: For each contact, its unit slip direction ``s``
            (shape ``(len(rows.tangential[k]),)``; ``Λ_T = -μ Λ_N s``) if it
            slides with tangential rows, zeros otherwise (and zeros for a
            frictionless contact whose post-impact slip is zero).
        restitution: Coefficient used per contact (0 where not approaching).
        residual: Largest scaled violation of the law's conditions: negative
            ``Λ_N``, cone and slide-law violations by ``max|Λ|``; equalities,
            negative ``w_N`` of open contacts and misaligned slip by
            ``max|b| + max|G| max|Λ|`` with ``b = ((1 + e) u-_N, u-_T)``.
        method: ``"enumerate"``, or ``"enumerate-newton"`` if a spatial slip
            direction was solved by Newton's method.
        energy_change: ``ΔT = Λ^T u- + ½ Λ^T G Λ`` (J).
        energy_gain: ``ΔT`` is positive beyond round-off (see the module doc of
            `contactdiff.dynamics.frictional_impact`).
        candidates: Number of state candidates tried.
    """

    impulses: np.ndarray
    u_plus: np.ndarray
    states: tuple[ContactState, ...]
    slide_directions: tuple[np.ndarray, ...]
    restitution: np.ndarray
    residual: float
    method: str
    energy_change: float
    energy_gain: bool
    candidates: int


def describe_states(states: Sequence[ContactState], signs: dict[int, float] | None = None) -> str:
    """The states of a candidate as text, ``{0: stick, 1: slide (+)}``, with the signs
    of its planar sliders (for messages)."""
    parts = []
    for k, s in enumerate(states):
        txt = s.value
        if signs and k in signs:
            txt += f" ({'+' if signs[k] > 0 else '-'})"
        parts.append(f"{k}: {txt}")
    return "{" + ", ".join(parts) + "}"


class ImpactCandidates(SlipDirections):
    """One validated problem's candidates: each one's solve and check, the best failure."""

    def __init__(self, G, u, rows: ContactRows, e, mu, tol):
        self.G, self.u, self.rows, self.e, self.mu, self.tol = G, u, rows, e, mu, tol
        self.n, self.m = rows.n_contacts, rows.n_rows
        self.normal = np.array(rows.normal, dtype=np.intp)
        self.tang = tuple(np.array(t, dtype=np.intp) for t in rows.tangential)
        # b = ((1 + e) u-_N, u-_T): w = G Λ + b, zero on equality rows.
        self.b = u.copy()
        self.b[self.normal] = (1.0 + e) * u[self.normal]
        self.gmax = float(np.abs(G).max())
        self.bmax = float(np.abs(self.b).max())
        # Closed states each contact may take.
        self.frictionless = [self.tang[k].size == 0 or mu[k] == 0.0 for k in range(self.n)]
        self.sticky = [self.tang[k].size > 0 and mu[k] == np.inf for k in range(self.n)]
        self.tried = 0
        self.best: tuple[float, str] = (np.inf, "none")
        self.newton_failed: list[str] = []
        self._fp: tuple[np.ndarray, np.ndarray] | None = None
        # dependent rows (a face's corners landing together): impulses by the principle of
        # `contactdiff.dynamics.redundant`, and no first guess (`contactdiff.dynamics.frictional_impact`)
        self.redundant = gram_range_basis(G) is not None
        self._bases: dict[tuple[int, ...], np.ndarray | None] = {}
        self._grids: dict[tuple[int, ...], tuple] = {}  # `SlipDirections.grid_turns`

    def equality_basis(self, eq) -> np.ndarray | None:
        """With dependent rows, a basis of the range of the equality rows ``eq`` of a
        candidate (`contactdiff.dynamics.redundant`; None where they are independent),
        formed once per set of rows: a candidate's evaluation and its slip search share it."""
        if not self.redundant:
            return None
        key = tuple(int(i) for i in eq)
        if key not in self._bases:
            self._bases[key] = gram_range_basis(self.G[np.ix_(eq, eq)])
        return self._bases[key]

    # ---- one candidate ---------------------------------------------------
    def layout(self, states):
        """Unknowns z (Λ_N of closed contacts, Λ_T of sticking ones) and equality rows."""
        cols_n: dict[int, int] = {}
        cols_t: dict[int, np.ndarray] = {}
        eq: list[int] = []
        p = 0
        for k, s in enumerate(states):
            if s is ContactState.OPEN:
                continue
            cols_n[k] = p
            eq.append(int(self.normal[k]))
            p += 1
            if s is ContactState.STICK:
                t = self.tang[k]
                cols_t[k] = np.arange(p, p + t.size)
                eq.extend(int(i) for i in t)
                p += t.size
        return cols_n, cols_t, np.array(eq, dtype=np.intp), p

    def build_B(self, states, dirs: dict[int, np.ndarray], lay) -> np.ndarray:
        """Λ = B z for the given slip directions of the sliding contacts."""
        cols_n, cols_t, _, p = lay
        B = np.zeros((self.m, p))
        for k, c in cols_n.items():
            B[self.normal[k], c] = 1.0
            if states[k] is ContactState.SLIDE and k in dirs:
                B[self.tang[k], c] = -self.mu[k] * dirs[k]
        for k, cs in cols_t.items():
            B[self.tang[k], cs] = 1.0  # the identity block of a sticking contact's tangential rows
        return B

    def evaluate(self, states, dirs, lay) -> CandidateEval:
        """The candidate's equalities solved at slip directions ``dirs`` (`CandidateEval`)."""
        _, _, eq, p = lay
        B = self.build_B(states, dirs, lay)
        if p == 0:
            return CandidateEval(np.zeros(self.m), self.u.copy(), np.zeros(0), None)
        K = (self.G @ B)[eq]
        rhs = -self.b[eq]
        U = self.equality_basis(eq)
        if U is not None:
            # dependent equality rows: the impulses compatible with equal compliant supports
            # (`contactdiff.dynamics.redundant`), z in the range of those rows
            try:
                z = U @ np.linalg.solve(U.T @ K @ U, U.T @ rhs)
            except np.linalg.LinAlgError:
                z = np.full(p, np.nan)
            lam = B @ z
            return CandidateEval(lam, self.u + self.G @ lam, z, K)
        try:
            z = np.linalg.solve(K, rhs)
            if not np.isfinite(z).all():
                raise np.linalg.LinAlgError
        except np.linalg.LinAlgError:
            z = np.linalg.lstsq(K, rhs, rcond=None)[0]
        lam = B @ z
        return CandidateEval(lam, self.u + self.G @ lam, z, K)

    def try_candidate(self, states, signs: dict[int, float], spatial: list[int]) -> FrictionalImpact | None:
        """The solution of the candidate ``states`` (planar sliders' ``signs``, spatial
        sliders' directions searched) that passes the law's check, or None."""
        lay = self.layout(states)
        dirs: dict[int, np.ndarray] = {k: np.array([s]) for k, s in signs.items()}
        if not spatial:
            ev = self.evaluate(states, dirs, lay)
            return self.check(states, dirs, ev, signs, "enumerate")
        # one map of the candidate's slip angles for the bound, the search and the batch
        # rejection (its construction and low-rank factorisation formed once)
        fmap = SlipMap(self, states, dirs, spatial, lay, cross=True)
        if self.pulls_everywhere(states, dirs, spatial, lay, fmap):
            return None
        roots = list(self.slip_roots(states, dirs, spatial, lay, fmap))
        if not roots:
            self.newton_failed.append(describe_states(states, signs))
            return None
        # roots that break an inequality of the law by far more than the check's tolerance
        # (a pulling normal impulse, most often: a face's corner the others lift) are
        # rejected in one batch, before each is evaluated and checked on its own; the
        # first root that passes the check is the same. A planar slider's friction is not
        # in `SlipMap.violating`'s impulse scale: with one, every root is checked.
        skip = (
            fmap.violating(np.array(roots), _SKIP_SHARE * self.tol) if not signs else np.zeros(len(roots), dtype=bool)
        )
        for theta, skipped in zip(roots, skip):
            if skipped:
                continue
            d = dict(dirs)
            for j, k in enumerate(spatial):
                d[k] = np.array([np.cos(theta[j]), np.sin(theta[j])])
            out = self.check(states, d, self.evaluate(states, d, lay), signs, "enumerate-newton")
            if out is not None:
                return out
        return None

    def pulls_everywhere(self, states, dirs, spatial, lay, fmap: SlipMap | None = None) -> bool:
        """Whether the candidate fails the law at every slip direction of its spatial
        sliders, a closed contact pulling by far more than the check's tolerance
        (`LowRankSolve.pulls_everywhere`, where its angle-free matrix is well
        conditioned): its search for slip directions is then skipped. ``fmap``: the
        candidate's cross-form `SlipMap` if already formed."""
        if fmap is None:
            fmap = SlipMap(self, states, dirs, spatial, lay, cross=True)
        low = fmap.low_rank()
        if not low.usable:
            return False
        # every sliding contact's friction, planar ones too, bounds the impulses' scale
        mu_max = max((float(self.mu[k]) for k, s in enumerate(states) if s is ContactState.SLIDE), default=0.0)
        return low.pulls_everywhere(fmap.closed, mu_max, _SKIP_SHARE * self.tol)

    # ---- slip directions of spatial sliding contacts ----------------------
    def residual(self, states, dirs, lam, up) -> float:
        """Largest scaled violation of the law's conditions (`FrictionalImpact.residual`)."""
        xmax = float(np.abs(lam).max())
        s_w = self.bmax + self.gmax * xmax
        if s_w == 0.0:
            return 0.0
        w = up.copy()
        w[self.normal] += self.e * self.u[self.normal]
        vx = 0.0  # scaled by xmax
        vw = 0.0  # scaled by s_w
        for k, s in enumerate(states):
            n_k, t_k = self.normal[k], self.tang[k]
            if s is ContactState.OPEN:
                vw = max(vw, -float(w[n_k]))
                continue
            lam_n = float(lam[n_k])
            vx = max(vx, -lam_n)
            vw = max(vw, abs(float(w[n_k])))
            if not t_k.size:
                continue
            lt, ut = lam[t_k], up[t_k]
            if s is ContactState.STICK:
                vw = max(vw, float(np.abs(ut).max()))
                if self.mu[k] < np.inf:
                    vx = max(vx, float(np.linalg.norm(lt)) - self.mu[k] * lam_n)
            elif self.mu[k] == 0.0:
                vx = max(vx, float(np.abs(lt).max()))
            else:
                d = dirs[k]
                vx = max(vx, float(np.linalg.norm(lt + self.mu[k] * lam_n * d)))
                vw = max(vw, float(np.linalg.norm(ut - np.linalg.norm(ut) * d)))
        return max(vx / xmax if vx > 0.0 else 0.0, vw / s_w)

    def check(self, states, dirs, ev: CandidateEval, signs, method: str) -> FrictionalImpact | None:
        """The solution if ``ev`` satisfies the law within ``tol`` (else None; the best
        residual so far noted for the failure's message)."""
        res = self.residual(states, dirs, ev.lam, ev.up)
        if not np.isfinite(res):
            res = np.inf
        if res < self.best[0]:
            self.best = (res, describe_states(states, signs))
        if res > self.tol:
            return None
        return self.finish(states, dirs, ev.lam, method)

    def finish(self, states, dirs, lam, method: str) -> FrictionalImpact:
        """Clip round-off: Λ_N >= 0, Λ_T exactly on (slide) or in (stick) the cone."""
        lam = lam.copy()
        out_dirs = []
        for k, s in enumerate(states):
            n_k, t_k = self.normal[k], self.tang[k]
            lam[n_k] = max(float(lam[n_k]), 0.0)
            d = np.zeros(t_k.size)
            if s is ContactState.SLIDE and t_k.size:
                if self.mu[k] > 0.0:
                    d = dirs[k].copy()
                    lam[t_k] = -self.mu[k] * lam[n_k] * d
                else:
                    lam[t_k] = 0.0
            elif s is ContactState.STICK and self.mu[k] < np.inf:
                nt = float(np.linalg.norm(lam[t_k]))
                cap = self.mu[k] * lam[n_k]
                if nt > cap:
                    lam[t_k] *= cap / nt
            out_dirs.append(d)
        up = self.u + self.G @ lam
        for k, s in enumerate(states):
            t_k = self.tang[k]
            if s is ContactState.SLIDE and t_k.size and self.mu[k] == 0.0:
                nrm = float(np.linalg.norm(up[t_k]))
                vscale = self.bmax + self.gmax * float(np.abs(lam).max())
                if nrm > SLIP_ZERO * vscale:
                    out_dirs[k] = up[t_k] / nrm
        res = self.residual(states, {k: d for k, d in enumerate(out_dirs)}, lam, up)
        dT = float(lam @ self.u + 0.5 * lam @ self.G @ lam)
        xmax = float(np.abs(lam).max())
        e_scale = xmax * float(np.abs(self.u).max()) + self.gmax * xmax * xmax
        gain = dT > self.tol * e_scale
        return FrictionalImpact(
            lam, up, tuple(states), tuple(out_dirs), self.e.copy(), res, method, dT, bool(gain), self.tried
        )
