"""Error-controlled one-step integrators with dense output: the factory and the names.

The methods: `DOP853` and `RK45` (`contactdiff.ode.explicit_rk`), `Radau`
(`contactdiff.ode.radau`), all on the `Stepper` base
(`contactdiff.ode.base`: what a new method implements; the state, units, frames and
the flow Jacobian are the package's contract, `contactdiff.ode`), over a configuration
space of `contactdiff.ode.lie`; how a stepper is driven, one accepted step at a time:
the package's docstring.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..errors import InvalidInputError
from .base import Stepper
from .dense import DenseOutput, LazyDenseOutput
from .explicit_rk import DOP853, RK45, ExplicitRK
from .field_types import AccelFn, JacFn
from .lie import LieGroup, PinocchioGroup, VectorSpace
from .radau import Radau

if TYPE_CHECKING:
    import pinocchio as pin
    from numpy.typing import ArrayLike

__all__ = [
    "METHODS",
    "AccelFn",
    "JacFn",
    "LieGroup",
    "VectorSpace",
    "PinocchioGroup",
    "DenseOutput",
    "LazyDenseOutput",
    "Stepper",
    "ExplicitRK",
    "RK45",
    "DOP853",
    "Radau",
    "make_stepper",
]

_CLASSES: dict[str, type[Stepper]] = {"DOP853": DOP853, "RK45": RK45, "Radau": Radau}
METHODS: tuple[str, ...] = tuple(_CLASSES)
"""Valid ``method`` names for `make_stepper`."""


def make_stepper(
    method: str, accel: AccelFn, group: LieGroup | pin.Model, t0: float, q0: ArrayLike, v0: ArrayLike, **options
) -> Stepper:
    """Create a stepper by name.

    Args:
        method: one of `METHODS` (case-insensitive): ``"DOP853"`` (explicit,
            default choice), ``"RK45"`` (explicit, loose tolerances),
            ``"Radau"`` (implicit, stiff springs).
        accel: ``accel(t, q, v) -> dv/dt`` (nv,).
        group: configuration space (`VectorSpace`, `PinocchioGroup`) or a
            ``pinocchio.Model``.
        t0: initial time (s).
        q0: initial configuration (nq,).
        v0: initial velocity (nv,), tangent space.
        **options: keyword arguments of `Stepper` (``rtol``, ``atol``, ``jac``,
            ``first_step``, ``max_step``, ``t_bound``, ``variational``, ...; see there
            for units and defaults).

    Raises:
        InvalidInputError: unknown method (the message lists the valid ones) or bad input.
    """
    by_lower = {m.lower(): c for m, c in _CLASSES.items()}
    cls = by_lower.get(str(method).lower())
    if cls is None:
        raise InvalidInputError(f"unknown integration method {method!r}; valid: {', '.join(METHODS)}")
    return cls(accel, group, t0, q0, v0, **options)
