"""Scenes: a robot, its contacts, its efforts, gravity and an initial state.

A scene is built in Python (`Scene`) or read from a TOML file (`load_scene`,
format in the README and DESIGN.md §5). `load_source` turns any command-line
SOURCE into a scene: a scene file or name, or a robot (URDF path or
example-robot-data name) whose feet get ground contacts automatically.
"""

from __future__ import annotations

import tomllib
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pinocchio as pin

from .contacts import FRICTION_MODES, BoundContact, Contact
from .efforts import JointSpring, Spring, UserEffort, bind_efforts
from ..errors import (InconsistentStateError, InvalidInputError, ModelLoadError, UnknownRobotError,
                     unknown_name)
from .feet import FootChoice, up_direction
from ..control.trot_controller import TrotController
from .kinematics import Kinematics
from .robot import (ROBOTS_DIR, Robot, example_robot_data_names, load_robot,
                    own_robot_names)

PENETRATION_TOL = 1e-9
"""Largest penetration (m) an initial state may have: a closed contact, not an error."""

UNIT_NORM_TOL = 1e-6
"""How far from 1 the norm of a quaternion or unit complex number of a state may be."""


class Scene:
    """A mechanical system with unilateral contacts, ready to simulate or check.

    Args:
        robot: the `Robot` (its model is copied if gravity changes it).
        contacts: `Contact` specs; their names must be unique.
        efforts: `JointSpring`, `Spring` or `UserEffort` specs (gravity is not one:
            it is the model's, set by ``gravity``).
        gravity: world gravity (m/s², 3 numbers); ``None`` keeps the model's.
        q0, v0: initial state, either full arrays (``nq`` / ``nv``) or mappings
            from joint name to value (a number, or a list for multi-coordinate
            joints); unnamed joints keep the robot's reference pose and zero velocity.
        name: label for reports.

    Raises:
        InconsistentStateError: the initial state penetrates a contact.
    """

    def __init__(self, robot: Robot, contacts: Sequence[Contact] = (), efforts: Sequence = (),
                 gravity=None, q0=None, v0=None, name: str | None = None):
        if not isinstance(robot, Robot):
            raise InvalidInputError(f"robot must be a contactdiff Robot (see load_robot), got {robot!r}")
        if gravity is not None:
            robot = robot.copy()
            robot.model.gravity = pin.Motion(_vector3("gravity", gravity), np.zeros(3))
        self.robot = robot
        self.name = name or robot.name
        self.contact_specs = tuple(contacts)
        self.effort_specs = tuple(efforts)
        for c in self.contact_specs:
            if not isinstance(c, Contact):
                raise InvalidInputError(f"contacts must be Contact objects, got {c!r}")
        names = [c.name for c in self.contact_specs]
        duplicates = sorted({n for n in names if names.count(n) > 1})
        if duplicates:
            raise InvalidInputError(f"contact names must be unique; repeated: {', '.join(duplicates)}")
        for e in self.effort_specs:
            if not isinstance(e, (JointSpring, Spring, UserEffort, TrotController)):
                raise InvalidInputError(
                    f"efforts must be JointSpring, Spring, UserEffort or TrotController objects, got {e!r}")
        self.contacts: list[BoundContact] = [c.bind(robot) for c in self.contact_specs]
        self.efforts = bind_efforts(self.effort_specs, robot)
        self.q0 = self._configuration(q0)
        self.v0 = self._velocity(v0)
        self._kinematics: Kinematics | None = None
        self.foot_choice: FootChoice | None = None  # set by from_robot: how its feet were chosen
        self.check_state(self.q0, self.v0)

    # -- basic facts -----------------------------------------------------------------
    @property
    def model(self) -> pin.Model:
        return self.robot.model

    @property
    def nv(self) -> int:
        return self.robot.nv

    @property
    def contact_names(self) -> list[str]:
        return [c.name for c in self.contacts]

    def contact_index(self, name: str) -> int:
        """Index of contact ``name``; unknown names raise with the list of contacts."""
        if name not in self.contact_names:
            raise unknown_name("contact", name, self.contact_names)
        return self.contact_names.index(name)

    @property
    def kinematics(self) -> Kinematics:
        """The scene's own kinematics cache (one `pinocchio.Data`, not thread safe)."""
        if self._kinematics is None:
            self._kinematics = Kinematics(self.model)
        return self._kinematics

    # -- evaluation ------------------------------------------------------------------
    def gaps(self, q: np.ndarray) -> np.ndarray:
        """Gaps of all contacts at ``q`` (m), in contact order."""
        kin = self.kinematics
        kin.update(q, np.zeros(self.nv))
        return np.array([c.gap(kin) for c in self.contacts])

    def tau(self, kin: Kinematics, t: float) -> np.ndarray:
        """Sum of the scene's efforts at the state of ``kin`` (gravity excluded)."""
        total = np.zeros(self.nv)
        for e in self.efforts:
            total += e.tau(kin, t)
        return total

    def tau_derivatives(self, kin: Kinematics, t: float) -> tuple[np.ndarray, np.ndarray]:
        """``d tau/dq`` and ``d tau/dv`` of the efforts (tangent space, nv × nv each)."""
        dq, dv = np.zeros((self.nv, self.nv)), np.zeros((self.nv, self.nv))
        for e in self.efforts:
            a, b = e.derivatives(kin, t)
            dq += a
            dv += b
        return dq, dv

    def tau_time_derivative(self, kin: Kinematics, t: float) -> np.ndarray:
        """``d tau/dt`` at fixed state (nv,): the explicit time rate of the efforts
        (zero for an autonomous scene; see each effort's ``time_derivative``)."""
        total = np.zeros(self.nv)
        for e in self.efforts:
            total += e.time_derivative(kin, t)
        return total

    def check_state(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Validate a state; return its gaps.

        Raises:
            InvalidInputError: wrong size or non-finite entries.
            InconsistentStateError: a gap is below ``-PENETRATION_TOL``.
        """
        q, v = np.asarray(q, dtype=float), np.asarray(v, dtype=float)
        if q.shape != (self.robot.nq,) or v.shape != (self.nv,):
            raise InvalidInputError(
                f"state must have q of shape ({self.robot.nq},) and v of shape ({self.nv},); "
                f"got {q.shape} and {v.shape}")
        for label, x in (("q", q), ("v", v)):
            if not np.all(np.isfinite(x)):
                bad = [n for n, ok in zip(self._labels(label), np.isfinite(x)) if not ok]
                raise InvalidInputError(f"initial {label} has non-finite entries at {', '.join(bad)}: {x}")
        self._check_unit_coordinates(q)
        gaps = self.gaps(q)
        for name, gap in zip(self.contact_names, gaps):
            if gap < -PENETRATION_TOL:
                raise InconsistentStateError(
                    f"initial state penetrates contact {name!r}: gap {gap:.6g} m < 0; "
                    "raise the robot or lower the contact offset")
        return gaps

    def _check_unit_coordinates(self, q: np.ndarray) -> None:
        """Refuse a quaternion (free-flyer, spherical joint) or unit complex number
        (unbounded revolute, planar joint) whose norm is not 1 within `UNIT_NORM_TOL`:
        Pinocchio would turn it into a rotation that is not one, or a zero
        quaternion into no rotation at all."""
        model = self.model
        if self.robot.is_vector_space or pin.isNormalized(model, q, UNIT_NORM_TOL):
            return
        for jid in range(1, model.njoints):
            joint = model.joints[jid]
            if joint.nq == joint.nv:
                continue
            alone = pin.neutral(model)
            alone[joint.idx_q:joint.idx_q + joint.nq] = q[joint.idx_q:joint.idx_q + joint.nq]
            if not pin.isNormalized(model, alone, UNIT_NORM_TOL):
                raise InvalidInputError(
                    f"initial q of joint {model.names[jid]!r} ({joint.shortname()}) holds a quaternion or "
                    f"unit complex number whose norm is not 1 (within {UNIT_NORM_TOL:g}): "
                    f"{q[joint.idx_q:joint.idx_q + joint.nq].tolist()}; a free-flyer is "
                    "[x, y, z, qx, qy, qz, qw] with qx² + qy² + qz² + qw² = 1")

    def _labels(self, kind: str) -> list[str]:
        return self.robot.tangent_names() if kind == "v" else self.robot.configuration_names()

    # -- initial state by joint name ---------------------------------------------------
    def _configuration(self, q0, base: np.ndarray | None = None) -> np.ndarray:
        q = (self.robot.q_ref if base is None else base).copy()
        if q0 is None:
            return q
        if isinstance(q0, Mapping):
            for name, value in q0.items():
                joint = self.model.joints[self.robot.joint_id(name)]
                q[joint.idx_q:joint.idx_q + joint.nq] = _joint_values(name, value, joint.nq, "q")
            if not self.robot.is_vector_space:
                q = pin.normalize(self.model, q)
            return q
        return _array("q0", q0, self.robot.nq)

    def _velocity(self, v0, base: np.ndarray | None = None) -> np.ndarray:
        v = np.zeros(self.nv) if base is None else base.copy()
        if v0 is None:
            return v
        if isinstance(v0, Mapping):
            for name, value in v0.items():
                joint = self.model.joints[self.robot.joint_id(name)]
                v[joint.idx_v:joint.idx_v + joint.nv] = _joint_values(name, value, joint.nv, "v")
            return v
        return _array("v0", v0, self.nv)

    # -- variants ----------------------------------------------------------------------
    def with_robot(self, robot: Robot) -> Scene:
        """The same scene on another robot model (e.g. one with armature)."""
        scene = Scene(robot, self.contact_specs, self.effort_specs, None, self.q0, self.v0, self.name)
        scene.foot_choice = self.foot_choice
        return scene

    def with_armature(self, armature: float) -> Scene:
        """The same scene with rotor inertia ``armature`` on the robot's actuated joints."""
        return self.with_robot(self.robot.with_armature(armature))

    def with_state(self, q0=None, v0=None) -> Scene:
        """The same scene from another initial state: full arrays, or joint-name
        mappings that change only the named joints of this scene's state."""
        scene = Scene.__new__(Scene)
        scene.__dict__.update(self.__dict__)
        scene._kinematics = None
        scene.q0 = self.q0 if q0 is None else scene._configuration(q0, self.q0)
        scene.v0 = self.v0 if v0 is None else scene._velocity(v0, self.v0)
        scene.check_state(scene.q0, scene.v0)
        return scene

    @classmethod
    def from_robot(cls, robot: Robot, restitution: float = 0.0, friction: str = "stick",
                   name: str | None = None) -> Scene:
        """A robot standing on the ground: one contact per foot (``robot.feet``, see
        `contactdiff.model.feet`), normal along the vertical ``-g / |g|`` and offset so the
        reference pose touches the ground. A robot without feet gets no contacts."""
        up = up_direction(robot.model)
        kin = Kinematics(robot.model)
        kin.update(robot.q_ref, np.zeros(robot.nv))
        contacts = [Contact(foot, normal=tuple(up), offset=float(up @ kin.position(robot.frame_id(foot))),
                            restitution=restitution, friction=friction) for foot in robot.feet]
        scene = cls(robot, contacts, name=name or robot.name)
        scene.foot_choice = robot.foot_choice
        return scene


def _vector3(name: str, value) -> np.ndarray:
    try:
        x = np.asarray(value, dtype=float).reshape(3)
    except (TypeError, ValueError):
        raise InvalidInputError(f"{name} must be 3 numbers, got {value!r}") from None
    if not np.all(np.isfinite(x)):
        raise InvalidInputError(f"{name} must be finite, got {value!r}")
    return x


def _array(name: str, value, size: int) -> np.ndarray:
    try:
        x = np.array(value, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise InvalidInputError(f"{name} must be {size} numbers, got {value!r}") from None
    if x.shape != (size,):
        raise InvalidInputError(f"{name} must have {size} entries, got {x.shape[0]}")
    return x


def _joint_values(joint: str, value, size: int, kind: str) -> np.ndarray:
    try:
        x = np.array(value, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise InvalidInputError(f"initial {kind} of joint {joint!r} must be numeric, got {value!r}") from None
    if x.shape != (size,):
        raise InvalidInputError(f"initial {kind} of joint {joint!r} needs {size} value(s), got {value!r}")
    if not np.all(np.isfinite(x)):
        raise InvalidInputError(f"initial {kind} of joint {joint!r} must be finite, got {value!r}")
    return x


# -- TOML ------------------------------------------------------------------------------
_TOP_KEYS = ("robot", "floating_base", "gravity", "name", "description", "contact", "spring",
             "joint_spring", "trot", "initial")
_TROT_KEYS = TrotController.KEYS
_CONTACT_KEYS = ("frame", "normal", "offset", "restitution", "friction", "against", "name")
_SPRING_KEYS = ("frame_a", "frame_b", "stiffness", "damping", "rest_length")
_JOINT_SPRING_KEYS = ("joint", "stiffness", "damping", "rest")
_INITIAL_KEYS = ("q", "v")


def _check_keys(where: str, table, valid: Sequence[str], required: Sequence[str] = ()) -> None:
    if not isinstance(table, Mapping):
        raise InvalidInputError(f"{where} must be a table, got {table!r}")
    for key in table:
        if key not in valid:
            raise unknown_name(f"key in {where}", key, valid)
    for key in required:
        if key not in table:
            raise InvalidInputError(f"{where} is missing the key {key!r} (keys: {', '.join(valid)})")


def _entries(doc: Mapping, key: str) -> list:
    value = doc.get(key, [])
    if not isinstance(value, list):
        raise InvalidInputError(f"[[{key}]] must be an array of tables (write [[{key}]]), got {value!r}")
    return value


def scene_names() -> list[str]:
    """Names of the scene files in the project's ``robots/`` folder."""
    return sorted(p.stem for p in ROBOTS_DIR.glob("*.toml"))


def driving_scenes(robot_name: str) -> list[str]:
    """Scene names of ``robots/`` whose files put efforts on robot ``robot_name``."""
    found = []
    for path in sorted(ROBOTS_DIR.glob("*.toml")):
        try:
            doc = tomllib.loads(path.read_text())
        except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
            continue
        if doc.get("robot") == robot_name and any(k in doc for k in ("trot", "spring", "joint_spring")):
            found.append(path.stem)
    return found


def passive_note(scene: Scene) -> str | None:
    """A warning for a robot with motors but no efforts (it folds under gravity), naming
    the scenes that drive it; None for any other scene."""
    robot = scene.robot
    if scene.efforts or not robot.actuated:
        return None
    scenes = driving_scenes(robot.name)
    text = (f"robot {robot.name!r} has no efforts: its {len(robot.actuated)} joints are passive, so it folds "
            "under gravity")
    from ..control.trot_scenes import TROT_PARAMETERS  # here: the trot module imports this one

    drivers = list(scenes)
    if robot.name in TROT_PARAMETERS:
        drivers.append(f"contactdiff.control.trot_scenes.trot_scene({robot.name!r}) in Python")
    return text + ("; scenes that drive it: " + ", ".join(drivers) if drivers else
                   "; add efforts to drive it (a [trot] controller, springs, or a UserEffort)")


def load_scene(source: str | Path) -> Scene:
    """Read a scene from a TOML file or a scene name of ``robots/``.

    Raises:
        ModelLoadError: missing or unparsable file.
        UnknownNameError: unknown keys, frames, joints or names (with the valid ones).
        InvalidInputError: bad numbers (non-finite, negative stiffness, restitution
            outside [0, 1], zero normal).
        InconsistentStateError: the initial state penetrates a contact.
    """
    path = Path(source)
    if path.suffix != ".toml":
        own = ROBOTS_DIR / f"{source}.toml"
        if not own.is_file():
            raise unknown_name("scene", str(source), scene_names())
        path = own
    if path.is_dir():
        raise ModelLoadError(f"scene path {str(path)!r} is a directory, not a TOML file")
    if not path.exists():
        raise ModelLoadError(f"scene file {str(path)!r} does not exist")
    if not path.is_file():
        raise ModelLoadError(f"scene path {str(path)!r} is not a regular file")
    try:
        doc = tomllib.loads(path.read_text())
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise ModelLoadError(f"cannot read scene file {str(path)!r}: {exc}") from None
    where = f"scene {path.name}"
    _check_keys(where, doc, _TOP_KEYS, required=("robot",))
    robot_source = doc["robot"]
    if not isinstance(robot_source, str):
        raise InvalidInputError(f"{where}: robot must be a file name or robot name, got {robot_source!r}")
    floating = doc.get("floating_base")
    if floating is not None and not isinstance(floating, bool):
        raise InvalidInputError(f"{where}: floating_base must be true or false, got {floating!r}")
    relative = path.parent / robot_source
    robot = load_robot(relative if robot_source.endswith(".urdf") else robot_source, floating)

    contacts = []
    for i, entry in enumerate(_entries(doc, "contact")):
        _check_keys(f"{where} [[contact]] #{i + 1}", entry, _CONTACT_KEYS, required=("frame",))
        contacts.append(Contact(**entry))
    efforts: list = []
    for i, entry in enumerate(_entries(doc, "spring")):
        _check_keys(f"{where} [[spring]] #{i + 1}", entry, _SPRING_KEYS,
                    required=("frame_a", "frame_b", "stiffness"))
        efforts.append(Spring(**entry))
    for i, entry in enumerate(_entries(doc, "joint_spring")):
        _check_keys(f"{where} [[joint_spring]] #{i + 1}", entry, _JOINT_SPRING_KEYS,
                    required=("joint", "stiffness"))
        efforts.append(JointSpring(**entry))
    if "trot" in doc:  # a TrotController (contactdiff.control.trot_controller) on the legs
        _check_keys(f"{where} [trot]", doc["trot"], _TROT_KEYS)
        stance = doc["trot"].get("stance", {})
        if not isinstance(stance, Mapping):
            raise InvalidInputError(f"{where}: trot.stance must be a table of joint = angle (rad), got {stance!r}")
        efforts.append(TrotController(**doc["trot"]))
    initial = doc.get("initial", {})
    _check_keys(f"{where} [initial]", initial, _INITIAL_KEYS)
    for key in _INITIAL_KEYS:
        if key in initial and not isinstance(initial[key], Mapping):
            raise InvalidInputError(f"{where}: initial.{key} must be a table of joint = value")
    return Scene(robot, contacts, efforts, doc.get("gravity"), initial.get("q"), initial.get("v"),
                 doc.get("name", path.stem))


def load_source(source: str | Path, floating_base: bool | None = None,
                feet: Sequence[str] | None = None) -> Scene:
    """Any SOURCE of the command line as a scene.

    A ``.toml`` path or a scene name of ``robots/`` is read with `load_scene`;
    anything else is loaded with `load_robot` (``floating_base`` and ``feet`` as
    there) and given ground contacts at its feet (`Scene.from_robot`).

    Raises:
        InvalidInputError: ``floating_base`` or ``feet`` given with a scene, whose
            file sets its robot and contacts.
    """
    if str(source).endswith(".toml") or (ROBOTS_DIR / f"{source}.toml").is_file():
        given = [k for k, v in (("floating_base", floating_base), ("feet", feet)) if v is not None]
        if given:
            raise InvalidInputError(
                f"{' and '.join(given)} {'apply' if len(given) > 1 else 'applies'} to a robot; scene "
                f"{str(source)!r} sets its robot's base and its contacts in its file")
        return load_scene(source)
    try:
        robot = load_robot(source, floating_base, feet)
    except UnknownRobotError:
        scenes = scene_names()
        robots = [n for n in own_robot_names() + example_robot_data_names() if n not in scenes]
        raise unknown_name("scene or robot", str(source), scenes + robots) from None
    return Scene.from_robot(robot)


__all__ = ["Scene", "load_scene", "load_source", "scene_names", "driving_scenes", "passive_note",
           "FRICTION_MODES"]
