"""Feet: the frames of a legged robot that touch the ground at its reference pose.

The automatic rule (`choose_feet`), for a floating-base robot:

1. **End frames.** Each limb gives one candidate. A limb is the chain of joints
   from a branching of the kinematic tree (or the base) down to a leaf joint
   (one that no other joint hangs from); a wheel's or a foot's contact frame may
   sit on the joint above the leaf. The candidate is the limb's lowest body or
   operational frame; among frames within `TIE_HEIGHT` of that one, a frame
   whose name says foot, sole, toe or ankle is taken first. Frames named like
   sensors (imu, camera, sensor, lidar, laser, depth, rgbd, optical, velodyne)
   are never feet.
2. **Heights** are measured along the vertical, ``up = -g / |g|``, at the
   reference pose, from the lowest frame of the whole robot (sensor frames and
   frames fixed to the world left out).
3. **Band.** An end frame is a foot when its height is at most
   ``max(BAND_MIN, BAND_FRACTION × robot height)``, the robot's height being the
   extent of all its frames along the vertical. Hands, heads, cameras, IMUs and
   the grippers of arms carried by a base stand far above that.
4. **Names.** When the end frames in the band include frames named like feet
   and frames that are not, the named ones are kept.
5. **Upright.** When no end frame in the band is named like a foot while two or
   more end frames elsewhere are, the model is drawn with another up axis
   (example-robot-data's ``human`` is y-up): the reference pose's base is turned
   by the smallest rotation that puts those frames' mean below the base, and
   the rule runs again on the turned pose.

A robot with a fixed base gets no automatic feet. `choose_feet` with
``given=`` takes the user's frames instead (any frame type), with an error
listing the frames when a name is wrong.

`contactdiff.model.round_feet` rounds the feet (their collision spheres).
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from enum import Enum

import numpy as np
import pinocchio as pin

from ..errors import unknown_name

TIE_HEIGHT = 1e-3
"""m: frames of one end this close in height count as equally low (names decide)."""

BAND_MIN = 0.01
"""m: the smallest height band above the lowest frame in which end frames are feet."""

BAND_FRACTION = 0.05
"""Height band as a fraction of the robot's height (extent of its frames along the vertical)."""

UPRIGHT_ANGLE = np.pi / 4
"""rad: frames named like feet further than this from straight below the base mean
the model's up axis is not the vertical (rule 5)."""

_FOOT_NAME = re.compile(r"foot|feet|sole|toe|ankle", re.IGNORECASE)
_SENSOR_NAME = re.compile(r"imu|camera|sensor|lidar|laser|depth|rgbd|optical|velodyne", re.IGNORECASE)
_END_FRAME_TYPES = (pin.FrameType.BODY, pin.FrameType.OP_FRAME)


class FootRule(Enum):
    """How the feet of a robot were chosen."""

    LOWEST_END_FRAMES = "the lowest end frames at the reference pose"
    MJCF_SPHERES = "the model's collision spheres on leaf bodies (MJCF), round contacts"
    GIVEN = "given by hand"
    FIXED_BASE = "none: the robot has a fixed base"


@dataclass(frozen=True)
class LeftOut:
    """An end frame that is not a foot, and why (height in m above the lowest frame)."""

    frame: str
    height: float
    reason: str


@dataclass(frozen=True)
class FootChoice:
    """The feet of a robot and the rule that chose them.

    Attributes:
        feet: foot frame names, in joint order.
        rule: the `FootRule` applied.
        band: height band used by the automatic rule (m; 0 otherwise).
        heights: height of each foot above the robot's lowest frame (m).
        left_out: end frames that were not taken, with the reason.
        upright_turn: angle (rad) by which the reference pose was turned upright (rule 5).
        radii: ``{foot: radius}`` (m) of feet that are spheres centred on their frame
            (`FootRule.MJCF_SPHERES`); their contacts are round.
        limbs: ``{limb: feet}`` for a foot touching at several points (an MJCF leaf
            body with several sphere feet, named by the body): those feet are one limb
            for `contactdiff.check_decoupling`. Every other foot is a limb of its own.
    """

    feet: tuple[str, ...]
    rule: FootRule
    band: float = 0.0
    heights: dict[str, float] = field(default_factory=dict)
    left_out: tuple[LeftOut, ...] = ()
    upright_turn: float = 0.0
    radii: dict[str, float] = field(default_factory=dict)
    limbs: dict[str, tuple[str, ...]] = field(default_factory=dict)

    def describe(self) -> str:
        """One line: which feet, by which rule, and what was left out."""
        feet = ", ".join(self.feet) or "(none)"
        text = f"feet {feet}: {self.rule.value}"
        if self.radii:
            text += " (radius " + ", ".join(sorted({f"{r * 1000:.3g} mm" for r in self.radii.values()})) + ")"
        if self.rule in (FootRule.LOWEST_END_FRAMES, FootRule.MJCF_SPHERES):
            text += f" (within {self.band * 100:.3g} cm of the lowest frame)"
            if self.upright_turn:
                text += (
                    f"; the reference pose was turned {np.degrees(self.upright_turn):.0f} deg "
                    "upright (the model's up axis is not the vertical)"
                )
            if self.left_out:
                shown = ", ".join(f"{x.frame} ({x.reason})" for x in self.left_out[:6])
                more = len(self.left_out) - 6
                text += f"; left out: {shown}" + (f" and {more} more" if more > 0 else "")
        if self.limbs:
            text += "; one foot of several points each: " + ", ".join(
                f"{limb} ({len(feet)})" for limb, feet in self.limbs.items()
            )
        return text

    def to_dict(self) -> dict:
        """JSON-ready form (keys name their units: ``band_m``, ``heights_m``, ``upright_turn_rad``),
        with the `describe` line."""
        return {
            "feet": list(self.feet),
            "rule": self.rule.name.lower(),
            "band_m": self.band,
            "heights_m": dict(self.heights),
            "upright_turn_rad": self.upright_turn,
            "radii_m": dict(self.radii),
            "limbs": {k: list(v) for k, v in self.limbs.items()},
            "left_out": [{"frame": x.frame, "height_m": x.height, "reason": x.reason} for x in self.left_out],
            "description": self.describe(),
        }


def up_direction(model: pin.Model) -> np.ndarray:
    """Unit vertical ``-g / |g|`` of the model's gravity (``+z`` without gravity)."""
    g = np.asarray(model.gravity.linear, dtype=float)
    norm = np.linalg.norm(g)
    return -g / norm if norm > 0 else np.array([0.0, 0.0, 1.0])


def choose_feet(
    model: pin.Model, q_ref: np.ndarray, floating_base: bool, given: Sequence[str] | None = None
) -> tuple[FootChoice, np.ndarray]:
    """Choose the feet of ``model`` at ``q_ref`` (module rule) or check the given ones.

    Args:
        model: the Pinocchio model.
        q_ref: the reference configuration (``nq`` entries).
        floating_base: whether the root joint is a free-flyer (fixed bases get no
            automatic feet).
        given: frame names chosen by hand, or ``None`` for the automatic rule.

    Returns:
        ``(choice, q_ref)``: the `FootChoice` and the reference configuration,
        turned upright where rule 5 applied (else ``q_ref`` itself).

    Raises:
        UnknownNameError: a given name is not a frame of the model (lists the frames).
    """
    if given is not None:
        names = [f.name for f in model.frames]
        feet = tuple(given)
        for name in feet:
            if not isinstance(name, str) or not model.existFrame(name):
                raise unknown_name("foot frame", name, names)
        return FootChoice(feet, FootRule.GIVEN), q_ref
    if not floating_base:
        return FootChoice((), FootRule.FIXED_BASE), q_ref
    choice = _lowest_end_frames(model, q_ref)
    turned = _turned_upright(model, q_ref, choice)
    if turned is not None:
        q_turned, angle = turned
        return dataclasses.replace(_lowest_end_frames(model, q_turned), upright_turn=angle), q_turned
    return choice, q_ref


def _limbs(model: pin.Model) -> list[list[int]]:
    """Joint chains from a branching of the tree (or the root) down to each leaf joint;
    the free-flyer root itself belongs to no limb."""
    children = {j: 0 for j in range(model.njoints)}
    for j in range(1, model.njoints):
        children[model.parents[j]] += 1
    root = 1 if model.joints[1].nq == 7 else 0  # free-flyer: the base, not a limb
    limbs = []
    for leaf in (j for j in range(1, model.njoints) if children[j] == 0 and j != root):
        chain = [leaf]
        while model.parents[chain[-1]] not in (0, root) and children[model.parents[chain[-1]]] == 1:
            chain.append(model.parents[chain[-1]])
        limbs.append(chain)
    return limbs


def _end_frames(model: pin.Model, data: pin.Data, up: np.ndarray) -> list[tuple[str, float]]:
    """One ``(frame, height along up)`` per limb (rule 1), in the order of the leaf joints."""
    ends = []
    for chain in _limbs(model):
        frames = [
            (f.name, float(up @ data.oMf[i].translation))
            for i, f in enumerate(model.frames)
            if f.parentJoint in chain and f.type in _END_FRAME_TYPES and not _SENSOR_NAME.search(f.name)
        ]
        if not frames:
            continue
        lowest = min(h for _, h in frames)
        tied = [(n, h) for n, h in frames if h <= lowest + TIE_HEIGHT]
        named = [x for x in tied if _FOOT_NAME.search(x[0])]
        ends.append(min(named or tied, key=lambda x: x[1]))
    return ends


def _lowest_end_frames(model: pin.Model, q: np.ndarray) -> FootChoice:
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    up = up_direction(model)
    heights = [
        float(up @ data.oMf[i].translation)
        for i, f in enumerate(model.frames)
        if f.parentJoint != 0 and not _SENSOR_NAME.search(f.name)
    ]
    if not heights:
        return FootChoice((), FootRule.LOWEST_END_FRAMES)
    bottom = min(heights)
    band = max(BAND_MIN, BAND_FRACTION * (max(heights) - bottom))
    ends = [(name, h - bottom) for name, h in _end_frames(model, data, up)]
    low = [(n, h) for n, h in ends if h <= band]
    left_out = [LeftOut(n, h, f"{h:.3g} m up") for n, h in ends if h > band]
    named = [x for x in low if _FOOT_NAME.search(x[0])]
    if named and len(named) < len(low):
        left_out += [LeftOut(n, h, "not named like a foot") for n, h in low if (n, h) not in named]
        low = named
    return FootChoice(
        tuple(n for n, _ in low), FootRule.LOWEST_END_FRAMES, band, {n: h for n, h in low}, tuple(left_out)
    )


def _turned_upright(model: pin.Model, q: np.ndarray, choice: FootChoice):
    """Rule 5: ``(q turned, angle)`` when frames named like feet exist only outside
    the band and lie more than `UPRIGHT_ANGLE` from below the base; else None."""
    if any(_FOOT_NAME.search(n) for n in choice.feet):
        return None
    named = [x.frame for x in choice.left_out if _FOOT_NAME.search(x.frame)]
    if len(named) < 2:
        return None
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    base = data.oMi[1].translation
    mean = np.mean([data.oMf[model.getFrameId(n)].translation for n in named], axis=0)
    direction = mean - base
    if np.linalg.norm(direction) == 0:
        return None
    direction /= np.linalg.norm(direction)
    down = -up_direction(model)
    angle = float(np.arccos(np.clip(direction @ down, -1.0, 1.0)))
    if angle <= UPRIGHT_ANGLE:
        return None
    axis = np.cross(direction, down)
    if np.linalg.norm(axis) < 1e-12:  # upside down: any horizontal axis
        axis = np.cross(direction, [1.0, 0.0, 0.0])
        if np.linalg.norm(axis) < 1e-12:
            axis = np.cross(direction, [0.0, 1.0, 0.0])
    turn = pin.exp3(axis / np.linalg.norm(axis) * angle)
    placement = pin.XYZQUATToSE3(q[:7])
    turned = pin.SE3(turn @ placement.rotation, turn @ placement.translation)
    q = np.array(q, dtype=float)
    q[:7] = pin.SE3ToXYZQUAT(turned)
    return q, angle
