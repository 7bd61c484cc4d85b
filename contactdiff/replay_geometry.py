"""What the replay draws (`contactdiff.replay`): the robot's visual geometry, stand-in
spheres for a model without any, the objects' shapes, the contact planes (floor, table) and the
sizes of markers.

Positions are in metres, in the model's frames; colours are RGBA in [0, 1] (the contact
planes': RGB hex, as meshcat takes them).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

from .errors import InvalidInputError
from .model.mjcf import replay_note, warn
from .model.mjcf_xml import looks_like_mjcf


def drawn_geometry(robot, sphere_radius: float, package_dirs=()) -> pin.GeometryModel:
    """Everything drawn for ``robot``: its URDF's visual geometry (`visual_model`, meshes
    also looked for in ``package_dirs``), or a sphere of ``sphere_radius`` (m) at each body
    frame when it has none, and each of its shaped objects as its box, sphere or cylinder."""
    geoms = visual_model(robot, package_dirs)
    if geoms.ngeoms == 0:
        geoms = _body_spheres(robot, sphere_radius)
    _add_object_shapes(geoms, robot)
    return geoms


def package_folders(package_dirs) -> list[Path]:
    """``package_dirs`` (paths, or one path) as existing folders, else `InvalidInputError`
    naming the one that is not a folder."""
    dirs = [package_dirs] if isinstance(package_dirs, (str, Path)) else list(package_dirs or ())
    out = []
    for d in dirs:
        path = Path(d).expanduser()
        if not path.is_dir():
            raise InvalidInputError(
                f"replay: package folder {str(d)!r} is not a folder (a package folder holds "
                "the packages that package://NAME/... mesh paths name, as NAME/...)"
            )
        out.append(path.resolve())
    return out


def visual_model(robot, package_dirs=()) -> pin.GeometryModel:
    """The visual geometry of ``robot``'s URDF, as Pinocchio's loaders read it: a mesh
    ``package://NAME/PATH`` is looked for as ``DIR/NAME/PATH`` in each of ``package_dirs``
    (`package_folders`), then in every folder above the URDF (where example-robot-data's
    loader points too). Empty if the robot has no URDF or its URDF has no ``<visual>``,
    or for an MJCF model, whose meshes are not read (a warning says so: stand-in
    spheres); the robot's own (dynamics-only) model is not changed."""
    if not robot.urdf:
        return pin.GeometryModel()
    urdf = Path(robot.urdf)
    if looks_like_mjcf(urdf):  # MJCF visuals are not read: stand-in spheres, said in a warning
        warn(str(replay_note(robot)))
        return pin.GeometryModel()
    dirs = [str(p) for p in package_folders(package_dirs)] + [str(p) for p in urdf.parents]
    try:
        return pin.buildGeomFromUrdf(robot.model, str(urdf), pin.GeometryType.VISUAL, package_dirs=dirs)
    except (RuntimeError, ValueError) as exc:
        raise InvalidInputError(
            f"replay: cannot read the visual geometry of {str(urdf)!r}: {exc} (meshes "
            "package://NAME/... are looked for as DIR/NAME/... in each package folder: "
            "--package-dir DIR, or package_dirs=[DIR] in Python; and above the URDF)"
        ) from None


def _shaped_objects(robot) -> set[str]:
    """Names of the frames of the robot's objects that have a shape (drawn as the shape)."""
    names = set()
    for obj in robot.objects:
        if obj.urdf is None:
            names.add(obj.name)
            names.update(f"{obj.name}/{label}" for label, _ in obj.local_points())
    return names


def _body_spheres(robot, radius: float) -> pin.GeometryModel:
    """A sphere of ``radius`` (m) at the origin of every body frame (but those of
    shaped objects): the stand-in for a model without visual geometry."""
    import coal

    geoms = pin.GeometryModel()
    shaped = _shaped_objects(robot)
    for fid, frame in enumerate(robot.model.frames):
        if frame.type != pin.FrameType.BODY or frame.name in shaped:
            continue
        g = pin.GeometryObject(f"{frame.name}_sphere", frame.parentJoint, fid, frame.placement, coal.Sphere(radius))
        g.meshColor = np.array([0.35, 0.45, 0.75, 1.0])
        geoms.addGeometryObject(g)
    return geoms


OBJECT_COLOUR = (0.85, 0.55, 0.25, 1.0)
"""RGBA of the objects' shapes."""


def _add_object_shapes(geoms: pin.GeometryModel, robot) -> None:
    """Each shaped object of ``robot`` as its box, sphere or cylinder, at its centre frame."""
    import coal

    for obj in robot.objects:
        if obj.urdf is not None:
            continue
        shape = {
            "box": lambda: coal.Box(*obj.size),
            "sphere": lambda: coal.Sphere(obj.radius),
            "cylinder": lambda: coal.Cylinder(obj.radius, obj.length),
        }[obj.shape]()
        fid = robot.frame_id(obj.name)
        frame = robot.model.frames[fid]
        g = pin.GeometryObject(f"{obj.name}_{obj.shape}", frame.parentJoint, fid, frame.placement, shape)
        g.meshColor = np.array(OBJECT_COLOUR)
        geoms.addGeometryObject(g)


def marker_radius(robot, size: float) -> float:
    """Default contact-marker radius (m): 4 % of the model's size, at most 30 % of the
    smallest half-dimension of its objects (a marker must not hide a grasped box)."""
    halves = [
        h
        for obj in robot.objects
        if obj.urdf is None
        for h in ([x / 2 for x in obj.size] if obj.shape == "box" else [obj.radius])
    ]
    return min([0.04 * size] + [0.3 * h for h in halves])


MARKER_MIN_SCREEN = 0.008
"""Smallest contact-marker radius, as a fraction of the camera's distance: about 1 % of
the view's height across at meshcat's 75-degree field of view (2 x 0.008 / (2 tan 37.5 deg)),
so that a marker on a small part (a gripper's pad) shows at the default distance."""


def visible_marker_radius(radius: float, distance: float) -> float:
    """``radius`` (m), raised to `MARKER_MIN_SCREEN` times the camera ``distance`` (m)."""
    return max(radius, MARKER_MIN_SCREEN * distance)


def model_size(robot, q: np.ndarray) -> float:
    """Size of the robot (m): the largest distance between two joint origins at
    configuration ``q``, at least 0.05 m; sets the default marker sizes."""
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, np.asarray(q, dtype=float))
    points = np.array([data.oMi[j].translation for j in range(robot.model.njoints)])
    spread = np.max(np.linalg.norm(points[:, None] - points[None], axis=-1)) if len(points) > 1 else 0.0
    return max(float(spread), 0.05)


GROUND_COLOUR = 0xDCDCDC
"""Colour (RGB hex) of the ground: an upward plane under the robot's own contacts."""

SURFACE_COLOUR = 0xD8C8A8
"""Colour (RGB hex) of every other contact plane (a table under an object)."""


@dataclass(frozen=True)
class Surface:
    """A contact plane drawn as a thin slab whose top face lies in the plane.

    Attributes:
        name: ``ground`` for an upward plane (``n = z``) that some of the robot's own
            contacts press against (feet), else ``plane1``, ``plane2``, ... (a table
            under an object's supports).
        contacts: the ground contacts that press against it.
        normal: the plane's unit normal (world frame).
        offset: the plane's position along the normal (m): ``n · p = offset`` on it.
        size: the slab's extent along its two in-plane axes and its thickness (m).
        pose: the slab's centre and axes in the world frame (4 x 4 homogeneous
            matrix; columns 1 and 2 in the plane, column 3 the normal).
        colour: RGB hex.
    """

    name: str
    contacts: tuple[str, ...]
    normal: np.ndarray
    offset: float
    size: tuple[float, float, float]
    pose: np.ndarray
    colour: int


def contact_surfaces(scene, points: dict[str, np.ndarray], size: float) -> list[Surface]:
    """The planes the scene's ground contacts press against (contacts with no ``against``
    frame: the plane ``n · p = offset``), one slab per distinct plane.

    Each slab covers, in its plane, where the contact points of its contacts go over the run
    (``points[name]``: (n, 3) positions, m, world frame), plus a margin: the robot's
    ``size`` (m) around the ground, which the whole body moves over; 0.15 ``size`` around
    any other plane, a table under an object beside the robot, so that it stays clear of
    the robot's base. Its thickness is 2 % of ``size``. The slab lies where the model
    closes the contacts (``n · p = offset``): a foot frame at the centre of a foot ball
    with the ball's radius as offset puts it at the balls' centres.
    """
    robot = scene.robot
    objects = [obj.name for obj in robot.objects]

    def on_object(c) -> bool:
        frame = robot.model.frames[c.fid].name
        return any(frame == name or frame.startswith(name + "/") for name in objects)

    groups: dict[tuple, list] = {}
    for c in scene.contacts:
        if c.against_fid is None and c.name in points:
            key = (tuple(np.round(c.normal, 9)), round(float(c.offset), 12))
            groups.setdefault(key, []).append(c)
    surfaces, k = [], 0
    for (normal, offset), contacts in groups.items():
        n = np.array(normal, dtype=float)
        ground = np.allclose(n, [0.0, 0.0, 1.0]) and not all(on_object(c) for c in contacts)
        if not ground:
            k += 1
        t1 = np.cross([0.0, 1.0, 0.0] if abs(n[1]) < 0.9 else [1.0, 0.0, 0.0], n)  # x, y, z for an upward n
        t1 /= np.linalg.norm(t1)
        axes = np.column_stack([t1, np.cross(n, t1), n])
        flat = np.concatenate([points[c.name] for c in contacts]) @ axes[:, :2]  # in-plane coordinates
        low, high = flat.min(axis=0), flat.max(axis=0)
        margin = (1.0 if ground else 0.15) * size
        thickness = 0.02 * size
        pose = np.eye(4)
        pose[:3, :3] = axes
        pose[:3, 3] = axes[:, :2] @ ((low + high) / 2) + (offset - thickness / 2) * n
        surfaces.append(
            Surface(
                "ground" if ground else f"plane{k}",
                tuple(c.name for c in contacts),
                n,
                float(offset),
                (*(high - low + 2 * margin).tolist(), thickness),
                pose,
                GROUND_COLOUR if ground else SURFACE_COLOUR,
            )
        )
    return surfaces
