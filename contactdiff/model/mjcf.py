"""Robots from MJCF (MuJoCo XML) files: Menagerie models, checked before Pinocchio reads them.

`load_mjcf` reads the file as untrusted input and writes default classes
inline (`contactdiff.model.mjcf_xml`), looks for what Pinocchio 4.1's MJCF
parser would drop (`contactdiff.model.mjcf_audit`), repairs what it can, refuses what it cannot
represent with `UnsupportedModelError` and warns (`MJCFWarning`, one line) about
what it leaves out, then builds the model with ``pinocchio.buildModelFromMJCF``.

* **Base.** A ``<freejoint/>`` (or ``<joint type="free">``) on the top body makes
  the floating base; ``floating_base=True`` on a model without one adds it,
  ``False`` removes it.
* **Reference pose.** The keyframe ``home``, else the first keyframe, else
  ``qpos0`` (joint ``ref`` values and the bodies' placements), as Pinocchio
  reads them into ``model.referenceConfigurations``.
* **Joint limits** as MuJoCo reads them (`_joint_limits`; Pinocchio converts a slide's
  range as an angle and ignores ``limited="false"``), ``±inf`` where unlimited.
* **Armature.** Pinocchio reads each joint's ``armature`` (classes included)
  into ``model.armature``, which its ``crba``, ``aba`` and ``computeMinverse``
  add to the mass matrix's diagonal, as MuJoCo does.
* **Feet.** Sphere collision geoms on leaf bodies (`contactdiff.model.mjcf_feet`).
* **Mesh inertia.** A body without ``<inertial>`` weighed by mesh geoms gets MuJoCo's
  volume inertia of each mesh (`contactdiff.model.mjcf_mesh`) when the files are there.

**MuJoCo's free-joint velocity.** MuJoCo's free joint velocity is the body
origin's linear velocity in the world frame and the angular velocity in the
body frame; Pinocchio's free-flyer has both in the body frame. So
``v_mujoco = T v_pinocchio`` with ``T = diag(R, I3)`` on each free joint's six
coordinates (``R`` the body's orientation) and the identity elsewhere, and
``M_pin = T^T M_mj T``, ``b_pin = T^T (b_mj + M_mj Ṫ v)`` (`mujoco_velocity_map`).
"""

from __future__ import annotations

import dataclasses
import tempfile
import warnings
from pathlib import Path
from xml.etree.ElementTree import Element, tostring

import numpy as np
import pinocchio as pin

from ..errors import ModelLoadError, UnsupportedModelError
from . import mjcf_xml
from .feet import choose_feet
from .mjcf_audit import Audit, audit, pinocchio_tree
from .mjcf_feet import add_sphere_frames, collision_spheres, sphere_feet, sphere_limbs
from .mjcf_xml import compiler_option, numbers
from .robot import Robot, _check_inertias, _check_mass_matrix


class MJCFWarning(UserWarning):
    """An MJCF feature was left out of the dynamics (the message names it)."""


def warn(message: str) -> None:
    """Issue an `MJCFWarning` printed on one line (no source line: the model is not Python)."""
    warnings.warn_explicit(MJCFWarning(message), MJCFWarning, "<mjcf>", 0)


def build_model(
    path: str | Path, floating_base: bool | None = None, allow_outside: bool = False
) -> tuple[pin.Model, Element, Audit]:
    """Pinocchio's model of an MJCF file, after `audit`.

    Returns:
        ``(model, root, audit)``: the model, the resolved tree it was built from
        (classes inline, repairs made) and the `Audit`.

    Raises:
        UnsafeModelFileError: see `contactdiff.model.mjcf_xml.read_document`.
        UnsupportedModelError: the audit refused a feature (all refused features listed).
        ModelLoadError: the file is malformed, or Pinocchio cannot build it.
    """
    path = Path(path)
    doc = mjcf_xml.read_document(path, allow_outside)
    root = mjcf_xml.resolve(doc)
    found = audit(root, floating_base, path.resolve().parent, allow_outside)
    if found.refused:
        raise UnsupportedModelError(f"MJCF {str(path)!r} cannot be loaded as given: " + "; ".join(found.refused))
    if found.left_out:
        warn(f"MJCF {path.name}: left out of the dynamics: " + "; ".join(found.left_out))
    _check_keyframes(root, path)
    with tempfile.TemporaryDirectory() as folder:
        resolved = Path(folder) / path.name
        resolved.write_bytes(tostring(pinocchio_tree(root)))
        try:
            model = pin.buildModelFromMJCF(str(resolved))
        except (RuntimeError, ValueError, IndexError) as exc:
            raise ModelLoadError(f"cannot read MJCF {str(path)!r}: {_message(exc)}") from None
    _rename_shared_frame_names(model)
    _joint_limits(model, root)
    return model, root, found


def _joint_limits(model: pin.Model, root: Element) -> None:
    """Set hinge and slide limits as MuJoCo reads them. Pinocchio 4.1 converts a slide's
    ``range`` from degrees as if it were an angle, and keeps the range of a joint with
    ``limited="false"``. MuJoCo: a joint is limited when ``limited="true"``, or with
    ``limited="auto"`` (the default) when it has a ``range`` and ``autolimits`` is on (the
    default); a hinge's range is in degrees unless ``<compiler angle="radian">``. Unlimited
    coordinates get ``±inf``."""
    degrees = compiler_option(root, "angle", "degree") == "degree"
    autolimits = compiler_option(root, "autolimits", "true") == "true"
    lower, upper = model.lowerPositionLimit.copy(), model.upperPositionLimit.copy()
    for joint in root.iter("joint"):
        kind = joint.get("type", "hinge")
        name = joint.get("name")
        if kind not in ("hinge", "slide") or not name or not model.existJointName(name):
            continue
        index = model.joints[model.getJointId(name)].idx_q
        given = numbers(joint.get("range"))
        limited = joint.get("limited", "auto")
        if limited == "true" or (limited == "auto" and autolimits and len(given) == 2):
            low, high = given if len(given) == 2 else (0.0, 0.0)
            scale = np.pi / 180 if kind == "hinge" and degrees else 1.0
            lower[index], upper[index] = low * scale, high * scale
        else:
            lower[index], upper[index] = -np.inf, np.inf
    model.lowerPositionLimit, model.upperPositionLimit = lower, upper


def _message(exc: Exception) -> str:
    """Pinocchio's error on one line: its ``message:`` part, without its source position."""
    text = str(exc)
    if "message:" in text:
        text = text.split("message:", 1)[1]
    return " ".join(text.split())


_JOINT_SIZES = {"free": 7, "ball": 4, "hinge": 1, "slide": 1}


def _check_keyframes(root: Element, path: Path) -> None:
    """Refuse a keyframe whose ``qpos`` is not MuJoCo's ``nq`` long, as MuJoCo does (named)."""
    nq = sum(
        7 if j.tag == "freejoint" else _JOINT_SIZES.get(j.get("type", "hinge"), 1)
        for world in root.findall("worldbody")
        for j in world.iter()
        if j.tag in ("joint", "freejoint")
    )
    for k, key in enumerate(root.iter("key")):
        size = len(numbers(key.get("qpos"))) if key.get("qpos") is not None else nq
        if size != nq:
            raise ModelLoadError(
                f"MJCF {str(path)!r}: keyframe {key.get('name') or f'#{k + 1}'!r} has {size} qpos "
                f"values; the model has nq = {nq}"
            )


def _rename_shared_frame_names(model: pin.Model) -> None:
    """MJCF keeps joints, bodies and sites in separate name spaces (Cassie has a joint and a
    body ``left-foot``); Pinocchio's frames share one. A name held by several frames stays
    the body's; the others get ``_joint`` or ``_site`` appended (their joints keep their names)."""
    names = [f.name for f in model.frames]
    for i, frame in enumerate(model.frames):
        if names.count(frame.name) < 2 or frame.type == pin.FrameType.BODY:
            continue
        suffix = {pin.FrameType.JOINT: "_joint", pin.FrameType.OP_FRAME: "_site"}.get(frame.type, "_frame")
        renamed = pin.Frame(frame)
        renamed.name = frame.name + suffix
        while renamed.name in names:
            renamed.name += suffix
        model.frames[i] = renamed
        names[i] = renamed.name


def reference_configuration(model: pin.Model, root: Element) -> tuple[np.ndarray, str]:
    """The reference pose and its name: keyframe ``home``, else the first keyframe, else
    ``qpos0`` (each as Pinocchio read it into ``model.referenceConfigurations``)."""
    keys = [k.get("name") for section in root.findall("keyframe") for k in section.findall("key")]
    available = {entry.key() for entry in model.referenceConfigurations}
    for name in ["home"] + [k for k in keys if k] + ["qpos0"]:
        if name in available:
            q = np.array(model.referenceConfigurations[name], dtype=float)
            if q.shape == (model.nq,) and np.all(np.isfinite(q)):
                return q, name
    return pin.neutral(model), "neutral"


def actuated_joints(model: pin.Model, root: Element, floating_base: bool) -> tuple[str, ...]:
    """Joints driven by an ``<actuator>`` (a ``joint=`` transmission); every joint but the
    base when the model has no actuators."""
    names = list(model.names)
    driven = {e.get("joint") for section in root.findall("actuator") for e in section if e.get("joint")}
    chosen = tuple(n for n in names[1:] if n in driven)
    if chosen:
        return chosen
    return tuple(names[2 if floating_base else 1 :])


def has_free_root(model: pin.Model) -> bool:
    """Whether the model's first joint is a free-flyer (a floating base)."""
    return model.njoints > 1 and model.joints[1].shortname() == "JointModelFreeFlyer"


def mujoco_velocity_map(model: pin.Model, q: np.ndarray, v: np.ndarray | None = None):
    """MuJoCo's velocity from Pinocchio's: ``v_mujoco = T v`` (module notes).

    Args:
        model: the Pinocchio model.
        q: configuration (``nq``).
        v: Pinocchio velocity (``nv``), for ``Ṫ v``; None to skip it.

    Returns:
        ``T`` (``nv × nv``), and ``Ṫ v`` (``nv``, zero but for each free joint's
        linear part ``R (ω × v_lin)``) when ``v`` is given.
    """
    data = model.createData()
    pin.forwardKinematics(model, data, q)
    T = np.eye(model.nv)
    Tdot_v = np.zeros(model.nv)
    for j in range(1, model.njoints):
        joint = model.joints[j]
        if joint.shortname() != "JointModelFreeFlyer":
            continue
        R = data.oMi[j].rotation
        i = joint.idx_v
        T[i : i + 3, i : i + 3] = R
        if v is not None:
            Tdot_v[i : i + 3] = R @ np.cross(v[i + 3 : i + 6], v[i : i + 3])
    return (T, Tdot_v) if v is not None else T


def load_mjcf(
    path: str | Path, floating_base: bool | None = None, feet=None, name: str | None = None, allow_outside: bool = False
):
    """Load a robot from an MJCF file (module notes); `contactdiff.model.robot_files.load_robot`
    calls this for ``.xml`` files whose root is ``<mujoco>``.

    Args:
        path: the MJCF file.
        floating_base: None keeps the model's own base (a free joint is a floating
            base); True adds a free joint to the top body, False removes it.
        feet: foot frames chosen by hand (a leaf body's collision sphere, by its
            geom's name or, unnamed, ``<body>_sphere[k]``, is a round foot), or None: the model's collision spheres on
            leaf bodies (`contactdiff.model.mjcf_feet`), else the rule of
            `contactdiff.model.feet`.
        name: the robot's name (default: the file's stem).
        allow_outside: read ``<include>`` files (and accept asset paths) outside the
            file's folder.

    Returns:
        The `Robot` (``robot.urdf`` holds the MJCF path; ``robot.foot_choice`` says how
        the feet were chosen).

    Raises:
        UnsafeModelFileError, UnsupportedModelError, ModelLoadError: see `build_model`.
    """
    path = Path(path)
    model, root, _ = build_model(path, floating_base, allow_outside)
    floating = has_free_root(model)
    _check_inertias(model, path, "MJCF")
    q_ref, _ = reference_configuration(model, root)
    _check_mass_matrix(model, q_ref, path, "MJCF")
    choice = sphere_feet(model, root, q_ref) if feet is None and floating else None
    spheres = {}
    if feet is not None:  # the leaf spheres' frames can be named by hand, and are round then
        spheres = add_sphere_frames(model, collision_spheres(root))
    if choice is None:
        choice, q_ref = choose_feet(model, q_ref, floating, feet)
        radii = {f: spheres[f].radius for f in choice.feet if f in spheres}
        if radii:
            choice = dataclasses.replace(choice, radii=radii, limbs=sphere_limbs(spheres, choice.feet))
    return Robot(
        model,
        name or path.stem,
        str(path),
        floating,
        q_ref,
        choice.feet,
        actuated_joints(model, root, floating),
        choice,
    )


def replay_note(robot) -> MJCFWarning:
    """The replay's note for an MJCF robot: drawn as spheres at its bodies, with how many of
    its mesh files are missing (a Menagerie model copied without its ``assets/``)."""
    path = Path(robot.urdf)
    try:
        root = mjcf_xml.read_document(path, allow_outside=True).root
        meshes = [p for tag, p in mjcf_xml.asset_files(root, path.resolve().parent) if tag == "mesh"]
    except ModelLoadError:
        meshes = []
    missing = sum(not p.is_file() for p in meshes)
    detail = f"{missing} of its {len(meshes)} mesh files are missing" if missing else "its meshes are not read"
    return MJCFWarning(f"replay: robot {robot.name!r} (MJCF) is drawn as spheres at its bodies ({detail})")
