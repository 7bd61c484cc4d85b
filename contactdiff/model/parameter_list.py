"""The named parameters a scene has: listed in order, and names resolved to
`Parameter` objects (part of `contactdiff.model.parameters`, which has the naming
rules and units)."""

from __future__ import annotations

import pinocchio as pin

from ..errors import InvalidInputError, unknown_name
from .contact_parameters import contact_parameters
from .efforts import EffortParameters
from .parameter_types import BODY_FIELDS, EFFORT_KINDS, SCENE_FIELDS, Parameter, ParameterKind, ParametrisedScene


def body_names(model: pin.Model) -> list[str]:
    """The name of the body of each joint ``1 .. njoints - 1`` (see the module notes)."""
    frames = model.frames
    by_joint: dict[int, list] = {}
    for f in frames:
        if f.type == pin.FrameType.BODY and f.placement.isIdentity():
            by_joint.setdefault(f.parentJoint, []).append(f)
    names = []
    for j in range(1, model.njoints):
        candidates = by_joint.get(j, [])
        own = [
            f
            for f in candidates
            if frames[f.parentFrame].type == pin.FrameType.JOINT and frames[f.parentFrame].parentJoint == j
        ]
        names.append((own or candidates)[0].name if candidates else model.names[j])
    return names


def _numbered(targets: list[str]) -> list[str]:
    """Targets with ``#k`` (1-based, in order) on those that occur more than once."""
    seen: dict[str, int] = {}
    out = []
    for t in targets:
        if targets.count(t) > 1:
            seen[t] = seen.get(t, 0) + 1
            out.append(f"{t}#{seen[t]}")
        else:
            out.append(t)
    return out


def all_parameters(scene: ParametrisedScene) -> list[Parameter]:
    """Every parameter of ``scene``, in the order of `parameter_names` (computed once per scene)."""
    cached = scene.__dict__.get("_parameter_list")
    if cached is not None:
        return cached
    model = scene.model
    out = [Parameter(ParameterKind.SCENE, "", f) for f in SCENE_FIELDS]
    for j, name in enumerate(_numbered(body_names(model)), start=1):
        out += [Parameter(ParameterKind.BODY, name, f, joint=j) for f in BODY_FIELDS]
    for j in range(1, model.njoints):
        if model.joints[j].nv == 1:
            out.append(Parameter(ParameterKind.JOINT, model.names[j], "armature", joint=j))
    out += contact_parameters(scene)
    declared = [(i, _declared(scene, i, s)) for i, s in enumerate(scene.effort_specs) if hasattr(s, "named_parameters")]
    for kind in EFFORT_KINDS:  # each effort declares its own (`EffortParameters`)
        mine = [(i, d) for i, d in declared if d.kind == kind.value]
        for (i, d), name in zip(mine, _numbered([d.target for _, d in mine])):
            out += [Parameter(kind, name, f, index=i) for f in d.fields]
    scene.__dict__["_parameter_list"] = out
    return out


def _declared(scene: ParametrisedScene, index: int, spec) -> EffortParameters:
    """The parameters effort spec ``index`` of ``scene`` declares, checked."""
    declared = spec.named_parameters()
    kinds = [k.value for k in EFFORT_KINDS]
    if not isinstance(declared, EffortParameters) or declared.kind not in kinds:
        raise InvalidInputError(
            f"scene {scene.name!r}: effort {index} ({type(spec).__name__}) declares its "
            f"parameters as {declared!r}; expected an EffortParameters of kind "
            f"{', '.join(kinds)}"
        )
    return declared


def parameter_names(scene: ParametrisedScene) -> list[str]:
    """Names of every parameter of ``scene`` (module notes: scene, bodies, joints,
    contacts, groups of contacts, springs, joint springs, trot, user efforts)."""
    return [p.name for p in all_parameters(scene)]


def resolve(scene: ParametrisedScene, names) -> list[Parameter]:
    """The `Parameter` of each name.

    Args:
        scene: the scene.
        names: one name, a sequence of names (or `Parameter` objects of this scene),
            or ``"all"`` for every parameter.

    Raises:
        UnknownNameError: a name the scene does not have (the message lists them all).
    """
    every = all_parameters(scene)
    if isinstance(names, str):
        if names == "all":
            return list(every)
        names = [names]
    by_name = scene.__dict__.get("_parameter_index")
    if by_name is None:
        by_name = scene.__dict__["_parameter_index"] = {p.name: p for p in every}
    out = []
    for name in names:
        key = name.name if isinstance(name, Parameter) else name
        par = by_name.get(key) if isinstance(key, str) else None
        if par is None or (isinstance(name, Parameter) and name != par):
            raise unknown_name(f"parameter of scene {scene.name!r}", name, by_name)
        out.append(par)
    return out


__all__ = ["all_parameters", "body_names", "parameter_names", "resolve"]
