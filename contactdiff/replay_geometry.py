"""What the replay draws (`contactdiff.replay`): the robot's visual geometry, stand-in
spheres for a model without any, the objects' shapes, and the sizes of markers.

Positions are in metres, in the model's frames; colours are RGBA in [0, 1].
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin

from .errors import InvalidInputError


def drawn_geometry(robot, sphere_radius: float) -> pin.GeometryModel:
    """Everything drawn for ``robot``: its URDF's visual geometry (`visual_model`), or a
    sphere of ``sphere_radius`` (m) at each body frame when it has none, and each of
    its shaped objects as its box, sphere or cylinder."""
    geoms = visual_model(robot)
    if geoms.ngeoms == 0:
        geoms = _body_spheres(robot, sphere_radius)
    _add_object_shapes(geoms, robot)
    return geoms


def visual_model(robot) -> pin.GeometryModel:
    """The visual geometry of ``robot``'s URDF, as Pinocchio's loaders read it (meshes
    found through ``package://`` against every folder above the URDF, which is where
    example-robot-data's loader points too). Empty if the robot has no URDF or its
    URDF has no ``<visual>`` (an MJCF model, whose meshes are not read: a warning
    says so); the robot's own (dynamics-only) model is not changed."""
    if not robot.urdf:
        return pin.GeometryModel()
    urdf = Path(robot.urdf)
    from .model.mjcf_xml import looks_like_mjcf

    if looks_like_mjcf(urdf):  # MJCF visuals are not read: stand-in spheres, said in a warning
        from .model.mjcf import replay_note, warn

        warn(str(replay_note(robot)))
        return pin.GeometryModel()
    try:
        return pin.buildGeomFromUrdf(robot.model, str(urdf), pin.GeometryType.VISUAL,
                                     package_dirs=[str(p) for p in urdf.parents])
    except (RuntimeError, ValueError) as exc:
        raise InvalidInputError(f"replay: cannot read the visual geometry of {str(urdf)!r}: {exc}") from None


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
        g = pin.GeometryObject(f"{frame.name}_sphere", frame.parentJoint, fid, frame.placement,
                               coal.Sphere(radius))
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
        shape = {"box": lambda: coal.Box(*obj.size), "sphere": lambda: coal.Sphere(obj.radius),
                 "cylinder": lambda: coal.Cylinder(obj.radius, obj.length)}[obj.shape]()
        fid = robot.frame_id(obj.name)
        frame = robot.model.frames[fid]
        g = pin.GeometryObject(f"{obj.name}_{obj.shape}", frame.parentJoint, fid, frame.placement, shape)
        g.meshColor = np.array(OBJECT_COLOUR)
        geoms.addGeometryObject(g)


def marker_radius(robot, size: float) -> float:
    """Default contact-marker radius (m): 4 % of the model's size, at most 30 % of the
    smallest half-dimension of its objects (a marker must not hide a grasped box)."""
    halves = [h for obj in robot.objects if obj.urdf is None
              for h in ([x / 2 for x in obj.size] if obj.shape == "box" else [obj.radius])]
    return min([0.04 * size] + [0.3 * h for h in halves])


def model_size(robot, q: np.ndarray) -> float:
    """Size of the robot (m): the largest distance between two joint origins at
    configuration ``q``, at least 0.05 m; sets the default marker sizes."""
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, np.asarray(q, dtype=float))
    points = np.array([data.oMi[j].translation for j in range(robot.model.njoints)])
    spread = np.max(np.linalg.norm(points[:, None] - points[None], axis=-1)) if len(points) > 1 else 0.0
    return max(float(spread), 0.05)
