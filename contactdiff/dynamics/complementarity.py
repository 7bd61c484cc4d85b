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

import numpy as np
from scipy.optimize import nnls

from ..errors import InvalidInputError
from .lcp_problem import (
    AUTO_ENUMERATE_MAX,
    DEFAULT_TOL,
    EIG_RCOND,
    ENUMERATE_MAX,
    LCP_METHODS,
    RELAX_ENUMERATE_MAX,
    ContactRows,
    LCPProblem,
    LCPSolution,
    as_real_array,
    as_row_vector,
    validate_lcp,
)

__all__ = [
    "ContactRows",
    "LCPSolution",
    "impact_rhs",
    "solve_contact_lcp",
    "DEFAULT_TOL",
    "AUTO_ENUMERATE_MAX",
    "ENUMERATE_MAX",
    "RELAX_ENUMERATE_MAX",
]


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
    u = as_row_vector(A_v_minus, "A_v_minus", rows.n_rows)
    e = as_real_array(restitution, "restitution")
    n = rows.n_contacts
    if e.ndim == 0:
        e_c = np.full(n, float(e))
    elif e.shape == (n,):
        e_c = e
    elif e.shape == (rows.n_rows,):
        e_c = e[list(rows.normal)]
    else:
        raise InvalidInputError(
            f"restitution has shape {e.shape}; valid: scalar, ({n},) per contact or ({rows.n_rows},) per row"
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
    G, b = validate_lcp(G, b, rows, tol, method)
    if on_infeasible not in ("raise", "relax"):
        raise InvalidInputError(f"on_infeasible is {on_infeasible!r}; valid: 'raise', 'relax'")
    n = rows.n_contacts
    if method == "nnls" and not rows.frictionless:
        raise InvalidInputError(
            "method='nnls' needs frictionless rows (one row per contact); "
            f"got tangential rows {rows.tangential}; valid methods: {', '.join(LCP_METHODS)}"
        )
    if method == "enumerate" and n > ENUMERATE_MAX:
        raise InvalidInputError(f"method='enumerate' accepts at most {ENUMERATE_MAX} contacts; got {n}")
    if n == 0:
        return LCPSolution(np.zeros(0), np.zeros(0), (), 0.0, "closed-form")
    if n == 1 and rows.n_rows == 1 and G[0, 0] > 0.0:
        # One frictionless contact: x = max(0, -b/G), exact.
        g, b0 = float(G[0, 0]), float(b[0])
        if b0 >= 0.0:
            return LCPSolution(np.zeros(1), b.copy(), (), 0.0, "closed-form")
        x0 = -b0 / g
        w0 = g * x0 + b0
        return LCPSolution(np.array([x0]), np.array([w0]), (0,), abs(w0) / (abs(b0) + g * x0), "closed-form")
    prob = LCPProblem(G, b, rows, tol)
    out = _solve(prob, method)
    if out is None and on_infeasible == "relax" and n <= RELAX_ENUMERATE_MAX:
        out = _enumerate_relaxed(prob)
    if out is None:
        raise prob.fail()
    return out


def _solve(prob: LCPProblem, method: str) -> LCPSolution | None:
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


def _chain(prob: LCPProblem, solvers) -> LCPSolution | None:
    """Run solvers in order until one returns a valid solution."""
    for solver in solvers:
        if solver is _enumerate and prob.n > ENUMERATE_MAX:
            continue
        out = solver(prob)
        if out is not None:
            return out
    return None


def _enumerate(prob: LCPProblem) -> LCPSolution | None:
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


def _enumerate_relaxed(prob: LCPProblem) -> LCPSolution | None:
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


def _pivot(prob: LCPProblem, start: tuple[int, ...] | None = None) -> LCPSolution | None:
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


def _nnls(prob: LCPProblem) -> LCPSolution | None:
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
        keep = lam > EIG_RCOND * max(float(lam[-1]), 0.0)
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
