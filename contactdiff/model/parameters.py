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
controller's own checks. It copies the robot and builds the new scene with
`Scene.rebuilt` (the constructor), so every effort is bound again on the changed model: the
trot controller's feed-forward (leg gravity torques and weight shares at the
stance pose) follows the bodies' masses and gravity, and
`tau_parameter_derivatives` differentiates it too. The initial state is kept:
a larger contact offset can make it penetrate (`InconsistentStateError`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import TypeVar

import numpy as np
import pinocchio as pin

from ..errors import GroupMismatchError, InvalidInputError
from .contact_parameters import contact_value, stage_contact_change
from .efforts import bound_positions
from .kinematics import Kinematics
from .parameter_list import all_parameters, body_names, parameter_names, resolve
from .parameter_types import BODY_FIELDS, EFFORT_KINDS, MODEL_KINDS, Parameter, ParameterKind, ParametrisedScene

S = TypeVar("S", bound=ParametrisedScene)

_AXIS = {"x": 0, "y": 1, "z": 2}
_INERTIA_ENTRY = {"ixx": (0, 0), "ixy": (0, 1), "ixz": (0, 2), "iyy": (1, 1), "iyz": (1, 2), "izz": (2, 2)}
_INERTIA_TOL = 1e-12  # relative to the largest principal moment: round-off of a valid inertia


# -- values -----------------------------------------------------------------------------
def _value(scene: ParametrisedScene, p: Parameter) -> float:
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


def parameter_values(scene: ParametrisedScene, names) -> np.ndarray:
    """Current values of the parameters ``names`` (see `resolve`), in their units."""
    return np.array([_value(scene, p) for p in resolve(scene, names)], dtype=float)


def parameter_table(scene: ParametrisedScene) -> list[dict]:
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


def with_parameters(scene: S, values: Mapping) -> S:
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
        if p.kind in MODEL_KINDS:
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
    return scene.rebuilt(robot, contacts, efforts)


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

    def __init__(self, scene: ParametrisedScene, params: list[Parameter]):
        self.n = len(params)
        positions = bound_positions(scene.effort_specs)
        own: dict[int, tuple[list[int], list]] = {}
        for col, p in enumerate(params):
            if p.kind in EFFORT_KINDS:
                i, k = positions[p.index]
                cols, fields = own.setdefault(i, ([], []))
                cols.append(col)
                fields.append((k, p.field))
        self.own = [(scene.efforts[i], _columns(cols), fields) for i, (cols, fields) in own.items()]
        model_cols = [col for col, p in enumerate(params) if p.kind in MODEL_KINDS]
        self.model = []
        dependent = [e for e in scene.efforts if hasattr(e, "model_parameter_derivatives")]
        if model_cols and dependent:
            perturbed = [self._perturbation(scene, params[col]) for col in model_cols]
            self.model = [(e, _columns(model_cols), perturbed) for e in dependent]

    @staticmethod
    def _perturbation(scene: ParametrisedScene, p: Parameter):
        value = _value(scene, p)

        def make(x: float) -> pin.Model:
            model = pin.Model(scene.model)
            _set_in_model(model, p, value + x)
            return model

        return p.name, MODEL_STEP * max(abs(value), 1.0), make


def tau_parameter_derivatives(scene: ParametrisedScene, kin: Kinematics, t: float, parameters) -> np.ndarray:
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
