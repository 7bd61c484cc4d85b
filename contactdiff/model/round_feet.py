"""Round feet: the feet's collision spheres and the scene whose foot contacts roll on them.

`foot_spheres` reads each foot's collision sphere from the
robot's URDF (Pinocchio's geometry model), and `round_feet` gives a scene's foot
contacts the radius of their sphere (`contactdiff.model.contacts`: the gap to
the sphere's lowest point, rolling without slipping). A sphere centred on its
foot frame rounds the contact in place; one centred elsewhere (ANYmal's) gets a
frame of its own at its centre, ``<foot>_sphere``, in a copy of the robot's
model, and the contact moves there.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

from ..errors import InvalidInputError, ModelLoadError
from .robot import Robot
from .scene import Scene

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
        raise InvalidInputError(
            f"robot {robot.name!r} is an MJCF model: its round feet are the collision spheres "
            "of its leaf bodies (load it with feet=None or name them), and none is at these feet"
        )
    # package://NAME/... resolves under any folder holding NAME: try the URDF's ancestors
    dirs = [str(p) for p in Path(robot.urdf).resolve().parents]
    try:
        return pin.buildGeomFromUrdf(robot.model, str(robot.urdf), pin.GeometryType.COLLISION, package_dirs=dirs)
    except (ValueError, RuntimeError, OSError) as exc:
        raise ModelLoadError(
            f"cannot load the collision geometry of robot {robot.name!r} from {robot.urdf}: {exc}"
        ) from None


def _geometry_kind(geometry) -> str:
    return type(geometry).__name__


def foot_spheres(robot: Robot, feet: Sequence[str] | None = None) -> dict[str, FootSphere | None]:
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
        return {
            foot: FootSphere(foot, radii[foot], (0.0, 0.0, 0.0), foot) if foot in radii else None
            for foot in (robot.feet if feet is None else feet)
        }
    geometry = _collision_model(robot)
    found: dict[str, FootSphere | None] = {}
    for foot in robot.feet if feet is None else feet:
        fid = robot.frame_id(foot)
        frame = model.frames[fid]
        spheres = [
            g
            for g in geometry.geometryObjects
            if _geometry_kind(g.geometry) == "Sphere" and g.parentJoint == frame.parentJoint
        ]
        own = [g for g in spheres if g.parentFrame == fid]

        def centre(g):
            return frame.placement.actInv(g.placement.translation)  # in the foot frame

        candidates = own or spheres
        if not candidates:
            found[foot] = None
            continue
        best = min(candidates, key=lambda g: np.linalg.norm(centre(g)))
        x, y, z = (float(c) for c in centre(best))
        found[foot] = FootSphere(foot, float(best.geometry.radius), (x, y, z), best.name)
    return found


SPHERE_FRAME_SUFFIX = "_sphere"
"""A foot whose sphere is not centred on it gets the frame ``<foot>_sphere`` at the sphere's centre."""


def round_feet(scene: Scene, spheres: Mapping[str, FootSphere | None] | None = None) -> Scene:
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
    robot = scene.robot
    at_feet = [i for i, c in enumerate(scene.contact_specs) if c.frame in robot.feet and c.against is None]
    if not at_feet:
        spheres_at = {f + SPHERE_FRAME_SUFFIX for f in robot.feet}
        done = any(c.frame in spheres_at and (c.radius or 0.0) > 0 for c in scene.contact_specs)  # (resolved: set)
        raise InvalidInputError(
            f"scene {scene.name!r}: no ground contact at a foot of robot {robot.name!r} "
            f"(feet: {', '.join(robot.feet) or 'none'})" + ("; its foot contacts are already round" if done else "")
        )
    rounded = [scene.contact_specs[i].name for i in at_feet if (scene.contact_specs[i].radius or 0.0) > 0]
    if rounded:  # their offsets already hold the spheres: lowering them again would sink the feet
        raise InvalidInputError(
            f"scene {scene.name!r}: the contacts {', '.join(rounded)} are already round "
            f"(radius > 0); round_feet takes a scene with point feet"
        )
    if spheres is None:
        spheres = foot_spheres(robot, sorted({scene.contact_specs[i].frame for i in at_feet}))
    missing = [
        foot for foot in dict.fromkeys(scene.contact_specs[i].frame for i in at_feet) if spheres.get(foot) is None
    ]
    if missing:
        raise InvalidInputError(
            f"robot {robot.name!r}: cannot round its feet: "
            + "; ".join(f"{foot} has no collision sphere (a mesh, or no collision geometry)" for foot in missing)
            + " (give Contact(radius=...) by hand)"
        )
    found = {foot: sphere for foot, sphere in spheres.items() if sphere is not None}  # every foot here has one
    off_centre = sorted(
        {scene.contact_specs[i].frame for i in at_feet if not found[scene.contact_specs[i].frame].centred}
    )
    if off_centre:
        rounded_robot, frames = _with_sphere_frames(robot, [found[foot] for foot in off_centre])
        data = rounded_robot.model.createData()
        pin.framesForwardKinematics(rounded_robot.model, data, rounded_robot.q_ref)
    else:
        rounded_robot, frames = robot, {}
    contacts = list(scene.contact_specs)
    for i in at_feet:
        c = contacts[i]
        r = found[c.frame].radius
        if c.frame not in frames:
            contacts[i] = dataclasses.replace(c, radius=r, offset=c.offset - r)
            continue
        n = np.array(c.normal)
        centre = data.oMf[rounded_robot.model.getFrameId(frames[c.frame])].translation
        foot = data.oMf[rounded_robot.model.getFrameId(c.frame)].translation
        offset = c.offset + float(n @ centre - n @ foot) - r
        contacts[i] = dataclasses.replace(c, frame=frames[c.frame], radius=r, offset=offset)
    rounded_scene = Scene(rounded_robot, contacts, scene.effort_specs, None, scene.q0, scene.v0, scene.name)
    rounded_scene.foot_choice = scene.foot_choice
    return rounded_scene


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
                there.placement.translation, placement.translation, rtol=0, atol=SPHERE_CENTRE_TOL
            ):
                raise InvalidInputError(
                    f"robot {robot.name!r}: cannot add frame {name!r} at the centre of {sphere.foot}'s "
                    "collision sphere: a frame of that name is already elsewhere"
                )
        else:
            model.addFrame(
                pin.Frame(name, foot.parentJoint, model.getFrameId(sphere.foot), placement, pin.FrameType.OP_FRAME),
                False,
            )
        frames[sphere.foot] = name
    return copy, frames
