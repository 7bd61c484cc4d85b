"""User efforts (`contactdiff.model.efforts`): `UserEffort`, a Python function of
``(q, v, t)`` and its own named numbers, with its Jacobians given or taken by
central differences."""

from __future__ import annotations

import bisect
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from ..errors import InvalidInputError, check_number
from .effort_protocol import EffortParameters, central_time_difference
from .kinematics import Kinematics
from .robot import Robot


@dataclass(frozen=True)
class UserEffort:
    """An effort given by a Python callable.

    Args:
        function: ``function(q, v, t) -> tau`` with ``tau`` of shape (nv,), in the
            robot's generalised coordinates (N or N m); with ``parameters``,
            ``function(q, v, t, **parameters)``.
        jacobian: optional ``jacobian(q, v, t) -> (dtau_dq, dtau_dv)`` in the tangent
            space. Without it, derivatives are central finite differences on the
            manifold with step ``fd_step`` (truncation error ~ step², round-off ~
            eps/step: 1e-6 balances both near 1e-10 relative for smooth efforts).
        name: label used in reports, and in the names of its parameters.
        time_derivative: optional ``time_derivative(q, v, t) -> dtau_dt`` (N/s or
            N m/s, shape (nv,)), the explicit time rate, used where a contact force
            is a guard (lift-off); without it, a central difference in ``t`` with
            step ``fd_step`` (1 s scale: relative error ~1e-10 as above).
        breakpoints: times (s) at which ``function`` is continuous but not smooth
            in ``t`` (the end of a ramp, a knot of a spline schedule); the
            integrator ends a step exactly on each (see the module notes). A
            force that jumps is better split into runs at the jump.
        parameters: the effort's own named numbers, a mapping (or ``(name, value)``
            pairs) from a Python identifier to a finite float, e.g. ``{"k": 2.0}``;
            kept as a tuple of pairs in the given order. When given, *every*
            callable of the effort (``function``, ``jacobian``, ``time_derivative``,
            ``parameter_jacobian``) receives them as keyword arguments
            (``function(q, v, t, k=2.0)``); without them the callables are called as
            before. They are the scene's parameters ``effort:<name>:<parameter>``
            (`contactdiff.model.parameters`): ``Scene.with_parameters`` changes them,
            and the dynamics differentiates through them.
        parameter_jacobian: optional ``parameter_jacobian(q, v, t, **parameters)``
            returning ``d tau/dp`` of shape (nv, len(parameters)), columns in the
            order of ``parameters`` (N or N m per unit of the parameter). Without it,
            a central difference in each parameter with step
            ``fd_step * max(1, |value|)`` (error as above, relative to that scale).
    """

    function: Callable
    jacobian: Callable | None = None
    name: str = "user effort"
    fd_step: float = 1e-6
    time_derivative: Callable | None = None
    breakpoints: tuple = ()
    parameters: tuple = ()
    parameter_jacobian: Callable | None = None

    def __post_init__(self) -> None:
        if not callable(self.function):
            raise InvalidInputError(f"{self.name}: function must be callable, got {self.function!r}")
        for field_name in ("jacobian", "time_derivative", "parameter_jacobian"):
            value = getattr(self, field_name)
            if value is not None and not callable(value):
                raise InvalidInputError(f"{self.name}: {field_name} must be callable or None, got {value!r}")
        check_number(self.name, "fd_step", self.fd_step, minimum=1e-15)
        try:
            times = [check_number(self.name, "breakpoint", t) for t in self.breakpoints]
        except TypeError:
            raise InvalidInputError(
                f"{self.name}: breakpoints must be a sequence of times (s), got {self.breakpoints!r}"
            ) from None
        object.__setattr__(self, "breakpoints", tuple(sorted(set(times))))
        object.__setattr__(self, "parameters", _named_numbers(self.name, self.parameters))
        if self.parameter_jacobian is not None and not self.parameters:
            raise InvalidInputError(f"{self.name}: parameter_jacobian is given but the effort has no parameters")

    def named_parameters(self) -> EffortParameters:
        """``effort:<name>:<parameter>`` for each of its own ``parameters``, in order."""
        return EffortParameters("effort", self.name, tuple(name for name, _ in self.parameters))

    def bind(self, robot: Robot) -> _BoundUserEffort:
        """The evaluator of this effort on ``robot`` (its output checked for shape (nv,) and
        finiteness at every call)."""
        return _BoundUserEffort(self, robot)


def _named_numbers(owner: str, value) -> tuple[tuple[str, float], ...]:
    """``value`` (a mapping or ``(name, number)`` pairs) as a tuple of pairs with distinct
    identifier names and finite float values."""
    items = value.items() if isinstance(value, Mapping) else value
    try:
        pairs = [(name, number) for name, number in items]
    except (TypeError, ValueError):
        raise InvalidInputError(f"{owner}: parameters must map names to numbers, got {value!r}") from None
    out = []
    for name, number in pairs:
        if not isinstance(name, str) or not name.isidentifier():
            raise InvalidInputError(
                f"{owner}: parameter names must be Python identifiers (they are passed "
                f"as keyword arguments), got {name!r}"
            )
        out.append((name, check_number(owner, f"parameter {name!r}", number)))
    names = [name for name, _ in out]
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated:
        raise InvalidInputError(f"{owner}: parameter names must be distinct; repeated: {', '.join(repeated)}")
    return tuple(out)


class _BoundUserEffort:
    def __init__(self, spec: UserEffort, robot: Robot):
        self.spec, self.robot = spec, robot
        self._kwargs = dict(spec.parameters)
        self._names = [name for name, _ in spec.parameters]
        if spec.breakpoints:
            self.next_breakpoint = self._next_breakpoint

    def _next_breakpoint(self, t: float) -> float:
        i = bisect.bisect_right(self.spec.breakpoints, t)
        return self.spec.breakpoints[i] if i < len(self.spec.breakpoints) else math.inf

    def _call(self, q, v, t, kwargs=None) -> np.ndarray:
        tau = np.asarray(self.spec.function(q, v, t, **(self._kwargs if kwargs is None else kwargs)), dtype=float)
        if tau.shape != (self.robot.nv,):
            raise InvalidInputError(
                f"{self.spec.name}: function returned shape {tau.shape}, expected ({self.robot.nv},)"
            )
        if not np.all(np.isfinite(tau)):
            raise InvalidInputError(f"{self.spec.name}: function returned non-finite values at t={t}: {tau}")
        return tau

    def tau(self, kin: Kinematics, t: float) -> np.ndarray:
        return self._call(kin.q, kin.v, t)

    def derivatives(self, kin: Kinematics, t: float) -> tuple[np.ndarray, np.ndarray]:
        q, v, nv = kin.q, kin.v, self.robot.nv
        if self.spec.jacobian is not None:
            dq, dv = (np.asarray(x, dtype=float) for x in self.spec.jacobian(q, v, t, **self._kwargs))
            if dq.shape != (nv, nv) or dv.shape != (nv, nv):
                raise InvalidInputError(
                    f"{self.spec.name}: jacobian returned shapes {dq.shape}, {dv.shape}; expected ({nv}, {nv})"
                )
            return dq, dv
        h = self.spec.fd_step
        dq, dv = np.empty((nv, nv)), np.empty((nv, nv))
        for k in range(nv):
            e = np.zeros(nv)
            e[k] = h
            dq[:, k] = (
                self._call(self.robot.integrate(q, e), v, t) - self._call(self.robot.integrate(q, -e), v, t)
            ) / (2 * h)
            dv[:, k] = (self._call(q, v + e, t) - self._call(q, v - e, t)) / (2 * h)
        return dq, dv

    def time_derivative(self, kin: Kinematics, t: float) -> np.ndarray:
        if self.spec.time_derivative is None:
            return central_time_difference(self, kin, t, self.spec.fd_step)
        rate = np.asarray(self.spec.time_derivative(kin.q, kin.v, t, **self._kwargs), dtype=float)
        if rate.shape != (self.robot.nv,) or not np.all(np.isfinite(rate)):
            raise InvalidInputError(
                f"{self.spec.name}: time_derivative returned {rate!r}; expected {self.robot.nv} finite numbers"
            )
        return rate

    def parameter_derivatives(self, kin: Kinematics, t: float, fields) -> np.ndarray:
        """``d tau/dp`` (nv × len(fields)) for ``fields`` = ``(0, name)`` pairs, ``name`` one
        of the effort's ``parameters``: from ``parameter_jacobian`` if given, else by
        central differences (see `UserEffort`)."""
        nv, names = self.robot.nv, [field for _, field in fields]
        for name in names:
            if name not in self._kwargs:
                raise InvalidInputError(
                    f"{self.spec.name}: no parameter {name!r}; its parameters: {', '.join(self._names) or '(none)'}"
                )
        columns = [self._names.index(name) for name in names]
        if self.spec.parameter_jacobian is not None:
            J = np.asarray(self.spec.parameter_jacobian(kin.q, kin.v, t, **self._kwargs), dtype=float)
            if J.shape != (nv, len(self._names)) or not np.all(np.isfinite(J)):
                raise InvalidInputError(
                    f"{self.spec.name}: parameter_jacobian returned shape {J.shape}"
                    f"{'' if J.shape != (nv, len(self._names)) else ' with non-finite entries'}; "
                    f"expected {nv} x {len(self._names)} finite numbers (one column a parameter)"
                )
            return J[:, columns].copy()
        out = np.empty((nv, len(names)))
        for col, name in enumerate(names):
            value = self._kwargs[name]
            h = self.spec.fd_step * max(1.0, abs(value))
            plus, minus = dict(self._kwargs), dict(self._kwargs)
            plus[name], minus[name] = value + h, value - h  # the step as represented: plus - minus
            out[:, col] = (self._call(kin.q, kin.v, t, plus) - self._call(kin.q, kin.v, t, minus)) / (
                plus[name] - minus[name]
            )
        return out
