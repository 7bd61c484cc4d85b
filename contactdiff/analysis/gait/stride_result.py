"""One stride's result (`Stride`): the states before two touchdowns of a foot, the
stride map's Jacobian on the section and its parameter block (the mathematics is
in `contactdiff.analysis.gait.stride`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...errors import InvalidInputError
from ...integration.trajectory import Trajectory


@dataclass(kw_only=True)
class Stride:
    """One stride: touchdown of ``foot`` to its next touchdown, both just before impact.

    Attributes:
        scene_name, foot: the scene and the contact whose touchdowns bound the stride.
        t0, q0, v0: start (s; q as Pinocchio, nq; v in the tangent space, nv).
        t, q, v: the next touchdown of the foot, just before its impact.
        jacobian: ``P = dx'/dx0`` (2nv × 2nv, tangent space) or None.
        time_gradient: ``dt'/dx0`` (2nv,) (s per tangent unit) or None.
        start_time_column: ``∂x'/∂t0`` (2nv,) or None.
        start_time_derivative: ``∂t'/∂t0`` (1 for an autonomous scene) or None.
        period: clock period (s) of a clock-driven scene, None if autonomous.
        trajectory: the simulated run (its events end with the foot's touchdown).
        simultaneous: other contacts landing at the same instant as the foot, at the
            start or at the end. There the pre-impact state is discontinuous (the other
            foot's velocity jumps if it lands first), and the Jacobian is the one-sided
            derivative for the other contacts landing at the same time or later.
        parameter_names: the scene parameters differentiated (``parameters=[...]``).
        parameter_jacobian: ``∂x'/∂p`` (2nv × p, tangent space, per unit of each) at a
            fixed start, or None: with the start's impact taken with the foot's guard
            (``Ξ0_p``, as ``Ξ0`` for the state) and the end's touchdown time moving with
            the parameters (``-F' (Dh' ∂x/∂p + ∂h/∂p) / (Dh' F')``).
        parameter_time_gradient: ``∂t'/∂p`` (p,) (s per unit of each), or None.
    """

    scene_name: str
    foot: str
    t0: float
    q0: np.ndarray
    v0: np.ndarray
    t: float
    q: np.ndarray
    v: np.ndarray
    jacobian: np.ndarray | None
    time_gradient: np.ndarray | None
    start_time_column: np.ndarray | None
    start_time_derivative: float | None
    period: float | None
    trajectory: Trajectory = field(repr=False)
    simultaneous: tuple[str, ...] = ()
    parameter_names: tuple[str, ...] = ()
    parameter_jacobian: np.ndarray | None = None
    parameter_time_gradient: np.ndarray | None = None

    @property
    def stride_time(self) -> float:
        """``t - t0`` (s)."""
        return self.t - self.t0

    @property
    def differentiable(self) -> bool:
        """False if any event of the stride has only a piecewise-linear derivative."""
        return self.trajectory.differentiable

    def extended_jacobian(self) -> np.ndarray:
        """The Jacobian in the map's state: ``P`` (autonomous), or in ``(x, τ)``
        ``[[P, ∂x'/∂t0], [dt'/dx0, ∂t'/∂t0]]`` ((2nv+1)², clock-driven)."""
        if self.jacobian is None:
            raise InvalidInputError("this stride was computed without its Jacobian (jacobian=False)")
        if self.period is None:
            return self.jacobian
        n = self.jacobian.shape[0]
        J = np.zeros((n + 1, n + 1))
        J[:n, :n] = self.jacobian
        J[:n, n] = self.start_time_column
        J[n, :n] = self.time_gradient
        J[n, n] = self.start_time_derivative
        return J

    def extended_parameter_jacobian(self) -> np.ndarray:
        """``∂x'/∂p`` in the map's state: (2nv × p), or in ``(x, τ)`` with the row ``∂t'/∂p``
        ((2nv+1) × p, clock-driven)."""
        if self.parameter_jacobian is None:
            raise InvalidInputError("this stride was computed without parameters (stride_map(..., parameters=[...]))")
        if self.period is None:
            return self.parameter_jacobian
        assert self.parameter_time_gradient is not None  # computed with the parameters' Jacobian
        return np.vstack([self.parameter_jacobian, self.parameter_time_gradient])

    def summary(self) -> dict:
        """The stride as JSON-ready data: ends, states, Jacobians where computed."""
        out = {
            "scene": self.scene_name,
            "foot": self.foot,
            "t0": self.t0,
            "t": self.t,
            "stride_time": self.stride_time,
            "q0": self.q0.tolist(),
            "v0": self.v0.tolist(),
            "q": self.q.tolist(),
            "v": self.v.tolist(),
            "period": self.period,
            "events": [f"{e.t:.12g} {e.kind} {'+'.join(e.contacts)}" for e in self.trajectory.events],
            "differentiable": self.differentiable,
            "simultaneous": list(self.simultaneous),
        }
        if self.jacobian is not None:
            assert self.time_gradient is not None and self.start_time_column is not None  # computed with it
            out |= {
                "jacobian": self.jacobian.tolist(),
                "time_gradient": self.time_gradient.tolist(),
                "start_time_column": self.start_time_column.tolist(),
                "start_time_derivative": self.start_time_derivative,
            }
        if self.parameter_jacobian is not None:
            assert self.parameter_time_gradient is not None  # computed with it
            out |= {
                "parameter_names": list(self.parameter_names),
                "parameter_jacobian": self.parameter_jacobian.tolist(),
                "parameter_time_gradient": self.parameter_time_gradient.tolist(),
            }
        return out
