"""Free objects beside a robot (boxes, spheres, cylinders, URDF models) and extra frames.

A scene for manipulation holds a robot and objects the robot touches. Each
object becomes part of the robot's Pinocchio model: a free-flyer joint on the
universe named after the object (``q`` ``[x y z qx qy qz qw]``, world frame;
``v`` its linear then angular velocity in the object's own frame, as every
Pinocchio free-flyer), carrying the object's body, appended after the robot's
joints, so the robot's coordinates keep their indices. A ``fixed`` object has
no joint: its frames hang on the universe at its pose.

Frames of an object (the names contacts use, ``frame`` and ``against``):

* ``NAME``: its centre (the centre of mass of a shape);
* ``NAME/POINT`` for each of its ``points`` (m, in the object's frame);
* a box also has its eight corners ``NAME/+x+y-z`` (signs of the half sizes);
* a URDF object keeps its own frames and joints, each prefixed ``NAME/``, and its
  root joint is named ``NAME``.

`RobotFrame` adds a named point to a frame of the robot (a fingertip, a pad).
`add_objects` builds the combined `Robot`; its ``objects`` attribute lists the
objects (the replay draws their shapes). A sphere's contacts with the ground
are round contacts of its radius (`Contact.radius`).
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin

from ..errors import InvalidInputError, check_number, check_vector, unknown_name
from .robot import Robot
from .robot_files import load_robot

SHAPES = ("box", "sphere", "cylinder")
"""Shapes an object may have without a URDF: a box (``size``: three edge lengths, m),
a sphere (``radius``), a cylinder along its own z axis (``radius`` and ``length``)."""

_DIMENSIONS = {"box": ("size",), "sphere": ("radius",), "cylinder": ("radius", "length")}


def _pose(owner: str, position, rpy) -> pin.SE3:
    p = check_vector(owner, "position", position, 3)
    r = check_vector(owner, "rpy", rpy, 3)
    return pin.SE3(pin.rpy.rpyToMatrix(*r), p)


def _points(owner: str, points) -> tuple[tuple[str, tuple[float, float, float]], ...]:
    if not isinstance(points, Mapping):
        raise InvalidInputError(f"{owner}: points must be a table of name = [x, y, z] (m), got {points!r}")
    out: list[tuple[str, tuple[float, float, float]]] = []
    for name, xyz in points.items():
        if not isinstance(name, str) or not name or "/" in name:
            raise InvalidInputError(f"{owner}: point names must be non-empty and without '/', got {name!r}")
        x, y, z = (float(c) for c in check_vector(owner, f"point {name!r}", xyz, 3))
        out.append((name, (x, y, z)))
    return tuple(out)


def _moments(owner: str, moments) -> tuple[float, float, float]:
    """Three principal moments (kg m²) from one number or three, checked to be those of
    a body: positive, each at most the sum of the other two."""
    values = (
        np.full(3, check_number(owner, "moments", moments))
        if np.ndim(moments) == 0
        else check_vector(owner, "moments", moments, 3)
    )
    if not np.all(values > 0.0):
        raise InvalidInputError(f"{owner}: moments of inertia must be > 0 kg m², got {moments!r}")
    total = values.sum()
    if np.any(2.0 * values > total * (1.0 + 1e-12)):
        raise InvalidInputError(
            f"{owner}: moments {values.tolist()} are not those of a body: each must be at most the sum of the other two"
        )
    x, y, z = (float(c) for c in values)
    return x, y, z


@dataclass(frozen=True)
class SceneObject:
    """An object of a scene: a shape of given size and mass, or a URDF model.

    Args:
        name: the object's name: its joint, its centre frame, the prefix of its other frames.
        shape: one of `SHAPES`, required for a shape; a URDF object has none.
        mass: kg, > 0; a shape needs its mass or its ``density`` (a URDF model has its
            own masses).
        size: a box's edge lengths along its x, y, z axes (m, > 0).
        radius: a sphere's or a cylinder's radius (m, > 0).
        length: a cylinder's length along its z axis (m, > 0).
        urdf: path of a URDF file (instead of a shape).
        position: the object's initial position (m, world frame).
        rpy: its initial orientation, roll-pitch-yaw about the world x, y, z axes (rad).
        fixed: True fixes the object in the world at its pose (no joint).
        points: named points of the object (m, object frame), frames ``NAME/POINT``.
        density: kg/m³, > 0, instead of ``mass``: the mass is set to ``density``
            times the shape's `volume` on construction (and ``density`` to None).
        moments: principal moments of inertia about the centre along the object's
            axes (kg m²): one number for all three, or three; None (default) takes
            those of uniform density. A measured body (a hollow or weighted cube)
            differs from uniform.

    Raises:
        InvalidInputError: a shape without ``shape``, or without ``mass`` or
            ``density`` (or with both), a URDF object with any of them, an unknown
            shape (the shapes are listed), a missing or extra dimension, a
            non-positive size, mass or density, non-finite numbers.
    """

    name: str
    shape: str | None = None
    mass: float | None = None
    size: tuple[float, float, float] | None = None
    radius: float | None = None
    length: float | None = None
    urdf: str | None = None
    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    fixed: bool = False
    points: Mapping | tuple = field(default_factory=dict)
    density: float | None = None
    moments: float | tuple[float, float, float] | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name or "/" in self.name:
            raise InvalidInputError(f"object name must be a non-empty name without '/', got {self.name!r}")
        owner = f"object {self.name!r}"
        set_ = object.__setattr__
        if not isinstance(self.fixed, bool):
            raise InvalidInputError(f"{owner}: fixed must be true or false, got {self.fixed!r}")
        _pose(owner, self.position, self.rpy)
        set_(self, "position", tuple(float(x) for x in self.position))
        set_(self, "rpy", tuple(float(x) for x in self.rpy))
        points = dict(self.points) if isinstance(self.points, tuple) else self.points
        set_(self, "points", _points(owner, points))
        given = [
            k
            for k in ("shape", "mass", "density", "size", "radius", "length", "moments")
            if getattr(self, k) is not None
        ]
        if self.urdf is not None:
            if given:
                raise InvalidInputError(
                    f"{owner}: a URDF object takes its shape and masses from its file; drop {', '.join(given)}"
                )
            set_(self, "urdf", str(self.urdf))
            return
        if self.shape is None:
            raise InvalidInputError(f"{owner} needs a shape ({', '.join(SHAPES)}) or a urdf file")
        if self.shape not in SHAPES:
            raise unknown_name(f"shape of {owner}", self.shape, SHAPES)
        needed = _DIMENSIONS[self.shape]
        for key in needed:
            if getattr(self, key) is None:
                raise InvalidInputError(f"{owner}: a {self.shape} needs {' and '.join(needed)}")
        extra = [k for k in given if k not in needed + ("shape", "mass", "density", "moments")]
        if extra:
            raise InvalidInputError(
                f"{owner}: a {self.shape} has no {', '.join(extra)} (it takes {' and '.join(needed)})"
            )
        if self.size is not None:
            size = check_vector(owner, "size", self.size, 3)
            if not np.all(size > 0.0):
                raise InvalidInputError(f"{owner}: size must be three edge lengths > 0 m, got {self.size!r}")
            set_(self, "size", tuple(float(x) for x in size))
        if self.moments is not None:
            set_(self, "moments", _moments(owner, self.moments))
        for key in ("radius", "length"):
            value = getattr(self, key)
            if value is not None:
                value = check_number(owner, key, value, minimum=0.0)
                if not value > 0.0:
                    raise InvalidInputError(f"{owner}: {key} must be > 0 m, got {value!r}")
                set_(self, key, value)
        self._set_mass(owner)

    def _set_mass(self, owner: str) -> None:
        """Check ``mass`` or turn ``density`` into it (a shape of checked dimensions)."""
        if (self.mass is None) == (self.density is None):
            raise InvalidInputError(
                f"{owner}: a {self.shape} needs its mass (kg, > 0) or its density (kg/m³, > 0; uniform), "
                f"one of the two; got mass = {self.mass!r}, density = {self.density!r}"
            )
        key, unit = ("mass", "kg") if self.density is None else ("density", "kg/m³")
        value = check_number(owner, key, getattr(self, key), minimum=0.0)
        if not value > 0.0:
            raise InvalidInputError(f"{owner}: {key} must be > 0 {unit}, got {getattr(self, key)!r}")
        object.__setattr__(self, "mass", value if key == "mass" else value * self.volume)
        object.__setattr__(self, "density", None)

    @property
    def volume(self) -> float:
        """A shape's volume (m³): a box's ``x y z``, a sphere's ``4/3 π r³``, a cylinder's
        ``π r² l``."""
        if self.shape == "box":
            assert self.size is not None  # a box has its size (__post_init__)
            return float(np.prod(self.size))
        assert self.radius is not None  # a sphere and a cylinder have theirs (__post_init__)
        if self.shape == "sphere":
            return 4.0 / 3.0 * np.pi * self.radius**3
        assert self.length is not None
        return np.pi * self.radius**2 * self.length

    @property
    def pose(self) -> pin.SE3:
        """The object's initial pose in the world."""
        return _pose(self.name, self.position, self.rpy)

    def inertia(self) -> pin.Inertia:
        """Spatial inertia of a shape about its centre (uniform density, or ``moments``)."""
        if self.moments is not None:
            return pin.Inertia(self.mass, np.zeros(3), np.diag(self.moments))
        if self.shape == "box":
            assert self.size is not None  # a box has its size (__post_init__)
            return pin.Inertia.FromBox(self.mass, *self.size)
        if self.shape == "sphere":
            return pin.Inertia.FromSphere(self.mass, self.radius)
        return pin.Inertia.FromCylinder(self.mass, self.radius, self.length)

    def local_points(self) -> list[tuple[str, np.ndarray]]:
        """Named points of the object's frame (m): the box corners, then ``points``."""
        out = []
        if self.urdf is None and self.shape == "box":
            half = np.array(self.size) / 2.0
            for signs in itertools.product((1, -1), repeat=3):
                label = "".join(("+" if s > 0 else "-") + axis for s, axis in zip(signs, "xyz"))
                out.append((label, half * np.array(signs)))
        return out + [(name, np.array(xyz)) for name, xyz in self.points]


@dataclass(frozen=True)
class RobotFrame:
    """A named point fixed to a frame of the robot (a fingertip, a finger pad).

    Args:
        name: the new frame's name.
        parent: the frame it is fixed to.
        position: its position in the parent frame (m).
        rpy: its orientation in the parent frame (rad).
    """

    name: str
    parent: str
    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        for key in ("name", "parent"):
            if not isinstance(getattr(self, key), str) or not getattr(self, key):
                raise InvalidInputError(f"frame {key} must be a frame name, got {getattr(self, key)!r}")
        _pose(f"frame {self.name!r}", self.position, self.rpy)
        object.__setattr__(self, "position", tuple(float(x) for x in self.position))
        object.__setattr__(self, "rpy", tuple(float(x) for x in self.rpy))


def empty_robot() -> Robot:
    """A robot without joints or bodies: the world of a scene made of objects only."""
    return Robot(pin.Model(), "world")


def add_objects(
    robot: Robot, objects: Sequence[SceneObject] = (), frames: Sequence[RobotFrame] = (), base: Path | None = None
) -> Robot:
    """``robot`` with extra frames and objects, as a new `Robot` (``robot`` is untouched).

    Args:
        robot: the robot (`empty_robot` for objects alone).
        objects: the objects, appended in order.
        frames: extra frames on the robot, added first.
        base: folder that relative URDF paths of objects are read from.

    Raises:
        InvalidInputError: a name already taken by a frame or joint (the model's
            names and the new ones must be unique), or an unknown parent frame.
    """
    model = pin.Model(robot.model)
    q_parts = [robot.q_ref]
    for extra in frames:
        _check_free(model, extra.name, f"frame {extra.name!r}")
        parent = robot.frame_id(extra.parent)
        holder = model.frames[parent]
        placement = holder.placement * _pose(extra.name, extra.position, extra.rpy)
        model.addFrame(pin.Frame(extra.name, holder.parentJoint, parent, placement, pin.FrameType.OP_FRAME))
    names = [o.name for o in objects]
    for name in {n for n in names if names.count(n) > 1}:
        raise InvalidInputError(f"object names must be unique; repeated: {name!r}")
    for obj in objects:
        if not isinstance(obj, SceneObject):
            raise InvalidInputError(f"objects must be SceneObject specs, got {obj!r}")
        _check_free(model, obj.name, f"object {obj.name!r}")
        if obj.urdf is not None:
            model, q_obj = _append_urdf(model, obj, base)
        else:
            model, q_obj = _append_shape(model, obj)
        q_parts.append(q_obj)
    # the model's named configurations (an SRDF's "standing") get the objects' poses too
    for entry in list(model.referenceConfigurations):
        model.referenceConfigurations[entry.key()] = np.concatenate([entry.data(), *q_parts[1:]])
    return Robot(
        model,
        robot.name,
        robot.urdf,
        robot.floating_base,
        np.concatenate(q_parts),
        robot.feet,
        robot.actuated,
        robot.foot_choice,
        objects=robot.objects + tuple(objects),
    )


def _check_free(model: pin.Model, name: str, what: str) -> None:
    if model.existFrame(name) or model.existJointName(name):
        raise InvalidInputError(f"{what}: the name {name!r} is already a frame or joint of the model; choose another")


def _append_shape(model: pin.Model, obj: SceneObject) -> tuple[pin.Model, np.ndarray]:
    if obj.fixed:
        jid, placement, q_obj = 0, obj.pose, np.zeros(0)
        centre = model.addFrame(pin.Frame(obj.name, 0, 0, placement, pin.FrameType.OP_FRAME))
    else:
        jid = model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), obj.name)
        model.appendBodyToJoint(jid, obj.inertia(), pin.SE3.Identity())
        centre = model.addBodyFrame(obj.name, jid, pin.SE3.Identity(), 0)
        placement, q_obj = pin.SE3.Identity(), pin.SE3ToXYZQUAT(obj.pose)
    for label, xyz in obj.local_points():
        name = f"{obj.name}/{label}"
        _check_free(model, name, f"point {label!r} of object {obj.name!r}")
        model.addFrame(pin.Frame(name, jid, centre, placement * pin.SE3(np.eye(3), xyz), pin.FrameType.OP_FRAME))
    return model, q_obj


def _append_urdf(model: pin.Model, obj: SceneObject, base: Path | None) -> tuple[pin.Model, np.ndarray]:
    if obj.points:
        raise InvalidInputError(
            f"object {obj.name!r}: points are for shapes; a URDF object has its "
            f"own frames (points {[name for name, _ in obj.points]})"
        )
    assert obj.urdf is not None  # a URDF object (the caller's branch)
    path = Path(obj.urdf)
    if not path.is_absolute() and base is not None:
        path = base / path
    loaded = load_robot(path, floating_base=not obj.fixed).model
    for j in range(1, loaded.njoints):  # the root free-flyer is the object's own name
        loaded.names[j] = obj.name if (j == 1 and not obj.fixed) else f"{obj.name}/{loaded.names[j]}"
    for i in range(len(loaded.frames)):
        frame = loaded.frames[i]
        frame.name = obj.name if (i == 1 and not obj.fixed) else f"{obj.name}/{frame.name}"
        loaded.frames[i] = frame
    nq_before = model.nq
    placement = obj.pose if obj.fixed else pin.SE3.Identity()
    try:
        model = pin.appendModel(model, loaded, 0, placement)
    except (RuntimeError, ValueError) as exc:
        raise InvalidInputError(f"object {obj.name!r}: cannot add URDF {str(path)!r}: {exc}") from None
    q_obj = pin.neutral(model)[nq_before:]
    if not obj.fixed:
        q_obj[:7] = pin.SE3ToXYZQUAT(obj.pose)
    return model, q_obj


__all__ = ["SceneObject", "RobotFrame", "SHAPES", "add_objects", "empty_robot"]
