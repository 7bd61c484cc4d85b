"""Error-controlled one-step integrators with dense output (mechanical systems): the factory.

The methods: `DOP853` and `RK45` (`contactdiff.integration.explicit_rk`), `Radau`
(`contactdiff.integration.radau`), all on the `Stepper` base
(`contactdiff.integration.stepper`, whose docstring states what a new method
implements), over a configuration space of `contactdiff.integration.lie`.

The state is a Pinocchio configuration ``q`` (size ``nq``; a Lie-group element
when the model has a free-flyer, spherical, planar or continuous joint) and a
velocity ``v`` (size ``nv``) driven by ``dv/dt = accel(t, q, v)`` and
``dq/dt = v`` in Pinocchio's sense, ``q(t + dt) = q(t) ⊕ dt·v + O(dt²)``.

Lie groups are handled by Runge–Kutta–Munthe-Kaas in a chart re-centred at the
start of every step: ``q = q_n ⊕ xi`` with ``xi(t_n) = 0`` and
``dxi/dt = Jr(xi)^-1 v`` (exact dexpinv), so every Runge–Kutta method keeps its
order; ``q_{n+1} = q_n ⊕ xi_{n+1}``. On vector spaces the chart is the identity
and the steppers integrate ``y = (q, v)`` directly without any chart call.

A stepper is driven one accepted step at a time by the hybrid loop::

    st = make_stepper("DOP853", accel, PinocchioGroup(model), t0, q0, v0,
                      rtol=1e-10, atol=1e-12)
    st.step()                       # one accepted step [st.t_old, st.t]
    dense = st.dense()              # (q, v) = dense(t) on that interval
    st.truncate(t_event)            # keep the step only up to an event
    st.restart(t_event, q_plus, v_plus, phi=Xi @ st.phi)   # after a jump

Units and frames: time in the model's unit (s); ``q`` and ``v`` in Pinocchio's
units and frames (m, rad, quaternion components; m/s and rad/s in each joint's
local frame). The flow Jacobian ``phi`` (``2nv x m``) maps perturbations at the
initial point to tangent perturbations ``(δq, δv)`` at the current point,
``q ⊕ δq`` (Pinocchio's convention, docs/design.md §2); by default its local error
is controlled together with the state's (``variational_error_control``).
Integration runs forward in time only.

Callbacks receive arrays that this module never modifies afterwards, so they
may keep references to them (e.g. for caching).
"""

from __future__ import annotations

from ..errors import InvalidInputError
from .dense import DenseOutput, LazyDenseOutput
from .explicit_rk import DOP853, RK45, ExplicitRK
from .lie import LieGroup, PinocchioGroup, VectorSpace
from .radau import Radau
from .stepper import AccelFn, JacFn, Stepper

__all__ = [
    "METHODS", "AccelFn", "JacFn", "LieGroup", "VectorSpace", "PinocchioGroup", "DenseOutput",
    "LazyDenseOutput", "Stepper", "ExplicitRK", "RK45", "DOP853", "Radau", "make_stepper",
]

_CLASSES: dict[str, type[Stepper]] = {"DOP853": DOP853, "RK45": RK45, "Radau": Radau}
METHODS: tuple[str, ...] = tuple(_CLASSES)
"""Valid ``method`` names for `make_stepper`."""


def make_stepper(method: str, accel: AccelFn, group, t0: float, q0, v0, **options) -> Stepper:
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
