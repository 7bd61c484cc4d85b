"""The force problem of a contact mode, ``G λ = b``: Cholesky for independent rows
without slip, LU with Painlevé's check where contacts slip, the compatible load
(`contactdiff.dynamics.redundant`) for dependent rows; `contactdiff.dynamics.mode`
assembles ``G`` and ``b``."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from scipy.linalg.lapack import dposv as _dposv

from ..errors import OutsideDomainError, PainleveError, SolverError
from .redundant import solve_in_range
from .slip import painleve_check

if TYPE_CHECKING:
    from ..model.scene import Scene


def force_solver(scene: Scene, slips, U, delassus, contacts):
    """``solve(G, b)`` of the mode's force problem: Cholesky for independent rows
    without slip, LU with Painlevé's check for slipping ones, and the compatible
    load (`contactdiff.dynamics.redundant`) for dependent rows."""
    if U is None:
        if slips:
            return lambda G, b: solve_general(G, b, slips, scene, delassus, contacts)
        return solve_spd

    def solve(G, b):
        if slips:
            painleve_check(G, slips, scene.contact_names)
        try:
            return solve_in_range(G, b, U)
        except SolverError as exc:
            if not slips:
                raise
            names = ", ".join(scene.contacts[s.index].name for s in slips)
            raise PainleveError(
                f"the sliding problem of {names} has no unique force even among the loads "
                f"of compatible support deflections ({exc}): Painlevé's paradox"
            ) from None

    return solve


def solve_general(
    G: np.ndarray, b: np.ndarray, slips, scene, delassus: np.ndarray | None = None, contacts=()
) -> np.ndarray:
    """Solve ``G x = b`` for the non-symmetric ``G = A M^-1 F^T`` of a mode with slipping
    contacts (LU); a slipping contact whose own block of ``G`` is not positive, or a
    singular ``G``, is Painlevé's paradox (`PainleveError`), unless the rows themselves
    became dependent at this state (``delassus = A M^-1 A^T`` singular in a mode whose
    rows were independent), an `OutsideDomainError` that says so."""
    painleve_check(G, slips, scene.contact_names)
    try:
        x = np.linalg.solve(G, b)
    except np.linalg.LinAlgError:
        x = None
    if x is None or not np.all(np.isfinite(x)):
        names = ", ".join(scene.contacts[s.index].name for s in slips)
        try:
            rank = np.linalg.matrix_rank(delassus) if delassus is not None else len(G)
        except np.linalg.LinAlgError:  # not finite: a trial stage far outside the mode's domain
            raise OutsideDomainError(
                f"the sliding problem of {names} has no finite solution at this state "
                "(its Delassus matrix is not finite)"
            ) from None
        if rank < len(G):
            held = ", ".join(dict.fromkeys(c.name for c in contacts))
            # rows of distinct contacts that were independent where the mode began become dependent
            # only at states far from it (two corners of an edge, the edge along the normal): a
            # trial stage's, outside the mode's domain, which the stepper answers with a shorter step
            raise OutsideDomainError(
                f"the rows of contacts {held} are dependent at this state (rank {rank} of {len(G)}) but "
                f"were not where the mode began, so the friction of sliding {names} has no unique force "
                "(rows that hold the same motion everywhere, as a face's corners, are solved by the "
                "compatible-load principle: contactdiff.dynamics.redundant)"
            )
        raise PainleveError(
            f"the sliding problem of {names} is singular (G = A M^-1 F^T = {G.tolist()}): "
            "no force makes the contacts' normal accelerations zero (Painlevé's paradox)"
        )
    return x


def solve_spd(G: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Solve ``G x = b`` for a symmetric positive (semi)definite Delassus matrix.

    Cholesky (LAPACK ``dposv``, called directly: numpy's and scipy's wrappers
    cost ten times the factorisation of these small G) when ``G`` is definite;
    otherwise (rows that became dependent at this state, not where the mode began)
    the minimum-norm least-squares solution. Modes of dependent rows solve by
    `contactdiff.dynamics.redundant` instead.
    """
    _, x, info = _dposv(G, b, lower=1)
    if info == 0:
        return x
    x, *_ = np.linalg.lstsq(G, b, rcond=None)
    if not np.all(np.isfinite(x)):
        raise SolverError(f"contact forces are not finite for Delassus matrix {G} and b={b}") from None
    return x
