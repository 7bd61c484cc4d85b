"""The trot controller's torques differentiated in its own numbers and in the robot's model.

A mixin of `contactdiff.control.trot_controller.TrotControllerEvaluator` (kept apart: it
is used only when parameters are differentiated, `contactdiff.model.parameters`). The
gains ``kp`` and ``kd`` and the clock's ``t_start`` have closed forms; the schedule's
other numbers, which move the breakpoints and the reference, central differences
through controllers bound anew; the model's parameters act through the feed-forward,
computed from the model when the controller is bound.
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING, Any, ClassVar, Protocol

import numpy as np

from ..errors import InvalidInputError
from ..model.kinematics import Kinematics
from .piecewise import PiecewisePolynomial

if TYPE_CHECKING:
    import pinocchio as pin

    from ..model.robot import Robot


class TrotSpec(Protocol):
    """What the derivatives read of the controller's spec
    (`contactdiff.control.trot_controller.TrotController`, a frozen dataclass)."""

    NUMBERS: ClassVar[tuple[str, ...]]
    """Its real numbers, the parameters ``trot:<field>``."""

    @property
    def feedforward(self) -> bool:
        """Whether the torques carry the feed-forward (leg gravity, scheduled load)."""

    def bind(self, robot: Robot) -> Any:
        """The evaluator of the spec on ``robot`` (a controller bound anew)."""


class TrotParameterDerivatives:
    """``d tau/dp`` of a bound trot controller (needs the evaluator's ``spec``, ``robot``,
    ``nv``, ``iv``, ``iq``, ``tau``, ``time_derivative``, ``_phase_terms``, ``_schedule``,
    ``_static_terms``)."""

    if TYPE_CHECKING:  # the evaluator's state it borrows (set there), for the type checker only
        spec: TrotSpec
        robot: Robot
        nv: int
        iq: np.ndarray
        iv: np.ndarray
        load_scale: float
        _schedule: PiecewisePolynomial
        _DEGREE: int

        def phase(self, t: float) -> float:
            """The gait phase at ``t`` (the evaluator's)."""

        def tau(self, kin: Kinematics, t: float) -> np.ndarray:
            """The efforts at ``t`` (the evaluator's)."""

        def time_derivative(self, kin: Kinematics, t: float) -> np.ndarray:
            """``d tau/dt`` at ``t`` (the evaluator's)."""

        def _phase_terms(self, phis: np.ndarray): ...
        def _static_terms(self, model: pin.Model | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]: ...

    SCHEDULE_STEP = 1e-5
    """Relative step of the central differences in the schedule numbers (see
    `parameter_derivatives`): ``SCHEDULE_STEP * max(|value|, 0.1)``."""

    def _parameter_terms(self, t: float) -> np.ndarray:
        """``(g q*, g, g q̇*)`` of the leg joints and the four loads ``w`` at time ``t`` (s),
        from a second table of the schedule, built on first use (a controller whose
        parameters are never differentiated pays nothing)."""
        table = self.__dict__.get("_parameter_table")
        if table is None:

            def sample(phis):
                q_ref, v_ref, g, loads = self._phase_terms(phis)
                return np.hstack([g * q_ref, g, g * v_ref, loads])

            table = self._parameter_table = PiecewisePolynomial(self._schedule.starts, sample, self._DEGREE)
        return table(self.phase(t))

    def parameter_derivatives(self, kin: Kinematics, t: float, fields) -> np.ndarray:
        """``d tau/dp`` (nv × len(fields)) for ``fields`` = ``(0, field)`` pairs, ``field`` in
        `PARAMETERS`, at the state of ``kin`` and time ``t`` (s); zero off the leg joints.

        * ``kp``: ``g (q* - q)`` (N m per N m/rad: rad); ``kd``: ``g (q̇* - v)`` (rad/s);
          exact (from a table of ``g q*``, ``g``, ``g q̇*``, like `tau`'s).
        * ``t_start``: ``-d tau/dt`` at fixed state (the clock is ``t - t_start``), i.e.
          `time_derivative` with its sign changed.
        * the other schedule numbers move the breakpoints and the reference (the
          inverse kinematics is solved again): a central difference of `tau` through
          controllers bound with the number at ``p ± h``, ``h = SCHEDULE_STEP *
          max(|p|, 0.1)`` (0.1 s, 0.1 m or a tenth of the period for the phase
          fractions); where ``p - h`` (or ``p + h``) is not a valid controller (e.g.
          ``release_gain = 0``), the second-order one-sided difference from ``p``,
          ``p + h``, ``p + 2h`` (or the other side). The two controllers are bound
          once per number (~0.04 s each), then each call costs two `tau` evaluations.
          Error: truncation ``~h² |d³tau/dp³|`` plus the tables' and the inverse
          kinematics' round-off over ``h``; on solo12's trot, against Richardson
          extrapolations of differences 100 times wider, 1e-9 to 1e-7 N m per unit
          of the number, 3e-6 at worst (the period, where ``|d tau/dp|`` reaches 160).
        """
        out = np.zeros((self.nv, len(fields)))
        iv, n = self.iv, self.iv.size
        terms = self._parameter_terms(t) if any(f in ("kp", "kd") for _, f in fields) else None
        for col, (_, field) in enumerate(fields):
            if field in ("kp", "kd"):
                assert terms is not None  # computed above for kp and kd
                if field == "kp":
                    out[iv, col] = terms[:n] - terms[n : 2 * n] * kin.q[self.iq]
                else:
                    out[iv, col] = terms[2 * n : 3 * n] - terms[n : 2 * n] * kin.v[iv]
            elif field == "t_start":
                out[:, col] = -self.time_derivative(kin, t)
            elif field in type(self.spec).NUMBERS:
                out[:, col] = self._schedule_difference(field, kin, t)
            else:
                raise InvalidInputError(
                    f"trot controller has no parameter {field!r}; its parameters: {', '.join(type(self.spec).NUMBERS)}"
                )
        return out

    def _schedule_difference(self, field: str, kin: Kinematics, t: float) -> np.ndarray:
        cache = self.__dict__.setdefault("_schedule_variants", {})
        if field not in cache:
            cache[field] = self._variants(field)
        weights, evaluators = cache[field]
        total = np.zeros(self.nv)
        for w, ev in zip(weights, evaluators):
            total += w * (self if ev is None else ev).tau(kin, t)
        return total

    def _variants(self, field: str) -> tuple[list[float], list]:
        """Weights and controllers (None: this one) of the difference formula in ``field``."""
        value = getattr(self.spec, field)
        h = self.SCHEDULE_STEP * max(abs(value), 0.1)

        def bound(x):
            try:
                return replace(self.spec, **{field: x}).bind(self.robot)
            except InvalidInputError:
                return None

        plus, minus = bound(value + h), bound(value - h)
        if plus is not None and minus is not None:
            step = (value + h) - (value - h)
            return [1.0 / step, -1.0 / step], [plus, minus]
        for sign, near in ((1.0, plus), (-1.0, minus)):
            far = bound(value + 2.0 * sign * h) if near is not None else None
            if far is not None:  # (-3 f(p) + 4 f(p + h) - f(p + 2h)) / (2h), h signed
                return [-1.5 / (sign * h), 2.0 / (sign * h), -0.5 / (sign * h)], [None, near, far]
        raise InvalidInputError(
            f"trot controller: cannot differentiate in {field} = {value!r}: neither "
            f"{field} +- {h:.3g} nor two steps to one side make a valid controller"
        )

    def model_parameter_derivatives(self, kin: Kinematics, t: float, perturbed) -> np.ndarray:
        """``d tau/dp`` (nv × len(perturbed)) for parameters of the robot's model (a body's
        mass, centre of mass, inertia, a joint's armature, gravity): the feed-forward's
        stance-pose terms (leg gravity torques, the weight each leg carries) are computed
        from the model when the controller is bound, so a scene built with other masses
        or gravity has another feed-forward. Zero without feed-forward.

        Args:
            kin: kinematics at the state (only the time matters: the terms are the
                feed-forward's).
            t: time (s).
            perturbed: per parameter ``(name, step, make)``: ``make(x)`` returns a copy of
                the model with the parameter moved by ``x`` (its unit), ``step`` the step
                of a central difference of the stance-pose terms. Those terms do not
                depend on time, so their derivative is computed on the first call with a
                given ``perturbed`` list and kept for later calls with the same list
                object (the next list replaces it). They are affine in each
                body's mass and centre of mass (``m``, ``m c``) and in gravity, and do
                not depend on inertia or armature, so the difference is exact up to
                round-off, except where a leg's share of the weight is clipped to 0 or 1
                (a centre of mass beyond the line of a diagonal pair's feet).
        """
        out = np.zeros((self.nv, len(perturbed)))
        if not self.spec.feedforward:
            return out
        stacked = self.__dict__.get("_model_derivatives")
        if stacked is None or stacked[0] is not perturbed:  # the same list at every stage: kept
            d_gravity, d_carry = np.zeros((self.iv.size, len(perturbed))), np.zeros((4, self.iv.size, len(perturbed)))
            for col, (key, step, make) in enumerate(perturbed):
                g_plus, c_plus, _ = self._static_terms(make(step))
                g_minus, c_minus, _ = self._static_terms(make(-step))
                d_gravity[:, col] = (g_plus - g_minus) / (2.0 * step)
                d_carry[:, :, col] = (c_plus - c_minus) / (2.0 * step)
            stacked = self._model_derivatives = (perturbed, d_gravity, d_carry.reshape(4, -1))
        _, gravity_derivative, carry_derivative = stacked  # carry's reshaped to (4, joints × parameters)
        loads = self._parameter_terms(t)[3 * self.iv.size :]
        out[self.iv] = gravity_derivative + self.load_scale * (loads @ carry_derivative).reshape(
            gravity_derivative.shape
        )
        return out
