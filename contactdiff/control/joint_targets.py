"""Joint-space PD tracking of a smooth schedule of targets, with optional gravity
compensation: an effort for manipulators.

`JointTargets` is an effort spec like those of `contactdiff.model.efforts`
(``bind(robot)`` returns an evaluator with ``tau``, ``derivatives``,
``time_derivative`` and ``next_breakpoint``). On each listed joint ``j``
(revolute or prismatic, tangent index ``i_j``) it applies

    tau_j = [g_j(q)] + K_j (r_j(t) - q_j) + D_j (ṙ_j(t) - v_j)       (N m or N)

and nothing on any other coordinate: ``K_j`` in N m/rad or N/m, ``D_j`` in
N m s/rad or N s/m, ``r_j`` in rad or m, and ``g(q)`` (N m or N) the
generalised gravity of the robot's model (its own ``model.gravity``), taken
only on the listed rows and only with ``gravity_compensation``. Bodies on other
subtrees of the model (free objects appended to the universe) do not enter
those rows.

**Schedule.** Knots ``t_0 < ... < t_{n-1}`` (s) carry rows ``r_k``. Before
``t_0`` and after ``t_{n-1}`` the first / last row is held; between knots,
with ``u = (t - t_k) / (t_{k+1} - t_k)`` and the quintic smooth step
``S(u) = 10u³ - 15u⁴ + 6u⁵``,

    r = r_k + (r_{k+1} - r_k) S(u),   ṙ = Δ_k S'(u) / T_k,   r̈ = Δ_k S''(u) / T_k²,

``Δ_k = r_{k+1} - r_k``, ``T_k = t_{k+1} - t_k``: ``r``, ``ṙ`` and ``r̈`` are
continuous, and ``ṙ = r̈ = 0`` at every knot. The third derivative jumps at the
knots, which `JointTargetsEvaluator.next_breakpoint` lists so that the
integrator ends a step on each.

**Derivatives** (tangent space): ``dtau/dq`` has rows ``i_j`` equal to those of
``dg/dq`` (with gravity compensation) minus ``K_j`` at ``(i_j, i_j)``;
``dtau/dv = -D_j`` at ``(i_j, i_j)``; ``dtau/dt = K ṙ + D r̈`` on the listed
joints.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pinocchio as pin

from ..errors import InvalidInputError, check_names, check_number
from ..model.kinematics import Kinematics
from ..model.robot import Robot


def _times(owner: str, value) -> tuple[float, ...]:
    try:
        times = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise InvalidInputError(f"{owner}: times must be a sequence of knot times (s), got {value!r}") from None
    if times.ndim != 1 or not times.size:
        raise InvalidInputError(f"{owner}: times must be a sequence of one or more knot times (s), got {value!r}")
    if not np.isfinite(times).all():
        k = int(np.flatnonzero(~np.isfinite(times))[0])
        raise InvalidInputError(f"{owner}: times[{k}] is {float(times[k])!r}; knot times must be finite")
    if np.any(np.diff(times) <= 0.0):
        k = int(np.flatnonzero(np.diff(times) <= 0.0)[0])
        raise InvalidInputError(
            f"{owner}: times must increase strictly, got times[{k}] = {float(times[k])!r} "
            f"then times[{k + 1}] = {float(times[k + 1])!r} in {value!r}"
        )
    return tuple(times.tolist())


def _targets(owner: str, value, joints: tuple[str, ...], n_knots: int) -> tuple[tuple[float, ...], ...]:
    shape = (n_knots, len(joints))
    try:
        rows = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise InvalidInputError(
            f"{owner}: targets must be {shape[0]} rows (one a knot) of {shape[1]} numbers (one a joint), got {value!r}"
        ) from None
    if rows.shape != shape:
        raise InvalidInputError(
            f"{owner}: targets have shape {rows.shape}; expected {shape} (one row a knot, "
            f"one column a joint), got {value!r}"
        )
    if not np.isfinite(rows).all():
        k, j = (int(i) for i in np.argwhere(~np.isfinite(rows))[0])
        raise InvalidInputError(
            f"{owner}: targets[{k}][{j}] ({joints[j]}) is {float(rows[k, j])!r}; targets must be finite"
        )
    return tuple(tuple(row) for row in rows.tolist())


def _gains(owner: str, name: str, value, joints: tuple[str, ...]) -> float | tuple[float, ...]:
    """A number (all joints) as a float, or one number per joint as a tuple; each finite, >= 0."""
    try:
        items = None if isinstance(value, str) else list(value)
    except TypeError:
        items = None
    if items is None:
        return check_number(owner, name, value, minimum=0.0)
    if len(items) != len(joints):
        raise InvalidInputError(
            f"{owner}: {name} must be a number or one number per joint ({len(joints)}), got {value!r}"
        )
    return tuple(
        check_number(owner, f"{name}[{i}] ({joint})", x, minimum=0.0) for i, (joint, x) in enumerate(zip(joints, items))
    )


@dataclass(frozen=True)
class JointTargets:
    """PD tracking of a quintic-smooth schedule of joint targets (see the module notes).

    Args:
        joints: names of one-coordinate (revolute or prismatic) joints, distinct.
        times: knot times (s), finite, strictly increasing, at least one.
        targets: one row per knot, one value per joint (rad or m), finite.
        stiffness: ``K`` (N m/rad or N/m), >= 0: a number for all joints or one per joint.
        damping: ``D`` (N m s/rad or N s/m), >= 0, same rule.
        gravity_compensation: add the model's gravity torque ``g(q)`` on the listed joints.
        name: label of the effort in reports.

    The fields are kept normalised: tuples of names and floats, a gain as a float
    or a tuple of floats (one per joint).
    """

    joints: tuple[str, ...]
    times: tuple[float, ...]
    targets: tuple[tuple[float, ...], ...]
    stiffness: float | tuple
    damping: float | tuple = 0.0
    gravity_compensation: bool = False
    name: str = "joint targets"

    KEYS: ClassVar[tuple[str, ...]] = (
        "joints",
        "times",
        "targets",
        "stiffness",
        "damping",
        "gravity_compensation",
        "name",
    )
    """The keys a scene-file table of this effort may hold (its field names)."""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise InvalidInputError(f"joint targets: name must be a non-empty string, got {self.name!r}")
        owner = self.name
        joints = check_names(owner, "joints", self.joints)
        times = _times(owner, self.times)
        values = {
            "joints": joints,
            "times": times,
            "targets": _targets(owner, self.targets, joints, len(times)),
            "stiffness": _gains(owner, "stiffness", self.stiffness, joints),
            "damping": _gains(owner, "damping", self.damping, joints),
        }
        if not isinstance(self.gravity_compensation, (bool, np.bool_)):
            raise InvalidInputError(
                f"{owner}: gravity_compensation must be true or false, got {self.gravity_compensation!r}"
            )
        values["gravity_compensation"] = bool(self.gravity_compensation)
        for key, value in values.items():
            object.__setattr__(self, key, value)

    def bind(self, robot: Robot) -> JointTargetsEvaluator:
        """The evaluator on ``robot`` (each joint resolved; it must be a one-coordinate joint)."""
        return JointTargetsEvaluator(self, robot)


_LIMIT_TOL = 1e-12  # rad or m: a target computed to land on a limit (by a script, IK) may miss it by round-off


def _check_limits(spec: JointTargets, robot: Robot, iq: list[int]) -> None:
    """Refuse a target outside the model's position limits of its joint: the PD law
    would press the joint against its stop (the model does not enforce the limits,
    so it would move past it instead). A joint without finite limits (a URDF
    ``continuous`` joint, limits of ±1.8e308) or with an empty range takes any target."""
    model = robot.model
    biggest = np.finfo(float).max
    for j, (joint, i) in enumerate(zip(spec.joints, iq)):
        lower, upper = float(model.lowerPositionLimit[i]), float(model.upperPositionLimit[i])
        if not (-biggest < lower < upper < biggest):
            continue
        for k, row in enumerate(spec.targets):
            if not lower - _LIMIT_TOL <= row[j] <= upper + _LIMIT_TOL:
                raise InvalidInputError(
                    f"{spec.name}: targets[{k}][{j}] of joint {joint!r} is {row[j]!r}, outside the joint's "
                    f"position limits [{lower:g}, {upper:g}] (the model's); targets must lie within them"
                )


class JointTargetsEvaluator:
    """`JointTargets` bound to a robot: index arrays of the joints, the gains per joint,
    the schedule as arrays and a ``pinocchio.Data`` of its own."""

    def __init__(self, spec: JointTargets, robot: Robot):
        self.spec, self.model, self.data = spec, robot.model, robot.new_data()
        idx = [robot.scalar_joint(name) for name in spec.joints]
        _check_limits(spec, robot, [i for i, _ in idx])
        self.iq = np.array([i for i, _ in idx], dtype=int)
        self.iv = np.array([i for _, i in idx], dtype=int)
        m, self.nv = len(spec.joints), robot.nv
        self.stiffness = np.broadcast_to(np.asarray(spec.stiffness, dtype=float), (m,)).copy()
        self.damping = np.broadcast_to(np.asarray(spec.damping, dtype=float), (m,)).copy()
        self.rows = np.array(spec.targets, dtype=float)
        self.steps = np.diff(self.rows, axis=0)
        self.times = list(spec.times)  # a list: bisect on an array probes numpy scalars
        self.widths = np.diff(spec.times).tolist()
        self._dq = np.zeros((self.nv, self.nv))
        self._dq[self.iv, self.iv] = -self.stiffness
        self._dv = np.zeros((self.nv, self.nv))
        self._dv[self.iv, self.iv] = -self.damping

    def reference(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(r, ṙ, r̈)`` at time ``t`` (s), one entry per listed joint (rad or m, per s, per s²)."""
        k = bisect.bisect_right(self.times, t) - 1
        if k < 0 or k >= len(self.widths):
            row = self.rows[0] if k < 0 else self.rows[-1]
            zero = np.zeros_like(row)
            return row.copy(), zero, zero.copy()
        width, step = self.widths[k], self.steps[k]
        u = (t - self.times[k]) / width
        s = u**3 * (10.0 - 15.0 * u + 6.0 * u * u)
        ds = 30.0 * (u * (1.0 - u)) ** 2
        dds = 60.0 * u * (1.0 - u) * (1.0 - 2.0 * u)
        return self.rows[k] + step * s, step * (ds / width), step * (dds / (width * width))

    def tau(self, kin: Kinematics, t: float) -> np.ndarray:
        """Generalised force (nv,): the PD terms (and ``g``) on the listed joints, 0 elsewhere."""
        r, dr, _ = self.reference(t)
        value = self.stiffness * (r - kin.q[self.iq]) + self.damping * (dr - kin.v[self.iv])
        if self.spec.gravity_compensation:
            value += pin.computeGeneralizedGravity(self.model, self.data, kin.q)[self.iv]
        out = np.zeros(self.nv)
        out[self.iv] = value
        return out

    def derivatives(self, kin: Kinematics, t: float) -> tuple[np.ndarray, np.ndarray]:
        """``(dtau/dq, dtau/dv)``, each (nv × nv), tangent space."""
        dq = self._dq.copy()
        if self.spec.gravity_compensation:
            dg = pin.computeGeneralizedGravityDerivatives(self.model, self.data, kin.q)
            # the result may share the Data's buffer: the fancy index copies the rows
            dq[self.iv] += np.reshape(dg, (self.nv, self.nv))[self.iv]
        return dq, self._dv.copy()

    def time_derivative(self, kin: Kinematics, t: float) -> np.ndarray:
        """``dtau/dt = K ṙ + D r̈`` (N m/s or N/s) on the listed joints at fixed state."""
        _, dr, ddr = self.reference(t)
        out = np.zeros(self.nv)
        out[self.iv] = self.stiffness * dr + self.damping * ddr
        return out

    def autonomous_from(self, t: float) -> bool:
        """Whether the targets no longer move after ``t`` (s): past the last knot."""
        return t >= self.times[-1]

    def next_breakpoint(self, t: float) -> float:
        """The first knot time strictly after ``t`` (s), inf when none is left."""
        k = bisect.bisect_right(self.times, t)
        return self.times[k] if k < len(self.times) else math.inf
