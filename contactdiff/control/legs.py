"""The legs of a floating-base quadruped, found from its kinematic tree: joints from
hip to foot, which quadrant of the base each foot is in, and the diagonal pairs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ..errors import InvalidInputError
from ..model.robot import Robot

PAIR_A, PAIR_B = "A", "B"
"""Diagonal pairs: A = front-left + hind-right (mid-stance at phase 0), B = front-right + hind-left."""


@dataclass(frozen=True)
class Leg:
    """One leg of a quadruped, as found from the kinematic tree.

    Attributes:
        foot: foot frame name.
        joints: joint names from hip to foot (the joints between the foot and the base).
        iq, iv: their configuration and tangent indices.
        front, left: where the foot is in the base frame at the stance pose (x > 0, y > 0).
    """

    foot: str
    joints: tuple[str, ...]
    iq: tuple[int, ...]
    iv: tuple[int, ...]
    front: bool
    left: bool

    @property
    def pair(self) -> str:
        """`PAIR_A` (front-left, hind-right) or `PAIR_B` (front-right, hind-left)."""
        return PAIR_A if self.front == self.left else PAIR_B

    @property
    def label(self) -> str:
        """The leg's quadrant: ``front-left``, ``front-right``, ``hind-left`` or ``hind-right``."""
        return ("front" if self.front else "hind") + "-" + ("left" if self.left else "right")


def find_legs(robot: Robot, q_stance: np.ndarray | None = None) -> list[Leg]:
    """The four legs of a floating-base quadruped, in the order of ``robot.feet``.

    Raises:
        InvalidInputError: not a floating-base robot with four feet, one per
            quadrant of the base frame, on chains of one-coordinate joints.
    """
    model = robot.model
    check_quadruped(robot)
    q = base_at_origin(robot.q_ref if q_stance is None else q_stance)
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    legs = []
    for foot in robot.feet:
        fid = robot.frame_id(foot)
        chain, jid = [], model.frames[fid].parentJoint
        while jid > 0 and model.joints[jid].nq != 7:  # up to the free-flyer
            if model.joints[jid].nq != 1 or model.joints[jid].nv != 1:
                raise InvalidInputError(
                    f"leg of foot {foot!r}: joint {model.names[jid]!r} has nq={model.joints[jid].nq}; "
                    "the trot controller needs one-coordinate (revolute or prismatic) leg joints"
                )
            chain.append(jid)
            jid = model.parents[jid]
        chain.reverse()
        p = data.oMf[fid].translation
        legs.append(
            Leg(
                foot,
                tuple(model.names[j] for j in chain),
                tuple(model.joints[j].idx_q for j in chain),
                tuple(model.joints[j].idx_v for j in chain),
                bool(p[0] > 0),
                bool(p[1] > 0),
            )
        )
    quadrants = sorted(leg.label for leg in legs)
    if quadrants != ["front-left", "front-right", "hind-left", "hind-right"]:
        raise InvalidInputError(
            f"robot {robot.name!r}: the feet {list(robot.feet)} are not one per quadrant of the base "
            f"frame at the stance pose (found {quadrants}); a trot needs front/hind x left/right feet"
        )
    return legs


def check_quadruped(robot: Robot) -> None:
    """Raise `InvalidInputError` unless ``robot`` has a floating base and four feet."""
    if not robot.floating_base or len(robot.feet) != 4:
        raise InvalidInputError(
            f"a trot needs a floating-base robot with four feet; {robot.name!r} has "
            f"floating_base={robot.floating_base} and feet {list(robot.feet)}"
        )


def base_at_origin(q: np.ndarray) -> np.ndarray:
    """``q`` with the free-flyer at the world origin, unrotated: world axes = base axes."""
    q = np.array(q, dtype=float)
    q[:7] = [0, 0, 0, 0, 0, 0, 1]
    return q
