"""One recording's residuals and their exact Jacobian, from a single run of the scene.

`evaluate` is what a fit's worker runs for each recording at each iterate: it
sets the unknowns on the scene, runs it from the recording's start once with
the flow's derivatives sampled at every compared sample time
(``SimulateOptions.sample_times``), and chains the residual's derivative in the
simulated configuration (`contactdiff.fit.residuals.PoseResidual.jacobian`)
with the sampled configuration's derivatives in the scene parameters (and in
the initial state, when it is fitted):

    ∂r_k/∂θ = W_k R_k (∂q_k/∂p) C,        ∂r_k/∂x0 = W_k R_k (∂q_k/∂x0) S,

``R_k`` the residual's derivative at sample k, ``∂q_k`` the configuration rows
of the sampled flow Jacobian, ``C`` the unknowns' map (`FitPlan`), ``S`` the
columns of the fitted initial-state components and ``W_k`` the sample's weight.
The events before the last compared sample give the recording's verdict: it is
differentiable when none of them is flagged (`Event.differentiable`).
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from enum import StrEnum

import numpy as np
import pinocchio as pin

from ..errors import ContactDiffError
from ..integration.hybrid import simulate
from .recordings import Recording
from .residuals import PoseResidual, ResidualWeights


class StateFit(StrEnum):
    """Which part of each recording's initial state a fit adjusts (its tangent-space offset)."""

    NONE = "none"
    """the starts are fixed"""
    VELOCITY = "velocity"
    """the initial velocity (nv per recording)"""
    FULL = "full"
    """configuration and velocity (2 nv per recording)"""

    def columns(self, nv: int) -> np.ndarray:
        """The fitted columns among the state's 2 nv tangent coordinates."""
        return {
            StateFit.NONE: np.arange(0),
            StateFit.VELOCITY: np.arange(nv, 2 * nv),
            StateFit.FULL: np.arange(2 * nv),
        }[self]


@dataclass(frozen=True)
class Task:
    """What a worker needs for one recording at one iterate (all of it pickles).

    Attributes:
        index: the recording's position in the fit.
        recording: the `Recording`.
        values: the scene parameters to set (`FitPlan.values`).
        offset: the fitted initial-state offset (its `StateFit` columns), or an empty array.
        state_fit: the `StateFit`.
        weights: the `ResidualWeights`.
        options: `SimulateOptions` fields for the run (rtol, atol, ...).
    """

    index: int
    recording: Recording
    values: dict
    offset: np.ndarray
    state_fit: StateFit
    weights: ResidualWeights
    options: dict = field(default_factory=dict)


@dataclass(frozen=True, eq=False)
class Evaluation:
    """One recording's residuals at one iterate.

    Attributes:
        index: the recording's position in the fit.
        residual: the weighted residual rows (m,), sample by sample (nv rows each).
        parameter_jacobian: ∂residual/∂(scene parameters) (m × p), before the map ``C``.
        state_jacobian: ∂residual/∂(fitted initial-state offset) (m × s).
        q: simulated configurations at the compared samples (k × nq).
        nonsmooth: `NonSmooth` names of the flagged events before the last sample, counted.
        events: events of the run.
        error: the run's error message when it failed (the other fields are then empty).
    """

    index: int
    residual: np.ndarray
    parameter_jacobian: np.ndarray
    state_jacobian: np.ndarray
    q: np.ndarray
    nonsmooth: Counter
    events: int
    error: str | None = None

    @classmethod
    def failed(cls, index: int, error: str) -> Evaluation:
        """A run that failed: its error, and empty residuals."""
        empty = np.zeros(0)
        return cls(index, empty, empty, empty, empty, Counter(), 0, error)

    @property
    def differentiable(self) -> bool:
        """No flagged event before the last compared sample."""
        return not self.nonsmooth


def start_state(model: pin.Model, recording: Recording, state_fit: StateFit, offset) -> tuple:
    """The rollout's start: the recording's ``(q0, v0)`` moved by the fitted tangent offset."""
    q0, v0 = recording.q0.copy(), recording.v0.copy()
    if len(offset):
        delta = np.zeros(2 * model.nv)
        delta[state_fit.columns(model.nv)] = offset
        q0 = pin.integrate(model, q0, delta[: model.nv])
        v0 = v0 + delta[model.nv :]
    return q0, v0


def _start_derivative(model: pin.Model, recording: Recording, state_fit: StateFit, offset) -> np.ndarray:
    """∂x0/∂(offset) (2nv × 2nv) in the start's tangent space: ``dIntegrate`` for the
    configuration (the offset is a step from the recording's ``q0``), identity for the velocity."""
    nv = model.nv
    delta = np.zeros(2 * nv)
    if len(offset):
        delta[state_fit.columns(nv)] = offset
    D = np.eye(2 * nv)
    D[:nv, :nv] = pin.dIntegrate(model, recording.q0, delta[:nv], pin.ARG1)
    return D


def evaluate(scene, plan_parameters: tuple, task: Task) -> Evaluation:
    """Run ``task``'s recording on ``scene`` (module doc); a failed run is returned, not raised."""
    rec = task.recording
    model = scene.model
    try:
        variant = scene.with_parameters(task.values)
        q0, v0 = start_state(model, rec, task.state_fit, task.offset)
        k = rec.compared
        fitted_state = len(task.state_fit.columns(model.nv)) > 0
        traj = simulate(
            variant.with_state(q0, v0),
            float(rec.t[-1]),
            t0=float(rec.t0),
            **task.options,
            sample_times=rec.t[k],
            parameters=list(plan_parameters),
            jacobian=fitted_state,
        )
    except ContactDiffError as exc:
        return Evaluation.failed(task.index, f"{type(exc).__name__}: {exc}")
    samples = traj.samples
    assert samples is not None  # asked for (sample_times)
    if len(samples) != len(k):
        return Evaluation.failed(task.index, f"the run ended at {traj.t} s, before its last sample at {rec.t[-1]} s")
    residual = PoseResidual(model, task.weights)
    nv = model.nv
    w = rec.sample_weights()
    if rec.mask is not None:  # unmeasured coordinates: zero rows (and zero derivatives)
        residual.scale = residual.scale * rec.mask
    r = np.concatenate([wk * residual.residual(qk, rec.q[i]) for wk, qk, i in zip(w, samples.q, k)])
    Jr = [wk * residual.jacobian(qk, rec.q[i]) for wk, qk, i in zip(w, samples.q, k)]
    Jp = (
        np.vstack([Jk @ P[:nv] for Jk, P in zip(Jr, samples.parameter_jacobian)])
        if samples.parameter_jacobian is not None
        else np.zeros((len(r), 0))
    )
    if fitted_state:
        assert samples.jacobian is not None  # asked for (jacobian=fitted_state)
        cols = task.state_fit.columns(nv)
        start = _start_derivative(model, rec, task.state_fit, task.offset)[:, cols]
        Js = np.vstack([Jk @ X[:nv] @ start for Jk, X in zip(Jr, samples.jacobian)])
    else:
        Js = np.zeros((len(r), 0))
    last = rec.t[-1]
    reasons = Counter(reason.name for e in traj.events if e.t <= last for reason in e.nonsmooth)
    return Evaluation(task.index, r, Jp, Js, samples.q, reasons, len(traj.events))


__all__ = ["Evaluation", "StateFit", "Task", "evaluate", "start_state"]
