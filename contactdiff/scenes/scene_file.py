"""Scene files (TOML), the project's scene names, and any command-line SOURCE as a scene.

The format (every key, with units) is in docs/scene-files.md. `load_source`
turns a SOURCE into a scene: a scene file or a name of the project's
``robots/`` folder, or a robot (URDF path or example-robot-data name) whose feet
get ground contacts (`Scene.from_robot`).
"""

from __future__ import annotations

import tomllib
from collections.abc import Mapping, Sequence
from pathlib import Path

from ..control.joint_targets import JointTargets
from ..control.trot_controller import TrotController
from ..control.trot_scenes import TROT_PARAMETERS
from ..errors import InvalidInputError, ModelLoadError, UnknownRobotError, unknown_name
from ..model.contacts import Contact
from ..model.efforts import JointSpring, Spring
from ..model.objects import RobotFrame, SceneObject, add_objects, empty_robot
from ..model.robot_files import ROBOTS_DIR, example_robot_data_names, load_robot, own_robot_names
from ..model.scene import Scene

_TOP_KEYS = (
    "robot",
    "floating_base",
    "gravity",
    "name",
    "description",
    "frame",
    "object",
    "contact",
    "spring",
    "joint_spring",
    "joint_targets",
    "trot",
    "initial",
)
_TROT_KEYS = TrotController.KEYS
_CONTACT_KEYS = ("frame", "normal", "offset", "restitution", "friction", "against", "name", "radius", "group")
_SPRING_KEYS = ("frame_a", "frame_b", "stiffness", "damping", "rest_length")
_JOINT_SPRING_KEYS = ("joint", "stiffness", "damping", "rest")
_INITIAL_KEYS = ("q", "v")
_EFFORT_KEYS = ("trot", "spring", "joint_spring", "joint_targets")  # the tables that put efforts on a robot
_FRAME_KEYS = ("name", "parent", "position", "rpy")
_OBJECT_KEYS = (
    "name",
    "shape",
    "mass",
    "size",
    "radius",
    "length",
    "urdf",
    "position",
    "rpy",
    "fixed",
    "points",
    "density",
    "moments",
)


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
        if doc.get("robot") == robot_name and any(k in doc for k in _EFFORT_KEYS):
            found.append(path.stem)
    return found


def passive_note(scene: Scene) -> str | None:
    """A warning for a robot with motors but no efforts (it folds under gravity), naming
    the scenes that drive it; None for any other scene."""
    robot = scene.robot
    if scene.efforts or not robot.actuated:
        return None
    scenes = driving_scenes(robot.name)
    text = (
        f"robot {robot.name!r} has no efforts: its {len(robot.actuated)} joints are passive, so it folds under gravity"
    )
    drivers = list(scenes)
    if robot.name in TROT_PARAMETERS:
        drivers.append(f"contactdiff.trot_scene({robot.name!r}) in Python")
    return text + (
        "; scenes that drive it: " + ", ".join(drivers)
        if drivers
        else "; add efforts to drive it (a [trot] controller, springs, or a UserEffort)"
    )


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
    robot = _scene_robot(where, doc, path.parent)
    contacts = []
    for i, entry in enumerate(_entries(doc, "contact")):
        _check_keys(f"{where} [[contact]] #{i + 1}", entry, _CONTACT_KEYS, required=("frame",))
        contacts.append(Contact(**entry))
    efforts: list = []
    for i, entry in enumerate(_entries(doc, "spring")):
        _check_keys(f"{where} [[spring]] #{i + 1}", entry, _SPRING_KEYS, required=("frame_a", "frame_b", "stiffness"))
        efforts.append(Spring(**entry))
    for i, entry in enumerate(_entries(doc, "joint_spring")):
        _check_keys(f"{where} [[joint_spring]] #{i + 1}", entry, _JOINT_SPRING_KEYS, required=("joint", "stiffness"))
        efforts.append(JointSpring(**entry))
    for i, entry in enumerate(_entries(doc, "joint_targets")):
        _check_keys(
            f"{where} [[joint_targets]] #{i + 1}",
            entry,
            JointTargets.KEYS,
            required=("joints", "times", "targets", "stiffness"),
        )
        efforts.append(JointTargets(**entry))
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
    return Scene(
        robot, contacts, efforts, doc.get("gravity"), initial.get("q"), initial.get("v"), doc.get("name", path.stem)
    )


def _scene_robot(where: str, doc: Mapping, folder: Path):
    """The scene's robot with its extra ``[[frame]]`` and its ``[[object]]`` (docs/scene-files.md);
    a scene of objects alone has no ``robot``."""
    _check_keys(where, doc, _TOP_KEYS)
    objects = []
    for i, entry in enumerate(_entries(doc, "object")):
        _check_keys(f"{where} [[object]] #{i + 1}", entry, _OBJECT_KEYS, required=("name",))
        objects.append(SceneObject(**entry))
    if not objects:
        _check_keys(where, doc, _TOP_KEYS, required=("robot",))
    robot_source = doc.get("robot")
    floating = doc.get("floating_base")
    if robot_source is None:
        if floating is not None:
            raise InvalidInputError(f"{where}: floating_base applies to a robot; this scene has none")
        robot = empty_robot()
    else:
        if not isinstance(robot_source, str):
            raise InvalidInputError(f"{where}: robot must be a file name or robot name, got {robot_source!r}")
        if floating is not None and not isinstance(floating, bool):
            raise InvalidInputError(f"{where}: floating_base must be true or false, got {floating!r}")
        relative = folder / robot_source
        robot = load_robot(relative if robot_source.endswith((".urdf", ".xml", ".mjcf")) else robot_source, floating)
    frames = []
    for i, entry in enumerate(_entries(doc, "frame")):
        _check_keys(f"{where} [[frame]] #{i + 1}", entry, _FRAME_KEYS, required=("name", "parent"))
        frames.append(RobotFrame(**entry))
    if not (objects or frames):
        return robot
    return add_objects(robot, objects, frames, base=folder)


def load_source(source: str | Path, floating_base: bool | None = None, feet: Sequence[str] | None = None) -> Scene:
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
                f"{str(source)!r} sets its robot's base and its contacts in its file"
            )
        return load_scene(source)
    try:
        robot = load_robot(source, floating_base, feet)
    except UnknownRobotError:
        scenes = scene_names()
        robots = [n for n in own_robot_names() + example_robot_data_names() if n not in scenes]
        raise unknown_name("scene or robot", str(source), scenes + robots) from None
    return Scene.from_robot(robot)


__all__ = ["load_scene", "load_source", "scene_names", "driving_scenes", "passive_note"]
