"""Impact with Coulomb friction of finite coefficient (pure numpy, no Pinocchio).

The law
-------
Each closed contact ``k`` owns a normal row ``n_k`` and 0, 1 (planar) or 2
(spatial) tangential rows ``t_k``, laid out by a `ContactRows`. With the
Delassus matrix ``G = A M^-1 A^T`` (symmetric positive semidefinite) and the
pre-impact row velocities ``u- = A v-``, the row impulses ``Λ`` give the
post-impact row velocities ``u+ = u- + G Λ`` (and ``v+ = v- + M^-1 A^T Λ``).
:func:`solve_frictional_impact` finds ``Λ`` such that, for every contact:

* **Normal, Newton's kinematic restitution with complementarity**:
  ``Λ_N >= 0``, ``w_N = u+_N + e u-_N >= 0`` and ``Λ_N w_N = 0``; ``e`` in
  [0, 1], replaced by 0 for a contact that is not approaching (``u-_N >= 0``),
  as `contactdiff.dynamics.impacts.resolve_impact` does.
* **Tangential, Coulomb's law with maximal dissipation on the post-impact slip**
  (Moreau's impact law with Newton's coefficient on the normal):
  ``||Λ_T|| <= μ Λ_N``; if ``||u+_T|| > 0`` then ``Λ_T = -μ Λ_N u+_T / ||u+_T||``
  (*slide*), else the contact *sticks* (``u+_T = 0``, ``Λ_T`` anywhere in the
  cone). ``μ = inf`` is the sticking contact of `solve_contact_lcp` (tangential
  rows are equalities ``u+_T = 0``, no cone); ``μ = 0`` and contacts without
  tangential rows are frictionless (``Λ_T = 0``).

Each contact ends `ContactState.OPEN` (``Λ = 0``), ``STICK`` or ``SLIDE``. A
closed contact without friction (no tangential rows, or ``μ = 0``) is reported
``SLIDE``: its tangential motion is free.

How it is solved, and what "exact" means
----------------------------------------
By enumeration of the contacts' states. For each candidate the equalities are
solved: open ``Λ_k = 0``; stick ``w_N = 0`` and ``u+_T = 0``; slide ``w_N = 0``
and ``Λ_T = -μ Λ_N s`` with the unit slip direction ``s`` an unknown. For
given ``s`` this is one linear system; ``s`` is ``±1`` on a planar contact
(both signs are tried) and ``(cos θ, sin θ)`` on a spatial one, where ``θ``
solves ``atan2(u+_T(θ)) = θ``: with one spatial sliding contact by a scan of
the circle, also split beside the poles of ``Λ_N`` (in closed form), then
bisection and a Newton polish (every root the scan separates), and the sign
changes of the cross form below polished too (a slip that vanishes at one
direction, its impulse on the cone's edge, is a root of that form only);
with several by Newton's method with a line search on the smooth cross form
``s_k x u+_T,k(θ) = 0`` (no angle wrap, and no ``1/||u+_T||`` that makes a root
with a small slip a needle in ``θ``), run at once from the pre-impact slip,
an approximate solution of the whole law (projected Gauss-Seidel), the
frictionless slip and every local minimum of a grid on the torus (see
`contactdiff.dynamics.friction_slip`). The roots of a candidate are tried
nearest the pre-impact slip directions first. Every condition of the
law is then checked on the candidate, and the first candidate that satisfies
all within the tolerance is returned. Two rejections skip work without changing
which candidate that is: a candidate whose closed contact pulls, by far more than
the tolerance, at every slip angle of its sliders (a bound over all angles,
`contactdiff.dynamics.slip_lowrank`) is not searched, and a candidate's roots that
break an inequality of the law by that much are rejected in one batch before the
others are checked one by one. "Exact" means: the true circular cone
(no polyhedral approximation, no regularisation or penalty), and an answer
that satisfies every condition of the law up to the scaled residual ``tol``
(about 1e-15 in practice: the linear solves are backward stable and Newton
converges quadratically). It does not mean the search is complete: for
several spatial sliding contacts a root may lie between the grid's basins
(none missed in 9000 random problems of 1-3 spatial contacts with ``e`` in
[0, 1]; the earlier search on the angle residual, without the poles in the
one-slider scan, missed 6 of the first 1800), so a `SolverError` there is
not a proof that no solution exists (for planar and
sticking contacts the search is finite and complete).

Enumeration order and tie rule
------------------------------
When a contact has a finite ``μ > 0``, the candidate that an approximate
solution of the law points to (projected Gauss-Seidel, `SlipDirections.fixed_point`:
open where its normal impulse is zero, sticking where its slip is zero, else
sliding) is tried first and checked like any other: where it is right, the
dozens of candidates before it in the order below (each a search for slip
directions) are skipped. Otherwise, and when that candidate fails: closed
sets from most contacts to fewest, lexicographic in the contact indices within
a size (the order of `solve_contact_lcp`: contacts stay engaged where they
can); within a closed set, fewest sliding contacts first (stick before slide),
lexicographic within a count; a planar sliding contact tries the sign of its
pre-impact slip first (+1 if there is none). With friction the
law may have several solutions (strong coupling, large ``μ``); the first valid
candidate in this order is returned (the approximate solution's, if valid). With
``μ = inf`` or ``0`` everywhere there is no first guess, and this is exactly the
active set that `solve_contact_lcp` enumerates first.

Redundant rows
--------------
When rows are dependent (the four corners of a face landing flat: normal rows of
rank 3), a candidate's equality system is singular and the law alone leaves the
impulses undetermined. They are then the impulses of equal compliant supports in
the rigid limit (`contactdiff.dynamics.redundant`): on the candidate's equality
rows, in the range of those rows. The approximate solution is not taken as it
is there (projected Gauss-Seidel on a singular ``G`` converges to some solution, not
to the principle's): its pattern is first completed by closing every contact it
leaves without impulse at zero normal speed, and a guessed solution that leaves such
a contact open is not taken; the enumeration's order (most contacts closed first)
decides otherwise.

Energy (known limit)
--------------------
The change of kinetic energy is ``ΔT = Λ^T u- + ½ Λ^T G Λ = ½ Λ^T (u- + u+)``
(from ``v+ = v- + M^-1 A^T Λ``). With ``e = 0`` it is never positive: normal
rows give ``Λ_N u+_N = 0``, tangential rows ``Λ_T . u+_T = -μ Λ_N ||u+_T|| <= 0``,
so ``ΔT = Λ^T u+ - ½ Λ^T G Λ <= 0``. With ``e > 0`` the normal rows add
``-e Λ_N u-_N >= 0``, and when the tangential impulse couples into the normal
velocity (``G_NT != 0``) Newton's kinematic restitution can *increase* the
energy even with finite friction (Kane's paradox; e.g. a planar contact with
``e = 1`` that sticks, see the tests; about 4 % of random coupled problems
with ``e`` in [0, 1], sticking or sliding, one contact or several). This is a property of the law, not a
numerical error: the result reports ``energy_change`` and ``energy_gain``, and
``on_energy_gain="raise"`` raises `EnergyGainError` instead.

Existence: with ``μ = inf`` a sticking solution may not exist (Painleve-type,
see `solve_contact_lcp`); with finite ``μ`` the enumeration raises
`SolverError` naming the best candidate if none is valid.
"""

from __future__ import annotations

import enum
import itertools
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import EnergyGainError, InvalidInputError, SolverError
from .friction_slip import SLIP_ZERO, CandidateEval, SlipDirections, SlipMap
from .lcp_problem import DEFAULT_TOL, ContactRows, _as_real_array, _as_vector, _validate
from .redundant import gram_range_basis

__all__ = [
    "ContactState",
    "EnergyGainError",
    "FrictionalImpact",
    "solve_frictional_impact",
    "FRICTION_ENUMERATE_MAX",
]

#: Largest number of contacts accepted (at most 3^n state candidates, times
#: the slip signs of planar sliding contacts).
FRICTION_ENUMERATE_MAX = 8

# A normal impulse, or a post-impact slip, below this share of its scale in the
# approximate solution (`SlipDirections.fixed_point`) is taken for zero in the
# candidate tried first: its sweeps stop at 1e-14 relative change (or at the cap,
# `friction_slip._FP_SWEEPS`), so a contact that should open or stick is far below this.
_GUESS_ZERO = 1e-6

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
        energy_gain: ``ΔT`` is positive beyond round-off (see the module doc).
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


def solve_frictional_impact(
    G: np.ndarray,
    u_minus: np.ndarray | Sequence[float],
    rows: ContactRows,
    restitution: float | np.ndarray | Sequence[float],
    friction: float | np.ndarray | Sequence[float],
    *,
    tol: float = DEFAULT_TOL,
    on_energy_gain: str = "flag",
) -> FrictionalImpact:
    """Solve the frictional impact law of the module doc by enumeration.

    Args:
        G: Delassus matrix ``A M^-1 A^T`` over all rows, shape ``(m, m)``,
            symmetric positive semidefinite (symmetry checked to a relative
            1e-8, then enforced).
        u_minus: Pre-impact row velocities ``A v-``, shape ``(m,)``.
        rows: Row layout (normal row, then 0-2 tangential rows per contact).
        restitution: Newton coefficient in [0, 1], scalar or one per contact.
        friction: Coulomb coefficient ``μ >= 0`` or ``inf`` (sticking), scalar
            or one per contact; ignored for contacts without tangential rows.
        tol: Acceptance tolerance on the scaled residual
            (`contactdiff.dynamics.lcp_problem.DEFAULT_TOL`).
        on_energy_gain: ``"flag"`` (default: set ``energy_gain``) or
            ``"raise"`` (raise `EnergyGainError`).

    Returns:
        The first valid candidate in the enumeration order of the module doc.

    Raises:
        InvalidInputError: Bad shapes, non-finite entries, asymmetric ``G``,
            ``e`` outside [0, 1], negative or NaN ``μ``, bad ``tol`` or
            ``on_energy_gain``, more than `FRICTION_ENUMERATE_MAX` contacts.
        SolverError: No candidate is valid; the message names the best one.
        EnergyGainError: ``on_energy_gain="raise"`` and the solution gains energy.
    """
    if not isinstance(rows, ContactRows):
        raise InvalidInputError(f"rows must be a ContactRows; got {type(rows).__name__}")
    m, n = rows.n_rows, rows.n_contacts
    G, _ = _validate(G, np.zeros(m), rows, tol, "auto")
    u = _as_vector(u_minus, "u_minus", m)
    e = _per_contact(restitution, "restitution", n)
    bad = ~np.isfinite(e) | (e < 0.0) | (e > 1.0)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise InvalidInputError(f"restitution of contact {k} is {float(e[k])!r}; valid: 0 <= e <= 1")
    mu = _per_contact(friction, "friction", n)
    bad = np.isnan(mu) | (mu < 0.0)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise InvalidInputError(f"friction coefficient of contact {k} is {float(mu[k])!r}; valid: mu >= 0 or inf")
    if on_energy_gain not in ("flag", "raise"):
        raise InvalidInputError(f"on_energy_gain is {on_energy_gain!r}; valid: 'flag', 'raise'")
    if n > FRICTION_ENUMERATE_MAX:
        raise InvalidInputError(f"solve_frictional_impact accepts at most {FRICTION_ENUMERATE_MAX} contacts; got {n}")
    normal = np.array(rows.normal, dtype=np.intp)
    e = np.where(u[normal] < 0.0, e, 0.0)
    if n == 0:
        return FrictionalImpact(np.zeros(0), np.zeros(0), (), (), e, 0.0, "enumerate", 0.0, False, 0)
    prob = _Impact(G, u, rows, e, mu, tol)
    out = prob.solve()
    if out.energy_gain and on_energy_gain == "raise":
        raise EnergyGainError(
            f"frictional impact: the solution gains kinetic energy dT = {out.energy_change:.6g} "
            f"(states {_describe(out.states)}, restitution {e.tolist()}, friction {mu.tolist()}); "
            "Newton's kinematic restitution with friction coupling (Kane's paradox)"
        )
    return out


# --------------------------------------------------------------------------
# internals


def _per_contact(value: object, name: str, n: int) -> np.ndarray:
    arr = _as_real_array(value, name)
    if arr.ndim == 0:
        return np.full(n, float(arr))
    if arr.shape != (n,):
        raise InvalidInputError(f"{name} has shape {arr.shape}; valid: scalar or ({n},), one per contact")
    return arr.astype(float, copy=True)


def _describe(states: Sequence[ContactState], signs: dict[int, float] | None = None) -> str:
    parts = []
    for k, s in enumerate(states):
        txt = s.value
        if signs and k in signs:
            txt += f" ({'+' if signs[k] > 0 else '-'})"
        parts.append(f"{k}: {txt}")
    return "{" + ", ".join(parts) + "}"


class _Impact(SlipDirections):
    """One validated problem: candidate solves, checks, the best failure."""

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
        # `contactdiff.dynamics.redundant`, and no first guess (module doc)
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

    # ---- enumeration ---------------------------------------------------
    def candidates(self) -> Iterator[tuple[tuple[ContactState, ...], tuple[int, ...]]]:
        """State tuples in the documented order, with the spatial sliders."""
        n = self.n
        for size in range(n, -1, -1):
            for closed in itertools.combinations(range(n), size):
                choice = [k for k in closed if not self.frictionless[k] and not self.sticky[k]]
                for n_slide in range(len(choice) + 1):
                    for sliding in itertools.combinations(choice, n_slide):
                        st = [ContactState.OPEN] * n
                        for k in closed:
                            if self.frictionless[k] or k in sliding:
                                st[k] = ContactState.SLIDE
                            else:
                                st[k] = ContactState.STICK
                        yield tuple(st), sliding

    def predicted(self, complete: bool = False) -> tuple[tuple[ContactState, ...], tuple[int, ...]] | None:
        """The candidate an approximate solution of the law points to (`fixed_point`):
        open where its normal impulse is below `_GUESS_ZERO` of the largest, sticking
        where its post-impact slip is below `_GUESS_ZERO` of the velocity scale, else
        sliding; None without a contact of finite positive ``μ`` (the enumeration is
        then linear solves only).

        With ``complete``, a contact the approximation leaves without impulse but
        closing at zero normal speed (``w_N`` below `_GUESS_ZERO` of the velocity
        scale) is closed too: with dependent rows the approximation puts the load on
        some of the contacts that hold the same motion, the principle on all of them
        (module doc, "Redundant rows")."""
        if all(self.frictionless[k] or self.sticky[k] for k in range(self.n)):
            return None
        lam, up = self.fixed_point()
        lam_max = float(np.abs(lam).max())
        if not np.isfinite(lam_max) or lam_max == 0.0:
            return None
        vscale = self.bmax + self.gmax * lam_max
        states = []
        for k in range(self.n):
            t, n = self.tang[k], self.normal[k]
            w_n = up[n] + self.e[k] * self.u[n]
            if lam[n] <= _GUESS_ZERO * lam_max and not (complete and abs(w_n) <= _GUESS_ZERO * vscale):
                states.append(ContactState.OPEN)
            elif self.frictionless[k]:
                states.append(ContactState.SLIDE)
            elif self.sticky[k] or np.linalg.norm(up[t]) <= _GUESS_ZERO * vscale:
                states.append(ContactState.STICK)
            else:
                states.append(ContactState.SLIDE)
        sliding = tuple(k for k, st in enumerate(states) if st is ContactState.SLIDE and not self.frictionless[k])
        return tuple(states), sliding

    def solve(self) -> FrictionalImpact:
        # with dependent rows the approximation's pattern completed first, then as it is
        guesses = [self.predicted(complete=True), self.predicted()] if self.redundant else [self.predicted()]
        # the guesses that failed (a candidate is a function of the problem: tried again in
        # the enumeration, it fails again; it is counted, and its search's failure noted, again)
        failed: dict[tuple, bool] = {}
        for guess in dict.fromkeys(g for g in guesses if g is not None):
            states, sliding = guess
            planar = [k for k in sliding if self.tang[k].size == 1]
            spatial = [k for k in sliding if self.tang[k].size == 2]
            _, up = self.fixed_point()
            signs = {k: (1.0 if up[self.tang[k][0]] >= 0.0 else -1.0) for k in planar}
            self.tried += 1
            noted = len(self.newton_failed)
            out = self.try_candidate(states, signs, spatial)
            if out is not None:
                return out
            failed[(states, tuple(sorted(signs.items())))] = len(self.newton_failed) > noted
        for states, sliding in self.candidates():
            planar = [k for k in sliding if self.tang[k].size == 1]
            spatial = [k for k in sliding if self.tang[k].size == 2]
            pref = {k: (1.0 if self.u[self.tang[k][0]] >= 0.0 else -1.0) for k in planar}
            for flips in itertools.product((1.0, -1.0), repeat=len(planar)):
                signs = {k: pref[k] * f for k, f in zip(planar, flips)}
                self.tried += 1
                key = (states, tuple(sorted(signs.items())))
                if key in failed:
                    if failed[key]:
                        self.newton_failed.append(_describe(states, signs))
                    continue
                out = self.try_candidate(states, signs, spatial)
                if out is not None:
                    return out
        res, where = self.best
        extra = ""
        if self.newton_failed:
            extra = (
                f"; Newton found no slip direction for {len(self.newton_failed)} candidate(s), "
                f"e.g. {self.newton_failed[0]} (a spatial slip direction may have been missed)"
            )
        u_txt = np.array2string(self.u, precision=6, max_line_width=200)
        raise SolverError(
            f"frictional impact: no valid state candidate among {self.tried} for G of size "
            f"{self.m}x{self.m} ({self.n} contacts), u- = {u_txt}, restitution {self.e.tolist()}, "
            f"friction {self.mu.tolist()}; best scaled residual {res:.3g} with states {where} "
            f"(tol {self.tol:g}){extra}"
        )

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
        lay = self.layout(states)
        dirs: dict[int, np.ndarray] = {k: np.array([s]) for k, s in signs.items()}
        if not spatial:
            ev = self.evaluate(states, dirs, lay)
            return self.check(states, dirs, ev, signs, "enumerate")
        if self.pulls_everywhere(states, dirs, spatial, lay):
            return None
        roots = list(self.slip_roots(states, dirs, spatial, lay))
        if not roots:
            self.newton_failed.append(_describe(states, signs))
            return None
        # roots that break an inequality of the law by far more than the check's tolerance
        # (a pulling normal impulse, most often: a face's corner the others lift) are
        # rejected in one batch, before each is evaluated and checked on its own; the
        # first root that passes the check is the same. A planar slider's friction is not
        # in `SlipMap.violating`'s impulse scale: with one, every root is checked.
        skip = (
            SlipMap(self, states, dirs, spatial, lay, cross=True).violating(np.array(roots), _SKIP_SHARE * self.tol)
            if not signs
            else np.zeros(len(roots), dtype=bool)
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

    def pulls_everywhere(self, states, dirs, spatial, lay) -> bool:
        """Whether the candidate fails the law at every slip direction of its spatial
        sliders, a closed contact pulling by far more than the check's tolerance
        (`LowRankSolve.pulls_everywhere`, where its angle-free matrix is well
        conditioned): its search for slip directions is then skipped."""
        fmap = SlipMap(self, states, dirs, spatial, lay, cross=True)
        low = fmap.low_rank()
        if not low.usable:
            return False
        # every sliding contact's friction, planar ones too, bounds the impulses' scale
        mu_max = max((float(self.mu[k]) for k, s in enumerate(states) if s is ContactState.SLIDE), default=0.0)
        return low.pulls_everywhere(fmap.closed, mu_max, _SKIP_SHARE * self.tol)

    # ---- slip directions of spatial sliding contacts ----------------------
    def residual(self, states, dirs, lam, up) -> float:
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
        res = self.residual(states, dirs, ev.lam, ev.up)
        if not np.isfinite(res):
            res = np.inf
        if res < self.best[0]:
            self.best = (res, _describe(states, signs))
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
