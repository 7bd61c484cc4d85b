"""The guards' terms of a saltation matrix: the gradient ``Dh`` of a touchdown's guard (a
contact's gap) and of a lift-off's (its normal force), and a force guard's explicit time rate
``h_t`` under time-dependent efforts (`contactdiff.integration.sensitivity` forms ``Ξ`` from them).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..dynamics.mode import ModeDynamics


def force_time_rate(dyn: ModeDynamics, q: np.ndarray, v: np.ndarray, t: float, mode: Sequence[int], row: int) -> float:
    """``∂lam_row/∂t`` at fixed state (N/s): the forces are affine in the efforts, so
    it is the forces' response to ``d tau/dt`` alone (exact up to round-off; zero for
    an autonomous scene)."""
    dyn.kin.update(q, v)
    tau_t = dyn.scene.tau_time_derivative(dyn.kin, t)
    if not np.any(tau_t):
        return 0.0
    tau = dyn.scene.tau(dyn.kin, t)
    mode = tuple(mode)
    return float(dyn.solve(q, v, t, mode, tau=tau + tau_t).forces[row] - dyn.solve(q, v, t, mode, tau=tau).forces[row])


def gap_gradient(dyn: ModeDynamics, q: np.ndarray, contact: int) -> np.ndarray:
    """``Dh = [A_i, 0]`` of the touchdown guard of ``contact`` (2nv,)."""
    dyn.kin.update(q, np.zeros(dyn.model.nv))
    return np.concatenate([dyn.contact(contact).rows(dyn.kin)[0], np.zeros(dyn.model.nv)])


def liftoff_guard(
    dyn: ModeDynamics, t: float, q: np.ndarray, v: np.ndarray, mode: Sequence[int], contact: int
) -> tuple[np.ndarray, np.ndarray, float]:
    """The lift-off guard of ``contact`` (a key of ``mode``), its normal force:
    ``(Dh, F-, h_t)`` with ``Dh`` its gradient (2nv,), ``F-`` the field of ``mode``
    and ``h_t`` its explicit time rate (`force_time_rate`)."""
    mode = tuple(mode)
    sol, der = dyn.solve(q, v, t, mode, derivatives=True)
    row = sol.row_slices[mode.index(contact)].start
    Dh = np.concatenate([der.forces_dq[row], der.forces_dv[row]])
    return Dh, np.concatenate([v, sol.ddq]), force_time_rate(dyn, q, v, t, mode, row)
