"""Contact complementarity problem (pure numpy/scipy, no Pinocchio).

Each contact ``k`` owns one *normal* constraint row and, for a *sticking*
contact, one (planar) or two (spatial) *tangential* rows. Given the Delassus
matrix ``G = A M^-1 A^T`` over all rows of the candidate contacts (symmetric
positive semidefinite; positive definite in well-posed cases) and a vector
``b``, :func:`solve_contact_lcp` finds ``x`` and an active set ``S`` of
contacts such that, with ``w = G x + b``:

* for ``k`` in ``S``: ``x_n >= 0``, ``w_n = 0`` and ``w_t = 0`` (``x_t`` free);
* for ``k`` not in ``S``: ``x_n = 0``, ``x_t = 0`` and ``w_n >= 0``
  (its tangential ``w`` is unconstrained);
* hence ``x_n * w_n = 0`` for every contact.

The tangential rows carry a free-sign force or impulse, but only while their
normal row is active; that conditional coupling is why this is not a
standard mixed LCP.

The same problem serves two uses:

1. **Impact** (Newton restitution per contact, tangential velocity stopped
   plastically). ``v+ = v- + M^-1 A^T x`` with ``x`` the impulses. On a
   normal row ``w = A_n v+ + e * A_n v-``, on a tangential row
   ``w = A_t v+``; hence ``b = (1 + e) * (A_n v-)`` on normal rows and
   ``b = A_t v-`` on tangential rows (see :func:`impact_rhs`), and
   ``A v+ = w - e * (A_n v-)`` on normal rows.
2. **Acceleration level** (mode choice, contact forces).
   ``ddq = a_free + M^-1 A^T x`` with ``x`` the contact forces,
   ``w = A ddq + drift`` and ``b = A a_free + drift``. ``S`` is the new mode.

Energy: for frictionless rows the kinetic energy change of an impact is
``½ Σ_k (1 - e_k) x_k (A_k v-)`` (use ``w_k = 0`` on active rows). It never
increases if ``e`` is the same for all contacts, or if every participating
contact is approaching or at rest (``A_k v- <= 0``). With different ``e_k`` and
a *separating* contact that the coupling forces into the set, Newton's law
can add energy, and the post-impact normal velocity ``-e_k A_k v-`` of that
contact is negative. With sticking rows and ``e > 0`` it can add energy even
for approaching contacts (Kane's paradox). With ``e = 0`` the change is
``-½ x^T G x <= 0`` in every case. These are properties of the impact law,
not numerical errors. The caller decides which contacts take part.

Existence: for frictionless rows and positive definite ``G`` the solution
exists and is unique. With redundant rows (singular ``G``) it exists for an
impact with one ``e`` for all contacts (``b`` is then in the range of ``G``),
but not always otherwise: a body clamped between two closed walls cannot
obey two different restitutions. With sticking rows it may not exist:
stopping the slip of a contact can require a pulling normal impulse while
releasing it lets it penetrate (a Painleve-type inconsistency of infinite
friction; 10-20 % of random strongly coupled test problems).
``on_infeasible="relax"`` then returns the infinite-friction limit (see
:func:`solve_contact_lcp`). With sticking rows several active sets may also
be valid; see the selection rule in :func:`solve_contact_lcp`.

Units: ``G`` in the inverse mass units of the rows, ``b`` and ``w`` in row
velocity (impact) or acceleration (forces) units, ``x`` in impulse or force
units.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.linalg import cho_solve
from scipy.optimize import nnls

from contactdiff.errors import InvalidInputError, SolverError

__all__ = ["ContactRows", "LCPSolution", "impact_rhs", "solve_contact_lcp"]

#: Default acceptance tolerance on the scaled residual (`LCPSolution.residual`). The
#: equalities of a set solve are backward stable: their residual is about
#: n * eps * (|G| |x| + |b|), independent of the conditioning of G. So 1e-9
#: leaves a margin of about 1e6 over rounding and still rejects any real
#: violation. A sign test on x_n can be off by about cond(G) * eps; when the
#: true x_n is 0 the neighbouring set (k dropped) then passes on its w_n test,
#: which is backward stable.
DEFAULT_TOL = 1e-9

#: Largest number of contacts that ``method="auto"`` solves by enumeration
#: (2^6 = 64 small solves at most) when the solution need not be unique.
AUTO_ENUMERATE_MAX = 6
#: Largest number of contacts that enumeration accepts at all.
ENUMERATE_MAX = 16
#: Largest number of contacts for the three-state search of
#: ``on_infeasible="relax"`` (3^8 = 6561 sets at most).
RELAX_ENUMERATE_MAX = 8

# A Cholesky pivot below this fraction of the largest pivot marks a set
# matrix as (nearly) singular: redundant rows, e.g. four coplanar sticking
# feet. It is then solved by eigendecomposition dropping eigenvalues below
# _EIG_RCOND * largest (exact redundancy leaves ~1e-16), which gives the
# minimum-norm solution; if that is not valid but Cholesky succeeded (an
# ill-conditioned, not redundant, set) the plain solve is tried as well.
# Pivots bound the eigenvalues from above, so the pivot test is the more
# cautious one of the two.
_PIVOT_RTOL = 1e-10
_EIG_RCOND = 1e-12

_METHODS = ("auto", "enumerate", "pivot", "nnls")


@dataclass(frozen=True)
class ContactRows:
    """Row layout of the candidate contacts in ``G`` and ``b``.

    Attributes:
        normal: For each contact, the index of its normal row.
        tangential: For each contact, the indices of its tangential rows
            (empty for a frictionless contact, one row for a planar sticking
            contact, two rows for a spatial sticking contact).

    The rows of all contacts must be exactly ``0 .. n_rows - 1``, each used once.
    """

    normal: tuple[int, ...]
    tangential: tuple[tuple[int, ...], ...]

    def __post_init__(self) -> None:
        normal = tuple(_as_index(i, "ContactRows.normal") for i in self.normal)
        tang = tuple(
            tuple(_as_index(i, "ContactRows.tangential") for i in t) for t in self.tangential
        )
        if len(tang) != len(normal):
            raise InvalidInputError(
                f"ContactRows: {len(normal)} normal rows but {len(tang)} tangential "
                f"groups; need one group (possibly empty) per contact"
            )
        used = list(normal) + [i for t in tang for i in t]
        if sorted(used) != list(range(len(used))):
            raise InvalidInputError(
                f"ContactRows: rows must be 0..{len(used) - 1}, each once; "
                f"got normal={normal}, tangential={tang}"
            )
        object.__setattr__(self, "normal", normal)
        object.__setattr__(self, "tangential", tang)
        # Row indices of each contact, normal first (cached for the solvers).
        object.__setattr__(
            self,
            "_rows_of",
            tuple(np.array((n, *t), dtype=np.intp) for n, t in zip(normal, tang)),
        )

    @classmethod
    def from_sizes(cls, sizes: Sequence[int]) -> ContactRows:
        """Layout with the rows of each contact stacked in order, normal first.

        Args:
            sizes: Rows per contact: 1 (frictionless), 2 (planar sticking) or
                3 (spatial sticking).

        Returns:
            The layout; e.g. ``from_sizes([1, 3])`` has normal rows ``(0, 1)``
            and tangential rows ``((), (2, 3))``.
        """
        normal: list[int] = []
        tang: list[tuple[int, ...]] = []
        row = 0
        for k, s in enumerate(sizes):
            if isinstance(s, bool) or not isinstance(s, (int, np.integer)) or s not in (1, 2, 3):
                raise InvalidInputError(
                    f"ContactRows.from_sizes: size of contact {k} is {_show(s)}; valid: 1, 2, 3"
                )
            normal.append(row)
            tang.append(tuple(range(row + 1, row + s)))
            row += s
        return cls(tuple(normal), tuple(tang))

    @property
    def n_contacts(self) -> int:
        """Number of contacts."""
        return len(self.normal)

    @property
    def n_rows(self) -> int:
        """Number of rows (size of ``G`` and ``b``)."""
        return len(self.normal) + sum(len(t) for t in self.tangential)

    @property
    def frictionless(self) -> bool:
        """True if no contact has tangential rows."""
        return all(len(t) == 0 for t in self.tangential)

    def rows_of(self, contacts: Sequence[int]) -> np.ndarray:
        """Row indices of the given contacts (each contact's normal row first)."""
        if len(contacts) == 0:
            return np.empty(0, dtype=np.intp)
        return np.concatenate([self._rows_of[k] for k in contacts])  # type: ignore[attr-defined]


@dataclass(frozen=True, eq=False)  # arrays: no element-wise ==
class LCPSolution:
    """Solution of the contact complementarity problem.

    Attributes:
        x: Impulses or forces on all rows (zero on the rows of inactive
            contacts; normal entries >= 0).
        w: ``G x + b`` on all rows.
        active: Indices of the contacts in the active set ``S``, ascending.
        residual: Largest violation of the conditions, scaled: negative
            ``x_n`` by ``max|x|``; ``w`` on active rows and negative ``w_n`` on
            inactive contacts by ``max|b| + max|G| max|x|``.
        method: Which solver produced it: "closed-form", "enumerate",
            "pivot", "nnls" or "relaxed".
        tangential_only: Contacts in the infinite-friction limit state
            (``x_n = 0``, ``w_n >= 0``, ``w_t = 0``, ``x_t`` free); empty unless
            ``on_infeasible="relax"`` was needed.
    """

    x: np.ndarray
    w: np.ndarray
    active: tuple[int, ...]
    residual: float
    method: str
    tangential_only: tuple[int, ...] = ()


def impact_rhs(
    A_v_minus: np.ndarray | Sequence[float],
    restitution: float | np.ndarray | Sequence[float],
    rows: ContactRows,
) -> np.ndarray:
    """Right-hand side ``b`` of the impact problem (use 1 of the module).

    Args:
        A_v_minus: Pre-impact constraint velocities ``A v-`` on all rows (m/s
            or rad/s, in the rows' own frames), shape ``(n_rows,)``.
        restitution: Newton coefficients in [0, 1]: a scalar, one per contact
            (shape ``(n_contacts,)``) or one per row (shape ``(n_rows,)``; only
            the entries of normal rows are used).
        rows: Row layout.

    Returns:
        ``b`` with ``(1 + e_k) (A v-)_n`` on normal rows and ``(A v-)_t`` on
        tangential rows (restitution acts on the normal row only).
    """
    u = _as_vector(A_v_minus, "A_v_minus", rows.n_rows)
    e = _as_real_array(restitution, "restitution")
    n = rows.n_contacts
    if e.ndim == 0:
        e_c = np.full(n, float(e))
    elif e.shape == (n,):
        e_c = e
    elif e.shape == (rows.n_rows,):
        e_c = e[list(rows.normal)]
    else:
        raise InvalidInputError(
            f"restitution has shape {e.shape}; valid: scalar, ({n},) per contact "
            f"or ({rows.n_rows},) per row"
        )
    bad = ~np.isfinite(e_c) | (e_c < 0.0) | (e_c > 1.0)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise InvalidInputError(f"restitution of contact {k} is {float(e_c[k])!r}; valid: 0 <= e <= 1")
    b = u.copy()
    nrm = list(rows.normal)
    b[nrm] = (1.0 + e_c) * u[nrm]
    return b


def solve_contact_lcp(
    G: np.ndarray,
    b: np.ndarray,
    rows: ContactRows,
    *,
    tol: float = DEFAULT_TOL,
    method: str = "auto",
    on_infeasible: str = "raise",
) -> LCPSolution:
    """Solve the contact complementarity problem described in the module doc.

    Args:
        G: Delassus matrix ``A M^-1 A^T`` over all rows, shape ``(m, m)``,
            symmetric positive semidefinite (symmetry is checked to a relative
            1e-8 and then enforced; definiteness is not checked beyond the
            diagonal: an indefinite ``G`` shows up as "no valid active set").
        b: Vector of shape ``(m,)``; see the module doc for its two uses.
        rows: Row layout; ``rows.n_rows`` must equal ``m``.
        tol: Acceptance tolerance on the scaled residual (see
            :data:`DEFAULT_TOL`).
        method: ``"auto"`` (default), ``"enumerate"`` (all ``2^n`` active
            sets), ``"pivot"`` (Murty's least-index principal pivoting) or
            ``"nnls"`` (frictionless rows only: ``min ½ x^T G x + b^T x,
            x >= 0`` as NNLS on a Cholesky factor).
        on_infeasible: ``"raise"`` (default) or ``"relax"``. With sticking
            rows a valid active set need not exist (see the module doc); with
            ``"relax"`` a third state is then allowed, *tangential-only*
            (``x_n = 0``, ``w_n >= 0``, ``w_t = 0``, ``x_t`` free: the limit of
            Coulomb friction as mu -> inf), and the solution with the fewest
            such contacts is returned (enumeration, at most
            :data:`RELAX_ENUMERATE_MAX` contacts). One always exists for
            positive definite ``G``: the convex problem
            ``min ½ x^T G x + b^T x, x_n >= 0, x_t free`` has a solution, and
            its KKT conditions put every contact in one of the three states.

    Returns:
        The solution. Which one, when several exist:

        * frictionless rows and positive definite ``G``: the solution is
          unique (proof in `_pivot`), every method gives it;
        * singular ``G`` (redundant rows): ``w`` is still unique for
          frictionless rows, ``x`` is not; within the chosen active set the
          minimum-norm ``x`` with ``x_n >= 0`` is returned;
        * sticking rows: several active sets can be valid (a separating
          contact that sticking would also press down). Enumeration returns
          the valid set with the most contacts (keep contacts sticking where
          possible), ties broken by the lexicographic order of contact
          indices. Above :data:`AUTO_ENUMERATE_MAX` contacts ``"auto"``
          returns the set found by pivoting from "all active".

    Raises:
        InvalidInputError: Bad shapes, non-finite entries, asymmetric ``G``,
            negative diagonal, bad ``tol``, ``method`` or ``on_infeasible``.
        SolverError: No active set satisfies the conditions within ``tol``.
    """
    G, b = _validate(G, b, rows, tol, method)
    if on_infeasible not in ("raise", "relax"):
        raise InvalidInputError(f"on_infeasible is {on_infeasible!r}; valid: 'raise', 'relax'")
    n = rows.n_contacts
    if method == "nnls" and not rows.frictionless:
        raise InvalidInputError(
            "method='nnls' needs frictionless rows (one row per contact); "
            f"got tangential rows {rows.tangential}; valid methods: {', '.join(_METHODS)}"
        )
    if method == "enumerate" and n > ENUMERATE_MAX:
        raise InvalidInputError(
            f"method='enumerate' accepts at most {ENUMERATE_MAX} contacts; got {n}"
        )
    if n == 0:
        return LCPSolution(np.zeros(0), np.zeros(0), (), 0.0, "closed-form")
    if n == 1 and rows.n_rows == 1 and G[0, 0] > 0.0:
        # One frictionless contact: x = max(0, -b/G), exact.
        g, b0 = float(G[0, 0]), float(b[0])
        if b0 >= 0.0:
            return LCPSolution(np.zeros(1), b.copy(), (), 0.0, "closed-form")
        x0 = -b0 / g
        w0 = g * x0 + b0
        return LCPSolution(
            np.array([x0]), np.array([w0]), (0,), abs(w0) / (abs(b0) + g * x0), "closed-form"
        )
    prob = _Problem(G, b, rows, tol)
    out = _solve(prob, method)
    if out is None and on_infeasible == "relax" and n <= RELAX_ENUMERATE_MAX:
        out = _enumerate_relaxed(prob)
    if out is None:
        raise prob.fail()
    return out


def _solve(prob: _Problem, method: str) -> LCPSolution | None:
    """Dispatch on method; None if no valid active set is found."""
    rows, n = prob.rows, prob.n

    if method == "nnls":
        return _chain(prob, (_nnls, _pivot, _enumerate))
    if method == "pivot":
        return _chain(prob, (_pivot, _enumerate))
    if method == "enumerate":
        return _chain(prob, (_enumerate,))

    # auto. Most impacts and most mode choices end with every contact active:
    # try that first (it is also the first set of the enumeration order).
    all_set = tuple(range(n))
    cand = prob.try_set(all_set)
    if cand.valid:
        return prob.finish(all_set, (), cand, "enumerate")
    unique = rows.frictionless and not cand.singular
    if unique:
        # Unique solution: any method returns the same; pivoting is cheapest
        # for few contacts, NNLS scales better. Pivoting starts from the
        # contacts that pushed in the all-active solve: usually one step.
        if n <= AUTO_ENUMERATE_MAX:
            guess = tuple(int(k) for k in np.flatnonzero(cand.x[prob.normal] > 0.0))
            out = _pivot(prob, start=guess)
            if out is not None:
                return out
        return _chain(prob, (_nnls, _pivot, _enumerate))
    if n <= AUTO_ENUMERATE_MAX:
        return _chain(prob, (_enumerate,))
    return _chain(prob, (_pivot, _enumerate))


# --------------------------------------------------------------------------
# internals


@dataclass
class _Candidate:
    x: np.ndarray  # full-length x (zeros off the set)
    w: np.ndarray  # G x + b
    residual: float
    valid: bool
    singular: bool  # the set matrix was rank deficient


class _Problem:
    """One validated problem: set solves, checks, and the best failure seen.

    A set is ``(S, T)``: ``S`` the active contacts, ``T`` the tangential-only
    contacts (only with ``on_infeasible="relax"``; empty otherwise).
    """

    def __init__(self, G: np.ndarray, b: np.ndarray, rows: ContactRows, tol: float):
        self.G, self.b, self.rows, self.tol = G, b, rows, tol
        self.m, self.n = G.shape[0], rows.n_contacts
        self.normal = np.array(rows.normal, dtype=np.intp)
        self.blocks = rows._rows_of  # type: ignore[attr-defined]
        self.tang = tuple(np.array(t, dtype=np.intp) for t in rows.tangential)
        self.gmax = float(np.abs(G).max())
        self.bmax = float(np.abs(b).max())
        self.best: tuple[float, tuple[int, ...], tuple[int, ...]] = (np.inf, (), ())
        self.cache: dict[tuple[tuple[int, ...], tuple[int, ...]], _Candidate] = {}

    def eq_rows(self, S: tuple[int, ...], T: tuple[int, ...]) -> np.ndarray:
        """Rows with w = 0: all rows of S, tangential rows of T."""
        parts = [self.blocks[k] for k in S] + [self.tang[k] for k in T]
        return np.concatenate(parts) if parts else np.empty(0, dtype=np.intp)

    def try_set(self, S: tuple[int, ...], T: tuple[int, ...] = ()) -> _Candidate:
        """Solve the equalities of the set ``(S, T)`` and check all conditions."""
        key = (S, T)
        if key in self.cache:
            return self.cache[key]
        idx = self.eq_rows(S, T)
        cand = None
        if idx.size:
            Gs, rhs = self.G[idx[:, None], idx], -self.b[idx]
            L, well = _definite(Gs)
            if not well:
                # Singular or nearly so: first the minimum-norm solution with
                # x_n >= 0 (redundant rows share the load; no huge internal
                # forces from round-off). If that fails and Gs is still
                # numerically definite (ill-conditioned, not redundant), the
                # plain solve: its residual is small however bad cond(Gs) is.
                cand = self.evaluate(S, T, idx, self.min_norm(S, Gs, rhs), singular=True)
                if cand.valid or L is None:
                    return self.store(key, cand)
            # LU is the faster call for tiny sets; the factor L is more robust
            # when a pivot is tiny (LU may then call the matrix singular).
            xs = np.linalg.solve(Gs, rhs) if well else cho_solve((L, True), rhs, check_finite=False)
            full = self.evaluate(S, T, idx, xs, singular=not well)
            if cand is None or full.residual < cand.residual:
                cand = full
        else:
            cand = self.evaluate(S, T, idx, np.zeros(0), singular=False)
        return self.store(key, cand)

    def min_norm(self, S: tuple[int, ...], Gs: np.ndarray, rhs: np.ndarray) -> np.ndarray:
        """Minimum-norm solution of Gs xs = rhs with x_n >= 0 if one exists."""
        xs, null = _min_norm(Gs, rhs)
        # Positions of the normal rows of S (first row of each block).
        pos = np.cumsum([0] + [self.blocks[k].size for k in S[:-1]])[: len(S)]
        if null.shape[1] and pos.size and np.any(xs[pos] < 0.0):
            # Another solution in the same affine set may have x_n >= 0:
            # the minimum-norm one is a least-distance problem.
            z = _ldp(null[pos], -xs[pos])
            if z is not None:
                xs = xs + null @ z
        return xs

    def evaluate(
        self, S: tuple[int, ...], T: tuple[int, ...], idx: np.ndarray, xs: np.ndarray, singular: bool
    ) -> _Candidate:
        x = np.zeros(self.m)
        x[idx] = xs
        w = self.G @ x + self.b
        res = self.residual(S, T, x, w)
        return _Candidate(x, w, res, res <= self.tol, singular)

    def store(self, key, cand: _Candidate) -> _Candidate:
        self.cache[key] = cand
        if cand.residual < self.best[0]:
            self.best = (cand.residual, *key)
        return cand

    def residual(
        self, S: tuple[int, ...], T: tuple[int, ...], x: np.ndarray, w: np.ndarray
    ) -> float:
        """Scaled violation of the conditions (0 when all hold exactly)."""
        xmax = float(np.abs(x).max())
        s_w = self.bmax + self.gmax * xmax
        if s_w == 0.0:  # b = 0 and x = 0: w = 0, nothing violated
            return 0.0
        viol_x = 0.0
        viol_w = 0.0
        if S:
            viol_x = max(0.0, -float(x[self.normal[list(S)]].min()))
        idx = self.eq_rows(S, T)
        if idx.size:
            viol_w = float(np.abs(w[idx]).max())
        if len(S) < self.n:
            out = [k for k in range(self.n) if k not in S]
            viol_w = max(viol_w, -float(w[self.normal[out]].min()))
        return max(viol_x / xmax if viol_x > 0.0 else 0.0, viol_w / s_w)

    def finish(
        self, S: tuple[int, ...], T: tuple[int, ...], cand: _Candidate, method: str
    ) -> LCPSolution:
        """Clip round-off negatives of x_n to 0 and package the solution."""
        x, w, res = cand.x.copy(), cand.w, cand.residual
        xn = x[self.normal]
        if (xn < 0.0).any():
            x[self.normal] = np.maximum(xn, 0.0)
            w = self.G @ x + self.b
            res = self.residual(S, T, x, w)
        return LCPSolution(x, w.copy(), tuple(sorted(S)), res, method, tuple(sorted(T)))

    def fail(self) -> SolverError:
        res, S, T = self.best
        b_txt = np.array2string(self.b, precision=6, max_line_width=200)
        where = f"active contacts {S}" + (f", tangential-only {T}" if T else "")
        hint = (
            "G may be indefinite, or b may violate a constraint that no impulse can correct"
            if self.rows.frictionless
            else "with sticking rows this happens when stopping a contact's slip would need "
            "a pulling normal impulse (Painleve-type); on_infeasible='relax' returns the "
            "infinite-friction limit instead"
        )
        return SolverError(
            f"contact LCP: no valid active set for G of size {self.m}x{self.m} "
            f"({self.n} contacts), b = {b_txt}; best scaled residual {res:.3g} "
            f"with {where} (tol {self.tol:g}). {hint}"
        )


def _chain(prob: _Problem, solvers) -> LCPSolution | None:
    """Run solvers in order until one returns a valid solution."""
    for solver in solvers:
        if solver is _enumerate and prob.n > ENUMERATE_MAX:
            continue
        out = solver(prob)
        if out is not None:
            return out
    return None


def _enumerate(prob: _Problem) -> LCPSolution | None:
    """All active sets, most contacts first, lexicographic within a size.

    Most-first makes the choice deterministic when several sets are valid
    (sticking rows, redundant rows): contacts stay engaged where they can,
    and redundant contacts share the load (min-norm x) instead of one of
    them taking it all.
    """
    for size in range(prob.n, -1, -1):
        for S in itertools.combinations(range(prob.n), size):
            cand = prob.try_set(S)
            if cand.valid:
                return prob.finish(S, (), cand, "enumerate")
    return None


def _enumerate_relaxed(prob: _Problem) -> LCPSolution | None:
    """Three-state search: fewest tangential-only contacts T first (|T| >= 1,
    since |T| = 0 was searched already), then most active contacts, then
    lexicographic."""
    sticking = [k for k in range(prob.n) if prob.tang[k].size]
    for t in range(1, len(sticking) + 1):
        for T in itertools.combinations(sticking, t):
            rest = [k for k in range(prob.n) if k not in T]
            for size in range(len(rest), -1, -1):
                for S in itertools.combinations(rest, size):
                    cand = prob.try_set(S, T)
                    if cand.valid:
                        return prob.finish(S, T, cand, "relaxed")
    return None


def _pivot(prob: _Problem, start: tuple[int, ...] | None = None) -> LCPSolution | None:
    """Murty's least-index principal pivoting, from "all active" by default.

    Each step toggles the lowest-index contact that violates its condition
    (x_n < 0 in the set, or w_n < 0 outside it). For frictionless rows and a
    positive definite G (a P-matrix) this ends after finitely many steps from
    any start (Murty 1974). A solution then exists (a positive definite
    matrix is a P-matrix) and is unique: if (x, w) and
    (x', w') both solve the LCP, then
    0 < (x - x')^T G (x - x') = (x - x')^T (w - w') = -x^T w' - x'^T w <= 0
    unless x = x' (using x^T w = x'^T w' = 0 and x, w, x', w' >= 0).
    With sticking rows this argument fails (a contact's x_t is free in one
    set and 0 in another) and pivoting may cycle; a repeated set stops it.
    """
    n = prob.n
    S = set(range(n)) if start is None else set(start)
    seen: set[tuple[int, ...]] = set()
    normal = prob.normal
    max_steps = 4 * n * n + 2 ** min(n, 12)
    for _ in range(max_steps):
        key = tuple(sorted(S))
        if key in seen:
            return None
        seen.add(key)
        cand = prob.try_set(key)
        if cand.valid:
            return prob.finish(key, (), cand, "pivot")
        x, w = cand.x, cand.w
        xmax = float(np.max(np.abs(x))) if x.size else 0.0
        s_w = prob.bmax + prob.gmax * xmax
        k_bad = None
        for k in range(n):
            if k in S:
                if x[normal[k]] < -prob.tol * xmax:
                    k_bad = k
                    break
            elif w[normal[k]] < -prob.tol * s_w:
                k_bad = k
                break
        if k_bad is None:
            # Invalid only through the equalities (inconsistent singular set):
            # pivoting has no rule for that.
            return None
        S ^= {k_bad}
    return None


def _nnls(prob: _Problem) -> LCPSolution | None:
    """Frictionless rows: min ½ x^T G x + b^T x, x >= 0, as an NNLS.

    With G = L L^T: ½ x^T G x + b^T x = ½ ||L^T x + L^-1 b||^2 - const. The
    NNLS support is then polished by an exact set solve and checked; if it
    fails (degenerate support), pivoting restarts from it.
    """
    G, b = prob.G, prob.b
    try:
        L = np.linalg.cholesky(G)
        F, c = L.T, -np.linalg.solve(L, b)
    except np.linalg.LinAlgError:
        # Semidefinite: G = F^T F from the eigendecomposition; b's component
        # in the null space is dropped, so this is only a guess to polish.
        lam, V = np.linalg.eigh(G)
        keep = lam > _EIG_RCOND * max(float(lam[-1]), 0.0)
        if not keep.any():
            return None
        F = np.sqrt(lam[keep])[:, None] * V[:, keep].T
        c = -(V[:, keep].T @ b) / np.sqrt(lam[keep])
    try:
        x, _ = nnls(F, c)
    except (RuntimeError, ValueError):  # iteration limit, degenerate input
        return None
    S = tuple(int(k) for k in np.flatnonzero(x[prob.normal] > 0.0))
    cand = prob.try_set(S)
    if cand.valid:
        return prob.finish(S, (), cand, "nnls")
    return _pivot(prob, start=S)


def _definite(Gs: np.ndarray) -> tuple[np.ndarray | None, bool]:
    """Cholesky factor (None if it fails), and whether every pivot is above
    _PIVOT_RTOL * the largest."""
    try:
        L = np.linalg.cholesky(Gs)
    except np.linalg.LinAlgError:
        return None, False
    piv = np.diag(L) ** 2
    return L, bool(piv.min() > _PIVOT_RTOL * piv.max())


def _min_norm(Gs: np.ndarray, rhs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Minimum-norm least-squares solution of Gs x = rhs (Gs symmetric PSD).

    Returns:
        ``(x, N)``: ``x`` drops eigenvalues below _EIG_RCOND * the largest;
        ``N`` is an orthonormal basis of the dropped (numerical null) space.
    """
    lam, V = np.linalg.eigh(Gs)
    keep = lam > _EIG_RCOND * max(float(lam[-1]), 0.0)
    Vk = V[:, keep]
    return Vk @ ((Vk.T @ rhs) / lam[keep]), V[:, ~keep]


def _ldp(E: np.ndarray, f: np.ndarray) -> np.ndarray | None:
    """Least-distance programming: min ||z|| subject to E z >= f.

    Lawson & Hanson (1974, ch. 23): solve the NNLS
    min ||[E^T; f^T] u - (0, ..., 0, 1)||, u >= 0, with residual r; the
    problem is infeasible if r = 0, else z = -r[:-1] / r[-1].
    """
    p, r = E.shape
    H = np.vstack([E.T, f[None, :]])
    d = np.zeros(r + 1)
    d[-1] = 1.0
    try:
        u, _ = nnls(H, d)
    except (RuntimeError, ValueError):
        return None
    res = H @ u - d
    if abs(res[-1]) < 1e-12:
        return None
    return -res[:-1] / res[-1]


def _as_real_array(a: object, name: str) -> np.ndarray:
    """``a`` as a float array; InvalidInputError if it is not real numbers."""
    try:
        arr = np.asarray(a)
    except Exception as exc:  # noqa: BLE001 - ragged lists and the like
        raise InvalidInputError(f"{name} must be an array of real numbers; got {a!r}") from exc
    if arr.dtype.kind not in "biuf":
        raise InvalidInputError(
            f"{name} must be an array of real numbers; got dtype {arr.dtype}: {a!r}"
        )
    return arr.astype(float, copy=False)


def _show(v: object) -> str:
    """repr of a value, numpy scalars shown as plain Python numbers."""
    return repr(v.item() if isinstance(v, np.generic) else v)


def _as_index(i: object, name: str) -> int:
    if isinstance(i, bool) or not isinstance(i, (int, np.integer)) or i < 0:
        raise InvalidInputError(f"{name}: row index {_show(i)} is not a non-negative integer")
    return int(i)


def _as_vector(v: object, name: str, m: int) -> np.ndarray:
    arr = _as_real_array(v, name)
    if arr.shape != (m,):
        raise InvalidInputError(f"{name} has shape {arr.shape}; expected ({m},) to match the rows")
    if not np.isfinite(arr).all():
        i = int(np.flatnonzero(~np.isfinite(arr))[0])
        raise InvalidInputError(f"{name}[{i}] is {float(arr[i])!r}; entries must be finite")
    return arr


def _validate(G, b, rows: ContactRows, tol: float, method: str) -> tuple[np.ndarray, np.ndarray]:
    if not isinstance(rows, ContactRows):
        raise InvalidInputError(f"rows must be a ContactRows; got {type(rows).__name__}")
    if method not in _METHODS:
        raise InvalidInputError(f"method {method!r} is not known; valid: {', '.join(_METHODS)}")
    if not (isinstance(tol, (int, float, np.floating)) and np.isfinite(tol) and tol > 0):
        raise InvalidInputError(f"tol is {_show(tol)}; it must be a positive finite number")
    G = _as_real_array(G, "G")
    m = rows.n_rows
    if G.shape != (m, m):
        raise InvalidInputError(
            f"G has shape {G.shape}; expected ({m}, {m}) for {rows.n_contacts} contacts "
            f"with {m} rows"
        )
    if not np.isfinite(G).all():
        i, j = np.argwhere(~np.isfinite(G))[0]
        raise InvalidInputError(f"G[{i}, {j}] is {float(G[i, j])!r}; entries must be finite")
    b = _as_vector(b, "b", m)
    if m:
        gmax = float(np.abs(G).max())
        asym = np.abs(G - G.T)
        if asym.max() > 1e-8 * gmax:
            i, j = np.unravel_index(np.argmax(asym), G.shape)
            raise InvalidInputError(
                f"G is not symmetric: G[{i}, {j}] = {float(G[i, j])!r} but G[{j}, {i}] = {float(G[j, i])!r}"
            )
        d = G.diagonal()
        if d.min() < -1e-12 * gmax:
            k = int(np.argmin(d))
            raise InvalidInputError(
                f"G[{k}, {k}] = {float(d[k])!r} is negative; a Delassus matrix is positive semidefinite"
            )
        G = 0.5 * (G + G.T)
    return G, b
