"""Error-controlled ODE steppers with dense output, free of the contact model.

Like scipy's ``_ivp``, this package integrates a given vector field and knows nothing
of contacts, modes, scenes or events' meaning: it imports nothing of
`contactdiff.model`, `contactdiff.dynamics` or `contactdiff.integration` (the hybrid
loop in `contactdiff.integration.hybrid` drives it; ``tests/test_ode_imports.py``
checks it).

**The problem.** The state is a Pinocchio configuration ``q`` (size ``nq``; a
Lie-group element when the model has a free-flyer, spherical, planar or continuous
joint) and a velocity ``v`` (size ``nv``) driven by ``dv/dt = accel(t, q, v)`` and
``dq/dt = v`` in Pinocchio's sense, ``q(t + dt) = q(t) ⊕ dt·v + O(dt²)``
(the callbacks' types: `field_types`). Lie groups are handled by
Runge–Kutta–Munthe-Kaas in a chart re-centred at the start of every step:
``q = q_n ⊕ xi`` with ``xi(t_n) = 0`` and ``dxi/dt = Jr(xi)^-1 v`` (exact dexpinv), so
every Runge–Kutta method keeps its order; ``q_{n+1} = q_n ⊕ xi_{n+1}``. On vector
spaces the chart is the identity and the steppers integrate ``y = (q, v)`` directly
without any chart call (the configuration spaces: `lie`).

Units and frames: time in the model's unit (s); ``q`` and ``v`` in Pinocchio's units
and frames (m, rad, quaternion components; m/s and rad/s in each joint's local frame).
The flow Jacobian ``phi`` (``2nv x m``) maps perturbations at the initial point to
tangent perturbations ``(δq, δv)`` at the current point, ``q ⊕ δq`` (Pinocchio's
convention, docs/design.md §2); by default its local error is controlled together
with the state's (``variational_error_control``). Integration runs forward in time
only. Callbacks receive arrays that a stepper never modifies afterwards, so they may
keep references to them (e.g. for caching).

**What a stepper provides** (every method, on the `base.Stepper` base), driven one
accepted step at a time::

    st = make_stepper("DOP853", accel, PinocchioGroup(model), t0, q0, v0,
                      rtol=1e-10, atol=1e-12)
    st.step()                       # one accepted step [st.t_old, st.t]
    dense = st.dense()              # (q, v) = dense(t) on that interval
    st.truncate(t_event)            # keep the step only up to an event
    st.restart(t_event, q_plus, v_plus, phi=Xi @ st.phi)   # after a jump

* ``step()``: one accepted step, retried internally after rejections; it never
  steps past ``t_bound`` and raises an `IntegrationError` (a step-size underflow, a
  Newton failure, a non-finite field) rather than return a wrong state;
* ``dense(lazy=False)``: a `dense.DenseOutput` of the last step on ``[t_old, t]``
  that stays valid after further steps;
* ``truncate(t)``: the last step kept only up to ``t`` (the state becomes the dense
  output there, ``phi`` is propagated over the shortened step);
* ``restart(t, q, v, phi=..., accel=..., jac=..., t_bound=...)``: a new start after
  a jump or a change of field, keeping the step-size estimate;
* the attributes ``t, q, v, phi``, ``t_old, q_old, v_old, phi_old``, ``h_next`` and
  the counts ``n_steps, n_rejected, n_accel, n_jac``.

What a new method implements is in `base.Stepper`'s docstring.

**The modules.** The explicit Runge–Kutta pairs DOP853 and RK45 (`explicit_rk`, their
coefficients in `tableaus`) and Radau IIA (`radau`) on the `base` class, with the
step-size control they share (`step_control`) and the flow Jacobian's linear algebra
(`variational`); the factory (`factory`: `make_stepper`, `METHODS`); dense output
(`dense`); guard crossings over one step, their location and grouping (`crossings`);
the choice between an explicit and an implicit stepper (`method_choice`); the watches
of a run's step sizes (`step_collapse`, `step_budget`).
"""

from .base import Stepper
from .dense import DenseOutput
from .factory import DOP853, METHODS, RK45, ExplicitRK, Radau, make_stepper
from .field_types import AccelFn, JacFn, ParameterJacFn
from .lie import LieGroup, PinocchioGroup, VectorSpace

__all__ = [
    "METHODS",
    "make_stepper",
    "Stepper",
    "ExplicitRK",
    "DOP853",
    "RK45",
    "Radau",
    "DenseOutput",
    "LieGroup",
    "VectorSpace",
    "PinocchioGroup",
    "AccelFn",
    "JacFn",
    "ParameterJacFn",
]
