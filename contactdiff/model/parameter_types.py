"""What a named parameter of a scene is: its kind, its name ``kind:target:field``
and where its number lives (part of `contactdiff.model.parameters`, which has the
naming rules and units)."""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum


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


__all__ = [
    "BODY_FIELDS",
    "EFFORT_KINDS",
    "JOINT_FIELDS",
    "MODEL_KINDS",
    "SCENE_FIELDS",
    "Parameter",
    "ParameterKind",
]
