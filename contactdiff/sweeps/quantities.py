"""What a sweep can vary, and how a point changes the scene and the run.

A swept quantity's name says what it is (`QuantityKind`):

============  ==========================  =============================================
kind          name                        effect at a point
============  ==========================  =============================================
q             ``q:<coordinate>``          initial configuration coordinate
                                          (`Robot.configuration_names`: ``body_pitch``,
                                          ``root_joint[2]``; rad or m)
v             ``v:<coordinate>``          initial velocity (`Robot.tangent_names`;
                                          rad/s or m/s, tangent space)
parameter     ``kind:target:field``       a named scene parameter (`Scene.parameter_names`,
                                          in its unit: ``body:base_link:mass`` kg)
option        ``t_final``, ``rtol``, ...  the run's final time (s) and `SimulateOptions`
                                          numbers and ``method`` (`OPTIONS`)
arg           ``arg:<name>``              keyword argument of a scene factory
                                          (``arg:robot`` of ``trot_scene``)
job           ``job:<name>``              an argument of the job (a built-in job's
                                          option, or anything a user job reads)
============  ==========================  =============================================

`resolve` checks every name against the scene before any run (an unknown one
lists the valid names); `apply` is what a worker does at each point.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, fields
from enum import StrEnum

import numpy as np

from ..errors import InvalidInputError, UnknownNameError
from ..integration.options import SimulateOptions
from ..model.parameters import ParameterKind
from ..model.scene import Scene


class QuantityKind(StrEnum):
    """What a swept quantity changes (module table)."""

    INITIAL_Q = "q"
    INITIAL_V = "v"
    PARAMETER = "parameter"
    OPTION = "option"
    SCENE_ARG = "arg"
    JOB_ARG = "job"


_NUMBER_FIELDS = {"float": float, "int": int, "float | None": float}
OPTIONS: dict[str, type] = (
    {"t_final": float}
    | {f.name: _NUMBER_FIELDS[f.type] for f in fields(SimulateOptions) if f.type in _NUMBER_FIELDS}
    | {"method": str}
)
"""Run options a sweep can vary, with their type: the final time ``t_final`` (s) and
the numeric fields of `SimulateOptions` (``rtol``, ``atol``, ``max_steps``, ...; units
there) and ``method``."""

PREFIXES = {
    "q:": QuantityKind.INITIAL_Q,
    "v:": QuantityKind.INITIAL_V,
    "arg:": QuantityKind.SCENE_ARG,
    "job:": QuantityKind.JOB_ARG,
}


@dataclass(frozen=True)
class Quantity:
    """One swept quantity.

    Attributes:
        name: as swept (a row's column).
        kind: its `QuantityKind`.
        target: the coordinate label, parameter name, option field, or argument name.
    """

    name: str
    kind: QuantityKind
    target: str


def resolve(
    names: Sequence[str],
    scene: Scene | Callable[[], Scene],
    arguments: Sequence[str] | None = (),
    job_arguments: Sequence[str] | None = (),
) -> tuple[Quantity, ...]:
    """The `Quantity` of each name, checked against ``scene``.

    Args:
        names: the swept names.
        scene: the scene the names refer to, or a function that builds it: called
            only for a name that needs the scene (a coordinate, a parameter, an
            unknown name), so that a sweep of a factory's arguments alone does not
            build one here.
        arguments: the scene factory's keyword arguments (None: any name; (): not a factory).
        job_arguments: the job's arguments (None: any name, a user job).

    Raises:
        UnknownNameError: an unknown name; the message lists the valid ones (the
            parameters of the kind named, or suggests close names).
        InvalidInputError: ``arg:`` for a scene that is not built by a factory.
    """
    built = scene if isinstance(scene, Scene) else None

    def get() -> Scene:
        nonlocal built
        if built is None:
            assert not isinstance(scene, Scene)  # built is None: scene is the factory
            built = scene()
        return built

    return tuple(_resolve_one(name, get, arguments, job_arguments) for name in names)


def _resolve_one(name: str, get: Callable[[], Scene], arguments, job_arguments) -> Quantity:
    if not isinstance(name, str):
        raise InvalidInputError(f"sweep: a quantity name must be a string, got {name!r}")
    if name in OPTIONS:
        return Quantity(name, QuantityKind.OPTION, name)
    for prefix, kind in PREFIXES.items():
        if not name.startswith(prefix):
            continue
        target = name[len(prefix) :]
        if kind is QuantityKind.INITIAL_Q:
            valid = get().robot.configuration_names()
        elif kind is QuantityKind.INITIAL_V:
            valid = get().robot.tangent_names()
        elif kind is QuantityKind.SCENE_ARG:
            if arguments == ():
                raise InvalidInputError(
                    f"sweep: {name!r} is an argument of a scene factory, but the scene "
                    f"{get().name!r} is a name or file; give a function that builds it"
                )
            valid = arguments
        else:
            valid = job_arguments
        if valid is not None and target not in valid:
            raise UnknownNameError(
                f"unknown quantity {name!r}; valid {prefix}<name>: "
                + (", ".join(prefix + v for v in valid) or "(none)")
            )
        return Quantity(name, kind, target)
    parameters = get().parameter_names()
    if name in parameters:
        return Quantity(name, QuantityKind.PARAMETER, name)
    raise _unknown(name, get(), parameters, arguments, job_arguments)


def _unknown(name: str, scene: Scene, parameters: list[str], arguments, job_arguments) -> UnknownNameError:
    kind = name.split(":", 1)[0]
    if kind in {k.value for k in ParameterKind}:
        same_kind = [p for p in parameters if p.split(":", 1)[0] == kind]
        return UnknownNameError(
            f"unknown quantity {name!r}: not a parameter of scene {scene.name!r}; its "
            f"{kind} parameters: " + (", ".join(same_kind) or "(none)")
        )
    valid = (
        [f"q:{c}" for c in scene.robot.configuration_names()]
        + [f"v:{c}" for c in scene.robot.tangent_names()]
        + list(OPTIONS)
        + [f"arg:{a}" for a in (arguments or ())]
        + [f"job:{a}" for a in (job_arguments or ())]
    )
    close = difflib.get_close_matches(name, valid + parameters, n=3)
    return UnknownNameError(
        f"unknown quantity {name!r}; valid: "
        + ", ".join(valid)
        + f", and the scene's {len(parameters)} parameters (kind:target:field, e.g. {parameters[0]}; "
        "'contactdiff simulate SCENE --param list' lists them)"
        + (f"; did you mean {', '.join(close)}?" if close else "")
    )


def check_values(quantities: Sequence[Quantity], rows: Sequence[Sequence]) -> None:
    """Refuse, before any run, a value that cannot be what its quantity is: anything but a
    number for a coordinate, a velocity, a parameter or a numeric option.

    Raises:
        InvalidInputError: naming the quantity, the point and the value.
    """
    for k, q in enumerate(quantities):
        if q.kind in (QuantityKind.SCENE_ARG, QuantityKind.JOB_ARG) or OPTIONS.get(q.name) is str:
            continue
        for i, row in enumerate(rows):
            value = row[k]
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise InvalidInputError(f"sweep: {q.name} must be a number, got {value!r} at point #{i}")


# -- at each point (in the worker) ---------------------------------------------------------
def split(quantities: Sequence[Quantity], values: Sequence) -> dict[QuantityKind, dict]:
    """A point's values by kind: ``{kind: {target: value}}``."""
    out: dict[QuantityKind, dict] = {kind: {} for kind in QuantityKind}
    for q, value in zip(quantities, values):
        out[q.kind][q.target] = value
    return out


def apply(scene: Scene, by_kind: Mapping[QuantityKind, Mapping]) -> Scene:
    """The scene with a point's parameters and initial state (a new scene; ``scene`` is kept).

    Raises:
        InvalidInputError, UnknownNameError, InconsistentStateError: a value the scene
            refuses (`Scene.with_parameters`, `Scene.with_state`).
    """
    parameters = by_kind.get(QuantityKind.PARAMETER) or {}
    if parameters:
        scene = scene.with_parameters(parameters)
    robot = scene.robot
    q0 = _with_coordinates(scene.q0, robot.configuration_names(), by_kind.get(QuantityKind.INITIAL_Q))
    v0 = _with_coordinates(scene.v0, robot.tangent_names(), by_kind.get(QuantityKind.INITIAL_V))
    if q0 is not None or v0 is not None:
        scene = scene.with_state(q0, v0)
    return scene


def run_options(values: Mapping) -> dict:
    """Option values in their fields' types (``max_steps`` 1e5 -> 100000).

    Raises:
        InvalidInputError: a count that is not a whole number, or a method that is not text.
    """
    out = {}
    for name, value in values.items():
        kind = OPTIONS[name]
        if kind is int and isinstance(value, float) and math.isfinite(value) and value == int(value):
            value = int(value)
        if kind is str and not isinstance(value, str):
            raise InvalidInputError(f"sweep: {name} must be a name, got {value!r}")
        out[name] = value
    return out


def _with_coordinates(base: np.ndarray, labels: list[str], values: Mapping | None) -> np.ndarray | None:
    """``base`` with the coordinates named by ``labels`` (`Robot.configuration_names` or
    `Robot.tangent_names`, in the vector's order) set to ``values``; None if there are none."""
    if not values:
        return None
    out = base.copy()
    index = {label: k for k, label in enumerate(labels)}
    for label, value in values.items():
        out[index[label]] = value
    return out


__all__ = ["Quantity", "QuantityKind", "OPTIONS", "resolve", "check_values", "split", "apply", "run_options"]
