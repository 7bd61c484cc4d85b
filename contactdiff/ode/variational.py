"""The flow Jacobian's linear algebra of a stepper: the field's Jacobian from the
user's callbacks (or forward differences), applied to the variational columns, with the
parameters' forcing, and the columns' error scale.

A mixin of `contactdiff.ode.base.Stepper` (its state: ``nv``, ``n``,
``_vs``, ``group``, ``accel``, ``jac``, ``parameter_jac``, ``phi``, ``rtol``,
``_atol_phi``, ``n_jac``, ``n_accel``); the conventions are in its docstring.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from ..errors import IntegrationError, InvalidInputError
from .tolerances import RTOL_FLOOR

if TYPE_CHECKING:
    from .field_types import AccelFn, JacFn, ParameterJacFn
    from .lie import LieGroup

_EPS = np.finfo(float).eps

StageDF = tuple[np.ndarray, np.ndarray, "np.ndarray | None", "np.ndarray | None"]
"""``(J_q, J_v, G, J_p)`` of the tangent-space field at a point (`VariationalAlgebra._stage_df`)."""


class VariationalAlgebra:
    """``DF`` at a point and ``DF @ phi`` (plus the parameters' forcing), for a stepper."""

    if TYPE_CHECKING:  # the state it borrows from Stepper (set there), for the type checker only
        nv: int
        n: int
        _vs: bool
        group: LieGroup
        accel: AccelFn
        jac: JacFn | None
        parameter_jac: ParameterJacFn | None
        phi: np.ndarray | None
        rtol: float
        _atol_phi: float | np.ndarray
        n_jac: int
        n_accel: int

    def _call_jac(self, t: float, q: np.ndarray, v: np.ndarray):
        """``(J_q, J_v)`` from the user's callback, or forward differences if none."""
        self.n_jac += 1
        if self.jac is None:
            return self._fd_jac(t, q, v)
        Jq, Jv = self.jac(t, q, v)
        Jq = np.asarray(Jq, dtype=np.float64)
        Jv = np.asarray(Jv, dtype=np.float64)
        shape = (self.nv, self.nv)
        if Jq.shape != shape or Jv.shape != shape:
            raise InvalidInputError(f"jac must return two {shape} arrays, got shapes {Jq.shape} and {Jv.shape}")
        if not math.isfinite(Jq.sum() + Jv.sum()):  # one reduction; a sum is NaN/inf iff an entry is (or overflows)
            raise IntegrationError(f"jac returned non-finite values at t={float(t)!r}")
        return Jq, Jv

    def _fd_jac(self, t: float, q: np.ndarray, v: np.ndarray):
        """Forward differences in the tangent space (only for Radau's Newton matrix)."""
        nv = self.nv
        a0 = np.asarray(self.accel(t, q, v), dtype=np.float64)
        Jq, Jv = np.empty((nv, nv)), np.empty((nv, nv))
        mq = np.abs(q[:nv]) if self._vs else self.group.magnitude(q)
        for k in range(nv):
            e = math.sqrt(_EPS) * max(1.0, mq[k])
            dq = np.zeros(nv)
            dq[k] = e
            qk = q + dq if self._vs else self.group.integrate(q, dq)
            Jq[:, k] = (np.asarray(self.accel(t, qk, v), dtype=np.float64) - a0) / e
            e = math.sqrt(_EPS) * max(1.0, abs(v[k]))
            vk = v.copy()
            vk[k] += e
            Jv[:, k] = (np.asarray(self.accel(t, q, vk), dtype=np.float64) - a0) / e
        self.n_accel += 1 + 2 * nv
        return Jq, Jv

    def _df(self, t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Full tangent-space Jacobian ``[[G, I], [J_q, J_v]]`` (2nv x 2nv) of the flow."""
        nv = self.nv
        Jq, Jv = self._call_jac(t, q, v)
        A = np.zeros((self.n, self.n))
        A[:nv, nv:] = np.eye(nv)
        if not self._vs:
            A[:nv, :nv] = self.group.velocity_jacobian_q(q, v)
        A[nv:, :nv] = Jq
        A[nv:, nv:] = Jv
        return A

    def _stage_df(self, t: float, q: np.ndarray, v: np.ndarray) -> StageDF:
        """``(J_q, J_v, G, J_p)`` of the tangent-space field at a point; ``G = -ad(v)`` (None on
        vector spaces), ``J_p`` the parameter Jacobian (None without ``parameter_jac``)."""
        Jq, Jv = self._call_jac(t, q, v)
        return (
            Jq,
            Jv,
            None if self._vs else self.group.velocity_jacobian_q(q, v),
            None if self.parameter_jac is None else self._call_parameter_jac(t, q, v),
        )

    def _call_parameter_jac(self, t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        assert self.parameter_jac is not None  # called only with one (`_stage_df`)
        Jp = np.asarray(self.parameter_jac(t, q, v), dtype=np.float64)
        m = 0 if self.phi is None else self.phi.shape[1]
        if Jp.ndim != 2 or Jp.shape[0] != self.nv or Jp.shape[1] > m:
            raise InvalidInputError(
                f"parameter_jac must return an ({self.nv}, p) array with p <= {m} (the "
                f"columns of phi), got shape {Jp.shape}"
            )
        if not math.isfinite(Jp.sum()):
            raise IntegrationError(f"parameter_jac returned non-finite values at t={float(t)!r}")
        return Jp

    def _df_apply(self, df, P: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """``[[G, I], [J_q, J_v]] @ P`` for ``df = (J_q, J_v, G, J_p)``, plus ``J_p`` on the
        acceleration rows of P's last p columns (the parameters' forcing), into ``out`` if given."""
        Jq, Jv, G, Jp = df
        nv = self.nv
        if out is None:
            out = np.empty(P.shape)
        top, bot = P[:nv], P[nv:]
        out[:nv] = bot
        if G is not None:
            out[:nv] += G @ top
        out[nv:] = Jq @ top + Jv @ bot
        if Jp is not None and Jp.shape[1]:
            out[nv:, P.shape[1] - Jp.shape[1] :] += Jp
        return out

    def _phi_scale(self, P0: np.ndarray, P1: np.ndarray) -> np.ndarray:
        """Entrywise ``variational_atol + rtol * max(|phi_n|, |phi_n+1|)``, at least
        `RTOL_FLOOR` times the largest entry of the entry's column.

        The floor: the field's Jacobian mixes a column's rows, so no entry of it is computed
        to better than round-off of the column's largest (a stiff sliding field whose Jacobian
        reaches 1e6 1/s, in a column of 2.5e5 after a Zeno sequence, made the ``atol`` of an
        entry near zero ask for 4e-16 of its column: steps of 6e-8 s and a run out of steps).
        It binds only where ``atol`` asks for less than that."""
        size = np.maximum(np.abs(P0), np.abs(P1))
        scale = self._atol_phi + self.rtol * size
        return np.maximum(scale, RTOL_FLOOR * size.max(axis=0, initial=0.0))
