"""The derivatives of a contact mode's accelerations and forces in the state and in a
generalised force, by the implicit function theorem on its KKT system
(`contactdiff.dynamics.mode` solves the system and calls this with its factors)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from .mode_solution import ModeDerivatives, ModeSolution

if TYPE_CHECKING:
    from ..model.scene import Scene


def kkt_derivatives(
    scene: Scene, model, data, kin, q, v, t, sol: ModeSolution, contacts, A, Minv, MinvAT, MinvFT, G, slips, solve, U
) -> ModeDerivatives:
    """Differentiate the KKT system implicitly.

    ``sol`` is the mode's solution at ``(q, v)`` and time ``t`` (s), ``kin`` the
    kinematics cache there and ``data`` Pinocchio's data of ``model``; ``A`` the
    constraint rows, ``Minv`` ``M^-1``, ``MinvAT``/``MinvFT`` ``M^-1 A^T``/``M^-1 F^T``,
    ``G`` the force problem's matrix, ``slips`` its `SlipRow`s, ``solve`` its
    `contactdiff.dynamics.mode_forces.force_solver` and ``U`` a basis of ``range(A)``
    or None (all from the solve).

    With ``r(q, v, ddq) = M ddq + nle`` (RNEA), both sides differentiated give

        [M  -A^T] [d ddq]   [R = dtau - dr/d(q,v)|ddq + d(A^T lam)/dq]
        [A   0  ] [d lam] = [C = -d drift - d(A ddq)/dq|ddq           ]

    solved by the Schur complement on the Delassus matrix ``G = A M^-1 A^T``:
    ``G d lam = C - A M^-1 R`` and ``d ddq = M^-1 (R + A^T d lam)``. A slipping
    contact's force row ``F = A_n - μ s^T A_T`` replaces ``A^T`` by ``F^T`` on the
    force side (``G = A M^-1 F^T``), and ``R`` gets the derivative of ``F^T lam``,
    through the rows at fixed ``s`` and through ``s(q, v)`` (`SlipRow.force_derivatives`).
    Dependent rows (``U`` a basis of ``range(A)``) add the turn of ``range(A)``:
    ``(I - U Uᵀ) dλ = (I - U Uᵀ) d(A w)/dq``, ``w = A⁺ λ`` (`contactdiff.dynamics.redundant`).
    """
    nv = model.nv
    dtau_dq, dtau_dv = scene.tau_derivatives(kin, t)
    dr_dq, dr_dv, _ = pin.computeRNEADerivatives(model, data, q, v, sol.ddq)
    R = np.hstack((dtau_dq - dr_dq, dtau_dv - dr_dv))
    C = np.zeros((A.shape[0], 2 * nv))
    slipping = {slip.row: slip for slip in slips}
    for c, s in zip(contacts, sol.row_slices):
        slip = slipping.get(s.start)
        if slip is None:
            R[:, :nv] += c.rows_transpose_dq(kin, sol.forces[s])
        else:
            R += slip.force_derivatives(kin, sol.forces[s.start])
        drift_dq, drift_dv = c.drift_derivatives(kin)
        C[s, :nv] = -drift_dq - c.rows_times_dq(kin, sol.ddq)
        C[s, nv:] = -drift_dv
    MinvR = Minv @ R
    rhs = C - A @ MinvR
    if U is not None:
        w = np.linalg.lstsq(A, sol.forces, rcond=None)[0]
        turn = np.zeros((A.shape[0], 2 * nv))
        for c, s in zip(contacts, sol.row_slices):
            turn[s, :nv] = c.rows_times_dq(kin, w)
        turn -= U @ (U.T @ turn)
        dlam = solve(G, rhs - G @ turn) + turn
    else:
        dlam = solve(G, rhs)
    dddq = MinvR + MinvFT @ dlam
    # a generalised force d: lam moves by -G^-1 A M^-1 d, ddq by M^-1 (d + F^T dlam)
    dlam_dtau = -solve(G, MinvAT.T)
    return ModeDerivatives(dddq[:, :nv], dddq[:, nv:], dlam[:, :nv], dlam[:, nv:], Minv + MinvFT @ dlam_dtau, dlam_dtau)
