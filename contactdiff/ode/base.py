"""The stepper base class: error-controlled one-step integration with dense output.

The state, units, frames, how a stepper is driven and what it provides are the
package's contract (`contactdiff.ode`); what a new method implements is in `Stepper`'s
docstring. Step-size control shared by the methods is in `contactdiff.ode.step_control`.
"""

from __future__ import annotations

import abc
from typing import TYPE_CHECKING

import numpy as np

from ..errors import (
    ContactDiffError,
    IntegrationError,
    InvalidInputError,
    OutsideDomainError,
    StepSizeUnderflowError,
    check_number,
    check_vector,
)
from .dense import DenseOutput
from .field_types import AccelFn, JacFn, ParameterJacFn
from .lie import _as_group
from .step_control import initial_step, roundoff_error
from .tolerances import checked_atol, checked_rtol, column_scaled_atol, variational_row_atol
from .variational import VariationalAlgebra

if TYPE_CHECKING:
    import pinocchio as pin
    from numpy.typing import ArrayLike

    from .lie import LieGroup


def _scalar(name: str, x, *, allow_inf: bool = False) -> float:
    return check_number("stepper", name, x, allow_inf=allow_inf)


def _vector(name: str, x, n: int) -> np.ndarray:
    return check_vector("stepper", name, x, n)


def _combine(weights: np.ndarray, stack: np.ndarray) -> np.ndarray:
    """``sum_s weights[s] stack[s]`` for a stack of matrices, as one matrix-vector
    product (``np.tensordot``'s Python-level reshaping costs more at these sizes)."""
    return (weights @ stack.reshape(len(weights), -1)).reshape(stack.shape[1:])


class Stepper(VariationalAlgebra, abc.ABC):
    """One-step integrator with error control and dense output (base class).

    The base validates the options, holds the current point, and does what every
    method shares: `truncate` to an event time, `restart` after a jump, the
    first-step heuristic, the chart's stage evaluations and the flow Jacobian's
    linear algebra. A new method is a subclass that implements (enforced with
    `abc`):

    * ``step()``: one *accepted* step from ``(t, q, v, phi)``, retrying with a
      smaller ``h`` internally after a rejection. Start with `_begin_step` (it
      raises at ``t_bound`` and gives the smallest and first ``h``), never step
      past ``t_bound`` (`_step_end`), raise `_underflow` when ``h`` falls below the smallest
      step, count rejections in ``n_rejected``, and end with `_accept_state`
      (it moves ``t_old, q_old, v_old, phi_old`` and counts ``n_steps``). Set
      ``phi`` for the end point when ``phi`` is not None (with
      ``variational_error_control``, accept only steps whose `_phi_scale`-scaled
      error of ``phi`` is also <= 1). Evaluate the field with `_eval_into` (it
      counts ``n_accel``) and its Jacobian with `_call_jac` (it counts ``n_jac``).
      A trial evaluation that raises `OutsideDomainError` rejects the attempt:
      keep the exception in ``_outside`` and try a shorter step (`_underflow`
      then raises it).
    * ``dense(lazy=False)``: a `DenseOutput` of the last step on ``[t_old, t]``
      that stays valid after further steps.
    * ``_redo_variational(h)``: ``phi`` at ``t_old + h`` propagated from
      ``phi_old`` over a step of size ``h`` (used by `truncate`).

    and sets the class attributes ``method`` (its name) and ``error_order`` (the
    local error is ``O(h^(error_order + 1))``). Optional hooks: ``_setup()``
    (buffers, after the base's ``__init__`` has set the point),
    ``_after_truncate()`` and ``_after_restart()`` (drop caches that belong to
    the abandoned step). States are ``y = (xi, v)`` in the chart at ``q`` of the
    step's start (``y = (q, v)`` on a vector space; see `contactdiff.ode.lie`).

    Args:
        accel: ``accel(t, q, v) -> dv/dt`` (nv,); it may raise `OutsideDomainError`
            where the field is not defined (see ``step()``).
        group: configuration space (`VectorSpace`, `PinocchioGroup`) or a
            ``pinocchio.Model``.
        t0: initial time (s).
        q0: initial configuration (nq,).
        v0: initial velocity (nv,).
        rtol: relative tolerance (>= 100 eps).
        atol: absolute tolerance, scalar or (2nv,) for ``(δq, δv)``, > 0.
            The error of a step is the RMS norm of the local error in
            ``(xi, v)`` divided by ``atol + rtol * |y|`` (scipy's norm).
        jac: ``jac(t, q, v) -> (J_q, J_v)``; needed for ``variational``; for
            `Radau` a forward-difference Jacobian is used when omitted.
        first_step: initial step (s); None selects it (Hairer's heuristic).
        max_step: largest step (s).
        t_bound: steps never go beyond this time (s).
        variational: initial flow Jacobian ``phi`` (2nv x m) to propagate with
            the same steps, or None.
        variational_error_control: with ``variational``, also control the
            local error of ``phi`` ("full error control", as CVODES'
            ``errconS``): every attempted step computes the stage increments
            of ``phi``, forms the method's embedded error estimate for them and
            is accepted only if both the state's and ``phi``'s error norms are
            <= 1; the step size is chosen from the larger. Without it the steps
            are chosen for the state alone, which can be far too long for
            ``phi`` when the state is easy but its linearisation is not (a
            spring at its rest length along the trajectory, free motion on a
            Lie group). It never changes how ``phi`` is propagated (on vector
            spaces ``phi`` stays the exact derivative of the discrete flow),
            only which steps are accepted.
        variational_atol: absolute tolerance of ``phi``, scalar or (2nv,) per
            row; None uses ``atol`` per row. Each column of ``phi`` is the
            response ``(δq, δv)`` to a unit initial perturbation, so its rows
            carry the state's units and the state's ``atol`` is the natural
            absolute floor (CVODES' default ``atolS = atol / pbar`` with
            ``pbar = 1``). The error of ``phi`` is the RMS over the rows of
            each column of its local error divided by
            ``variational_atol + rtol * |phi|`` (entrywise, at least 100 eps times
            the column's largest entry: its round-off), maximised over the columns
            (CVODES' norm for a set of sensitivities).
        parameter_jac: ``parameter_jac(t, q, v) -> J_p`` (nv x p), the derivative of
            ``accel`` with respect to p parameters at fixed state. The last p
            columns of ``phi`` are then the state's sensitivities to those
            parameters, ``d(δq, δv)/dp``, propagated by the forced variational
            equation ``phi_p' = DF phi_p + (0, J_p)`` (the augmented state
            ``(x, p)`` with ``p' = 0``); their error is controlled like the
            other columns' (scale a parameter so that a unit change is a
            natural perturbation, or give its ``variational_column_scale``).
        variational_column_scale: (m,) typical sizes of the perturbations the columns
            of ``phi`` respond to (1 for a state column, ``|p|`` for a parameter's); a
            column's absolute tolerance is ``variational_atol / scale`` (CVODES'
            ``atolS = atol / pbar``). None: all 1.

    Attributes:
        t, q, v, phi: current time, state and flow Jacobian (phi None if off).
        t_old, q_old, v_old, phi_old: the same at the start of the last step.
        n_steps, n_rejected, n_accel, n_jac: accepted steps, rejected step
            attempts, calls of ``accel`` and Jacobian evaluations.
    """

    method: str = ""
    error_order: int = 0  # error ~ h^(error_order + 1); for the first-step heuristic

    # the previous point: None until a step is accepted (and after a restart); read only
    # after one (`dense`, `truncate` check ``t_old is None`` first)
    t_old: float
    q_old: np.ndarray
    v_old: np.ndarray
    phi_old: np.ndarray | None
    _outside: OutsideDomainError | None

    def __init__(
        self,
        accel: AccelFn,
        group: LieGroup | pin.Model,
        t0: float,
        q0: ArrayLike,
        v0: ArrayLike,
        *,
        rtol: float = 1e-6,
        atol: ArrayLike = 1e-9,
        jac: JacFn | None = None,
        first_step: float | None = None,
        max_step: float = np.inf,
        t_bound: float = np.inf,
        variational: ArrayLike | None = None,
        variational_error_control: bool = True,
        variational_atol: ArrayLike | None = None,
        parameter_jac: ParameterJacFn | None = None,
        variational_column_scale: ArrayLike | None = None,
    ) -> None:
        if not callable(accel):
            raise InvalidInputError(f"accel must be callable accel(t, q, v), got {accel!r}")
        if jac is not None and not callable(jac):
            raise InvalidInputError(f"jac must be callable jac(t, q, v) -> (J_q, J_v) or None, got {jac!r}")
        self.group = _as_group(group)
        self.nq, self.nv = int(self.group.nq), int(self.group.nv)
        if self.nv < 1:
            raise InvalidInputError(f"group must have nv >= 1, got nv={self.nv}")
        self.n = 2 * self.nv
        self._vs = bool(self.group.is_vector_space)
        self.accel, self.jac = accel, jac
        if parameter_jac is not None and not callable(parameter_jac):
            raise InvalidInputError(
                f"parameter_jac must be callable parameter_jac(t, q, v) -> J_p or None, got {parameter_jac!r}"
            )
        self.parameter_jac = parameter_jac

        t0 = _scalar("t0", t0)
        self.q = _vector("q0", q0, self.nq)
        self.v = _vector("v0", v0, self.nv)
        self.rtol = checked_rtol(rtol)
        self.atol = checked_atol(atol, self.n)
        self.max_step = _scalar("max_step", max_step, allow_inf=True)
        if not self.max_step > 0:
            raise InvalidInputError(f"max_step must be > 0, got {max_step!r}")
        self.t_bound = _scalar("t_bound", t_bound, allow_inf=True)
        if self.t_bound < t0:
            raise InvalidInputError(f"t_bound must be >= t0 = {t0!r} (forward integration only), got {t_bound!r}")
        self.variational_error_control = bool(variational_error_control)
        self._atol_phi = variational_row_atol(self.atol, variational_atol, self.n)
        self.t = t0
        self.phi = None if variational is None else self._check_phi(variational)
        if variational_column_scale is not None:
            m = 0 if self.phi is None else self.phi.shape[1]
            self._atol_phi = column_scaled_atol(self._atol_phi, variational_column_scale, m)

        self.n_steps = self.n_rejected = self.n_accel = self.n_jac = 0
        self._outside = None
        self.t_old = self.q_old = self.v_old = self.phi_old = None  # type: ignore[assignment]  # no step yet (class doc)
        self._y = self._point_y(self.q, self.v)
        self._f = self._point_f(self.t, self.q, self.v)
        self._setup()
        if first_step is None:
            self.h_abs = self._initial_step()
        else:
            self.h_abs = _scalar("first_step", first_step)
            if self.h_abs <= 0:
                raise InvalidInputError(f"first_step must be > 0, got {first_step!r}")

    # -- public API ---------------------------------------------------------

    @property
    def h_next(self) -> float:
        """Size of the next step to try (s)."""
        return min(self.h_abs, self.max_step)

    @property
    def f(self) -> np.ndarray:
        """The field ``(v, ddq)`` (2nv,) at the current point: the last accepted step's end
        (its last stage), or the point of the last `truncate` or `restart`."""
        return self._f

    @abc.abstractmethod
    def step(self) -> None:
        """Take one accepted step (retrying internally after rejections).

        Raises:
            IntegrationError: step-size underflow, Newton failure, ``t`` already
                at ``t_bound``, or non-finite ``accel``/``jac`` output.
        """

    @abc.abstractmethod
    def dense(self, lazy: bool = False) -> DenseOutput:
        """Interpolant of the last step on ``[t_old, t]``; with ``lazy`` any extra
        vector-field evaluations it needs are deferred until it is first read."""

    def truncate(self, t: float) -> None:
        """Keep the last step only up to ``t`` (an event time).

        The state becomes the dense output at ``t`` exactly (so a guard located
        on the dense output is zero at the new state). With a flow Jacobian,
        the step is re-taken with ``h = t - t_old`` from the step's start and
        the variational equation is propagated over it; its state differs from
        the dense value by the local error only (O(tol)), which is negligible
        for the Jacobian.

        Args:
            t: time in ``[t_old, t]`` of the last step (s).
        """
        if self.t_old is None:
            raise InvalidInputError("truncate() needs a step taken since the last (re)start")
        t = _scalar("t", t)
        if not self.t_old <= t <= self.t:
            raise InvalidInputError(f"truncate time t={t!r} is outside the last step [{self.t_old!r}, {self.t!r}]")
        if t == self.t:
            return
        dense = self.dense()
        if t == self.t_old:
            q, v = self.q_old, self.v_old
        else:
            q, v = dense(t)
            q, v = np.array(q), np.array(v)
        if self.phi is not None:
            self.phi = self.phi_old if t == self.t_old else self._redo_variational(t - self.t_old)
        dense.t = t
        self.t, self.q, self.v = t, q, v
        self._y = self._point_y(q, v)
        self._f = self._point_f(t, q, v)
        self._after_truncate()

    def restart(
        self,
        t: float,
        q: ArrayLike,
        v: ArrayLike,
        phi: ArrayLike | None = None,
        *,
        accel: AccelFn | None = None,
        jac: JacFn | None = None,
        t_bound: float | None = None,
        parameter_jac: ParameterJacFn | None = None,
    ) -> None:
        """Start again from a new state (after a jump or a mode change).

        The step-size estimate is kept; Jacobian, LU factors and the dense
        output of the previous step are dropped.

        Args:
            t: time (s).
            q: configuration (nq,).
            v: velocity (nv,).
            phi: new flow Jacobian (2nv x m), e.g. ``Xi @ stepper.phi``; None
                keeps the current one (an identity jump).
            accel: new vector field (mode change); None keeps the current one.
            jac: new Jacobian callback; None keeps the current one.
            t_bound: new bound (s); None keeps the current one.
            parameter_jac: new parameter-Jacobian callback (with ``jac``, for a new
                field); None keeps the current one.
        """
        if accel is not None:
            if not callable(accel):
                raise InvalidInputError(f"accel must be callable accel(t, q, v), got {accel!r}")
            self.accel = accel
        if jac is not None:
            if not callable(jac):
                raise InvalidInputError(f"jac must be callable jac(t, q, v) -> (J_q, J_v), got {jac!r}")
            self.jac = jac
        if parameter_jac is not None:
            if not callable(parameter_jac):
                raise InvalidInputError(
                    f"parameter_jac must be callable parameter_jac(t, q, v) -> J_p, got {parameter_jac!r}"
                )
            self.parameter_jac = parameter_jac
        t = _scalar("t", t)
        q = _vector("q", q, self.nq)
        v = _vector("v", v, self.nv)
        if t_bound is not None:
            self.t_bound = _scalar("t_bound", t_bound, allow_inf=True)
        if self.t_bound < t:
            raise InvalidInputError(f"t_bound = {self.t_bound!r} is before the restart time t = {t!r}")
        if phi is not None:
            self.phi = self._check_phi(phi)
        self.t, self.q, self.v = t, q, v
        self.t_old = self.q_old = self.v_old = self.phi_old = None  # type: ignore[assignment]  # no step yet (class doc)
        self._y = self._point_y(q, v)
        self._f = self._point_f(t, q, v)
        self._after_restart()

    # -- hooks for subclasses -------------------------------------------------

    def _setup(self) -> None:
        pass

    def _after_truncate(self) -> None:
        pass

    def _after_restart(self) -> None:
        pass

    @abc.abstractmethod
    def _redo_variational(self, h: float) -> np.ndarray:
        """``phi`` at ``t_old + h``, propagated from ``phi_old`` over one step of size ``h``."""

    # -- shared machinery -----------------------------------------------------

    def _check_phi(self, phi) -> np.ndarray:
        if self.jac is None:
            raise InvalidInputError("a flow Jacobian (variational/phi) needs jac(t, q, v) -> (J_q, J_v)")
        arr = np.array(phi, dtype=float)
        if arr.ndim != 2 or arr.shape[0] != self.n:
            raise InvalidInputError(f"phi must have shape ({self.n}, m), got shape {arr.shape}")
        if not np.isfinite(arr).all():
            raise InvalidInputError("phi must be finite")
        return arr

    def _point_y(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``y`` of a point in its own chart: ``(q, v)`` or ``(0, v)``."""
        if self._vs:
            return np.concatenate((q, v))
        y = np.zeros(self.n)
        y[self.nv :] = v
        return y

    def _point_f(self, t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``dy/dt = (v, accel)`` at a point in its own chart (validates ``accel``)."""
        a = self.accel(t, q, v)
        self.n_accel += 1
        a = np.asarray(a, dtype=float)
        if a.shape != (self.nv,):
            raise InvalidInputError(f"accel must return shape ({self.nv},), got shape {a.shape}")
        if not np.isfinite(a).all():
            raise IntegrationError(f"accel returned non-finite values at t={float(t)!r}: {a.tolist()}")
        return np.concatenate((v, a))

    def _mag(self, y: np.ndarray, q: np.ndarray | None) -> np.ndarray:
        """Sizes that ``rtol`` is relative to, per component of ``y``."""
        if self._vs:
            return np.abs(y)
        assert q is not None  # off vector spaces the caller passes the point
        return np.concatenate((self.group.magnitude(q), np.abs(y[self.nv :])))

    def _eval_into(self, t: float, y: np.ndarray, out: np.ndarray, qc, accel=None) -> np.ndarray:
        """Write ``F(t, y)`` in the chart at ``qc`` (None: vector space) into ``out``; return the stage ``q``.

        ``accel`` overrides the current vector field (a lazy interpolant evaluates
        the field of the step it belongs to)."""
        nv = self.nv
        v = y[nv:]
        if qc is None:
            q = y[:nv]
            out[:nv] = v
        else:
            xi = y[:nv]
            q = self.group.integrate(qc, xi)
            out[:nv] = self.group.chart_velocity(qc, xi, v)
        out[nv:] = (self.accel if accel is None else accel)(t, q, v)
        self.n_accel += 1
        return q

    def _nonfinite_stage(self, t: float, y: np.ndarray, fa: np.ndarray) -> None:
        """Raise if ``accel`` returned non-finite values for a finite state."""
        if not np.isfinite(fa).all() and np.isfinite(y).all():
            raise IntegrationError(
                f"accel returned non-finite values at t={float(t)!r} (v={y[self.nv :].tolist()}); "
                "the vector field must be finite at every finite state"
            )

    def _initial_step(self) -> float:
        """The first step (s): `step_control.initial_step` at the current point."""

        def field(h0: float, y1: np.ndarray) -> np.ndarray | None:
            f1 = np.empty(self.n)
            try:
                self._eval_into(self.t + h0, y1, f1, None if self._vs else self.q)
            except OutsideDomainError:
                return None
            self._nonfinite_stage(self.t + h0, y1, f1[self.nv :])
            return f1

        return initial_step(
            self.t_bound - self.t,
            self.max_step,
            self._y,
            self._f,
            self._mag(self._y, self.q),
            self.atol,
            self.rtol,
            self.error_order,
            field,
        )

    def _roundoff_error(self, y: np.ndarray, y_new: np.ndarray, mag: np.ndarray) -> float:
        """`step_control.roundoff_error` of a step from ``y`` to ``y_new`` (``mag``: `_mag` at its start)."""
        return roundoff_error(y, y_new, mag, self.atol, self.rtol)

    def _begin_step(self) -> tuple[float, float]:
        """Check that a step is possible; return (min_step, first h to try)."""
        t = self.t
        if t >= self.t_bound:
            raise IntegrationError(f"cannot step: t = {t!r} is already at t_bound = {self.t_bound!r}")
        min_step = 10.0 * abs(np.nextafter(t, np.inf) - t)
        self._outside = None  # an `OutsideDomainError` met by a trial stage of this step
        return min_step, max(min(self.h_abs, self.max_step), min_step)

    def _step_end(self, t: float, h_abs: float) -> tuple[float, bool]:
        """End of a step of ``h_abs`` from ``t`` and whether ``t_bound`` (the final time or
        an effort's breakpoint) cut it short. A step cut short says nothing against the
        step the error control wanted: a subclass keeps that one for the next step."""
        clipped = t + h_abs > self.t_bound
        return (self.t_bound if clipped else t + h_abs), clipped

    def _underflow(self, h_abs: float, min_step: float) -> ContactDiffError:
        """The error of a step that shrank below ``min_step``: the field's own
        `OutsideDomainError` if trial stages kept leaving its domain, else an `IntegrationError`."""
        if self._outside is not None:
            exc = self._outside
            said = type(exc)(
                f"{exc} (at t = {float(self.t)!r} s every step down to h = {h_abs:.3g} s "
                "reaches such states: the trajectory itself does)"
            )
            said.__dict__.update(exc.__dict__)  # what the error carries (`PainleveError.contact`)
            return said
        return StepSizeUnderflowError(
            f"{self.method}: step size underflow at t={float(self.t)!r}: h={h_abs:.3g} < {min_step:.3g} "
            f"(rtol={self.rtol:g}); the vector field may be singular or non-smooth here",
            float(self.t),
            h_abs,
        )

    def _accept_state(self, t_new: float, y_new: np.ndarray, q_new: np.ndarray, a_new: np.ndarray) -> None:
        """Move the current point to the end of the accepted step."""
        self.t_old, self.q_old, self.v_old, self.phi_old = self.t, self.q, self.v, self.phi
        self.t = t_new
        nv = self.nv
        if self._vs:
            self._y = y_new
            self.q, self.v = y_new[:nv], y_new[nv:]
        else:
            self.q, self.v = q_new, y_new[nv:]
            self._y = self._point_y(q_new, self.v)
        self._f = np.concatenate((self.v, a_new))
        self.n_steps += 1
