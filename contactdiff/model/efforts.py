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
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

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

    def __post_init__(self) -> None:
        owner = f"joint spring on {self.joint!r}"
        for name, minimum in (("stiffness", 0.0), ("damping", 0.0), ("rest", None)):
            object.__setattr__(self, name, check_number(owner, name, getattr(self, name), minimum=minimum))

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


@dataclass(frozen=True)
class Spring:
    """Linear spring-damper between the origins of two frames.

    With ``d = p_b - p_a`` (world), ``l = |d|``, ``u = d / l`` and ``l̇ = u · ḋ``,
    frame ``b`` is pulled by ``-(stiffness (l - rest_length) + damping l̇) u`` and
    frame ``a`` by the opposite force.

    Args:
        frame_a, frame_b: frame names.
        stiffness: N/m, >= 0.  damping: N s/m, >= 0.  rest_length: m, >= 0.
    """

    frame_a: str
    frame_b: str
    stiffness: float
    damping: float = 0.0
    rest_length: float = 0.0

    def __post_init__(self) -> None:
        owner = f"spring {self.frame_a!r}-{self.frame_b!r}"
        for name in ("stiffness", "damping", "rest_length"):
            object.__setattr__(self, name, check_number(owner, name, getattr(self, name), minimum=0.0))

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
                f"(length {length:.3g} m), so the spring has no direction")
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
        dq = -(((u * force) @ H.reshape(3, nv * nv)).reshape(nv, nv)
               + force * (Jd.T @ du_dq) + np.outer(JTu, force_dq))
        dv = -s.damping * np.outer(JTu, JTu)
        return dq, dv

    def time_derivative(self, kin: Kinematics, t: float) -> np.ndarray:
        return np.zeros(kin.v.size)  # autonomous


def bind_efforts(specs, robot: Robot) -> list:
    """Bind effort specs on ``robot``; every `JointSpring` goes into one evaluator
    (a dozen joint springs then cost one vectorised call, not a dozen)."""
    joint_springs = [s for s in specs if isinstance(s, JointSpring)]
    bound = [_BoundJointSpring(joint_springs, robot)] if joint_springs else []
    return bound + [s.bind(robot) for s in specs if not isinstance(s, JointSpring)]


@dataclass(frozen=True)
class UserEffort:
    """An effort given by a Python callable.

    Args:
        function: ``function(q, v, t) -> tau`` with ``tau`` of shape (nv,), in the
            robot's generalised coordinates (N or N m).
        jacobian: optional ``jacobian(q, v, t) -> (dtau_dq, dtau_dv)`` in the tangent
            space. Without it, derivatives are central finite differences on the
            manifold with step ``fd_step`` (truncation error ~ step², round-off ~
            eps/step: 1e-6 balances both near 1e-10 relative for smooth efforts).
        name: label used in reports.
        time_derivative: optional ``time_derivative(q, v, t) -> dtau_dt`` (N/s or
            N m/s, shape (nv,)), the explicit time rate, used where a contact force
            is a guard (lift-off); without it, a central difference in ``t`` with
            step ``fd_step`` (1 s scale: relative error ~1e-10 as above).
        breakpoints: times (s) at which ``function`` is continuous but not smooth
            in ``t`` (the end of a ramp, a knot of a spline schedule); the
            integrator ends a step exactly on each (see the module notes). A
            force that jumps is better split into runs at the jump.
    """

    function: Callable
    jacobian: Callable | None = None
    name: str = "user effort"
    fd_step: float = 1e-6
    time_derivative: Callable | None = None
    breakpoints: tuple = ()

    def __post_init__(self) -> None:
        if not callable(self.function):
            raise InvalidInputError(f"{self.name}: function must be callable, got {self.function!r}")
        for field_name in ("jacobian", "time_derivative"):
            value = getattr(self, field_name)
            if value is not None and not callable(value):
                raise InvalidInputError(f"{self.name}: {field_name} must be callable or None, got {value!r}")
        check_number(self.name, "fd_step", self.fd_step, minimum=1e-15)
        try:
            times = [check_number(self.name, "breakpoint", t) for t in self.breakpoints]
        except TypeError:
            raise InvalidInputError(f"{self.name}: breakpoints must be a sequence of times (s), "
                                    f"got {self.breakpoints!r}") from None
        object.__setattr__(self, "breakpoints", tuple(sorted(set(times))))

    def bind(self, robot: Robot) -> _BoundUserEffort:
        """The evaluator of this effort on ``robot`` (its output checked for shape (nv,) and
        finiteness at every call)."""
        return _BoundUserEffort(self, robot)


class _BoundUserEffort:
    def __init__(self, spec: UserEffort, robot: Robot):
        self.spec, self.robot = spec, robot
        if spec.breakpoints:
            self.next_breakpoint = self._next_breakpoint

    def _next_breakpoint(self, t: float) -> float:
        i = bisect.bisect_right(self.spec.breakpoints, t)
        return self.spec.breakpoints[i] if i < len(self.spec.breakpoints) else math.inf

    def _call(self, q, v, t) -> np.ndarray:
        tau = np.asarray(self.spec.function(q, v, t), dtype=float)
        if tau.shape != (self.robot.nv,):
            raise InvalidInputError(
                f"{self.spec.name}: function returned shape {tau.shape}, expected ({self.robot.nv},)")
        if not np.all(np.isfinite(tau)):
            raise InvalidInputError(f"{self.spec.name}: function returned non-finite values at t={t}: {tau}")
        return tau

    def tau(self, kin: Kinematics, t: float) -> np.ndarray:
        return self._call(kin.q, kin.v, t)

    def derivatives(self, kin: Kinematics, t: float) -> tuple[np.ndarray, np.ndarray]:
        q, v, nv = kin.q, kin.v, self.robot.nv
        if self.spec.jacobian is not None:
            dq, dv = (np.asarray(x, dtype=float) for x in self.spec.jacobian(q, v, t))
            if dq.shape != (nv, nv) or dv.shape != (nv, nv):
                raise InvalidInputError(
                    f"{self.spec.name}: jacobian returned shapes {dq.shape}, {dv.shape}; expected ({nv}, {nv})")
            return dq, dv
        h = self.spec.fd_step
        dq, dv = np.empty((nv, nv)), np.empty((nv, nv))
        for k in range(nv):
            e = np.zeros(nv)
            e[k] = h
            dq[:, k] = (self._call(self.robot.integrate(q, e), v, t)
                        - self._call(self.robot.integrate(q, -e), v, t)) / (2 * h)
            dv[:, k] = (self._call(q, v + e, t) - self._call(q, v - e, t)) / (2 * h)
        return dq, dv

    def time_derivative(self, kin: Kinematics, t: float) -> np.ndarray:
        if self.spec.time_derivative is None:
            return central_time_difference(self, kin, t, self.spec.fd_step)
        rate = np.asarray(self.spec.time_derivative(kin.q, kin.v, t), dtype=float)
        if rate.shape != (self.robot.nv,) or not np.all(np.isfinite(rate)):
            raise InvalidInputError(f"{self.spec.name}: time_derivative returned {rate!r}; "
                                    f"expected {self.robot.nv} finite numbers")
        return rate


def central_time_difference(effort, kin: Kinematics, t: float, step: float) -> np.ndarray:
    """``d tau/dt`` of a bound effort at fixed state by a central difference in ``t``
    (step in s; truncation ~ step² times the third time derivative, round-off
    ~ eps |tau| / step)."""
    return (effort.tau(kin, t + step) - effort.tau(kin, t - step)) / (2.0 * step)
