"""Named parameters of a scene: list them, read them, change them, differentiate the efforts in them.

Every number of a scene that a study may vary has a name ``kind:target:field``
(``kind:field`` for the trot controller and the scene itself):

============  ==============  ===========================================  ==============================
kind          target          fields                                       unit
============  ==============  ===========================================  ==============================
scene         (none)          ``gravity_x``, ``gravity_y``, ``gravity_z``  m/s², world frame
body          link name       ``mass``                                     kg
                              ``com_x``, ``com_y``, ``com_z``              m, link frame
                              ``ixx ixy ixz iyy iyz izz``                  kg m², about the centre of
                                                                           mass, link axes
joint         joint name      ``armature``                                 kg m² (revolute), kg (prismatic)
contact       contact name    ``restitution``, ``offset``, ``friction``    1, m, 1 (``friction``: Coulomb
                                                                           contacts only)
group         group name      ``restitution``, ``offset``, ``friction``    as ``contact``, shared by the
                                                                           group's contacts
spring        spring name     ``stiffness``, ``damping``, ``rest_length``  N/m, N s/m, m
joint_spring  joint name      ``stiffness``, ``damping``, ``rest``         N m/rad, N m s/rad, rad (or N/m,
                                                                           N s/m, m on a prismatic joint)
trot          (none)          ``TrotController.NUMBERS``: ``period``,      as `TrotController`
                              ``duty``, ..., ``kp``, ``kd``, ``t_start``
effort        effort name     the `UserEffort`'s own ``parameters``        the effort's
============  ==============  ===========================================  ==============================

`parameter_names` lists them in that order (bodies and joints in Pinocchio's
joint order, contacts and efforts in scene order, groups after the contacts). The rules:

* **Bodies.** A body is what one Pinocchio joint ``j >= 1`` moves rigidly:
  ``model.inertias[j]``. Links attached by fixed joints are merged into it by
  the URDF parser and are not bodies of their own (their mass is part of the
  body's). The base of a floating robot is a body (joint ``root_joint``). A body
  is named after its link: the BODY frame of joint ``j`` placed at the joint's
  origin (URDF puts the child link's frame at its joint), the one whose parent
  frame is the joint itself if a link is fixed at that origin too; without such
  a frame, after the joint. The link frame is then the joint frame: ``com_*`` is
  Pinocchio's ``Inertia.lever`` and ``i**`` its ``Inertia.inertia`` (about the
  centre of mass). Changing ``mass`` keeps the centre of mass and the inertia
  about it.
* **Joints.** ``armature`` (Pinocchio's ``model.armature``, reflected rotor
  inertia) of every one-coordinate-velocity joint (revolute, bounded or not,
  prismatic, helical, their unaligned forms). A free-flyer, spherical or planar
  joint has none here (Pinocchio keeps one value per axis).
* **Contacts** by contact name (``friction`` for a Coulomb coefficient only; μ = 0
  makes the contact frictionless), **groups** by `Contact.group`: a value shared by
  the members (`contactdiff.model.contact_parameters` has the rules).
* **Springs**: by `Spring.name` (default ``"<frame_a>-<frame_b>"``); **joint
  springs**: by joint. **User efforts**: by `UserEffort.name`, one parameter per
  entry of its ``parameters`` (the protocol is in `UserEffort`'s docstring).
  Each effort spec declares its own (its ``named_parameters()``, an
  `contactdiff.model.efforts.EffortParameters`: kind, target, fields), so this
  module knows no effort class.
* A target that two specs share (two springs between the same frames, two joint
  springs on one joint, two efforts with one name, two trot controllers) gets
  ``#1``, ``#2``, ... in scene order: ``joint_spring:knee#2:stiffness``,
  ``trot:#1:kp``.

`with_parameters` validates values as a scene file is validated: finite numbers;
a changed body keeps mass > 0 and an inertia about its centre of mass that some
mass distribution has (positive semi-definite, principal moments obeying the
triangle inequality ``I1 <= I2 + I3``: semi-definite, not definite, because the
planar models' bodies are point masses with zero inertia); armature >= 0;
restitution in [0, 1]; friction >= 0; stiffness, damping, rest length >= 0; the trot
controller's own checks. It copies the robot and builds the new scene with the
`Scene` constructor, so every effort is bound again on the changed model: the
trot controller's feed-forward (leg gravity torques and weight shares at the
stance pose) follows the bodies' masses and gravity, and
`tau_parameter_derivatives` differentiates it too. The initial state is kept:
a larger contact offset can make it penetrate (`InconsistentStateError`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from enum import Enum

import numpy as np
import pinocchio as pin

from ..errors import GroupMismatchError, InvalidInputError, unknown_name
from .contact_parameters import contact_parameters, contact_value, stage_contact_change
from .efforts import EffortParameters, bound_positions
from .kinematics import Kinematics
from .scene import Scene


class ParameterKind(Enum):
    """What a parameter belongs to (its value is the first part of its name)."""

    BODY = "body"
    JOINT = "joint"
    CONTACT = "contact"
    SPRING = "spring"
    JOINT_SPRING = "joint_spring"
    TROT = "trot"
    EFFORT = "effort"
    SCENE = "scene"
    GROUP = "group"


BODY_FIELDS = ("mass", "com_x", "com_y", "com_z", "ixx", "ixy", "ixz", "iyy", "iyz", "izz")
"""Fields of a body: mass (kg), centre of mass (m, link frame), inertia about it (kg m², link axes)."""
JOINT_FIELDS = ("armature",)
SCENE_FIELDS = ("gravity_x", "gravity_y", "gravity_z")

_AXIS = {"x": 0, "y": 1, "z": 2}
_INERTIA_ENTRY = {"ixx": (0, 0), "ixy": (0, 1), "ixz": (0, 2), "iyy": (1, 1), "iyz": (1, 2), "izz": (2, 2)}
_MODEL_KINDS = (ParameterKind.BODY, ParameterKind.JOINT, ParameterKind.SCENE)
_EFFORT_KINDS = (ParameterKind.SPRING, ParameterKind.JOINT_SPRING, ParameterKind.TROT, ParameterKind.EFFORT)
_INERTIA_TOL = 1e-12  # relative to the largest principal moment: round-off of a valid inertia


@dataclass(frozen=True)
class Parameter:
    """One named parameter of a scene.

    Attributes:
        kind: what it belongs to.
        target: the link, joint, contact, spring or effort name ("" for ``trot`` and
            ``scene``; ``#k`` suffixes as in the module notes).
        field: the number's name (``mass``, ``stiffness``, ``kp``, ``gravity_z``, ...).
        joint: Pinocchio joint index for ``body`` (``model.inertias[joint]``) and
            ``joint`` (its tangent index is ``model.joints[joint].idx_v``); 0 otherwise.
        index: position of the spec in ``scene.contact_specs`` (``contact``) or in
            ``scene.effort_specs`` (``spring``, ``joint_spring``, ``trot``, ``effort``);
            -1 otherwise.
        members: positions in ``scene.contact_specs`` of the contacts it sets (one for
            ``contact``, the group's for ``group``); empty otherwise.
    """

    kind: ParameterKind
    target: str
    field: str
    joint: int = 0
    index: int = -1
    members: tuple[int, ...] = ()

    @property
    def name(self) -> str:
        """``kind:target:field``, or ``kind:field`` when there is no target."""
        head = f"{self.kind.value}:{self.target}" if self.target else self.kind.value
        return f"{head}:{self.field}"

    def __str__(self) -> str:
        return self.name


# -- listing ------------------------------------------------------------------------------
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


def all_parameters(scene: Scene) -> list[Parameter]:
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
    for kind in _EFFORT_KINDS:  # each effort declares its own (`EffortParameters`)
        mine = [(i, d) for i, d in declared if d.kind == kind.value]
        for (i, d), name in zip(mine, _numbered([d.target for _, d in mine])):
            out += [Parameter(kind, name, f, index=i) for f in d.fields]
    scene.__dict__["_parameter_list"] = out
    return out


def _declared(scene: Scene, index: int, spec) -> EffortParameters:
    """The parameters effort spec ``index`` of ``scene`` declares, checked."""
    declared = spec.named_parameters()
    kinds = [k.value for k in _EFFORT_KINDS]
    if not isinstance(declared, EffortParameters) or declared.kind not in kinds:
        raise InvalidInputError(
            f"scene {scene.name!r}: effort {index} ({type(spec).__name__}) declares its "
            f"parameters as {declared!r}; expected an EffortParameters of kind "
            f"{', '.join(kinds)}"
        )
    return declared


def parameter_names(scene: Scene) -> list[str]:
    """Names of every parameter of ``scene`` (module notes: scene, bodies, joints,
    contacts, groups of contacts, springs, joint springs, trot, user efforts)."""
    return [p.name for p in all_parameters(scene)]


def resolve(scene: Scene, names) -> list[Parameter]:
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


# -- values -----------------------------------------------------------------------------
def _value(scene: Scene, p: Parameter) -> float:
    model = scene.model
    kind = p.kind
    if kind is ParameterKind.SCENE:
        return float(model.gravity.linear[_AXIS[p.field[-1]]])
    if kind is ParameterKind.BODY:
        inertia = model.inertias[p.joint]
        if p.field == "mass":
            return float(inertia.mass)
        if p.field.startswith("com_"):
            return float(inertia.lever[_AXIS[p.field[-1]]])
        return float(inertia.inertia[_INERTIA_ENTRY[p.field]])
    if kind is ParameterKind.JOINT:
        return float(model.armature[model.joints[p.joint].idx_v])
    if kind in (ParameterKind.CONTACT, ParameterKind.GROUP):
        return contact_value(scene, p)
    spec = scene.effort_specs[p.index]
    if kind is ParameterKind.EFFORT:
        return float(dict(spec.parameters)[p.field])
    return float(getattr(spec, p.field))


def parameter_values(scene: Scene, names) -> np.ndarray:
    """Current values of the parameters ``names`` (see `resolve`), in their units."""
    return np.array([_value(scene, p) for p in resolve(scene, names)], dtype=float)


def parameter_table(scene: Scene) -> list[dict]:
    """Every parameter of ``scene`` as a dict (what ``simulate --param list --json``
    prints): ``name``, ``kind`` (a `ParameterKind` value), ``target`` ("" for
    ``trot`` and ``scene``), ``field`` and ``value`` (its current value, in its unit;
    the units are in the module notes; None for a group whose contacts differ), in the
    order of `parameter_names`."""

    def value(p):
        try:
            return _value(scene, p)
        except GroupMismatchError:
            return None

    return [
        {"name": p.name, "kind": p.kind.value, "target": p.target, "field": p.field, "value": value(p)}
        for p in all_parameters(scene)
    ]


def _number(name: str, value) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise InvalidInputError(f"parameter {name!r} must be a number, got {value!r}") from None
    if not math.isfinite(x):
        raise InvalidInputError(f"parameter {name!r} must be finite, got {value!r}")
    return x


def _set_in_model(model: pin.Model, p: Parameter, value: float) -> None:
    """Set one model parameter (body, joint, scene) in ``model``, unchecked."""
    if p.kind is ParameterKind.SCENE:
        g = np.array(model.gravity.linear)
        g[_AXIS[p.field[-1]]] = value
        model.gravity = pin.Motion(g, np.zeros(3))
    elif p.kind is ParameterKind.JOINT:
        armature = np.array(model.armature)
        armature[model.joints[p.joint].idx_v] = value
        model.armature = armature
    else:  # through the setters: Pinocchio's constructor would refuse a perturbed, indefinite inertia
        inertia = pin.Inertia(model.inertias[p.joint])
        if p.field == "mass":
            inertia.mass = value
        elif p.field.startswith("com_"):
            lever = np.array(inertia.lever)
            lever[_AXIS[p.field[-1]]] = value
            inertia.lever = lever
        else:
            rot = np.array(inertia.inertia)
            a, b = _INERTIA_ENTRY[p.field]
            rot[a, b] = rot[b, a] = value
            inertia.inertia = rot
        model.inertias[p.joint] = inertia


def _check_body(target: str, inertia: pin.Inertia, changed: list[str]) -> None:
    """Refuse a changed body that no mass distribution has (module notes)."""
    names = ", ".join(repr(n) for n in changed)
    mass, rot = float(inertia.mass), np.array(inertia.inertia)
    if not mass > 0:
        hint = (
            ""
            if any(n.endswith(":mass") for n in changed)
            else (" (a massless body has no centre of mass or inertia to change; give it a mass too)")
        )
        raise InvalidInputError(f"parameters {names}: body {target!r} must have mass > 0 kg, got {mass!r}{hint}")
    moments = np.linalg.eigvalsh(rot)
    tol = _INERTIA_TOL * max(float(np.abs(moments).max()), 1e-300)
    if moments[0] < -tol:
        raise InvalidInputError(
            f"parameters {names}: the inertia of body {target!r} about its centre of mass must be positive "
            f"semi-definite; principal moments {moments.tolist()} kg m² from {rot.tolist()}"
        )
    if moments[2] > moments[0] + moments[1] + tol:
        raise InvalidInputError(
            f"parameters {names}: the inertia of body {target!r} about its centre of mass has principal moments "
            f"{moments.tolist()} kg m², the largest above the sum of the other two (no mass distribution has "
            f"them: I1 <= I2 + I3); from {rot.tolist()}"
        )


def _replaced(spec, changes: dict, names: list[str], values: list[float]):
    """``dataclasses.replace(spec, **changes)``, its validation errors naming the parameters."""
    try:
        return dataclasses.replace(spec, **changes)
    except InvalidInputError as exc:
        given = ", ".join(f"{n!r} = {v!r}" for n, v in zip(names, values))
        raise InvalidInputError(f"parameters {given}: {exc}") from None


def with_parameters(scene: Scene, values: Mapping) -> Scene:
    """A new scene with the parameters ``values`` (name or `Parameter` -> value, in
    their units) changed; the original scene, its robot and its model are untouched.

    Several parameters of one body, spring or controller combine (``mass`` and
    ``com_x`` of one body give one new inertia). The new scene keeps the name, the
    initial state and the foot choice; its efforts and contacts are bound again on
    the changed model (module notes).

    Raises:
        UnknownNameError: an unknown name (the valid ones are listed).
        InvalidInputError: a non-finite or out-of-range value (named, with its value).
        InconsistentStateError: the initial state penetrates a changed contact.
    """
    if not isinstance(values, Mapping):
        raise InvalidInputError(f"with_parameters takes a mapping from parameter name to value, got {values!r}")
    params = resolve(scene, list(values))
    numbers = [_number(p.name, v) for p, v in zip(params, values.values())]
    robot = scene.robot.copy()
    model = robot.model
    bodies: dict[int, tuple[str, list[str]]] = {}  # joint -> (its body's name, the names changed)
    specs: dict[tuple[str, int], tuple[dict, list, list]] = {}
    for p, x in zip(params, numbers):
        if p.kind in _MODEL_KINDS:
            if p.kind is ParameterKind.JOINT and x < 0:
                raise InvalidInputError(f"parameter {p.name!r} (armature) must be >= 0, got {x!r}")
            _set_in_model(model, p, x)
            if p.kind is ParameterKind.BODY:
                bodies.setdefault(p.joint, (p.target, []))[1].append(p.name)
            continue
        if p.kind in (ParameterKind.CONTACT, ParameterKind.GROUP):
            stage_contact_change(scene, specs, p, x)
            continue
        where = "effort"
        changes, names, xs = specs.setdefault((where, p.index), ({}, [], []))
        if p.kind is ParameterKind.EFFORT:
            current = changes.get("parameters", dict(scene.effort_specs[p.index].parameters))
            current[p.field] = x
            changes["parameters"] = current
        else:
            changes[p.field] = x
        names.append(p.name)
        xs.append(x)
    for j, (target, changed) in bodies.items():
        _check_body(target, model.inertias[j], changed)
    contacts, efforts = list(scene.contact_specs), list(scene.effort_specs)
    for (where, i), (changes, names, xs) in specs.items():
        if where == "contact":
            contacts[i] = _replaced(contacts[i], changes, names, xs)
        else:
            efforts[i] = _replaced(efforts[i], changes, names, xs)
    new = Scene(robot, contacts, efforts, None, scene.q0, scene.v0, scene.name)
    new.foot_choice = scene.foot_choice
    return new


# -- derivatives of the efforts ---------------------------------------------------------------
MODEL_STEP = 1e-3
"""Relative step of the central differences of a model-dependent effort (the trot
controller's feed-forward) in a model parameter: ``MODEL_STEP * max(|value|, 1)``.
Those terms are affine in the parameter (see
`TrotControllerEvaluator.model_parameter_derivatives`), so the difference is
exact up to round-off whatever the step; a large one keeps the round-off small."""


def _columns(cols: list[int]):
    """A slice for consecutive columns (a view, no index array), else an index array."""
    if cols == list(range(cols[0], cols[0] + len(cols))):
        return slice(cols[0], cols[0] + len(cols))
    return np.array(cols, dtype=int)


class _Plan:
    """How to fill the columns of `tau_parameter_derivatives` for one list of parameters."""

    def __init__(self, scene: Scene, params: list[Parameter]):
        self.n = len(params)
        positions = bound_positions(scene.effort_specs)
        own: dict[int, tuple[list[int], list]] = {}
        for col, p in enumerate(params):
            if p.kind in _EFFORT_KINDS:
                i, k = positions[p.index]
                cols, fields = own.setdefault(i, ([], []))
                cols.append(col)
                fields.append((k, p.field))
        self.own = [(scene.efforts[i], _columns(cols), fields) for i, (cols, fields) in own.items()]
        model_cols = [col for col, p in enumerate(params) if p.kind in _MODEL_KINDS]
        self.model = []
        dependent = [e for e in scene.efforts if hasattr(e, "model_parameter_derivatives")]
        if model_cols and dependent:
            perturbed = [self._perturbation(scene, params[col]) for col in model_cols]
            self.model = [(e, _columns(model_cols), perturbed) for e in dependent]

    @staticmethod
    def _perturbation(scene: Scene, p: Parameter):
        value = _value(scene, p)

        def make(x: float) -> pin.Model:
            model = pin.Model(scene.model)
            _set_in_model(model, p, value + x)
            return model

        return p.name, MODEL_STEP * max(abs(value), 1.0), make


def tau_parameter_derivatives(scene: Scene, kin: Kinematics, t: float, parameters) -> np.ndarray:
    """``d tau/dp`` (nv × len(parameters)) of the scene's efforts (their sum, `Scene.tau`)
    at the state of ``kin`` (updated at ``(q, v)``) and time ``t`` (s), in generalised
    force per unit of each parameter.

    * joint springs, frame springs, the trot's ``kp``, ``kd`` and ``t_start``: closed
      forms (the evaluators' ``parameter_derivatives``);
    * the trot's schedule numbers: central differences through controllers bound
      with the number moved (`TrotControllerEvaluator.parameter_derivatives`);
    * a user effort: its ``parameter_jacobian``, else central differences;
    * bodies, joints and gravity: zero, except through an effort computed from the
      model when it is bound (the trot controller's feed-forward,
      `TrotControllerEvaluator.model_parameter_derivatives`);
    * contacts: zero (they act at events and in constraints, not as efforts).

    Args:
        scene: the scene.
        kin: kinematics at the state.
        t: time (s).
        parameters: `Parameter` objects of this scene or names (see `resolve`).
    """
    plans = scene.__dict__.setdefault("_parameter_plans", {})
    last = plans.get(None)  # called at every stage with the same parameters: no lookup then
    if last is not None and len(last[0]) == len(parameters) and all(a is b for a, b in zip(last[0], parameters)):
        plan = last[1]
    else:
        params = tuple(resolve(scene, parameters))
        plan = plans.get(params)
        if plan is None:
            plan = plans[params] = _Plan(scene, list(params))
        plans[None] = (tuple(parameters), plan)
    out = np.zeros((scene.nv, plan.n))
    for evaluator, cols, fields in plan.own:
        out[:, cols] += evaluator.parameter_derivatives(kin, t, fields)
    for evaluator, cols, perturbed in plan.model:
        out[:, cols] += evaluator.model_parameter_derivatives(kin, t, perturbed)
    return out


__all__ = [
    "Parameter",
    "ParameterKind",
    "all_parameters",
    "body_names",
    "parameter_names",
    "parameter_table",
    "parameter_values",
    "resolve",
    "tau_parameter_derivatives",
    "with_parameters",
    "BODY_FIELDS",
    "MODEL_STEP",
]
