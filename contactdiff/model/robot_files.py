"""Where robots come from: URDF and MJCF files, the project's ``robots/`` folder and
example-robot-data names, loaded by `load_robot` into a `contactdiff.model.robot.Robot`.

Only dynamics is loaded: no meshes or collision geometry (they cost up to
seconds to parse and are never used here). Sources, in the order tried:

1. a path to a URDF file, or to an MJCF file (`contactdiff.model.mjcf`);
2. a model of the project's own ``robots/`` folder, by name (``"ball"``);
3. an example-robot-data name (``"solo12"``, ``"anymal"``, ...).
"""

from __future__ import annotations

import math
import os
import re
import sys
from collections.abc import Sequence
from pathlib import Path
from xml.etree import ElementTree

import pinocchio as pin

from ..errors import InvalidInputError, ModelLoadError, UnknownRobotError, check_names, unknown_name
from .feet import choose_feet
from .robot import Robot, _check_inertias, _check_mass_matrix


def _robots_dir() -> Path:
    """The package ``contactdiff.robots`` of an installed wheel or an editable install,
    else (a source checkout imported from its folder) ``robots/`` beside ``contactdiff/``."""
    try:
        from importlib.resources import files

        return Path(str(files("contactdiff.robots")))
    except ModuleNotFoundError:
        return Path(__file__).resolve().parents[2] / "robots"


ROBOTS_DIR = _robots_dir()
"""Folder of the project's own URDF and scene files (top-level ``robots/``)."""


QUADRUPEDS = ("solo12", "anymal", "a1", "go1", "go2", "hyq")
"""example-robot-data quadrupeds whose feet and standing pose are known to load."""


def _is_path(source) -> bool:
    return isinstance(source, Path) or (
        isinstance(source, str) and (os.sep in source or source.endswith((".urdf", ".xml", ".mjcf")))
    )


def own_robot_names() -> list[str]:
    """Names of the URDF models in the project's ``robots/`` folder."""
    return sorted(p.stem for p in ROBOTS_DIR.glob("*.urdf"))


def example_robot_data_names() -> list[str]:
    """Names of example-robot-data models that load from a URDF."""
    from example_robot_data.robots_loader import ROBOTS

    return sorted(n for n, loader in ROBOTS.items() if loader.urdf_filename)


def load_robot(source: str | Path, floating_base: bool | None = None, feet: Sequence[str] | None = None) -> Robot:
    """Load a robot for dynamics only (no meshes).

    Args:
        source: a URDF path, an MJCF path (``.xml`` with a ``<mujoco>`` root, read by
            `contactdiff.model.mjcf.load_mjcf`), a name of a model in ``robots/`` (see
            `own_robot_names`), an example-robot-data name (see
            `example_robot_data_names`) or, with the optional robot_descriptions
            package, one of its names (``go2_mj_description``,
            `contactdiff.model.descriptions`).
        floating_base: add a free-flyer root joint. ``None`` takes the model's
            own choice: True for example-robot-data legged robots and MJCF files
            with a free joint, False for the project's planar models and for URDF paths.
        feet: foot frames chosen by hand; ``None`` chooses them automatically
            for a floating base (the lowest end frames at the reference pose,
            see `contactdiff.model.feet`) and gives a fixed base none.

    Returns:
        The `Robot`, with its reference pose and its feet (``robot.foot_choice``
        says how they were chosen).

    Raises:
        UnknownRobotError: ``source`` is neither a file nor a known name (the
            known names are listed).
        UnknownNameError: a given foot is not a frame (the frames are listed).
        ModelLoadError: the URDF is missing, not a file or cannot be parsed, or
            example-robot-data cannot load the model.
    """
    if feet is not None:
        feet = _frame_list(feet)
    if _is_path(source):
        from .mjcf import load_mjcf
        from .mjcf_xml import looks_like_mjcf

        if looks_like_mjcf(source):
            return load_mjcf(source, floating_base, feet)
        return _from_urdf(Path(source), bool(floating_base), Path(source).stem, feet=feet)
    if not isinstance(source, str):
        raise InvalidInputError(f"robot source must be a URDF path or a name, got {source!r}")
    own = ROBOTS_DIR / f"{source}.urdf"
    if own.is_file():
        return _from_urdf(own, bool(floating_base), source, feet=feet)
    from example_robot_data.robots_loader import ROBOTS

    loader = ROBOTS.get(source)
    if loader is None:
        from .descriptions import description_file, legged

        described = description_file(source)  # the optional robot_descriptions package
        if described is not None:
            if floating_base is None and described.suffix == ".urdf":
                floating_base = legged(source)
            return load_robot(described, floating_base, feet)
        known = own_robot_names() + example_robot_data_names()
        raise UnknownRobotError(str(unknown_name("robot", source, known)))
    if not loader.urdf_filename:
        raise ModelLoadError(_unloadable_reason(source, loader))
    return _from_example_robot_data(source, loader, floating_base, feet)


def _frame_list(feet) -> tuple[str, ...]:
    """Foot frames: names, or one string of comma-separated names (the command line's)."""
    if isinstance(feet, str):
        feet = [f.strip() for f in feet.split(",") if f.strip()]
    return check_names("", "feet", feet)


def _unloadable_reason(name: str, loader) -> str:
    """Why example-robot-data's model ``name`` cannot be loaded here (it has no URDF)."""
    import example_robot_data

    described = next(
        (
            f"{kind} file {getattr(loader, attr)}"
            for kind, attr in (("SDF", "sdf_filename"), ("MJCF", "mjcf_filename"))
            if getattr(loader, attr, "")
        ),
        "no URDF file",
    )
    try:
        example_robot_data.load(name)
    except Exception as exc:  # noqa: BLE001 - any failure of the loader is the reason
        failure = f"its loader fails: {type(exc).__name__}: {exc}"
    else:
        failure = "it has no URDF, the only format contactdiff reads"
    return f"example-robot-data's robot {name!r} cannot be loaded: it is described by a {described}, and {failure}"


def _from_urdf(
    path: Path,
    floating_base: bool,
    name: str,
    srdf: str = "",
    posture: str = "standing",
    feet: Sequence[str] | None = None,
) -> Robot:
    if path.is_dir():
        raise ModelLoadError(f"URDF path {str(path)!r} is a directory, not a URDF file")
    if not path.exists():
        raise ModelLoadError(f"URDF file {str(path)!r} does not exist")
    if not path.is_file():
        raise ModelLoadError(f"URDF path {str(path)!r} is not a regular file")
    _check_numbers(path)
    with _captured_stderr() as captured:
        try:
            if floating_base:
                model = pin.buildModelFromUrdf(str(path), pin.JointModelFreeFlyer())
            else:
                model = pin.buildModelFromUrdf(str(path))
        except (RuntimeError, ValueError) as exc:
            error: RuntimeError | ValueError | None = exc
        else:
            error = None
    if error is not None:
        detail = " ".join(line.strip() for line in captured.lines() if line.strip())
        detail = re.sub(r" at line \d+ in \S+", "", detail)  # the parser's own source position
        raise ModelLoadError(f"cannot read URDF {str(path)!r}: {error}" + (f" ({detail})" if detail else "")) from None
    _check_inertias(model, path)
    q_ref = pin.neutral(model)
    if srdf:
        pin.loadReferenceConfigurations(model, srdf, False)
        if posture in model.referenceConfigurations:
            q_ref = model.referenceConfigurations[posture].copy()
    _check_mass_matrix(model, q_ref, path)
    root = 2 if floating_base else 1
    actuated = tuple(model.names[j] for j in range(root, model.njoints)) if floating_base else ()
    choice, q_ref = choose_feet(model, q_ref, floating_base, feet)
    return Robot(model, name, str(path), floating_base, q_ref, choice.feet, actuated, choice)


class _captured_stderr:
    """Capture what C++ code writes to file descriptor 2 (urdfdom's parser prints
    its errors there before raising), to put it into our one-line error."""

    def __enter__(self):
        import tempfile

        self._file = tempfile.TemporaryFile(mode="w+b")
        try:
            sys.stderr.flush()
            self._saved = os.dup(2)
            os.dup2(self._file.fileno(), 2)
        except OSError:  # no file descriptor 2 (embedded interpreters): leave it alone
            self._saved = None
        return self

    def __exit__(self, *exc) -> None:
        if self._saved is not None:
            os.dup2(self._saved, 2)
            os.close(self._saved)

    def lines(self) -> list[str]:
        self._file.seek(0)
        text = self._file.read().decode(errors="replace")
        self._file.close()
        return text.splitlines()


_NAME_ATTRIBUTES = {"name", "link", "joint", "filename", "type"}  # never numbers, even "nan"


def _check_numbers(path: Path) -> None:
    """Refuse non-finite numbers in the URDF's attributes: the URDF parser drops an
    element it cannot read (an inertial block with ``ixx="nan"`` loses its whole
    rotational inertia) and would give a wrong model without a word."""
    try:
        root = ElementTree.parse(path).getroot()
    except ElementTree.ParseError as exc:
        raise ModelLoadError(f"cannot read URDF {str(path)!r}: {exc}") from None
    parents = {child: parent for parent in root.iter() for child in parent}
    for element in root.iter():
        for key, text in element.attrib.items():
            if key in _NAME_ATTRIBUTES:
                continue
            for token in text.split():
                try:
                    value = float(token)
                except ValueError:
                    continue  # names, file paths
                if not math.isfinite(value):
                    raise ModelLoadError(
                        f"URDF {str(path)!r}: <{element.tag} {key}={text!r}> in {_owner(element, parents)} "
                        "is not a finite number"
                    )


def _owner(element, parents) -> str:
    """``<link name='x'>`` (or joint, ...) that holds ``element``: the nearest named ancestor."""
    node = element
    while node is not None:
        if node.get("name"):
            return f"<{node.tag} name={node.get('name')!r}>"
        node = parents.get(node)
    return "the robot"


def _from_example_robot_data(name: str, loader, floating_base: bool | None, feet: Sequence[str] | None = None) -> Robot:
    from example_robot_data import getModelPath

    rel = os.path.join(loader.path, loader.urdf_subpath, loader.urdf_filename)
    root = getModelPath(rel)
    srdf = ""
    if loader.srdf_filename:
        srdf = os.path.join(root, loader.path, loader.srdf_subpath, loader.srdf_filename)
    floating = loader.free_flyer if floating_base is None else bool(floating_base)
    return _from_urdf(Path(root) / rel, floating, name, srdf, loader.ref_posture, feet)
