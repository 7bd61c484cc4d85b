"""Efforts of a scene (generalised forces ``tau(q, v, t)`` in R^nv) and their derivatives.

Gravity, Coriolis and centrifugal terms come from Pinocchio (``nle``) and are not
listed here. Each effort is a robot-independent spec (`JointSpring`, `Spring`,
`UserEffort`, the trot controller of `contactdiff.control`, or any object that
follows the `Effort` protocol) whose ``bind(robot)`` returns an evaluator with

    tau(kin, t)              -> (nv,)   generalised force (N or N m per coordinate)
    derivatives(kin, t)      -> (dtau/dq, dtau/dv), each (nv × nv), tangent space
    time_derivative(kin, t)  -> (nv,)   d tau/dt at fixed state

where ``kin`` is a `Kinematics` updated at the state (with ``derivatives=True``
for the second call). An evaluator whose time dependence has breakpoints (a
schedule made of polynomial pieces, the end of a ramp) also has

    next_breakpoint(t)       -> float   the first time (s) after t where a time
                                        derivative of tau jumps, tau itself being
                                        continuous (inf: none left)

and the integrator ends a step exactly on each such time instead of stepping
across it: a high-order method that steps across a jump of the third
derivative rejects the step, or keeps a shorter one, again and again.

A spec with named parameters (`contactdiff.model.parameters`: a joint spring's
stiffness, a user effort's own numbers, ...) declares them with

    named_parameters()       -> EffortParameters  their kind, target and fields

and its evaluator also has

    parameter_derivatives(kin, t, fields) -> (nv × len(fields))  d tau/dp

with ``fields`` a sequence of ``(k, field)``: ``k`` says which spec of the
evaluator (always 0, except for the one evaluator of all joint springs, where
it is the spring's rank among them, see `bound_positions`) and ``field`` the
parameter's name.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import ClassVar, Protocol, runtime_checkable

import numpy as np

from ..errors import InvalidInputError, check_number
from .kinematics import Kinematics
from .robot import Robot


@runtime_checkable
class BoundEffort(Protocol):
    """An effort bound to a robot: what the scene and the dynamics evaluate."""

    def tau(self, kin: Kinematics, t: float) -> np.ndarray:
        """Generalised force (nv,) at the state of ``kin`` and time ``t`` (s)."""

    def derivatives(self, kin: Kinematics, t: float) -> tuple[np.ndarray, np.ndarray]:
        """``(d tau/dq, d tau/dv)``, each (nv × nv), tangent space (``kin`` updated with
        ``derivatives=True``)."""

    def time_derivative(self, kin: Kinematics, t: float) -> np.ndarray:
        """``d tau/dt`` (nv,) at fixed state (zero for an autonomous effort)."""

    # optional: ``autonomous_from(t) -> bool``, whether the effort no longer depends on time
    # after ``t`` (s); an effort without it counts as time-dependent (`Scene.autonomous_from`)


@dataclass(frozen=True)
class EffortParameters:
    """The named parameters an effort spec declares: ``kind:target:field`` for each field
    (``kind:field`` without a target; `contactdiff.model.parameters`).

    Attributes:
        kind: the first part of their names, a `contactdiff.model.parameters.ParameterKind`
            value of an effort: ``spring``, ``joint_spring``, ``trot`` or ``effort``.
        target: the spec's name ("" for none; ``#k`` is added where two specs share one).
        fields: the numbers' names, in order.
    """

    kind: str
    target: str
    fields: tuple[str, ...]


@runtime_checkable
class Effort(Protocol):
    """A robot-independent effort spec: `Scene` accepts any object with ``bind``."""

    def bind(self, robot: Robot) -> BoundEffort:
        """The evaluator of this effort on ``robot`` (names resolved, sizes checked)."""


@dataclass(frozen=True)
class JointSpring:
    """Spring-damper on one revolute or prismatic joint:
    ``tau = -stiffness (q_j - rest) - damping v_j``.

    Args:
        joint: joint name.
        stiffness: N/m or N m/rad, >= 0.
        damping: N s/m or N m s/rad, >= 0.
        rest: rest coordinate (m or rad).
    """

    joint: str
    stiffness: float
    damping: float = 0.0
    rest: float = 0.0
    FIELDS: ClassVar[tuple[str, ...]] = ("stiffness", "damping", "rest")
    """Its parameters ``joint_spring:<joint>:<field>`` (N m/rad, N m s/rad, rad or N/m, N s/m, m)."""

    def __post_init__(self) -> None:
        owner = f"joint spring on {self.joint!r}"
        for name, minimum in (("stiffness", 0.0), ("damping", 0.0), ("rest", None)):
            object.__setattr__(self, name, check_number(owner, name, getattr(self, name), minimum=minimum))

    def named_parameters(self) -> EffortParameters:
        """``joint_spring:<joint>:<field>`` for each of `FIELDS`."""
        return EffortParameters("joint_spring", self.joint, self.FIELDS)

    def bind(self, robot: Robot) -> _BoundJointSpring:
        """The evaluator of this spring on ``robot`` (the joint's indices resolved; it must
        be a one-coordinate joint)."""
        return _BoundJointSpring(self, robot)


class _BoundJointSpring:
    """One or several joint springs, evaluated together (index arrays, no Python loop)."""

    def __init__(self, specs: JointSpring | list[JointSpring], robot: Robot):
        specs = [specs] if isinstance(specs, JointSpring) else list(specs)
        self.specs = specs
        idx = [robot.scalar_joint(s.joint) for s in specs]
        self.iq = np.array([i for i, _ in idx], dtype=int)
        self.iv = np.array([i for _, i in idx], dtype=int)
        self.stiffness = np.array([s.stiffness for s in specs])
        self.damping = np.array([s.damping for s in specs])
        self.rest = np.array([s.rest for s in specs])
        self.nv = robot.nv
        self._unique = len(set(self.iv.tolist())) == len(self.iv)
        # springs on the same joint add up: accumulate with np.add.at
        self._dq = np.zeros((self.nv, self.nv))
        np.add.at(self._dq, (self.iv, self.iv), -self.stiffness)
        self._dv = np.zeros((self.nv, self.nv))
        np.add.at(self._dv, (self.iv, self.iv), -self.damping)

    def tau(self, kin: Kinematics, t: float) -> np.ndarray:
        out = np.zeros(self.nv)
        value = -self.stiffness * (kin.q[self.iq] - self.rest) - self.damping * kin.v[self.iv]
        if self._unique:
            out[self.iv] = value
        else:
            np.add.at(out, self.iv, value)
        return out

    def derivatives(self, kin: Kinematics, t: float) -> tuple[np.ndarray, np.ndarray]:
        return self._dq.copy(), self._dv.copy()

    def time_derivative(self, kin: Kinematics, t: float) -> np.ndarray:
        return np.zeros(self.nv)  # autonomous

    def autonomous_from(self, t: float) -> bool:
        """Whether the effort no longer depends on time after ``t`` (s): always."""
        return True

    _FIELDS = JointSpring.FIELDS

    def parameter_derivatives(self, kin: Kinematics, t: float, fields) -> np.ndarray:
        """``d tau/dp`` (nv × len(fields)) for ``fields`` = ``(k, field)`` pairs: spring ``k``
        (rank among the joint springs) and ``field`` in ``stiffness`` (``-(q_j - rest)``,
        N m/rad per N m/rad or N/m per N/m: rad or m), ``damping`` (``-v_j``) or ``rest``
        (``+stiffness``), on the spring's coordinate only. The index arrays of the last
        ``fields`` list are kept (the dynamics asks with the same list at every stage)."""
        last = self.__dict__.get("_last_fields")
        if last is None or last[0] is not fields:
            for k, field in fields:
                if field not in self._FIELDS:
                    raise InvalidInputError(f"joint spring on {self.specs[k].joint!r} has no parameter {field!r}")
            ks = np.array([k for k, _ in fields], dtype=int)
            codes = np.array([self._FIELDS.index(field) for _, field in fields], dtype=int)
            last = self._last_fields = (fields, ks, codes, np.arange(len(fields)))
        _, ks, codes, cols = last
        values = np.stack([-(kin.q[self.iq[ks]] - self.rest[ks]), -kin.v[self.iv[ks]], self.stiffness[ks]])
        out = np.zeros((self.nv, len(fields)))
        out[self.iv[ks], cols] = values[codes, cols]
        return out


@dataclass(frozen=True)
class Spring:
    """Linear spring-damper between the origins of two frames.

    With ``d = p_b - p_a`` (world), ``l = |d|``, ``u = d / l`` and ``l̇ = u · ḋ``,
    frame ``b`` is pulled by ``-(stiffness (l - rest_length) + damping l̇) u`` and
    frame ``a`` by the opposite force.

    Args:
        frame_a: name of the first frame (``a``).
        frame_b: name of the second frame (``b``).
        stiffness: N/m, >= 0.
        damping: N s/m, >= 0.
        rest_length: m, >= 0.
        name: label of the spring (its parameters are ``spring:<name>:stiffness``, ...,
            see `contactdiff.model.parameters`); defaults to ``"<frame_a>-<frame_b>"``.
    """

    frame_a: str
    frame_b: str
    stiffness: float
    damping: float = 0.0
    rest_length: float = 0.0
    name: str | None = None
    FIELDS: ClassVar[tuple[str, ...]] = ("stiffness", "damping", "rest_length")
    """Its parameters ``spring:<name>:<field>`` (N/m, N s/m, m)."""

    def __post_init__(self) -> None:
        owner = f"spring {self.frame_a!r}-{self.frame_b!r}"
        for name in ("stiffness", "damping", "rest_length"):
            object.__setattr__(self, name, check_number(owner, name, getattr(self, name), minimum=0.0))
        if self.name is None:
            object.__setattr__(self, "name", f"{self.frame_a}-{self.frame_b}")
        elif not isinstance(self.name, str) or not self.name:
            raise InvalidInputError(f"{owner}: name must be a non-empty string, got {self.name!r}")

    def named_parameters(self) -> EffortParameters:
        """``spring:<name>:<field>`` for each of `FIELDS`."""
        return EffortParameters("spring", str(self.name), self.FIELDS)

    def bind(self, robot: Robot) -> _BoundSpring:
        """The evaluator of this spring on ``robot`` (both frames resolved, distinct)."""
        return _BoundSpring(self, robot)


_MIN_LENGTH = 1e-9  # m; below this the spring direction is undefined


class _BoundSpring:
    def __init__(self, spec: Spring, robot: Robot):
        self.spec = spec
        self.fa, self.fb = robot.frame_id(spec.frame_a), robot.frame_id(spec.frame_b)
        if self.fa == self.fb:
            raise InvalidInputError(f"spring: frame_a and frame_b are both {spec.frame_a!r}")

    def _geometry(self, kin: Kinematics):
        d = kin.position(self.fb) - kin.position(self.fa)
        length = math.sqrt(d @ d)
        if length < _MIN_LENGTH:
            raise InvalidInputError(
                f"spring {self.spec.frame_a!r}-{self.spec.frame_b!r}: the frames coincide "
                f"(length {length:.3g} m), so the spring has no direction"
            )
        Jd = kin.jacobian(self.fb) - kin.jacobian(self.fa)
        return d, length, d / length, Jd

    def tau(self, kin: Kinematics, t: float) -> np.ndarray:
        s = self.spec
        _, length, u, Jd = self._geometry(kin)
        rate = u @ (Jd @ kin.v)
        return -(Jd.T @ u) * (s.stiffness * (length - s.rest_length) + s.damping * rate)

    def derivatives(self, kin: Kinematics, t: float) -> tuple[np.ndarray, np.ndarray]:
        s = self.spec
        _, length, u, Jd = self._geometry(kin)
        d_dot = Jd @ kin.v
        rate = u @ d_dot
        force = s.stiffness * (length - s.rest_length) + s.damping * rate
        JTu = Jd.T @ u
        du_dq = (Jd - np.outer(u, JTu)) / length  # (I - u u^T) Jd / l
        ddot_dq = kin.velocity_derivative(self.fb) - kin.velocity_derivative(self.fa)
        rate_dq = d_dot @ du_dq + u @ ddot_dq
        force_dq = s.stiffness * JTu + s.damping * rate_dq
        H = kin.hessian(self.fb) - kin.hessian(self.fa)  # d(Jd)/dq, (3, nv, nv)
        nv = H.shape[1]
        dq = -(((u * force) @ H.reshape(3, nv * nv)).reshape(nv, nv) + force * (Jd.T @ du_dq) + np.outer(JTu, force_dq))
        dv = -s.damping * np.outer(JTu, JTu)
        return dq, dv

    def time_derivative(self, kin: Kinematics, t: float) -> np.ndarray:
        return np.zeros(kin.v.size)  # autonomous

    def autonomous_from(self, t: float) -> bool:
        """Whether the effort no longer depends on time after ``t`` (s): always."""
        return True

    def parameter_derivatives(self, kin: Kinematics, t: float, fields) -> np.ndarray:
        """``d tau/dp`` (nv × len(fields)) for ``fields`` = ``(0, field)`` pairs, with
        ``Jdᵀu = (J_b - J_a)ᵀ u`` (m per unit q): ``stiffness`` ``-Jdᵀu (l - rest_length)``
        (N per N/m: m), ``damping`` ``-Jdᵀu l̇`` (m/s), ``rest_length`` ``+stiffness Jdᵀu``
        (N/m)."""
        s = self.spec
        _, length, u, Jd = self._geometry(kin)
        JTu = Jd.T @ u
        per_field = {
            "stiffness": lambda: -JTu * (length - s.rest_length),
            "damping": lambda: -JTu * (u @ (Jd @ kin.v)),
            "rest_length": lambda: s.stiffness * JTu,
        }
        out = np.zeros((JTu.size, len(fields)))
        for col, (_, field) in enumerate(fields):
            if field not in per_field:
                raise InvalidInputError(f"spring {s.name!r} has no parameter {field!r}")
            out[:, col] = per_field[field]()
        return out


def bind_efforts(specs, robot: Robot) -> list:
    """Bind effort specs on ``robot``; every `JointSpring` goes into one evaluator
    (a dozen joint springs then cost one vectorised call, not a dozen). The order
    is that of `bound_positions`."""
    joint_springs = [s for s in specs if isinstance(s, JointSpring)]
    bound = [_BoundJointSpring(joint_springs, robot)] if joint_springs else []
    return bound + [s.bind(robot) for s in specs if not isinstance(s, JointSpring)]


def bound_positions(specs) -> list[tuple[int, int]]:
    """Where each spec of ``specs`` went in `bind_efforts` ``(specs, robot)``: per spec
    ``(i, k)``, the index ``i`` of its evaluator in the returned list and its rank ``k``
    in that evaluator (the joint springs share evaluator 0, ranked in spec order; every
    other spec is alone in its own, ``k = 0``)."""
    n_joint = sum(isinstance(s, JointSpring) for s in specs)
    first = 1 if n_joint else 0
    positions, rank, other = [], 0, 0
    for s in specs:
        if isinstance(s, JointSpring):
            positions.append((0, rank))
            rank += 1
        else:
            positions.append((first + other, 0))
            other += 1
    return positions


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


def central_time_difference(effort, kin: Kinematics, t: float, step: float) -> np.ndarray:
    """``d tau/dt`` of a bound effort at fixed state by a central difference in ``t``
    (step in s; truncation ~ step² times the third time derivative, round-off
    ~ eps |tau| / step)."""
    return (effort.tau(kin, t + step) - effort.tau(kin, t - step)) / (2.0 * step)
