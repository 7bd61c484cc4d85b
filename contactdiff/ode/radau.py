"""Radau IIA of order 5, implicit, for stiff scenes (simplified Newton, analytic Jacobian)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.linalg.lapack import dgetrf, dgetrs, zgetrf, zgetrs

from ..errors import IntegrationError, InvalidInputError, OutsideDomainError
from .base import Stepper
from .dense import DenseOutput
from .step_control import _EPS, _MAX_FACTOR, _MIN_FACTOR, _rms, _rms_cols
from .variational import StageDF

_S6 = 6**0.5
_RC = np.array([(4 - _S6) / 10, (4 + _S6) / 10, 1.0])
_RA = np.array(
    [
        [(88 - 7 * _S6) / 360, (296 - 169 * _S6) / 1800, (-2 + 3 * _S6) / 225],
        [(296 + 169 * _S6) / 1800, (88 + 7 * _S6) / 360, (-2 - 3 * _S6) / 225],
        [(16 - _S6) / 36, (16 + _S6) / 36, 1 / 9],
    ]
)
_RE = np.array([-13 - 7 * _S6, -13 + 7 * _S6, -1]) / 3
# A^-1 = T diag(mu_real, mu_complex pair) T^-1 decouples the Newton systems.
_MU_REAL = 3 + 3 ** (2 / 3) - 3 ** (1 / 3)
_MU_COMPLEX = 3 + 0.5 * (3 ** (1 / 3) - 3 ** (2 / 3)) - 0.5j * (3 ** (5 / 6) + 3 ** (7 / 6))
_RT = np.array(
    [
        [0.09443876248897524, -0.14125529502095421, 0.03002919410514742],
        [0.25021312296533332, 0.20412935229379994, -0.38294211275726192],
        [1, 1, 0],
    ]
)
_RTI = np.array(
    [
        [4.17871859155190428, 0.32768282076106237, 0.52337644549944951],
        [-4.17871859155190428, -0.32768282076106237, 0.47662355450055044],
        [0.50287263494578682, -2.57192694985560522, 0.59603920482822492],
    ]
)
_RTI_REAL = _RTI[0]
_RTI_COMPLEX = _RTI[1] + 1j * _RTI[2]
# Collocation polynomial in monomials: Z^T P gives y(x) - y_old for x = 1..3 powers.
_RP = np.array(
    [
        [13 / 3 + 7 * _S6 / 3, -23 / 3 - 22 * _S6 / 3, 10 / 3 + 5 * _S6],
        [13 / 3 - 7 * _S6 / 3, -23 / 3 + 22 * _S6 / 3, 10 / 3 - 5 * _S6],
        [1 / 3, -8 / 3, 10 / 3],
    ]
)
_NEWTON_MAXITER = 6
NEWTON_STALL_TOL = 0.03
"""Newton increments (in units of the step's tolerance) below which an iteration that stops
contracting counts as converged: it has reached the round-off of the vector field. Along a
contact's constrained directions the field is a double integrator (no restoring force),
so the noise of the contact forces (~1e-13 m/s² on a standing quadruped) gives Newton
increments of ``h`` times it, which stop contracting: at rest on four feet, a 10-s step
stalls at 1e-3 of the tolerance, far below ``newton_tol`` = 1e-4 at rtol = 1e-8. 0.03 is
the largest Newton error RADAU5 accepts (its ``FNEWT`` at loose tolerances; Hairer &
Wanner, Solving ODEs II, IV.8, take 0.01 to 0.1 of the tolerance)."""
_NOISE_FLOOR = 0.1
"""Newton increments at most this share of ``newton_tol`` that stop contracting (rate >= 1)
are round-off, and the iterate is taken as converged: as if the rate were 0.9, whose
predicted error ``rate / (1 - rate) |dW|`` is then within ``newton_tol``."""
_RETAKE_SPLITS = 6  # halvings of a re-taken step whose Newton fails (64 pieces at most)


def _predict_factor(h_abs, h_abs_old, err, err_old) -> float:
    """Gustafsson's predictive step-size controller (Hairer–Wanner II, IV.8)."""
    if err_old is None or h_abs_old is None or err == 0:
        mult = 1.0
    else:
        mult = h_abs / h_abs_old * (err_old / err) ** 0.25
    return min(1.0, mult) * err**-0.25 if err > 0 else math.inf


class Radau(Stepper):
    """Radau IIA, 3 stages, order 5, for stiff systems (after scipy's ``radau.py``).

    Simplified Newton iterations on the collocation system with the
    transformation to one real and one complex linear system. The Newton
    matrix uses the approximate Jacobian ``[[0, I], [J_q, J_v]]`` of the chart
    field (it neglects d(dxi/dt)/dxi = O(|v|), which only slows Newton
    slightly), so the 2nv systems reduce to nv x nv Schur complements
    ``alpha^2 I - alpha J_v - J_q``. LU factors are reused while ``h`` and the
    Jacobian are unchanged (the controller keeps ``h`` when it would grow by
    less than 20%). Error estimate (3rd order), controller and dense output
    (the cubic collocation polynomial) as in scipy.

    The flow Jacobian differentiates the stage equations:
    ``(I - h (A ⊗ I) diag(DF_j)) dY = 1 ⊗ phi_n``, ``phi_{n+1} = dY_3``, with
    ``DF_j`` at the converged stages (a dense solve of size 6nv); parameter
    columns add their forcing ``h (A ⊗ I) (0, J_p,j)`` to the right-hand side.

    That is Radau IIA applied to the linear ODE ``phi' = DF(t) phi`` (``DF``
    sampled at the stages), so with ``variational_error_control`` its own
    embedded estimator applies unchanged to the stage increments
    ``dZ_i = dY_i - phi_n``: ``err_phi = (gamma/h I - J)^-1 (DF_n phi_n +
    sum_i e_i dZ_i / h)``, with the state's LU factors, its filtered variant
    after a rejection, and ``DF_n`` the exact Jacobian at the step's start
    (the previous step's last stage, so no extra evaluation). It is what the
    state's estimator gives for the augmented system ``(y, phi)`` with the
    block-diagonal Newton matrix; ``J`` only filters the estimate, the
    cancellation to ``O(h^4)`` is in the bracket. The 6nv solve and the three
    stage Jacobians are then done per attempt (only for attempts whose state
    error passes) instead of per accepted step.

    Attributes:
        n_lu: number of LU factorisations (pairs).
    """

    method = "Radau"
    error_order = 3

    def _setup(self) -> None:
        self.n_lu = 0
        self.newton_tol = max(10 * _EPS / self.rtol, min(0.03, self.rtol**0.5))
        self._J = self._call_jac(self.t, self.q, self.v)
        self._current_jac = True
        # (h, J, lu_real, piv_real, lu_complex, piv_complex, singular)
        self._lu: tuple[float, Any, np.ndarray, np.ndarray, np.ndarray, np.ndarray, bool] | None = None
        self._sol: DenseOutput | None = None
        self._h_abs_old: float | None = None
        self._err_old: float | None = None
        # the last step's start: None until a step is accepted, read only after one
        self._y_old: np.ndarray = None  # type: ignore[assignment]  # no step yet
        self._qc_old: np.ndarray | None = None
        self._Z: np.ndarray | None = None
        self._df_start: StageDF | None = None  # (J_q, J_v, G, J_p) at the current point, when known

    # -- linear algebra on (alpha I - [[0, I], [J_q, J_v]]) --------------------

    def _factor(self, h: float, J) -> None:
        Jq, Jv = J
        eye = np.eye(self.nv)
        ar, ac = _MU_REAL / h, _MU_COMPLEX / h
        lur, pivr, info_r = dgetrf(ar * ar * eye - ar * Jv - Jq)
        luc, pivc, info_c = zgetrf(ac * ac * eye - ac * Jv - Jq)
        self.n_lu += 1
        singular = info_r != 0 or info_c != 0
        self._lu = (h, J, lur, pivr, luc, pivc, singular)

    def _solve(self, r: np.ndarray, real: bool) -> np.ndarray:
        """Solve ``(alpha I - J) x = r`` via the Schur complement on the velocity block."""
        assert self._lu is not None  # factored by _ensure_lu before any solve
        h, (Jq, _), lur, pivr, luc, pivc, _ = self._lu
        nv = self.nv
        r1, r2 = r[:nv], r[nv:]
        if real and r.ndim == 2:  # phi's error estimate: one column at a time, because
            # OpenBLAS threads getrs with several right-hand sides, which costs ~0.1 ms a
            # call on small busy machines (10x the whole step in tests)
            alpha: complex = _MU_REAL / h  # real here, complex for the conjugate pair
            b = alpha * r2 + Jq @ r1
            w = np.empty_like(b)
            for j in range(b.shape[1]):
                w[:, j] = dgetrs(lur, pivr, b[:, j])[0]
        elif real:
            alpha = _MU_REAL / h
            w, _ = dgetrs(lur, pivr, alpha * r2 + Jq @ r1)
        else:
            alpha = _MU_COMPLEX / h
            w, _ = zgetrs(luc, pivc, alpha * r2 + Jq @ r1)
        x = np.empty(r.shape, dtype=w.dtype)
        x[:nv] = (r1 + w) / alpha
        x[nv:] = w
        return x

    def _ensure_lu(self, h: float) -> None:
        if self._lu is None or self._lu[0] != h or self._lu[1] is not self._J:
            self._factor(h, self._J)

    # -- Newton on the collocation system ----------------------------------------

    def _newton(self, t: float, y: np.ndarray, h: float, Z0: np.ndarray, scale: np.ndarray, qc):
        assert self._lu is not None  # factored by _ensure_lu before Newton
        if self._lu[6]:
            return False, 1, Z0, None
        nv = self.nv
        Mr, Mc = _MU_REAL / h, _MU_COMPLEX / h
        W = _RTI @ Z0
        Z = Z0
        F = np.empty((3, self.n))
        ch = h * _RC
        dW = np.empty_like(W)
        dW_norm_old = rate = None
        converged = False
        k = 0
        for k in range(_NEWTON_MAXITER):
            for i in range(3):
                self._eval_into(t + ch[i], y + Z[i], F[i], qc)
            if not np.isfinite(F).all():
                for i in range(3):
                    self._nonfinite_stage(t + ch[i], y + Z[i], F[i, nv:])
                break
            f_real = _RTI_REAL @ F - Mr * W[0]
            f_complex = _RTI_COMPLEX @ F - Mc * (W[1] + 1j * W[2])
            dW[0] = self._solve(f_real, True)
            dWc = self._solve(f_complex, False)
            dW[1], dW[2] = dWc.real, dWc.imag
            dW_norm = _rms(dW / scale)
            if dW_norm_old is not None:
                rate = dW_norm / dW_norm_old
            if rate is not None and rate >= 1 and dW_norm <= _NOISE_FLOOR * self.newton_tol:
                # the iterates already agree to well within newton_tol and only swap round-off
                # (rate ~ 1: a stiff field at rest, whose forces carry k ulp(q)): as converged as
                # the arithmetic allows, not diverging (halving h for it collapsed the steps)
                converged = True
                break
            # stop when diverging or when the predicted final error cannot reach newton_tol
            if rate is not None and (
                rate >= 1 or rate ** (_NEWTON_MAXITER - k) / (1 - rate) * dW_norm > self.newton_tol
            ):
                # stalled at the field's round-off, far below the tolerance: the last iterate
                assert dW_norm_old is not None  # rate is set from the second iterate on
                converged = dW_norm <= NEWTON_STALL_TOL and dW_norm_old <= NEWTON_STALL_TOL
                break
            W += dW
            Z = _RT @ W
            if dW_norm == 0 or (rate is not None and rate / (1 - rate) * dW_norm < self.newton_tol):
                converged = True
                break
            dW_norm_old = dW_norm
        return converged, k + 1, Z, rate

    def _predict(self, t: float, h: float, y: np.ndarray, qc) -> np.ndarray:
        """Newton starting guess from the previous step's collocation polynomial."""
        sol = self._sol
        if sol is None:
            return np.zeros((3, self.n))
        ts = t + h * _RC
        if qc is None:
            return sol._y(ts) - y
        Z0 = np.empty((3, self.n))
        qs, vs = sol(ts)
        for i in range(3):  # the old polynomial lives in the previous chart
            Z0[i, : self.nv] = self.group.difference(qc, qs[i])
        Z0[:, self.nv :] = vs - y[self.nv :]
        return Z0

    def step(self) -> None:
        """Take one accepted step (`Stepper.step`): simplified Newton on the collocation
        system, halving the step when Newton fails and shrinking it when the error is
        too large; the flow Jacobian, if carried, is propagated over the step."""
        min_step, _ = self._begin_step()
        t, y, f = self.t, self._y, self._f
        qc = None if self._vs else self.q
        nv = self.nv
        if self.h_abs > self.max_step:
            h_abs, h_abs_old, err_old = self.max_step, None, None
        elif self.h_abs < min_step:
            h_abs, h_abs_old, err_old = min_step, None, None
        else:
            h_abs, h_abs_old, err_old = self.h_abs, self._h_abs_old, self._err_old
        mag_n = self._mag(y, qc)
        scale_newton = self.atol + self.rtol * mag_n
        control = self.phi is not None and self.variational_error_control
        phi_new = J_end = df_end = None
        rejected = False
        wanted = h_abs  # the step the error control asked for, before t_bound (a breakpoint) clips it
        while True:
            if h_abs < min_step:
                raise self._underflow(h_abs, min_step)
            t_new, clipped = self._step_end(t, h_abs)
            h = t_new - t
            h_abs = h
            Z0 = self._predict(t, h, y, qc)
            while True:
                self._ensure_lu(h)
                try:
                    converged, n_iter, Z, rate = self._newton(t, y, h, Z0, scale_newton, qc)
                except OutsideDomainError as exc:  # an iterate left the field's domain: shorter step
                    self._outside, converged = exc, False
                    break
                if converged or self._current_jac:
                    break
                self._J = self._call_jac(t, self.q, self.v)
                self._current_jac = True
            if not converged:
                h_abs *= 0.5
                self.n_rejected += 1
                continue
            y_new = y + Z[2]
            q_new = y_new[:nv] if qc is None else self.group.integrate(qc, y_new[:nv])
            ZE = (_RE @ Z) / h
            err_vec = self._solve(f + ZE, True)
            scale = self.atol + self.rtol * np.maximum(mag_n, self._mag(y_new, q_new))
            err = _rms(err_vec / scale)
            safety = 0.9 * (2 * _NEWTON_MAXITER + 1) / (2 * _NEWTON_MAXITER + n_iter)
            if rejected and err > 1:  # Hairer's filtered estimate, more reliable after a rejection
                fe = np.empty(self.n)
                ye = y + err_vec
                try:
                    self._eval_into(t, ye, fe, qc)
                except OutsideDomainError as exc:  # keep the unfiltered estimate (> 1: rejected)
                    self._outside = exc
                    fe[:] = np.nan
                if np.isfinite(fe).all():
                    err = _rms(self._solve(fe + ZE, True) / scale)
            roundoff = self._roundoff_error(y, y_new, mag_n)
            if roundoff > 1.0:  # a step too long for its own round-off (`Stepper._roundoff_error`)
                h_abs *= max(_MIN_FACTOR, 0.9 / roundoff)
                rejected = True
                self.n_rejected += 1
                continue
            if not math.isfinite(err):
                err = math.inf
            if control and err <= 1:
                phi_new, df_end, err_phi = self._controlled_variational(t, h, y, Z, qc, rejected)
                J_end = df_end[:2]
                err = max(err, err_phi)
            if err > 1:
                factor = _predict_factor(h_abs, h_abs_old, err, err_old)
                h_abs *= max(_MIN_FACTOR, safety * factor if math.isfinite(err) else 0.0)
                rejected = True
                self.n_rejected += 1
                continue
            break

        recompute_jac = n_iter > 2 and rate is not None and rate > 1e-3
        factor = min(_MAX_FACTOR, safety * _predict_factor(h_abs, h_abs_old, err, err_old))
        if roundoff > 0.0:  # the next step's round-off stays within the tolerance
            factor = min(factor, 1.0 / roundoff)
        if not recompute_jac and factor < 1.2:
            factor = 1.0  # keep h so that the LU factors stay valid

        # Final state and derivative at t_new (the last Newton evaluation was not at the converged Z).
        a_new = np.asarray(self.accel(t_new, q_new, y_new[nv:]), dtype=float)
        self.n_accel += 1
        self._nonfinite_stage(t_new, y_new, a_new)
        if self.phi is not None and not control:
            phi_new, J_end = self._variational(t, h, y, Z, qc, self.phi)
        # the last stage is the new point: its DF starts phi's next error estimate
        self._df_start = df_end if control else None
        if recompute_jac:
            self._J = J_end if J_end is not None else self._call_jac(t_new, q_new, y_new[nv:])
            self._current_jac = True
        else:
            self._current_jac = False

        self._y_old, self._qc_old, self._Z = y, qc, Z
        self._h_abs_old, self._err_old = h_abs, err
        self._accept_state(t_new, y_new, q_new, a_new)
        self.phi = phi_new
        self.h_abs = h_abs * factor
        if clipped and not rejected:  # see `_step_end`
            self.h_abs = max(self.h_abs, wanted)
        self._sol = DenseOutput(t, t_new, h, y, _RP.T @ Z, None if self._vs else self.group, qc, nv)

    def _variational_stages(self, t: float, h: float, y: np.ndarray, Z: np.ndarray, qc, P0: np.ndarray):
        """Differentiate the stage equations; return (dY (3, n, m), (J_q, J_v, G) at the last stage)."""
        nv, n = self.nv, self.n
        M = np.eye(3 * n)
        DF = np.zeros((n, n))
        DF[:nv, nv:] = np.eye(nv)
        df = None
        rhs = np.tile(P0, (3, 1))
        for j in range(3):
            Yj = y + Z[j]
            qj = Yj[:nv] if qc is None else self.group.integrate(qc, Yj[:nv])
            df = self._stage_df(t + _RC[j] * h, qj, Yj[nv:])
            if df[2] is not None:
                DF[:nv, :nv] = df[2]
            DF[nv:, :nv], DF[nv:, nv:] = df[0], df[1]
            Jp = df[3]
            for i in range(3):
                M[i * n : (i + 1) * n, j * n : (j + 1) * n] -= (h * _RA[i, j]) * DF
                if Jp is not None and Jp.shape[1]:  # the parameters' forcing (0, J_p) of stage j
                    rhs[i * n + nv : (i + 1) * n, P0.shape[1] - Jp.shape[1] :] += (h * _RA[i, j]) * Jp
        dY = np.linalg.solve(M, rhs)
        return dY.reshape(3, n, P0.shape[1]), df

    def _variational(self, t: float, h: float, y: np.ndarray, Z: np.ndarray, qc, P0: np.ndarray):
        """Return (phi_{n+1}, (J_q, J_v) at the last stage)."""
        dY, df = self._variational_stages(t, h, y, Z, qc, P0)
        return dY[2], df[:2]

    def _controlled_variational(self, t: float, h: float, y: np.ndarray, Z: np.ndarray, qc, rejected: bool):
        """phi_{n+1} of an attempt, (J_q, J_v) at its end and phi's error norm (Radau's estimator)."""
        P0 = self.phi
        assert P0 is not None  # called only with a flow Jacobian
        dY, df_end = self._variational_stages(t, h, y, Z, qc, P0)
        phi_new = dY[2]
        if self._df_start is None:
            self._df_start = self._stage_df(t, self.q, self.v)
        df_n = self._df_start
        ZE = np.tensordot(_RE / h, dY - P0, axes=1)
        err_vec = self._solve(self._df_apply(df_n, P0) + ZE, True)
        scale = self._phi_scale(P0, phi_new)
        err = _rms_cols(err_vec / scale)
        if rejected and err > 1:  # linearisation of the state's filtered estimate
            err = _rms_cols(self._solve(self._df_apply(df_n, P0 + err_vec) + ZE, True) / scale)
        return phi_new, df_end, err

    def _redo_variational(self, h: float) -> np.ndarray:
        assert self.phi_old is not None  # called only with a flow Jacobian (`truncate`)
        return self._retake(self.t_old, self._y_old, h, self._qc_old, self.phi_old, _RETAKE_SPLITS)

    def _retake(self, t: float, y: np.ndarray, h: float, qc, P0: np.ndarray, splits: int) -> np.ndarray:
        """``phi`` over ``[t, t + h]`` from ``P0`` at ``(t, y)`` (a point of the last step, in its
        chart): the step re-taken, Newton started on the step's collocation polynomial. A
        long step re-taken shorter (an event cuts it) can fail where the long one converged
        (Newton's predicted-convergence test is strict at tight tolerances): then the two
        halves are re-taken in turn, the second started on the polynomial, up to
        ``splits`` times (the derivative of those shorter steps' flow: the same to the
        tolerance)."""
        nv = self.nv
        q = y[:nv] if qc is None else self.group.integrate(qc, y[:nv])
        scale = self.atol + self.rtol * self._mag(y, None if qc is None else q)
        assert self._sol is not None  # the step being re-taken has its polynomial
        Z0 = self._sol._y(t + h * _RC) - y  # same chart: an excellent guess
        for _ in range(2):
            self._ensure_lu(h)
            converged, _, Z, _ = self._newton(t, y, h, Z0, scale, qc)
            if converged:
                return self._variational(t, h, y, Z, qc, P0)[0]
            self._J = self._call_jac(t, q, y[nv:])
        if splits == 0:
            raise IntegrationError(
                f"Radau: Newton failed when re-taking the step from t={float(t)!r} with h={float(h)!r}"
            )
        half = 0.5 * h
        P_mid = self._retake(t, y, half, qc, P0, splits - 1)
        return self._retake(t + half, self._sol._y(t + half), h - half, qc, P_mid, splits - 1)

    def dense(self, lazy: bool = False) -> DenseOutput:
        """The collocation polynomial of the last step on ``[t_old, t]`` (``lazy`` changes nothing)."""
        # the collocation polynomial costs nothing extra: lazy changes nothing
        if self.t_old is None or self._sol is None:
            raise InvalidInputError("dense() needs a step taken since the last (re)start")
        return self._sol

    def _after_truncate(self) -> None:
        self._df_start = None

    def _after_restart(self) -> None:
        self._df_start = None
        self._sol = None
        self._h_abs_old = self._err_old = None
        self._J = self._call_jac(self.t, self.q, self.v)
        self._current_jac = True
        self._lu = None
