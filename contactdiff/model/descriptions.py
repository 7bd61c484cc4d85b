"""Robots by their `robot_descriptions <https://github.com/robot-descriptions/robot_descriptions.py>`_
name (``go2_mj_description``, ``anymal_c_description``, ...), when that optional package is installed.

The package keeps clones of the models' repositories in its cache, the folder
``ROBOT_DESCRIPTIONS_CACHE`` (default ``~/.cache/robot_descriptions``), and clones a
repository there the first time one of its models is asked for (that needs the
network). `description_file` returns the model file (MJCF if the description has
one, else URDF) for `contactdiff.model.robot_files.load_robot`, and `legged` says whether
the package tags the robot quadruped, biped or humanoid (a URDF of one then gets a
floating base by default; an MJCF says so itself with its free joint).
"""

from __future__ import annotations

import importlib
import importlib.util
import os
from pathlib import Path

from ..errors import ModelLoadError


def installed() -> bool:
    """Whether the optional ``robot_descriptions`` package can be imported."""
    return importlib.util.find_spec("robot_descriptions") is not None


def description_file(name: str) -> Path | None:
    """The model file of robot_descriptions' ``name``; None when the package is not
    installed or does not know the name.

    Raises:
        ModelLoadError: the package knows the name but cannot provide the files (its
            cache lacks the repository and it cannot be cloned, e.g. without network).
    """
    if not installed():
        return None
    from robot_descriptions import DESCRIPTIONS

    if name not in DESCRIPTIONS:
        return None
    cache = os.environ.get("ROBOT_DESCRIPTIONS_CACHE", "~/.cache/robot_descriptions")
    try:
        module = importlib.import_module(f"robot_descriptions.{name}")
    except Exception as exc:  # noqa: BLE001 - git, network and file errors of the package alike
        raise ModelLoadError(
            f"robot_descriptions cannot provide {name!r}: {type(exc).__name__}: "
            f"{str(exc).strip().splitlines()[0] if str(exc).strip() else ''} "
            f"(its cache is {cache!r}, set by ROBOT_DESCRIPTIONS_CACHE; a first use clones "
            "the model's repository there and needs the network)"
        ) from None
    for attribute in ("MJCF_PATH", "URDF_PATH"):
        path = getattr(module, attribute, None)
        if path:
            return Path(path)
    raise ModelLoadError(f"robot_descriptions' {name!r} has neither an MJCF nor a URDF file")


LEGGED_TAGS = frozenset({"quadruped", "biped", "humanoid"})
"""robot_descriptions' tags of robots that stand on feet (a floating base)."""


def legged(name: str) -> bool:
    """Whether robot_descriptions tags ``name`` as a legged robot (`LEGGED_TAGS`)."""
    if not installed():
        return False
    from robot_descriptions import DESCRIPTIONS

    description = DESCRIPTIONS.get(name)
    return description is not None and bool(set(description.tags) & LEGGED_TAGS)
