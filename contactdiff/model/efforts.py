"""Efforts of a scene (generalised forces ``tau(q, v, t)`` in R^nv) and their derivatives.

Gravity, Coriolis and centrifugal terms come from Pinocchio (``nle``) and are not
listed here. Each effort is a robot-independent spec (`JointSpring`, `Spring`,
`UserEffort`, the trot controller of `contactdiff.control`, or any object that
follows the `Effort` protocol) whose ``bind(robot)`` returns an evaluator with

    tau(kin, t)              -> (nv,)   generalised force (N or N m per coordinate)
    derivatives(kin, t)      -> (dtau/dq, dtau/dv), each (nv × nv), tangent space
    time_derivative(kin, t)  -> (nv,)   d tau/dt at fixed state

where ``kin`` is a `Kinematics` updated at the state (with ``derivatives=True``
for the second call). An evaluator whose time dependence has breakpoints (a
schedule made of polynomial pieces, the end of a ramp) also has

    next_breakpoint(t)       -> float   the first time (s) after t where a time
                                        derivative of tau jumps, tau itself being
                                        continuous (inf: none left)

and the integrator ends a step exactly on each such time instead of stepping
across it: a high-order method that steps across a jump of the third
derivative rejects the step, or keeps a shorter one, again and again.

A spec with named parameters (`contactdiff.model.parameters`: a joint spring's
stiffness, a user effort's own numbers, ...) declares them with

    named_parameters()       -> EffortParameters  their kind, target and fields

and its evaluator also has

    parameter_derivatives(kin, t, fields) -> (nv × len(fields))  d tau/dp

with ``fields`` a sequence of ``(k, field)``: ``k`` says which spec of the
evaluator (always 0, except for the one evaluator of all joint springs, where
it is the spring's rank among them, see `bound_positions`) and ``field`` the
parameter's name.
"""

from __future__ import annotations

from .effort_protocol import BoundEffort, Effort, EffortParameters, central_time_difference
from .robot import Robot
from .springs import BoundJointSprings, JointSpring, Spring
from .user_efforts import UserEffort


def bind_efforts(specs, robot: Robot) -> list:
    """Bind effort specs on ``robot``; every `JointSpring` goes into one evaluator
    (a dozen joint springs then cost one vectorised call, not a dozen). The order
    is that of `bound_positions`."""
    joint_springs = [s for s in specs if isinstance(s, JointSpring)]
    bound = [BoundJointSprings(joint_springs, robot)] if joint_springs else []
    return bound + [s.bind(robot) for s in specs if not isinstance(s, JointSpring)]


def bound_positions(specs) -> list[tuple[int, int]]:
    """Where each spec of ``specs`` went in `bind_efforts` ``(specs, robot)``: per spec
    ``(i, k)``, the index ``i`` of its evaluator in the returned list and its rank ``k``
    in that evaluator (the joint springs share evaluator 0, ranked in spec order; every
    other spec is alone in its own, ``k = 0``)."""
    n_joint = sum(isinstance(s, JointSpring) for s in specs)
    first = 1 if n_joint else 0
    positions, rank, other = [], 0, 0
    for s in specs:
        if isinstance(s, JointSpring):
            positions.append((0, rank))
            rank += 1
        else:
            positions.append((first + other, 0))
            other += 1
    return positions


__all__ = [
    "BoundEffort",
    "Effort",
    "EffortParameters",
    "JointSpring",
    "Spring",
    "UserEffort",
    "bind_efforts",
    "bound_positions",
    "central_time_difference",
]
