"""The steppers' former home, kept so that ``contactdiff.integration.steppers`` imports
keep working: the steppers live in `contactdiff.ode` (the factory in
`contactdiff.ode.factory`)."""

from ..ode.factory import (
    DOP853,
    METHODS,
    RK45,
    AccelFn,
    DenseOutput,
    ExplicitRK,
    JacFn,
    LazyDenseOutput,
    LieGroup,
    PinocchioGroup,
    Radau,
    Stepper,
    VectorSpace,
    make_stepper,
)

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
