"""Flow in a contact mode: accelerations, contact forces and their derivatives.

In mode ``J`` (the set of active contacts) the rows ``A`` of the active contacts
(normal, plus tangents for sticking contacts) are held at zero acceleration:

    M ddq - A^T lam = tau - nle,      A ddq + drift = 0,

with ``M`` the mass matrix (armature included), ``nle`` Coriolis + gravity,
``tau`` the scene's efforts and ``lam`` the row forces (N; normal forces push
when positive). The Delassus matrix ``G = A M^-1 A^T`` is symmetric positive
definite when the rows are independent; with redundant rows the minimum-norm
forces are returned.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from .errors import SolverError
from .scene import Scene


@dataclass
class ModeSolution:
    """Accelerations and forces of one mode at one state.

    Attributes:
        ddq: joint accelerations (nv,), tangent space.
        forces: row forces (n_rows,), rows stacked in the order of ``active``.
        active: indices of the active contacts.
        row_slices: for each active contact, its slice of ``forces``.
    """

    ddq: np.ndarray
    forces: np.ndarray
    active: tuple[int, ...]
    row_slices: tuple[slice, ...]

    def normal_forces(self) -> np.ndarray:
        """Normal force of each active contact (N), in the order of ``active``."""
        return np.array([self.forces[s.start] for s in self.row_slices])


@dataclass
class ModeDerivatives:
    """Derivatives of a `ModeSolution` in the tangent space (each column a perturbation)."""

    ddq_dq: np.ndarray
    ddq_dv: np.ndarray
    forces_dq: np.ndarray
    forces_dv: np.ndarray


class ModeDynamics:
    """Evaluates the flow of a scene in any contact mode.

    Uses the scene's kinematics cache and a ``pinocchio.Data`` of its own for the
    dynamics; not thread safe (one instance per thread, each with its own scene).
    """

    def __init__(self, scene: Scene):
        self.scene = scene
        self.model = scene.model
        self.kin = scene.kinematics
        self.data = self.model.createData()

    def _rows(self, active: Sequence[int]):
        contacts = [self.scene.contacts[i] for i in active]
        slices, start = [], 0
        for c in contacts:
            slices.append(slice(start, start + c.n_rows))
            start += c.n_rows
        return contacts, tuple(slices)

    def solve(self, q: np.ndarray, v: np.ndarray, t: float, active: Sequence[int] = (),
              *, derivatives: bool = False) -> ModeSolution | tuple[ModeSolution, ModeDerivatives]:
        """Accelerations and forces in mode ``active`` at ``(q, v, t)``.

        Args:
            q, v: state (configuration, tangent velocity).
            t: time (s), passed to time-dependent efforts.
            active: indices of the active contacts (scene order).
            derivatives: also return the `ModeDerivatives`.
        """
        active = tuple(active)
        kin = self.kin
        kin.update(q, v, derivatives=derivatives)
        tau = self.scene.tau(kin, t)
        contacts, slices = self._rows(active)
        if not contacts:  # free flow: ABA, O(n) and one call
            ddq = pin.aba(self.model, self.data, q, v, tau)
            A, forces = np.zeros((0, self.model.nv)), np.zeros(0)
        else:
            Minv = pin.computeMinverse(self.model, self.data, q)  # symmetric copy
            a_free = Minv @ (tau - pin.nonLinearEffects(self.model, self.data, q, v))
            A = np.vstack([c.rows(kin) for c in contacts])
            drift = np.concatenate([c.drift(kin) for c in contacts])
            MinvAT = Minv @ A.T
            forces = _solve_spd(A @ MinvAT, -(drift + A @ a_free))
            ddq = a_free + MinvAT @ forces
        solution = ModeSolution(ddq, forces, active, slices)
        if not derivatives:
            return solution
        return solution, self._derivatives(q, v, t, solution, contacts, A, pin.crba(self.model, self.data, q))

    def _derivatives(self, q, v, t, sol: ModeSolution, contacts, A, M) -> ModeDerivatives:
        """Differentiate the KKT system implicitly.

        With ``r(q, v, ddq) = M ddq + nle`` (RNEA), both sides differentiated give
            [M  -A^T] [d ddq]   [dtau - dr/d(q,v)|ddq + d(A^T lam)/dq]
            [A   0  ] [d lam] = [-d drift - d(A ddq)/dq|ddq           ]
        """
        kin, nv = self.kin, self.model.nv
        dtau_dq, dtau_dv = self.scene.tau_derivatives(kin, t)
        dr_dq, dr_dv, _ = pin.computeRNEADerivatives(self.model, self.data, q, v, sol.ddq)
        rhs_q = dtau_dq - dr_dq
        rhs_v = dtau_dv - dr_dv
        m = A.shape[0]
        con_q, con_v = np.zeros((m, nv)), np.zeros((m, nv))
        for c, s in zip(contacts, sol.row_slices):
            rhs_q += c.rows_transpose_dq(kin, sol.forces[s])
            drift_dq, drift_dv = c.drift_derivatives(kin)
            con_q[s] = -drift_dq - c.rows_times_dq(kin, sol.ddq)
            con_v[s] = -drift_dv
        K = np.block([[M, -A.T], [A, np.zeros((m, m))]])
        try:
            X = np.linalg.solve(K, np.block([[rhs_q, rhs_v], [con_q, con_v]]))
        except np.linalg.LinAlgError:
            X = np.linalg.lstsq(K, np.block([[rhs_q, rhs_v], [con_q, con_v]]), rcond=None)[0]
        return ModeDerivatives(X[:nv, :nv], X[:nv, nv:], X[nv:, :nv], X[nv:, nv:])


def _solve_spd(G: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Solve ``G x = b`` for a symmetric positive (semi)definite Delassus matrix.

    Cholesky when ``G`` is definite; otherwise (redundant rows) the minimum-norm
    least-squares solution, which is the physically chosen force distribution
    of a redundant rigid contact set. (numpy's Cholesky, not scipy's: the
    latter's input checks cost more than the factorisation of these small G.)
    """
    try:
        L = np.linalg.cholesky(G)
        return np.linalg.solve(L.T, np.linalg.solve(L, b))
    except np.linalg.LinAlgError:
        x, *_ = np.linalg.lstsq(G, b, rcond=None)
        if not np.all(np.isfinite(x)):
            raise SolverError(f"contact forces are not finite for Delassus matrix {G} and b={b}") from None
        return x
