"""The effort protocol (`contactdiff.model.efforts` has its notes): `Effort` (a spec
with ``bind(robot)``), `BoundEffort` (its evaluator), `EffortParameters` (the named
parameters a spec declares), and the time derivative by central differences that
evaluators without a closed form use."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

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


def central_time_difference(effort, kin: Kinematics, t: float, step: float) -> np.ndarray:
    """``d tau/dt`` of a bound effort at fixed state by a central difference in ``t``
    (step in s; truncation ~ step² times the third time derivative, round-off
    ~ eps |tau| / step)."""
    return (effort.tau(kin, t + step) - effort.tau(kin, t - step)) / (2.0 * step)
