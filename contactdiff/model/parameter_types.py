"""What a named parameter of a scene is: its kind, its name ``kind:target:field``
and where its number lives (part of `contactdiff.model.parameters`, which has the
naming rules and units), and what of a scene the parameters read and rebuild
(`ParametrisedScene`: `contactdiff.model.scene.Scene` is one; the parameters' code
depends on that protocol, not on the scene's module, which calls it)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from enum import Enum
from typing import Any, Protocol, Self

import pinocchio as pin

from .contacts import Contact
from .robot import Robot


class ParameterKind(Enum):
    """What a parameter belongs to (its value is the first part of its name)."""

    BODY = "body"
    JOINT = "joint"
    CONTACT = "contact"
    SPRING = "spring"
    JOINT_SPRING = "joint_spring"
    TROT = "trot"
    EFFORT = "effort"
    SCENE = "scene"
    GROUP = "group"


BODY_FIELDS = ("mass", "com_x", "com_y", "com_z", "ixx", "ixy", "ixz", "iyy", "iyz", "izz")
"""Fields of a body: mass (kg), centre of mass (m, link frame), inertia about it (kg m², link axes)."""
JOINT_FIELDS = ("armature",)
SCENE_FIELDS = ("gravity_x", "gravity_y", "gravity_z")

MODEL_KINDS = (ParameterKind.BODY, ParameterKind.JOINT, ParameterKind.SCENE)
"""Kinds whose numbers live in the Pinocchio model (inertias, armatures, gravity)."""
EFFORT_KINDS = (ParameterKind.SPRING, ParameterKind.JOINT_SPRING, ParameterKind.TROT, ParameterKind.EFFORT)
"""Kinds whose numbers an effort spec declares (`EffortParameters`) and its evaluator differentiates."""


@dataclass(frozen=True)
class Parameter:
    """One named parameter of a scene.

    Attributes:
        kind: what it belongs to.
        target: the link, joint, contact, spring or effort name ("" for ``trot`` and
            ``scene``; ``#k`` suffixes as in the module notes).
        field: the number's name (``mass``, ``stiffness``, ``kp``, ``gravity_z``, ...).
        joint: Pinocchio joint index for ``body`` (``model.inertias[joint]``) and
            ``joint`` (its tangent index is ``model.joints[joint].idx_v``); 0 otherwise.
        index: position of the spec in ``scene.contact_specs`` (``contact``) or in
            ``scene.effort_specs`` (``spring``, ``joint_spring``, ``trot``, ``effort``);
            -1 otherwise.
        members: positions in ``scene.contact_specs`` of the contacts it sets (one for
            ``contact``, the group's for ``group``); empty otherwise.
    """

    kind: ParameterKind
    target: str
    field: str
    joint: int = 0
    index: int = -1
    members: tuple[int, ...] = ()

    @property
    def name(self) -> str:
        """``kind:target:field``, or ``kind:field`` when there is no target."""
        head = f"{self.kind.value}:{self.target}" if self.target else self.kind.value
        return f"{head}:{self.field}"

    def __str__(self) -> str:
        return self.name


class ParametrisedScene(Protocol):
    """What the named parameters read of a scene and how they build a changed one
    (`contactdiff.model.scene.Scene` has it all). Its ``__dict__`` holds the lists
    and plans computed once per scene (``_parameter_list``, ``_parameter_index``,
    ``_parameter_plans``)."""

    @property
    def name(self) -> str:
        """Label for reports (named in the messages)."""
        ...

    @property
    def robot(self) -> Robot:
        """The robot; its model holds the body, joint and gravity numbers."""
        ...

    @property
    def model(self) -> pin.Model:
        """The robot's Pinocchio model."""
        ...

    @property
    def nv(self) -> int:
        """Tangent (velocity) size."""
        ...

    @property
    def contact_specs(self) -> Sequence[Contact]:
        """The contact specs, in scene order (``contact`` and ``group`` numbers)."""
        ...

    @property
    def effort_specs(self) -> Sequence[Any]:
        """The effort specs, in scene order (``spring``, ..., ``effort`` numbers)."""
        ...

    @property
    def efforts(self) -> Sequence[Any]:
        """The bound efforts (their evaluators differentiate ``tau``)."""
        ...

    def rebuilt(self, robot: Robot, contacts: Sequence[Contact], efforts: Sequence[Any] | None = None) -> Self:
        """The same scene (state, name, feet) on ``robot`` with ``contacts`` and
        ``efforts`` (None: its own), every spec bound again."""
        ...


__all__ = [
    "BODY_FIELDS",
    "EFFORT_KINDS",
    "JOINT_FIELDS",
    "MODEL_KINDS",
    "SCENE_FIELDS",
    "Parameter",
    "ParameterKind",
    "ParametrisedScene",
]
