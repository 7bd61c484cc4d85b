"""Robots from MJCF (MuJoCo XML) files: Menagerie models, checked before Pinocchio reads them.

`load_mjcf` reads the file as untrusted input and writes default classes
inline (`contactdiff.model.mjcf_xml`), looks for what Pinocchio 4.1's MJCF
parser would drop (`audit`), repairs what it can, refuses what it cannot
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

**MuJoCo's free-joint velocity.** MuJoCo's free joint velocity is the body
origin's linear velocity in the world frame and the angular velocity in the
body frame; Pinocchio's free-flyer has both in the body frame. So
``v_mujoco = T v_pinocchio`` with ``T = diag(R, I3)`` on each free joint's six
coordinates (``R`` the body's orientation) and the identity elsewhere, and
``M_pin = T^T M_mj T``, ``b_pin = T^T (b_mj + M_mj Ṫ v)`` (`mujoco_velocity_map`).
"""

from __future__ import annotations

import copy
import dataclasses
import tempfile
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from xml.etree.ElementTree import Element, tostring

import numpy as np
import pinocchio as pin

from ..errors import ModelLoadError, UnsupportedModelError
from . import mjcf_tree, mjcf_xml
from .mjcf_xml import bodies, compiler_option, numbers


class MJCFWarning(UserWarning):
    """An MJCF feature was left out of the dynamics (the message names it)."""


_DYNAMIC_ACTUATORS = ("cylinder", "muscle", "adhesion")  # shortcuts with activation dynamics
_FLEX_TAGS = ("flex", "flexcomp", "composite")
_GENERATED = ("replicate", "attach")  # MuJoCo 3's generated bodies: unknown to Pinocchio 4.1
_PLACEMENT = {"pos", "quat", "euler", "axisangle", "xyaxes", "zaxis"}


@dataclass
class Audit:
    """What Pinocchio would drop from an MJCF model, found before it reads it.

    Attributes:
        left_out: one phrase per feature left out of the dynamics (warned about).
        refused: one phrase per feature that would change the dynamics (an error).
        repaired: one phrase per change made to the tree so Pinocchio reads it fully.
    """

    left_out: list[str] = field(default_factory=list)
    refused: list[str] = field(default_factory=list)
    repaired: list[str] = field(default_factory=list)


def _joints(body: Element) -> list[Element]:
    return [e for e in body if e.tag in ("joint", "freejoint")]


def _is_free(joint: Element) -> bool:
    return joint.tag == "freejoint" or joint.get("type") == "free"


def _has_joint(body: Element) -> bool:
    return any(e.tag in ("joint", "freejoint") for e in body.iter())


def _listed(items: list[str]) -> str:
    """``a, b, connect (unnamed) ×4``: repeated phrases counted."""
    counts = {item: items.count(item) for item in items}
    return ", ".join(item + (f" ×{n}" if n > 1 else "") for item, n in counts.items())


def _named(element: Element, fallback: str = "") -> str:
    name = element.get("name")
    return repr(name) if name else fallback or f"<{element.tag}> #?"


def audit(root: Element, floating_base: bool | None = None) -> Audit:
    """Find (and repair in ``root``, in place) what Pinocchio's MJCF parser would drop.

    Repairs: orientations become quaternions, ``<frame>`` elements are replaced by
    their children and bodies with several joints are split (`contactdiff.model.mjcf_tree`);
    several top-level bodies without a free joint, or one placed away from the
    world's origin, are put into one body fixed to the world (Pinocchio reads only the
    first top-level body, and drops its placement); the free joint is added or
    removed as ``floating_base`` asks. (The geoms Pinocchio weighs are set in a
    copy, `pinocchio_tree`.)

    Refused: a mesh geom that gives mass to a moving body without ``<inertial>``
    (no mesh is integrated here; a body welded to the world may weigh anything),
    several top-level trees with a free joint, flex and composite bodies (degrees
    of freedom Pinocchio cannot represent),
    ``<replicate>`` and ``<attach>`` (bodies Pinocchio would not create).

    Left out (warned): other top-level bodies without joints (fixed to the world,
    no effect on the robot's dynamics), height fields, equality constraints,
    tendons, actuator activation dynamics.
    """
    found = Audit()
    mjcf_tree.orientations_as_quaternions(root)
    frames = mjcf_tree.flatten_frames(root)
    if frames:
        found.repaired.append(f"{frames} <frame> element(s) replaced by their children, placed")
    split = mjcf_tree.split_joints(root, {e.get("name") for e in root.iter() if e.get("name")})
    if split:
        found.repaired.append(f"bodies with several joints ({', '.join(split)}) split into one body per joint")
    _base_joint(root, floating_base, found)
    _top_bodies(root, found)
    _mesh_masses(root, found)
    for tag in _FLEX_TAGS:
        for element in root.iter(tag):
            found.refused.append(f"<{tag}> {_named(element, '(unnamed)')} (deformable bodies add degrees of "
                                 "freedom the rigid-body model does not have)")
    for tag in _GENERATED:
        for element in root.iter(tag):
            found.refused.append(f"<{tag}> (its bodies would be lost: save the model expanded by MuJoCo, "
                                 "mujoco.mj_saveLastXML, and load that)")
    hfields = [_named(e, "(unnamed)") for e in root.iter("hfield")]
    _remove(root, lambda e: e.tag == "hfield" or (e.tag == "geom" and (e.get("type") == "hfield" or e.get("hfield"))))
    if hfields:
        found.left_out.append(f"height field(s) {', '.join(hfields)} (the ground is the scene's plane)")
    for section, what in (("equality", "equality constraint(s)"), ("tendon", "tendon(s)")):
        items = [f"{e.tag} {_named(e, '(unnamed)')}" for s in root.findall(section) for e in s]
        if items:
            found.left_out.append(f"{what} {_listed(items)}")
    dynamic = []
    for actuators in root.findall("actuator"):
        for e in actuators:
            if e.tag in _DYNAMIC_ACTUATORS or e.get("dyntype", "none") != "none":
                dynamic.append(f"{e.tag} {_named(e, '(unnamed)')}")
    if dynamic:
        found.left_out.append(f"the activation dynamics of actuator(s) {_listed(dynamic)} "
                              "(efforts act directly)")
    return found


def _remove(root: Element, condition) -> None:
    """Remove every element meeting ``condition`` (Pinocchio's parser refuses some, e.g. height fields)."""
    for parent in root.iter():
        for child in [c for c in parent if condition(c)]:
            parent.remove(child)


def _top_bodies(root: Element, found: Audit) -> None:
    world = root.find("worldbody")
    if world is None:
        return
    top = world.findall("body")
    placed = [b for b in top if set(b.attrib) & _PLACEMENT]
    if len(top) == 1 and not any(_is_free(j) for j in _joints(top[0])) and placed:
        _hold(root, world, top)  # Pinocchio drops the placement of the top body
        found.repaired.append(f"body {_named(top[0])} put into a body fixed to the world (its placement kept)")
        return
    if len(top) < 2:
        return
    jointed = [b for b in top if _has_joint(b)]
    free = [b for b in jointed if any(_is_free(j) for j in _joints(b))]
    if free:
        if len(jointed) > 1:
            found.refused.append(
                f"<worldbody> holds {len(jointed)} top-level bodies with joints "
                f"({', '.join(_named(b) for b in jointed)}), one of them floating; the model holds one tree: "
                "load each body's own file")
            return
        dropped = [b for b in top if b is not free[0]]
        for b in dropped:
            world.remove(b)
        found.left_out.append(f"top-level bod{'y' if len(dropped) == 1 else 'ies'} "
                              f"{', '.join(_named(b) for b in dropped)} (no joints: fixed to the world, "
                              "not part of the floating robot)")
        return
    _hold(root, world, top)
    found.repaired.append(f"the {len(top)} top-level bodies put into one body fixed to the world")


def _hold(root: Element, world: Element, top: list[Element]) -> None:
    """Put the top-level bodies ``top`` into one new body at the world's origin: Pinocchio
    reads only the first top-level body and ignores its placement (a fixed hand's palm
    turned upside down by its ``quat`` would hang upright), while it keeps a child's."""
    holder = Element("body", {"name": _free_name(root, "world_fixed")})
    for b in top:
        world.remove(b)
        holder.append(b)
    world.insert(0, holder)


def _free_name(root: Element, name: str) -> str:
    used = {e.get("name") for e in root.iter() if e.get("name")}
    while name in used:
        name += "_"
    return name


def _base_joint(root: Element, floating_base: bool | None, found: Audit) -> None:
    world = root.find("worldbody")
    top = world.findall("body") if world is not None else []
    if floating_base is None or not top:
        return
    base = top[0]
    free = [j for j in _joints(base) if _is_free(j)]
    if floating_base and not free:
        if len(top) > 1 or _joints(base):
            raise UnsupportedModelError(
                f"cannot give {', '.join(_named(b) for b in top)} a floating base: "
                + (f"{len(top)} top-level bodies" if len(top) > 1 else
                   f"the top body already has joints ({', '.join(_named(j) for j in _joints(base))})")
                + "; add <freejoint/> to a body with mass above them")
        base.insert(0, Element("freejoint", {"name": _free_name(root, "root")}))
        pose = " ".join(map(str, numbers(base.get("pos"), (0.0, 0.0, 0.0)) + (1.0, 0.0, 0.0, 0.0)))
        for key in root.iter("key"):  # the new joint's coordinates come first: the body's position
            if key.get("qpos") is not None:
                key.set("qpos", pose + " " + key.get("qpos"))
        found.repaired.append(f"a free joint added to body {_named(base)} (floating_base=True)")
    elif floating_base is False and free:
        for j in free:
            base.remove(j)
        for key in root.iter("key"):  # the free joint's seven coordinates come first: drop them
            if key.get("qpos") is not None:
                key.set("qpos", " ".join(key.get("qpos").split()[7 * len(free):]))
        found.repaired.append(f"the free joint of body {_named(base)} removed (floating_base=False)")


def _bodies_weighed_by_geoms(root: Element):
    """``(body, [(geom, weighs)])`` of each body whose inertia MuJoCo takes from its geoms (no
    ``<inertial>``, or ``<compiler inertiafromgeom="true">``); a geom weighs nothing with
    ``mass="0"``, ``density="0"`` or a ``group`` outside ``inertiagrouprange``."""
    from_geoms = compiler_option(root, "inertiafromgeom", "auto")
    low, high = numbers(compiler_option(root, "inertiagrouprange", "0 5"))[:2]
    for body, _ in bodies(root):
        if body.find("inertial") is not None and from_geoms != "true":
            continue
        geoms = []
        for geom in body.findall("geom"):
            group = numbers(geom.get("group"), (0.0,))[0]
            weighs = not (numbers(geom.get("mass"), (1.0,))[0] == 0 or numbers(geom.get("density"), (1.0,))[0] == 0
                          or not low <= group <= high)
            geoms.append((geom, weighs))
        yield body, geoms


def _is_mesh(geom: Element) -> bool:
    return geom.get("type") == "mesh" or (geom.get("type") is None and geom.get("mesh") is not None)


def _moving_bodies(root: Element) -> set[int]:
    """``id()`` of every body with a joint on its path from the world (the others are
    welded to the world: their mass moves nothing)."""
    moving = set()
    for body, parent in bodies(root):
        if (parent is not None and id(parent) in moving) or _joints(body):
            moving.add(id(body))
    return moving


def _mesh_masses(root: Element, found: Audit) -> None:
    moving = _moving_bodies(root)
    heavy_bodies = [_named(body) for body, geoms in _bodies_weighed_by_geoms(root)
                    if id(body) in moving and any(weighs and _is_mesh(geom) for geom, weighs in geoms)]
    if heavy_bodies:
        shown = ", ".join(heavy_bodies[:8]) + (f" and {len(heavy_bodies) - 8} more" if len(heavy_bodies) > 8 else "")
        found.refused.append(f"{len(heavy_bodies)} bodies without <inertial> take mass from mesh geoms ({shown}); "
                             "meshes are not integrated here: give each such body an <inertial>")


def pinocchio_tree(root: Element) -> Element:
    """A copy of ``root`` whose geoms Pinocchio weighs as MuJoCo does: in bodies that take
    their inertia from geoms, a geom that weighs nothing in MuJoCo is removed (Pinocchio
    gives a mesh 1 kg and weighs geoms of any group), and a visual geom
    (``contype = conaffinity = 0``) that weighs is marked colliding (Pinocchio weighs only
    colliding geoms). Contacts are not read from Pinocchio's model, so this changes nothing else."""
    tree = copy.deepcopy(root)
    for body, geoms in _bodies_weighed_by_geoms(tree):
        for geom, weighs in geoms:
            if not weighs:
                body.remove(geom)
            elif geom.get("contype", "1") == "0" and geom.get("conaffinity", "1") == "0":
                geom.set("contype", "1")
                geom.set("conaffinity", "1")
    return tree


def build_model(path: str | Path, floating_base: bool | None = None,
                allow_outside: bool = False) -> tuple[pin.Model, Element, Audit]:
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
    found = audit(root, floating_base)
    if found.refused:
        raise UnsupportedModelError(f"MJCF {str(path)!r} cannot be loaded as given: " + "; ".join(found.refused))
    if found.left_out:
        warnings.warn(MJCFWarning(f"MJCF {path.name}: left out of the dynamics: " + "; ".join(found.left_out)),
                      stacklevel=3)
    with tempfile.TemporaryDirectory() as folder:
        resolved = Path(folder) / path.name
        resolved.write_bytes(tostring(pinocchio_tree(root)))
        try:
            model = pin.buildModelFromMJCF(str(resolved))
        except (RuntimeError, ValueError, IndexError) as exc:
            raise ModelLoadError(f"cannot read MJCF {str(path)!r}: {exc}") from None
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
    return tuple(names[2 if floating_base else 1:])


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
        T[i:i + 3, i:i + 3] = R
        if v is not None:
            Tdot_v[i:i + 3] = R @ np.cross(v[i + 3:i + 6], v[i:i + 3])
    return (T, Tdot_v) if v is not None else T


def load_mjcf(path: str | Path, floating_base: bool | None = None, feet=None, name: str | None = None,
              allow_outside: bool = False):
    """Load a robot from an MJCF file (module notes); `contactdiff.model.robot.load_robot`
    calls this for ``.xml`` files whose root is ``<mujoco>``.

    Args:
        path: the MJCF file.
        floating_base: None keeps the model's own base (a free joint is a floating
            base); True adds a free joint to the top body, False removes it.
        feet: foot frames chosen by hand (a leaf body's collision sphere, by its
            geom's name, is a round foot), or None: the model's collision spheres on
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
    from .feet import choose_feet
    from .mjcf_feet import add_sphere_frames, collision_spheres, sphere_feet
    from .robot import Robot, _check_inertias, _check_mass_matrix

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
            choice = dataclasses.replace(choice, radii=radii)
    return Robot(model, name or path.stem, str(path), floating, q_ref, choice.feet,
                 actuated_joints(model, root, floating), choice)


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
