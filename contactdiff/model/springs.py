"""Springs as efforts (`contactdiff.model.efforts`): `JointSpring` on one joint
coordinate (all of a scene's bound into one vectorised evaluator) and `Spring`
between two frames, with their closed-form derivatives in the state and in their
named parameters."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..errors import InvalidInputError, check_number
from .effort_protocol import EffortParameters
from .kinematics import Kinematics
from .robot import Robot


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

    def bind(self, robot: Robot) -> BoundJointSprings:
        """The evaluator of this spring on ``robot`` (the joint's indices resolved; it must
        be a one-coordinate joint)."""
        return BoundJointSprings(self, robot)


class BoundJointSprings:
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
        """The springs' generalised force (nv,) at the state of ``kin``."""
        out = np.zeros(self.nv)
        value = -self.stiffness * (kin.q[self.iq] - self.rest) - self.damping * kin.v[self.iv]
        if self._unique:
            out[self.iv] = value
        else:
            np.add.at(out, self.iv, value)
        return out

    def derivatives(self, kin: Kinematics, t: float) -> tuple[np.ndarray, np.ndarray]:
        """``(d tau/dq, d tau/dv)``: constant, minus the stiffnesses and dampings on the diagonal."""
        return self._dq.copy(), self._dv.copy()

    def time_derivative(self, kin: Kinematics, t: float) -> np.ndarray:
        """Zero: the springs do not depend on time."""
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
