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

**Round feet.** `foot_spheres` reads each foot's collision sphere from the
robot's URDF (Pinocchio's geometry model), and `round_feet` gives a scene's foot
contacts the radius of their sphere (`contactdiff.model.contacts`: the gap to
the sphere's lowest point, rolling without slipping). A sphere centred on its
foot frame rounds the contact in place; one centred elsewhere (ANYmal's) gets a
frame of its own at its centre, ``<foot>_sphere``, in a copy of the robot's
model, and the contact moves there.
"""

from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass, field
from enum import Enum
from pathlib import Path

import numpy as np
import pinocchio as pin

from ..errors import InvalidInputError, ModelLoadError, unknown_name

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
                text += (f"; the reference pose was turned {np.degrees(self.upright_turn):.0f} deg "
                         "upright (the model's up axis is not the vertical)")
            if self.left_out:
                shown = ", ".join(f"{x.frame} ({x.reason})" for x in self.left_out[:6])
                more = len(self.left_out) - 6
                text += f"; left out: {shown}" + (f" and {more} more" if more > 0 else "")
        if self.limbs:
            text += "; one foot of several points each: " + ", ".join(
                f"{limb} ({len(feet)})" for limb, feet in self.limbs.items())
        return text

    def to_dict(self) -> dict:
        """JSON-ready form (keys name their units: ``band_m``, ``heights_m``, ``upright_turn_rad``),
        with the `describe` line."""
        return {"feet": list(self.feet), "rule": self.rule.name.lower(), "band_m": self.band,
                "heights_m": dict(self.heights), "upright_turn_rad": self.upright_turn,
                "radii_m": dict(self.radii), "limbs": {k: list(v) for k, v in self.limbs.items()},
                "left_out": [{"frame": x.frame, "height_m": x.height, "reason": x.reason}
                             for x in self.left_out],
                "description": self.describe()}


def up_direction(model: pin.Model) -> np.ndarray:
    """Unit vertical ``-g / |g|`` of the model's gravity (``+z`` without gravity)."""
    g = np.asarray(model.gravity.linear, dtype=float)
    norm = np.linalg.norm(g)
    return -g / norm if norm > 0 else np.array([0.0, 0.0, 1.0])


def choose_feet(model: pin.Model, q_ref: np.ndarray, floating_base: bool,
                given=None) -> tuple[FootChoice, np.ndarray]:
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
        frames = [(f.name, float(up @ data.oMf[i].translation)) for i, f in enumerate(model.frames)
                  if f.parentJoint in chain and f.type in _END_FRAME_TYPES and not _SENSOR_NAME.search(f.name)]
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
    heights = [float(up @ data.oMf[i].translation) for i, f in enumerate(model.frames)
               if f.parentJoint != 0 and not _SENSOR_NAME.search(f.name)]
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
    return FootChoice(tuple(n for n, _ in low), FootRule.LOWEST_END_FRAMES, band,
                      {n: h for n, h in low}, tuple(left_out))


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


# -- round feet -------------------------------------------------------------------------
SPHERE_CENTRE_TOL = 1e-6
"""m: a collision sphere whose centre is this close to the foot frame is centred on it."""


@dataclass(frozen=True)
class FootSphere:
    """A foot's collision sphere, as the robot's URDF gives it.

    Attributes:
        foot: foot frame name.
        radius: sphere radius (m).
        centre: the sphere's centre in the foot frame's axes, from its origin (m).
        geometry: name of the collision geometry in Pinocchio's geometry model.
    """

    foot: str
    radius: float
    centre: tuple[float, float, float]
    geometry: str

    @property
    def centre_offset(self) -> float:
        """Distance (m) from the foot frame's origin to the sphere's centre."""
        return float(np.linalg.norm(self.centre))

    @property
    def centred(self) -> bool:
        """Whether the sphere is centred on the foot frame (within `SPHERE_CENTRE_TOL`)."""
        return self.centre_offset <= SPHERE_CENTRE_TOL


def _collision_model(robot) -> pin.GeometryModel:
    if not robot.urdf:
        raise InvalidInputError(f"robot {robot.name!r} was built in code: no URDF to read collision geometry from")
    if Path(robot.urdf).suffix == ".xml":
        raise InvalidInputError(f"robot {robot.name!r} is an MJCF model: its round feet are the collision spheres "
                                "of its leaf bodies (load it with feet=None or name them), and none is at these feet")
    # package://NAME/... resolves under any folder holding NAME: try the URDF's ancestors
    dirs = [str(p) for p in Path(robot.urdf).resolve().parents]
    try:
        return pin.buildGeomFromUrdf(robot.model, str(robot.urdf), pin.GeometryType.COLLISION, package_dirs=dirs)
    except (ValueError, RuntimeError, OSError) as exc:
        raise ModelLoadError(f"cannot load the collision geometry of robot {robot.name!r} "
                             f"from {robot.urdf}: {exc}") from None


def _geometry_kind(geometry) -> str:
    return type(geometry).__name__


def foot_spheres(robot, feet=None) -> dict[str, FootSphere | None]:
    """Each foot's collision sphere, from the robot's URDF (``pin.buildGeomFromUrdf``), or
    the MJCF sphere a foot was chosen by (``robot.foot_choice.radii``).

    A foot's sphere is a ``Sphere`` collision geometry of the foot frame's own
    link; failing that, the sphere on the foot frame's joint nearest to it.

    Args:
        robot: a `Robot` loaded from a URDF.
        feet: frame names, default ``robot.feet``.

    Returns:
        ``{foot: FootSphere or None}`` (None: no collision sphere; the foot may be a mesh).

    Raises:
        InvalidInputError: the robot has no URDF.
        ModelLoadError: the collision geometry cannot be loaded (a mesh not found).
    """
    model = robot.model
    radii = robot.foot_choice.radii if robot.foot_choice is not None else {}
    if radii:  # an MJCF's sphere feet: frames at the spheres' centres
        return {foot: FootSphere(foot, radii[foot], (0.0, 0.0, 0.0), foot) if foot in radii else None
                for foot in (robot.feet if feet is None else feet)}
    geometry = _collision_model(robot)
    found = {}
    for foot in (robot.feet if feet is None else feet):
        fid = robot.frame_id(foot)
        frame = model.frames[fid]
        spheres = [g for g in geometry.geometryObjects if _geometry_kind(g.geometry) == "Sphere"
                   and g.parentJoint == frame.parentJoint]
        own = [g for g in spheres if g.parentFrame == fid]

        def centre(g):
            return frame.placement.actInv(g.placement.translation)  # in the foot frame
        candidates = own or spheres
        if not candidates:
            found[foot] = None
            continue
        best = min(candidates, key=lambda g: np.linalg.norm(centre(g)))
        found[foot] = FootSphere(foot, float(best.geometry.radius), tuple(float(x) for x in centre(best)),
                                 best.name)
    return found


SPHERE_FRAME_SUFFIX = "_sphere"
"""A foot whose sphere is not centred on it gets the frame ``<foot>_sphere`` at the sphere's centre."""


def round_feet(scene, spheres: dict | None = None):
    """The scene with its ground contacts at the robot's feet made round.

    Each contact of a foot frame with the ground (``against`` unset) gets the
    radius ``r`` of the foot's collision sphere (`foot_spheres`); the contact
    keeps its name, so reports and parameters that name it still do.

    * **Sphere centred on the foot frame** (a1, go1, hyq): the contact stays on
      the frame and its offset is lowered by ``r``. Every gap, at every pose, is
      unchanged (the frame is ``offset`` above the plane at contact, as before),
      while a sticking foot now rolls instead of pivoting on a point. When every
      foot is like this the scene keeps its robot, frames and all.
    * **Sphere centred off the foot frame** (ANYmal: 0.02325 m along the frame's
      z): a copy of the robot's model gets an operational frame ``<foot>_sphere``
      (`SPHERE_FRAME_SUFFIX`) at the sphere's centre (the foot frame's parent
      joint and axes, the centre's position), and the contact moves to it with
      radius ``r``. Its offset is chosen so that its gap at the robot's
      reference pose ``robot.q_ref`` equals the old one (to round-off):
      ``offset + n · (c - p) - r``, ``c`` the centre and ``p`` the foot frame's
      origin there. The contact point is then **the sphere's lowest point, no
      longer the foot frame's origin**. At the reference pose this changes
      nothing: same gaps, so the same touchdowns from the same states. Away from
      it the gap follows the sphere, not the old point: a foot that tilts rolls
      about the sphere's centre, so the gap changes by ``n · (c - p)`` varying
      with the foot's orientation (up to the centre's 0.02325 m on ANYmal), and a
      sticking foot rolls on its sphere where the point would have pivoted.
      The scene's robot is then the copy (the same robot, feet and reference
      pose, with the new frames); the given scene and its robot are untouched.

    Args:
        scene: a `Scene` (e.g. ``Scene.from_robot(robot)``).
        spheres: ``{foot: FootSphere}``, default ``foot_spheres(scene.robot)``.

    Raises:
        InvalidInputError: a foot contact has no collision sphere; or no contact
            is at a foot; or a frame named ``<foot>_sphere`` already exists
            elsewhere than the sphere's centre.
    """
    import dataclasses as _dc

    from .scene import Scene

    robot = scene.robot
    at_feet = [i for i, c in enumerate(scene.contact_specs) if c.frame in robot.feet and c.against is None]
    if not at_feet:
        spheres_at = {f + SPHERE_FRAME_SUFFIX for f in robot.feet}
        done = any(c.frame in spheres_at and c.radius > 0 for c in scene.contact_specs)
        raise InvalidInputError(f"scene {scene.name!r}: no ground contact at a foot of robot {robot.name!r} "
                                f"(feet: {', '.join(robot.feet) or 'none'})"
                                + ("; its foot contacts are already round" if done else ""))
    rounded = [scene.contact_specs[i].name for i in at_feet if scene.contact_specs[i].radius > 0]
    if rounded:  # their offsets already hold the spheres: lowering them again would sink the feet
        raise InvalidInputError(f"scene {scene.name!r}: the contacts {', '.join(rounded)} are already round "
                                f"(radius > 0); round_feet takes a scene with point feet")
    if spheres is None:
        spheres = foot_spheres(robot, sorted({scene.contact_specs[i].frame for i in at_feet}))
    missing = [foot for foot in dict.fromkeys(scene.contact_specs[i].frame for i in at_feet)
               if spheres.get(foot) is None]
    if missing:
        raise InvalidInputError(
            f"robot {robot.name!r}: cannot round its feet: "
            + "; ".join(f"{foot} has no collision sphere (a mesh, or no collision geometry)" for foot in missing)
            + " (give Contact(radius=...) by hand)")
    off_centre = sorted({scene.contact_specs[i].frame for i in at_feet
                         if not spheres[scene.contact_specs[i].frame].centred})
    if off_centre:
        rounded_robot, frames = _with_sphere_frames(robot, [spheres[foot] for foot in off_centre])
        data = rounded_robot.model.createData()
        pin.framesForwardKinematics(rounded_robot.model, data, rounded_robot.q_ref)
    else:
        rounded_robot, frames = robot, {}
    contacts = list(scene.contact_specs)
    for i in at_feet:
        c = contacts[i]
        r = spheres[c.frame].radius
        if c.frame not in frames:
            contacts[i] = _dc.replace(c, radius=r, offset=c.offset - r)
            continue
        n = np.array(c.normal)
        centre = data.oMf[rounded_robot.model.getFrameId(frames[c.frame])].translation
        foot = data.oMf[rounded_robot.model.getFrameId(c.frame)].translation
        offset = c.offset + float(n @ centre - n @ foot) - r
        contacts[i] = _dc.replace(c, frame=frames[c.frame], radius=r, offset=offset)
    rounded = Scene(rounded_robot, contacts, scene.effort_specs, None, scene.q0, scene.v0, scene.name)
    rounded.foot_choice = scene.foot_choice
    return rounded


def _with_sphere_frames(robot, spheres) -> tuple:
    """A copy of ``robot`` whose model has an OP_FRAME ``<foot>_sphere`` at each sphere's
    centre (parent joint and axes of the foot frame); returns ``(copy, {foot: frame})``.
    A frame of that name already at the centre is used as it is."""
    copy = robot.copy()
    model = copy.model
    frames = {}
    for sphere in spheres:
        foot = model.frames[model.getFrameId(sphere.foot)]
        placement = foot.placement * pin.SE3(np.eye(3), np.array(sphere.centre))
        name = sphere.foot + SPHERE_FRAME_SUFFIX
        if model.existFrame(name):
            there = model.frames[model.getFrameId(name)]
            if there.parentJoint != foot.parentJoint or not np.allclose(
                    there.placement.translation, placement.translation, rtol=0, atol=SPHERE_CENTRE_TOL):
                raise InvalidInputError(
                    f"robot {robot.name!r}: cannot add frame {name!r} at the centre of {sphere.foot}'s "
                    "collision sphere: a frame of that name is already elsewhere")
        else:
            model.addFrame(pin.Frame(name, foot.parentJoint, model.getFrameId(sphere.foot), placement,
                                     pin.FrameType.OP_FRAME), False)
        frames[sphere.foot] = name
    return copy, frames
