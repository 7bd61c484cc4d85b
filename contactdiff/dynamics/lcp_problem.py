"""The contact complementarity problem's data: rows of each contact, the solution,
the problem a solver works on, tolerances, and the validation of the inputs.

The mathematics is in `contactdiff.dynamics.complementarity`, which solves it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from scipy.linalg import cho_solve
from scipy.optimize import nnls

from ..errors import InvalidInputError, SolverError

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
# EIG_RCOND * largest (exact redundancy leaves ~1e-16), which gives the
# minimum-norm solution; if that is not valid but Cholesky succeeded (an
# ill-conditioned, not redundant, set) the plain solve is tried as well.
# Pivots bound the eigenvalues from above, so the pivot test is the more
# cautious one of the two.
_PIVOT_RTOL = 1e-10
EIG_RCOND = 1e-12

#: The methods of `contactdiff.dynamics.complementarity.solve_contact_lcp`.
LCP_METHODS = ("auto", "enumerate", "pivot", "nnls")


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
    if TYPE_CHECKING:  # set by __post_init__, not a field (annotated for the type checker only)
        _rows_of: tuple[np.ndarray, ...] = field(init=False)

    def __post_init__(self) -> None:
        normal = tuple(_as_index(i, "ContactRows.normal") for i in self.normal)
        tang = tuple(tuple(_as_index(i, "ContactRows.tangential") for i in t) for t in self.tangential)
        if len(tang) != len(normal):
            raise InvalidInputError(
                f"ContactRows: {len(normal)} normal rows but {len(tang)} tangential "
                f"groups; need one group (possibly empty) per contact"
            )
        used = list(normal) + [i for t in tang for i in t]
        if sorted(used) != list(range(len(used))):
            raise InvalidInputError(
                f"ContactRows: rows must be 0..{len(used) - 1}, each once; got normal={normal}, tangential={tang}"
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
                raise InvalidInputError(f"ContactRows.from_sizes: size of contact {k} is {_show(s)}; valid: 1, 2, 3")
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

    @property
    def contact_rows(self) -> tuple[np.ndarray, ...]:
        """Row indices of each contact, normal first (one index array per contact, formed
        once; not to be written)."""
        return self._rows_of

    def rows_of(self, contacts: Sequence[int]) -> np.ndarray:
        """Row indices of the given contacts (each contact's normal row first)."""
        if len(contacts) == 0:
            return np.empty(0, dtype=np.intp)
        return np.concatenate([self._rows_of[k] for k in contacts])


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


# --------------------------------------------------------------------------
# internals


@dataclass
class _Candidate:
    x: np.ndarray  # full-length x (zeros off the set)
    w: np.ndarray  # G x + b
    residual: float
    valid: bool
    singular: bool  # the set matrix was rank deficient


class LCPProblem:
    """One validated problem: set solves, checks, and the best failure seen.

    A set is ``(S, T)``: ``S`` the active contacts, ``T`` the tangential-only
    contacts (only with ``on_infeasible="relax"``; empty otherwise).
    """

    def __init__(self, G: np.ndarray, b: np.ndarray, rows: ContactRows, tol: float):
        self.G, self.b, self.rows, self.tol = G, b, rows, tol
        self.m, self.n = G.shape[0], rows.n_contacts
        self.normal = np.array(rows.normal, dtype=np.intp)
        self.blocks = rows.contact_rows
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
        """The set's solution ``xs`` on rows ``idx`` extended by zeros, its ``w`` and check."""
        x = np.zeros(self.m)
        x[idx] = xs
        w = self.G @ x + self.b
        res = self.residual(S, T, x, w)
        return _Candidate(x, w, res, res <= self.tol, singular)

    def store(self, key, cand: _Candidate) -> _Candidate:
        """Keep the candidate of set ``key`` (and note it if it is the best so far)."""
        self.cache[key] = cand
        if cand.residual < self.best[0]:
            self.best = (cand.residual, *key)
        return cand

    def residual(self, S: tuple[int, ...], T: tuple[int, ...], x: np.ndarray, w: np.ndarray) -> float:
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

    def finish(self, S: tuple[int, ...], T: tuple[int, ...], cand: _Candidate, method: str) -> LCPSolution:
        """Clip round-off negatives of x_n to 0 and package the solution."""
        x, w, res = cand.x.copy(), cand.w, cand.residual
        xn = x[self.normal]
        if (xn < 0.0).any():
            x[self.normal] = np.maximum(xn, 0.0)
            w = self.G @ x + self.b
            res = self.residual(S, T, x, w)
        return LCPSolution(x, w.copy(), tuple(sorted(S)), res, method, tuple(sorted(T)))

    def fail(self) -> SolverError:
        """The error for no valid set: the best candidate seen and a hint why."""
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
        ``(x, N)``: ``x`` drops eigenvalues below EIG_RCOND * the largest;
        ``N`` is an orthonormal basis of the dropped (numerical null) space.
    """
    lam, V = np.linalg.eigh(Gs)
    keep = lam > EIG_RCOND * max(float(lam[-1]), 0.0)
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


def as_real_array(a: object, name: str) -> np.ndarray:
    """``a`` as a float array; InvalidInputError if it is not real numbers."""
    try:
        arr = np.asarray(a)
    except Exception as exc:  # noqa: BLE001 - ragged lists and the like
        raise InvalidInputError(f"{name} must be an array of real numbers; got {a!r}") from exc
    if arr.dtype.kind not in "biuf":
        raise InvalidInputError(f"{name} must be an array of real numbers; got dtype {arr.dtype}: {a!r}")
    return arr.astype(float, copy=False)


def _show(v: object) -> str:
    """repr of a value, numpy scalars shown as plain Python numbers."""
    return repr(v.item() if isinstance(v, np.generic) else v)


def _as_index(i: object, name: str) -> int:
    if isinstance(i, bool) or not isinstance(i, (int, np.integer)) or i < 0:
        raise InvalidInputError(f"{name}: row index {_show(i)} is not a non-negative integer")
    return int(i)


def as_row_vector(v: object, name: str, m: int) -> np.ndarray:
    """``v`` as a finite float vector of the ``m`` rows; InvalidInputError naming ``name``
    and the bad entry otherwise."""
    arr = as_real_array(v, name)
    if arr.shape != (m,):
        raise InvalidInputError(f"{name} has shape {arr.shape}; expected ({m},) to match the rows")
    if not np.isfinite(arr).all():
        i = int(np.flatnonzero(~np.isfinite(arr))[0])
        raise InvalidInputError(f"{name}[{i}] is {float(arr[i])!r}; entries must be finite")
    return arr


def validate_lcp(G, b, rows: ContactRows, tol: float, method: str) -> tuple[np.ndarray, np.ndarray]:
    """The inputs of a contact problem on ``rows`` checked: ``method`` one of the LCP's,
    ``tol`` positive and finite, the Delassus matrix ``G`` (m, m) finite, symmetric to a
    relative 1e-8 and with a non-negative diagonal, ``b`` (m,) finite. Returns ``G``
    symmetrised and ``b`` as float arrays; InvalidInputError naming the bad value otherwise."""
    if not isinstance(rows, ContactRows):
        raise InvalidInputError(f"rows must be a ContactRows; got {type(rows).__name__}")
    if method not in LCP_METHODS:
        raise InvalidInputError(f"method {method!r} is not known; valid: {', '.join(LCP_METHODS)}")
    if not (isinstance(tol, (int, float, np.floating)) and np.isfinite(tol) and tol > 0):
        raise InvalidInputError(f"tol is {_show(tol)}; it must be a positive finite number")
    G = as_real_array(G, "G")
    m = rows.n_rows
    if G.shape != (m, m):
        raise InvalidInputError(
            f"G has shape {G.shape}; expected ({m}, {m}) for {rows.n_contacts} contacts with {m} rows"
        )
    if not np.isfinite(G).all():
        i, j = np.argwhere(~np.isfinite(G))[0]
        raise InvalidInputError(f"G[{i}, {j}] is {float(G[i, j])!r}; entries must be finite")
    b = as_row_vector(b, "b", m)
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
