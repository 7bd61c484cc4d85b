"""Forces of redundant contact rows: the rigid limit of equal compliant supports.

Four corners of a box's face on a plane, the four sole corners of a flat foot,
or a sticking contact and the ground both holding the same motion give a mode
whose rows ``A`` (k × nv) have rank ``r < k``: rigid-body mechanics fixes the
motion's constrained part but leaves the forces undetermined along
``null(Aᵀ)`` (a load pattern that pushes on the body with zero net generalised
force, such as (+, -, +, -) over a face's corners). With sliding friction the
motion itself depends on that choice: a corner's friction is proportional to
its own load.

**The principle.** The forces are the limit, as the compliance ``ε`` goes to
zero, of the mode's problem with equal compliance at every row (``G λ = b``
relaxed to ``(G + ε I) λ = b``, the constraint-force mixing of compliant
contact models: each row yields by ``ε`` times its force). Its limit is the
solution that lies in ``range(A)``: the loads are stiffness times a
*compatible* deflection ``A δq`` of the supports. For a symmetric ``G =
A M⁻¹ Aᵀ`` (sticking and frictionless rows) it is the least-norm force, the
least elastic energy of the supports (Menabrea's principle); with sliding rows
(``G = A M⁻¹ Fᵀ`` not symmetric) it is the same compatible-deflection load,
which least norm is not. On a face it is the load linear in the corners'
positions (a plane of deflection), so a sliding box's front/back shift is the
one its pitch balance forces and the left/right split is even.

With ``U`` an orthonormal basis of ``range(A)`` (``k × r``), ``λ = U y`` and
``Uᵀ G U y = Uᵀ b``: ``r`` equations for ``r`` unknowns. Where ``λ`` depends on
the state, its derivative adds the turn of ``range(A)``:
``(I - U Uᵀ) dλ = (I - U Uᵀ) d(A w)`` with ``w = A⁺ λ`` (zero when the rows'
dependence is fixed, as for the corners of one rigid face).

**Impulses** follow the same principle (`contactdiff.dynamics.frictional_impact`):
the impulses on a candidate's equality rows lie in the range of those rows, the
range of their Delassus block ``G_ee = A_e M⁻¹ A_eᵀ`` (`gram_range_basis`).

**When rows are redundant** is decided from ``A``'s singular values: rank
``r`` counts those above `RANK_TOL` times the largest. The rows of one rigid
face are dependent to round-off (1e-16 relative); rows that are merely close
to dependent (two feet 1 µm apart) are a badly conditioned but determined set
and keep the exact solve. From a Delassus block (its eigenvalues are squares of
singular values, and its round-off is 1e-16 of its largest) the threshold is
`GRAM_RANK_TOL`.
"""

from __future__ import annotations

import numpy as np

from ..errors import SolverError

RANK_TOL = 1e-9
"""Singular values of the rows ``A`` below this share of the largest count as zero
(round-off of dependent rows is ~1e-16; well-posed contact sets are above ~1e-3)."""


GRAM_RANK_TOL = 1e-12
"""Eigenvalues of a Delassus block below this share of the largest count as zero:
dependent rows leave ~1e-16 (round-off); 1e-12 is a singular-value ratio of 1e-6 of
the rows, far below that of a well-posed contact set."""


def gram_range_basis(G: np.ndarray) -> np.ndarray | None:
    """Orthonormal basis (k × r) of the range of a symmetric positive semidefinite
    Delassus block ``G`` when it is singular (rank ``r < k``), None otherwise."""
    k = len(G)
    if k == 0:
        return None
    values, vectors = np.linalg.eigh(0.5 * (G + G.T))
    top = values[-1]
    keep = values > GRAM_RANK_TOL * top if top > 0.0 else np.zeros(k, dtype=bool)
    if keep.all():
        return None
    return vectors[:, keep]


def range_basis(A: np.ndarray) -> np.ndarray | None:
    """Orthonormal basis ``U`` (k × r) of ``range(A)`` when the rows of ``A`` are
    dependent (rank ``r < k``), None when they are independent."""
    k, nv = A.shape
    if k == 0:
        return None
    W, s, _ = np.linalg.svd(A, full_matrices=False)
    rank = int(np.sum(s > RANK_TOL * s[0])) if s[0] > 0.0 else 0
    if rank >= k:
        return None
    return W[:, :rank]


def row_rank(A: np.ndarray) -> int:
    """Rank of the rows ``A`` by the rule of `range_basis` (singular values above
    `RANK_TOL` of the largest); 0 for no rows."""
    if A.size == 0:
        return 0
    s = np.linalg.svd(A, compute_uv=False)
    return int(np.sum(s > RANK_TOL * s[0])) if s[0] > 0.0 else 0


def solve_in_range(G: np.ndarray, b: np.ndarray, U: np.ndarray) -> np.ndarray:
    """The forces ``λ = U y`` in ``range(A)`` with ``Uᵀ (G λ - b) = 0`` (module doc).

    ``b`` may hold several right-hand sides as columns.

    Raises:
        SolverError: the reduced matrix ``Uᵀ G U`` is singular (a sliding problem
            with no unique solution even among compatible loads).
    """
    reduced = U.T @ G @ U
    try:
        y = np.linalg.solve(reduced, U.T @ b)
    except np.linalg.LinAlgError:
        y = None
    if y is None or not np.all(np.isfinite(y)):
        raise SolverError(
            f"the compatible-load problem of redundant contact rows is singular (U^T G U = {reduced.tolist()})"
        )
    return U @ y
