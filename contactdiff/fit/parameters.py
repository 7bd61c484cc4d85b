"""The unknowns of a fit: named scene parameters, and scales of several at once.

A fitted unknown is either a scene parameter by name (`contactdiff.Scene`'s
``kind:target:field`` names, `parameter_names`) or a `Scaled` group: one number
``s`` that sets each member parameter to ``s × base`` (an inertia scale, a
length scale of several offsets). `FitPlan` maps the unknowns to the scene
parameters and back: ``values(θ)`` for `with_parameters`, and the matrix
``C`` (scene parameters × unknowns) with ``∂r/∂θ = ∂r/∂p C`` (the chain rule:
a plain name is a column of the identity, a scale the column of its bases).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..errors import InvalidInputError
from ..model.parameters import parameter_values, resolve

LOWER_BOUNDS = {
    "friction": 0.0,
    "restitution": 0.0,
    "mass": 0.0,
    "ixx": 0.0,
    "iyy": 0.0,
    "izz": 0.0,
    "armature": 0.0,
    "stiffness": 0.0,
    "damping": 0.0,
    "rest_length": 0.0,
}
"""Default lower bounds by the parameter's field (`with_parameters` refuses values below)."""

UPPER_BOUNDS = {"restitution": 1.0}
"""Default upper bounds by field."""


@dataclass(frozen=True)
class Scaled:
    """One unknown ``s`` that sets each member parameter to ``s × base``.

    Attributes:
        name: the unknown's name in the fit's results (not a scene parameter's name).
        base: the members' values at ``s = 1``, by scene parameter name (for an
            inertia scale: the nominal moments ``{"body:cube:ixx": 8.1e-4, ...}``).
        lower, upper: bounds of ``s`` (default ``s >= 0``).
    """

    name: str
    base: Mapping[str, float] = field(default_factory=dict)
    lower: float = 0.0
    upper: float = np.inf

    def __post_init__(self):
        if not self.base:
            raise InvalidInputError(
                f"Scaled {self.name!r}: give the members' base values, e.g. {{'body:cube:ixx': 8.1e-4}}"
            )
        for member, value in self.base.items():
            if not (isinstance(value, (int, float)) and np.isfinite(value)):
                raise InvalidInputError(
                    f"Scaled {self.name!r}: the base of {member!r} must be a finite number, got {value!r}"
                )


class FitPlan:
    """The unknowns of a fit and the scene parameters they set (module doc).

    Args:
        scene: the scene whose parameters are fitted (names are checked against it).
        unknowns: scene parameter names and `Scaled` groups.
        bounds: bounds by unknown name, ``{name: (lower, upper)}``, over the defaults
            (`LOWER_BOUNDS`, `UPPER_BOUNDS` by field; a `Scaled`'s own).

    Raises:
        InvalidInputError: no unknowns, a name twice, a bound for an unknown not fitted,
            or bounds that hold no value; UnknownNameError: a name the scene does not have.
    """

    def __init__(self, scene, unknowns: Sequence, bounds: Mapping | None = None):
        unknowns = [unknowns] if isinstance(unknowns, (str, Scaled)) else list(unknowns)
        if not unknowns:
            raise InvalidInputError(
                "fit: name at least one parameter to fit (contactdiff simulate SCENE --param list shows them)"
            )
        self.unknowns = tuple(unknowns)
        self.names = tuple(u.name if isinstance(u, Scaled) else str(u) for u in unknowns)
        if len(set(self.names)) != len(self.names):
            raise InvalidInputError(f"fit: an unknown is named twice in {list(self.names)}")
        members = []
        for u in unknowns:
            for name in u.base if isinstance(u, Scaled) else [u]:
                if name not in members:
                    members.append(name)
        resolve(scene, members)  # unknown names are refused with the valid ones listed
        self.parameters = tuple(members)
        C = np.zeros((len(members), len(unknowns)))
        for j, u in enumerate(unknowns):
            for name, base in u.base.items() if isinstance(u, Scaled) else [(u, 1.0)]:
                C[members.index(name), j] += base
        self.C = C
        self.lower, self.upper = self._bounds(dict(bounds or {}))

    def _bounds(self, given: dict) -> tuple[np.ndarray, np.ndarray]:
        unknown = sorted(set(given) - set(self.names))
        if unknown:
            raise InvalidInputError(f"fit: bounds for {unknown}, which are not fitted (fitted: {list(self.names)})")
        lower, upper = [], []
        for u, name in zip(self.unknowns, self.names):
            if isinstance(u, Scaled):
                lo, hi = u.lower, u.upper
            else:
                fld = name.rsplit(":", 1)[-1]
                lo, hi = LOWER_BOUNDS.get(fld, -np.inf), UPPER_BOUNDS.get(fld, np.inf)
            lo, hi = given.get(name, (lo, hi))
            if not lo < hi:
                raise InvalidInputError(f"fit: the bounds of {name} hold no value: ({lo}, {hi})")
            lower.append(float(lo))
            upper.append(float(hi))
        return np.array(lower), np.array(upper)

    def start(self, scene) -> np.ndarray:
        """The unknowns at the scene's values: a name's value, 1 for a `Scaled` group."""
        current = dict(zip(self.parameters, parameter_values(scene, self.parameters)))
        return np.array([1.0 if isinstance(u, Scaled) else current[u] for u in self.unknowns])

    def values(self, theta: np.ndarray) -> dict[str, float]:
        """The scene parameters the unknowns ``theta`` set (for `Scene.with_parameters`)."""
        p = self.C @ np.asarray(theta, dtype=float)
        return dict(zip(self.parameters, (float(x) for x in p)))


__all__ = ["FitPlan", "Scaled", "LOWER_BOUNDS", "UPPER_BOUNDS"]
