"""What Pinocchio 4.1's MJCF parser would drop, found (and repaired where possible) before
it reads a model: `audit` on the class-resolved tree, `pinocchio_tree` for the geoms it
weighs. `contactdiff.model.mjcf` raises and warns with what these find.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field
from pathlib import Path
from xml.etree.ElementTree import Element

from ..errors import ModelLoadError, UnsupportedModelError
from . import mjcf_tree
from .mjcf_mesh import MeshInertia, equivalent_box, mesh_inertia
from .mjcf_xml import asset_elements, bodies, compiler_option, mesh_name, numbers

_DYNAMIC_ACTUATORS = ("cylinder", "muscle", "adhesion")  # shortcuts with activation dynamics
_FLEX_TAGS = ("flex", "flexcomp", "composite")
_GENERATED = ("replicate", "attach")  # MuJoCo 3's generated bodies: unknown to Pinocchio 4.1
_PLACEMENT = {"pos", "quat", "euler", "axisangle", "xyaxes", "zaxis"}
_PASSIVE = ("stiffness", "damping", "frictionloss")  # joint forces MuJoCo adds; the dynamics here does not


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


def audit(
    root: Element, floating_base: bool | None = None, folder: Path | None = None, allow_outside: bool = False
) -> Audit:
    """Find (and repair in ``root``, in place) what Pinocchio's MJCF parser would drop.

    Repairs: orientations become quaternions, ``<frame>`` elements are replaced by
    their children and bodies with several joints are split (`contactdiff.model.mjcf_tree`);
    several top-level bodies without a free joint, or one placed away from the
    world's origin, are put into one body fixed to the world (Pinocchio reads only the
    first top-level body, and drops its placement); the free joint is added or
    removed as ``floating_base`` asks. (The geoms Pinocchio weighs are set in a
    copy, `pinocchio_tree`.)

    Repaired too: a mesh geom that weighs in a body without ``<inertial>`` becomes the box
    MuJoCo weighs it as (`contactdiff.model.mjcf_mesh`) when its file is in ``folder``
    (the model's folder; files outside it only with ``allow_outside``).

    Refused: a mesh geom that gives mass to a moving body without ``<inertial>`` whose
    mesh file is missing or cannot be weighed (a body welded to the world may weigh anything),
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
    split = mjcf_tree.split_joints(root, {name for e in root.iter() if (name := e.get("name"))})
    if split:
        found.repaired.append(f"bodies with several joints ({', '.join(split)}) split into one body per joint")
    _base_joint(root, floating_base, found)
    _top_bodies(root, found)
    _mesh_masses(root, found, folder, allow_outside)
    for tag in _FLEX_TAGS:
        for element in root.iter(tag):
            found.refused.append(
                f"<{tag}> {_named(element, '(unnamed)')} (deformable bodies add degrees of "
                "freedom the rigid-body model does not have)"
            )
    for tag in _GENERATED:
        for element in root.iter(tag):
            found.refused.append(
                f"<{tag}> (its bodies would be lost: save the model expanded by MuJoCo, "
                "mujoco.mj_saveLastXML, and load that)"
            )
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
        found.left_out.append(f"the activation dynamics of actuator(s) {_listed(dynamic)} (efforts act directly)")
    passive = _passive_forces(root)
    if passive:
        found.left_out.append(passive)
    return found


def _passive_forces(root: Element) -> str | None:
    """``joint stiffness of 'a'; damping of 'a', 'b'; ...`` for the joints with nonzero
    ``stiffness``, ``damping`` or ``frictionloss`` (classes resolved), or None: MuJoCo adds
    these passive forces, the loaded dynamics does not."""
    parts = []
    for attribute in _PASSIVE:
        names = [
            _named(j, "(unnamed)")
            for world in root.findall("worldbody")
            for j in world.iter("joint")
            if any(x != 0 for x in numbers(j.get(attribute), (0.0,)))
        ]
        if names:
            shown = ", ".join(names[:6]) + (f" and {len(names) - 6} more" if len(names) > 6 else "")
            parts.append(f"{attribute} of {len(names)} joint(s) ({shown})")
    if not parts:
        return None
    return "joint " + "; ".join(parts) + " (passive forces: give them as efforts, e.g. JointSpring)"


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
                "load each body's own file"
            )
            return
        dropped = [b for b in top if b is not free[0]]
        for b in dropped:
            world.remove(b)
        found.left_out.append(
            f"top-level bod{'y' if len(dropped) == 1 else 'ies'} "
            f"{', '.join(_named(b) for b in dropped)} (no joints: fixed to the world, "
            "not part of the floating robot)"
        )
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
                + (
                    f"{len(top)} top-level bodies"
                    if len(top) > 1
                    else f"the top body already has joints ({', '.join(_named(j) for j in _joints(base))})"
                )
                + "; add <freejoint/> to a body with mass above them"
            )
        base.insert(0, Element("freejoint", {"name": _free_name(root, "root")}))
        pose = " ".join(map(str, numbers(base.get("pos"), (0.0, 0.0, 0.0)) + (1.0, 0.0, 0.0, 0.0)))
        for key in root.iter("key"):  # the new joint's coordinates come first: the body's position
            if (qpos := key.get("qpos")) is not None:
                key.set("qpos", pose + " " + qpos)
        found.repaired.append(f"a free joint added to body {_named(base)} (floating_base=True)")
    elif floating_base is False and free:
        for j in free:
            base.remove(j)
        for key in root.iter("key"):  # the free joint's seven coordinates come first: drop them
            if (qpos := key.get("qpos")) is not None:
                key.set("qpos", " ".join(qpos.split()[7 * len(free) :]))
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
            weighs = not (
                numbers(geom.get("mass"), (1.0,))[0] == 0
                or numbers(geom.get("density"), (1.0,))[0] == 0
                or not low <= group <= high
            )
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


def _mesh_masses(root: Element, found: Audit, folder: Path | None, allow_outside: bool) -> None:
    """Replace each mesh geom that weighs in a body weighed by its geoms by MuJoCo's box of
    the same mass and inertia (`contactdiff.model.mjcf_mesh`) where its mesh file is there;
    refuse a moving body whose mesh file is missing (or cannot be weighed)."""
    meshes = (
        {mesh_name(e): (e, path) for e, path in asset_elements(root, folder, allow_outside) if e.tag == "mesh"}
        if folder is not None
        else {}
    )
    inline = {mesh_name(e) for asset in root.findall("asset") for e in asset.findall("mesh") if not e.get("file")}
    moving = _moving_bodies(root)
    cache: dict[str, MeshInertia | ModelLoadError] = {}
    missing, failed, replaced = [], [], 0
    for body, geoms in _bodies_weighed_by_geoms(root):
        for geom, weighs in geoms:
            if not (weighs and _is_mesh(geom)):
                continue
            mesh, path = meshes.get(geom.get("mesh", ""), (None, None))
            if path is None and geom.get("mesh") in inline:
                if id(body) in moving:
                    failed.append(
                        f"body {_named(body)}: <mesh> {geom.get('mesh')!r} is given by its vertices in "
                        "the XML; only mesh files are weighed here: give the body an <inertial>"
                    )
                continue
            if path is None or not path.is_file():
                if id(body) in moving:
                    missing.append((_named(body), path.name if path is not None else geom.get("mesh", "?")))
                continue
            name = geom.get("mesh")
            if name not in cache:
                assert mesh is not None  # a file path is found only with its <mesh> element
                try:
                    cache[name] = mesh_inertia(mesh, path)
                except ModelLoadError as exc:
                    cache[name] = exc
            weighed = cache[name]
            if isinstance(weighed, ModelLoadError):
                if id(body) in moving:
                    failed.append(f"body {_named(body)}: {weighed}")
                continue
            box = equivalent_box(geom, weighed)
            for key in ("mesh", "density", "euler", "axisangle", "xyaxes", "zaxis", "fromto"):
                geom.attrib.pop(key, None)
            geom.attrib.update(box)
            replaced += 1
    if replaced:
        found.repaired.append(
            f"{replaced} mesh geom(s) weighed as MuJoCo weighs them (a box of the mesh's volume inertia)"
        )
    if missing:
        heavy = list(dict.fromkeys(body for body, _ in missing))
        files = list(dict.fromkeys(file for _, file in missing))
        shown = ", ".join(heavy[:8]) + (f" and {len(heavy) - 8} more" if len(heavy) > 8 else "")
        found.refused.append(
            f"{len(heavy)} bodies without <inertial> take mass from mesh geoms ({shown}) whose "
            f"mesh files are missing ({', '.join(files[:4])}{' ...' if len(files) > 4 else ''}): "
            "put the meshes beside the model, or give each such body an <inertial>"
        )
    found.refused.extend(failed)


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
