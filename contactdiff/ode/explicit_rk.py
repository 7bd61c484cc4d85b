"""Explicit embedded Runge–Kutta pairs with FSAL: RK45 (Dormand–Prince 5(4)) and DOP853."""

from __future__ import annotations

import math

import numpy as np

from ..errors import InvalidInputError, OutsideDomainError
from . import tableaus
from .base import Stepper, _combine
from .dense import DenseOutput, LazyDenseOutput
from .step_control import _MAX_FACTOR, _MIN_FACTOR, _SAFETY, _rms, _rms_cols
from .variational import StageDF


class ExplicitRK(Stepper):
    """Explicit embedded Runge–Kutta pair with FSAL (base of `RK45`, `DOP853`).

    The flow Jacobian is propagated by applying the same Runge–Kutta stages to
    the variational equation, ``K_i = DF(x_i) (phi_n + h sum_j a_ij K_j)`` with
    ``DF`` at each stage's state (for vector spaces this is the exact
    derivative of the discrete step).

    With ``variational_error_control`` these stage increments are computed in
    every attempt whose state error passes (a rejection on the state alone
    costs no Jacobian), and the pair's embedded error formula is applied to
    them. ``DF`` at the step's start is evaluated once per step (not once per
    attempt); when the error formula weights the FSAL stage (RK45) its
    ``DF(x_{n+1})`` is reused as the next step's first stage.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    n_stages: int
    n_rows: int  # rows of the stage buffer (stages + FSAL + dense-output extras)
    E: np.ndarray  # error weights (of the embedded pair)
    # the last step's start and end: None until a step is accepted, read only after one
    _f_old: np.ndarray
    _y_old: np.ndarray
    _y_end: np.ndarray
    _qc_old: np.ndarray | None  # the step's chart point (None on vector spaces)

    def _setup(self) -> None:
        self._K = np.empty((self.n_rows, self.n))
        self._dense_cache: DenseOutput | None = None
        self._f_old = self._y_old = self._qc_old = self._y_end = None  # type: ignore[assignment]  # no step yet
        self._h_last = 0.0
        self._KP: np.ndarray | None = None  # stage increments of phi, (n_stages + 1, n, m)
        self._df_start: StageDF | None = None  # DF at the current point (t, y), when known
        # stages the error formula uses: the FSAL stage only if it has a nonzero weight
        self._n_err = self.n_stages + int(any(e[self.n_stages] != 0 for e in self._error_weights()))

    def _error_weights(self) -> tuple[np.ndarray, ...]:
        return (self.E,)

    def _stages(self, t: float, y: np.ndarray, h: float, qc):
        """Stages of one attempt; ``K[n_stages]`` is ``F(t + h, y_new)`` (FSAL)."""
        K, C, ns, nv = self._K, self.C, self.n_stages, self.nv
        hA = h * self.A
        ys = [y]
        if qc is None:  # vector-space fast path, inlined (this loop dominates the cost)
            accel = self.accel
            qs = [y[:nv]]
            for s in range(1, ns):
                ys_s = y + hA[s, :s].dot(K[:s])
                v = ys_s[nv:]
                K[s, :nv] = v
                K[s, nv:] = accel(t + C[s] * h, ys_s[:nv], v)
                ys.append(ys_s)
                qs.append(ys_s[:nv])
            self.n_accel += ns - 1
        else:  # the same in the chart at qc (`_eval_into`, inlined)
            accel, integrate, chart_velocity = self.accel, self.group.integrate, self.group.chart_velocity
            qs = [qc]
            for s in range(1, ns):
                ys_s = y + hA[s, :s].dot(K[:s])
                xi, v = ys_s[:nv], ys_s[nv:]
                q = integrate(qc, xi)
                K[s, :nv] = chart_velocity(qc, xi, v)
                K[s, nv:] = accel(t + C[s] * h, q, v)
                ys.append(ys_s)
                qs.append(q)
            self.n_accel += ns - 1
        y_new = y + (h * self.B).dot(K[:ns])
        q_new = self._eval_into(t + h, y_new, K[ns], qc)
        return y_new, q_new, ys, qs

    def _error_norm(self, h: float, K: np.ndarray, scale: np.ndarray) -> float:
        return _rms(h * (self.E @ K[: self.n_stages + 1]) / scale)

    def _phi_error_norm(self, h: float, KP: np.ndarray, scale: np.ndarray) -> float:
        """`_error_norm` applied to each column of phi's stage increments (max over columns)."""
        ne = self._n_err
        return _rms_cols(_combine(h * self.E[:ne], KP[:ne]) / scale)

    def _controlled_variational(self, t, h, ys, qs, t_new, y_new, q_new):
        """phi_{n+1} of an attempt and its error norm; the end point's DF, if evaluated, is kept."""
        P0, nv, ns = self.phi, self.nv, self.n_stages
        KP = self._KP
        if KP is None or KP.shape[2] != P0.shape[1]:
            KP = self._KP = np.empty((ns + 1, self.n, P0.shape[1]))
        if self._df_start is None:
            self._df_start = self._stage_df(t, qs[0], ys[0][nv:])
        phi_new = self._variational(t, h, ys, qs, P0, KP, self._df_start)
        df_end = None
        if self._n_err > ns:
            df_end = self._stage_df(t_new, q_new, y_new[nv:])
            self._df_apply(df_end, phi_new, KP[ns])
        err = self._phi_error_norm(h, KP, self._phi_scale(P0, phi_new))
        return phi_new, err, df_end

    def step(self) -> None:
        """Take one accepted step (`Stepper.step`) of the embedded pair, shrinking the step
        after each rejection; the flow Jacobian, if carried, is propagated over the step."""
        min_step, h_abs = self._begin_step()
        t, y = self.t, self._y
        qc = None if self._vs else self.q
        nv, ns, K = self.nv, self.n_stages, self._K
        K[0] = self._f
        mag_n = self._mag(y, qc)
        exponent = -1.0 / (self.error_order + 1)
        control = self.phi is not None and self.variational_error_control
        phi_new: np.ndarray | None = None
        df_end = None
        rejected = False
        while True:
            if h_abs < min_step:
                raise self._underflow(h_abs, min_step)
            wanted = h_abs  # the step the error control asked for, before t_bound clips it
            t_new, clipped = self._step_end(t, h_abs)
            h = t_new - t
            try:
                y_new, q_new, ys, qs = self._stages(t, y, h, qc)
            except OutsideDomainError as exc:  # a trial stage left the field's domain: shorter step
                self._outside = exc
                h_abs = h * _MIN_FACTOR
                rejected = True
                self.n_rejected += 1
                continue
            scale = self.atol + self.rtol * np.maximum(mag_n, self._mag(y_new, q_new))
            err = self._error_norm(h, K, scale)
            roundoff = self._roundoff_error(y, y_new, mag_n)
            if roundoff > 1.0:  # a step too long for its own round-off (`Stepper._roundoff_error`)
                h_abs = h * max(_MIN_FACTOR, _SAFETY / roundoff)
                rejected = True
                self.n_rejected += 1
                continue
            if not math.isfinite(err):
                for s in range(1, ns + 1):  # name the culprit if accel itself returned inf/nan
                    self._nonfinite_stage(t + self.C[s] * h if s < ns else t_new, ys[s] if s < ns else y_new, K[s, nv:])
                err = math.inf  # overflow of a too-large step: reject it
            if control and err < 1.0:
                phi_new, err_phi, df_end = self._controlled_variational(t, h, ys, qs, t_new, y_new, q_new)
                err = max(err, err_phi)
            if err < 1.0:
                factor = _MAX_FACTOR if err == 0 else min(_MAX_FACTOR, _SAFETY * err**exponent)
                if roundoff > 0.0:  # the next step's round-off stays within the tolerance
                    factor = min(factor, 1.0 / roundoff)
                if rejected:
                    factor = min(1.0, factor)
                h_abs = h * factor
                if clipped and not rejected:  # see `_step_end`
                    h_abs = max(h_abs, wanted)
                break
            h_abs = h * max(_MIN_FACTOR, _SAFETY * err**exponent if math.isfinite(err) else 0.0)
            rejected = True
            self.n_rejected += 1

        if self.phi is not None and not control:
            phi_new = self._variational(t, h, ys, qs, self.phi)
        self._df_start = df_end  # DF at the new point if the error formula needed it, else unknown
        # Kept for dense output and truncate(): the step's start, its chart and its end in that chart.
        self._y_old, self._f_old, self._qc_old, self._h_last, self._y_end = y, self._f, qc, h, y_new
        self._dense_cache = None
        self._accept_state(t_new, y_new, q_new, K[ns, nv:].copy())
        self.phi = phi_new
        self.h_abs = h_abs

    def _variational(
        self, t: float, h: float, ys, qs, P0: np.ndarray, KP: np.ndarray | None = None, df0=None
    ) -> np.ndarray:
        """phi_{n+1}; the stage increments go to ``KP[:n_stages]``; ``df0``: DF at the first stage if known."""
        nv, ns = self.nv, self.n_stages
        hA, hB, C = h * self.A, h * self.B, self.C
        if KP is None:
            KP = np.empty((ns, self.n, P0.shape[1]))
        for s in range(ns):
            Ps = P0 + _combine(hA[s, :s], KP[:s]) if s else P0
            df = df0 if s == 0 and df0 is not None else self._stage_df(t + C[s] * h, qs[s], ys[s][nv:])
            self._df_apply(df, Ps, KP[s])
        return P0 + _combine(hB, KP[:ns])

    def _redo_variational(self, h: float) -> np.ndarray:
        self._K[0] = self._f_old
        assert self.phi_old is not None  # called only with a flow Jacobian (`truncate`)
        _, _, ys, qs = self._stages(self.t_old, self._y_old, h, self._qc_old)
        return self._variational(self.t_old, h, ys, qs, self.phi_old)

    def dense(self, lazy: bool = False) -> DenseOutput:
        """Interpolant of the last step; ``lazy`` defers its extra work to first use."""
        if self.t_old is None:
            raise InvalidInputError("dense() needs a step taken since the last (re)start")
        if self._dense_cache is not None:
            return self._dense_cache
        group = None if self._vs else self.group
        if not lazy:
            self._dense_cache = DenseOutput(
                self.t_old, self.t, self._h_last, self._y_old, self._dense_coef(), group, self._qc_old, self.nv
            )
            return self._dense_cache
        step = (self._K.copy(), self._h_last, self._y_old, self._y_end.copy(), self._qc_old, self.t_old, self.accel)
        return LazyDenseOutput(
            self.t_old, self.t, self._h_last, self._y_old, lambda: self._coef_from(*step), group, self._qc_old, self.nv
        )

    def _dense_coef(self) -> np.ndarray:
        """Monomial coefficients (degree x n) of the last step's interpolant, x in [0, 1]."""
        return self._coef_from(self._K, self._h_last, self._y_old, self._y_end, self._qc_old, self.t_old, None)

    def _coef_from(self, K, h, y_old, y_end, qc, t_old, accel) -> np.ndarray:
        """Interpolant coefficients from a step's stages ``K`` (extra rows may be written)."""
        raise NotImplementedError

    def _after_truncate(self) -> None:
        self._df_start = None

    def _after_restart(self) -> None:
        self._dense_cache = None
        self._df_start = None


class RK45(ExplicitRK):
    """Dormand–Prince 5(4) with FSAL and its quartic dense output (scipy's coefficients)."""

    method = "RK45"
    error_order = 4
    n_stages = 6
    n_rows = 7

    A, B, C, E, P = tableaus.RK45_A, tableaus.RK45_B, tableaus.RK45_C, tableaus.RK45_E, tableaus.RK45_P

    def _coef_from(self, K, h, y_old, y_end, qc, t_old, accel) -> np.ndarray:
        return h * (self.P.T @ K)


class DOP853(ExplicitRK):
    """Dormand–Prince 8(5,3) with FSAL and its 7th-order dense output.

    Coefficients are scipy's (``scipy/integrate/_ivp/dop853_coefficients.py``);
    the error estimate combines the 5th- and 3rd-order embedded formulas as in
    Hairer's DOP853. The three extra stages of the dense output are only
    evaluated when `dense` is called.
    """

    method = "DOP853"
    error_order = 7
    n_stages = tableaus.N_STAGES
    n_rows = tableaus.N_STAGES_EXTENDED
    A = tableaus.A[: tableaus.N_STAGES, : tableaus.N_STAGES]
    A_FULL = tableaus.A
    B = tableaus.B
    C = tableaus.C
    E3 = tableaus.E3
    E5 = tableaus.E5
    D = tableaus.D

    def _error_weights(self) -> tuple[np.ndarray, ...]:
        return (self.E5, self.E3)

    def _error_norm(self, h: float, K: np.ndarray, scale: np.ndarray) -> float:
        Ks = K[: self.n_stages + 1]
        err5 = (self.E5 @ Ks) / scale
        err3 = (self.E3 @ Ks) / scale
        e5 = float(err5 @ err5)
        e3 = float(err3 @ err3)
        if e5 == 0.0:  # (also where 0.01 e3 underflows: 0 / 0)
            return 0.0
        return abs(h) * e5 / math.sqrt((e5 + 0.01 * e3) * self.n)

    def _phi_error_norm(self, h: float, KP: np.ndarray, scale: np.ndarray) -> float:
        """Hairer's 5(3) combination per column of phi (RMS over its rows), max over columns."""
        ne = self._n_err
        err5 = _combine(self.E5[:ne], KP[:ne]) / scale
        err3 = _combine(self.E3[:ne], KP[:ne]) / scale
        e5 = np.einsum("ij,ij->j", err5, err5)
        den = (e5 + 0.01 * np.einsum("ij,ij->j", err3, err3)) * self.n
        if not np.isfinite(den).all():
            return math.inf
        pos = den > 0.0
        if not pos.any():
            return 0.0
        return abs(h) * float(np.max(e5[pos] / np.sqrt(den[pos])))

    def _coef_from(self, K, h, y_old, y_end, qc, t_old, accel) -> np.ndarray:
        A, C = self.A_FULL, self.C
        for s in range(self.n_stages + 1, self.n_rows):
            ys = y_old + (h * A[s, :s]) @ K[:s]
            self._eval_into(t_old + C[s] * h, ys, K[s], qc, accel)
            self._nonfinite_stage(t_old + C[s] * h, ys, K[s, self.nv :])
        f_old, f_new = K[0], K[self.n_stages]
        dy = y_end - y_old
        F = [dy, h * f_old - dy, 2 * dy - h * (f_new + f_old), *(h * (self.D @ K))]
        # Expand y_old + x(F0 + (1-x)(F1 + x(F2 + (1-x)(F3 + ...)))) into monomials of x.
        c = np.zeros((len(F) + 1, self.n))
        for i, f in enumerate(reversed(F)):
            c[0] += f
            if i % 2 == 0:
                c[1:] = c[:-1].copy()
                c[0] = 0.0
            else:
                c[1:] = c[1:] - c[:-1]
        return c[1:]
