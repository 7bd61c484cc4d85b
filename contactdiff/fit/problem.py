"""`fit`: scene parameters (and, when asked, initial states) by nonlinear least squares.

The cost is half the sum of squares of every recording's weighted residuals
(`contactdiff.fit.residuals`) at its compared samples, or with a robust `Loss`
half the sum of ``f_scale² ρ((r / f_scale)²)`` (scipy's robust losses). Each evaluation runs
every recording once (in parallel on the sweep engine's workers) and gets the
residuals and their exact Jacobian from that one run (`contactdiff.fit.evaluation`);
scipy's trust-region reflective method (``least_squares(method="trf")``) keeps
the unknowns inside their bounds (`contactdiff.fit.parameters`).

**Standard errors** come from the Gauss–Newton covariance at the solution,
``s² (JᵀJ)⁻¹`` with ``s² = Σr² / (m − n)`` (m residual rows, n unknowns; with a
robust loss each row weighed by ``ρ'``, as its last Gauss–Newton step weighs it): they
describe the noise of a model that fits, and are too small when the model
misses systematically. A direction the residuals do not see (a singular
``JᵀJ``, relative to its largest singular value below `RANK_TOL`) gets an
infinite standard error, and the result says so.

**Recordings whose outcome is not differentiable** (a flagged event before
their last sample: a face landing whose order matters, a friction threshold,
a Zeno cut) make the cost's gradient a one-sided derivative there.
`NonDifferentiablePolicy` says what the fit does with them: ``keep`` (default)
uses them as they are, counts them at every evaluation (`FitResult.nondifferentiable`)
and warns; ``exclude`` leaves out, for the whole fit, those not differentiable
at the starting values (so that the cost stays one function).
"""

from __future__ import annotations

import math
import time
import warnings
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from enum import StrEnum

import numpy as np
from scipy import sparse
from scipy.optimize import least_squares

from ..errors import FitError, InvalidInputError, check_count, check_member
from ..model.scene import Scene
from .evaluation import Evaluation, StateFit, Task, evaluate
from .loss import Loss
from .parameters import FitPlan
from .recordings import Recording
from .residuals import ResidualWeights

FAILED_RESIDUAL = 1e3
"""A trial value at which a run fails gets every residual row this many times the start's RMS
(so trust-region steps into a region where the scene cannot run are rejected, not fatal)."""

RANK_TOL = 1e-10
"""Singular values of J below this fraction of the largest count as zero in the covariance."""


class NonDifferentiablePolicy(StrEnum):
    """What a fit does with recordings whose outcome is not differentiable (module doc)."""

    KEEP = "keep"
    EXCLUDE = "exclude"


class NotDifferentiableWarning(UserWarning):
    """Some recordings' outcomes are not differentiable at the fit's values (the gradient is one-sided there)."""


@dataclass(frozen=True)
class RecordingFit:
    """One recording at the fitted values.

    Attributes:
        name: the recording's name.
        rms: root mean square of its weighted residual rows.
        cost: half its sum of squares.
        differentiable: no flagged event before its last sample.
        nonsmooth: the flagged events' reasons, counted (`NonSmooth` names).
        events: events of its run.
        excluded: left out of the cost (`NonDifferentiablePolicy.EXCLUDE`).
        state_offset: its fitted initial-state offset (tangent space; empty when not fitted).
        q: its simulated configurations at the compared samples.
    """

    name: str
    rms: float
    cost: float
    differentiable: bool
    nonsmooth: dict
    events: int
    excluded: bool
    state_offset: np.ndarray
    q: np.ndarray = field(repr=False)


@dataclass
class FitResult:
    """What `fit` found.

    Attributes:
        names: the unknowns' names; start, values: their values before and after.
        standard_errors: from the Gauss–Newton covariance (inf where not identifiable).
        covariance: of the unknowns (n × n), the initial-state offsets marginalised.
        cost: half the sum of squares at ``values`` (with a robust `Loss`, of its ``ρ``);
            start_cost: at ``start``.
        recordings: a `RecordingFit` per recording, in the order given.
        iterations: Jacobian evaluations (scipy's ``njev``); evaluations: residual
            evaluations (``nfev``), each one run per recording.
        nondifferentiable: recordings not differentiable at each evaluation.
        failed_trials: messages of the trial values at which a run failed (each rejected).
        policy: the `NonDifferentiablePolicy`; success, message: scipy's verdict.
        rank_deficient: some direction had no information (infinite standard errors).
        wall_time: s.
    """

    names: tuple[str, ...]
    start: np.ndarray
    values: np.ndarray
    standard_errors: np.ndarray
    covariance: np.ndarray
    cost: float
    start_cost: float
    recordings: list[RecordingFit]
    iterations: int
    evaluations: int
    nondifferentiable: list[int]
    failed_trials: list[str]
    policy: NonDifferentiablePolicy
    success: bool
    message: str
    rank_deficient: bool
    wall_time: float

    def to_dict(self) -> dict:
        """Everything but the simulated configurations, JSON-ready (inf as the string "inf")."""

        def number(x):
            return float(x) if np.isfinite(x) else str(x)

        return {
            "parameters": {
                n: {"start": number(s), "value": number(v), "standard_error": number(e)}
                for n, s, v, e in zip(self.names, self.start, self.values, self.standard_errors)
            },
            "cost": self.cost,
            "start_cost": self.start_cost,
            "iterations": self.iterations,
            "evaluations": self.evaluations,
            "nondifferentiable": self.nondifferentiable,
            "failed_trials": self.failed_trials,
            "policy": self.policy.value,
            "success": self.success,
            "message": self.message,
            "rank_deficient": self.rank_deficient,
            "wall_time": self.wall_time,
            "recordings": [
                {
                    "name": r.name,
                    "rms": r.rms,
                    "cost": r.cost,
                    "differentiable": r.differentiable,
                    "nonsmooth": r.nonsmooth,
                    "events": r.events,
                    "excluded": r.excluded,
                    "state_offset": r.state_offset.tolist(),
                }
                for r in self.recordings
            ],
        }

    def table(self) -> str:
        """The fitted values, one line each: name, start, value ± standard error."""
        width = max(len(n) for n in self.names)
        return "\n".join(
            f"{n:<{width}}  {s:12.6g} -> {v:12.6g} ± {e:.3g}"
            for n, s, v, e in zip(self.names, self.start, self.values, self.standard_errors)
        )


class _Workers:
    """Runs `evaluate` on every task: in this process, or on the sweep engine's workers."""

    def __init__(self, scene, jobs: int, backend: str, progress):
        from ..sweeps.engines import Engine
        from ..sweeps.sources import SceneSource

        self.scene = scene if isinstance(scene, Scene) else None
        self.source = None if self.scene is not None else SceneSource.of(scene)
        if self.scene is None and jobs == 1:
            assert self.source is not None  # not a Scene: a source
            self.scene = self.source.build()
        if self.scene is not None and jobs > 1 and self.source is None:
            raise InvalidInputError(
                f"fit: jobs={jobs} needs a scene the workers can rebuild (a scene name, TOML file or a "
                f"function that builds it, such as contactdiff.cube_scene); a Scene object runs with jobs=1"
            )
        self.engine = Engine.of(backend, jobs) if jobs > 1 else None
        self.progress = progress

    def model_scene(self) -> Scene:
        if self.scene is not None:
            return self.scene
        assert self.source is not None  # not a Scene: a source
        return self.source.build()

    def run(self, tasks: list[Task], parameters: tuple, label: str) -> list[Evaluation]:
        from ..sweeps.runner import _progress_bar

        out: list[Evaluation | None] = [None] * len(tasks)
        with _progress_bar(len(tasks), label, self.progress) as bar:
            if self.engine is None:
                for task in tasks:
                    out[task.index] = evaluate(self.scene, parameters, task)
                    bar.update(1)
            else:
                with self.engine.session() as run:
                    for ev in run(_evaluate_in_worker, [(self.source, parameters, t) for t in tasks]):
                        out[ev.index] = ev
                        bar.update(1)
        evaluations = [ev for ev in out if ev is not None]
        assert len(evaluations) == len(tasks)  # every task has its evaluation
        return evaluations


def _evaluate_in_worker(source, parameters: tuple, task: Task) -> Evaluation:
    return evaluate(source.build(), parameters, task)


def fit(
    scene,
    recordings: Sequence[Recording],
    parameters,
    *,
    bounds: Mapping | None = None,
    state: StateFit | str = StateFit.NONE,
    weights: ResidualWeights = ResidualWeights(),
    policy: NonDifferentiablePolicy | str = NonDifferentiablePolicy.KEEP,
    jobs: int = 1,
    backend: str = "loky",
    options: Mapping | None = None,
    max_evaluations: int = 30,
    tolerance: float = 1e-8,
    progress: bool | None = None,
    loss: Loss | str = Loss.LINEAR,
    f_scale: float = 1.0,
) -> FitResult:
    """Fit ``parameters`` of ``scene`` to ``recordings`` (module doc).

    Args:
        scene: a `Scene` (runs in this process), or what a sweep takes (a scene name,
            TOML path, or a function returning the scene, such as ``contactdiff.cube_scene``)
            for ``jobs > 1``.
        recordings: the `Recording` s (measured trajectories and their starts).
        parameters: the unknowns: scene parameter names and `Scaled` groups.
        bounds: ``{unknown: (lower, upper)}`` over the defaults (μ, e, masses, ... >= 0, e <= 1).
        state: the `StateFit`: which part of each recording's initial state is fitted too.
        weights: the `ResidualWeights` (position per m, orientation per rad, joints).
        policy: the `NonDifferentiablePolicy`.
        jobs: worker processes (1: this process).
        backend: the sweep engine's backend (``loky``, ``dask``, ``ray``).
        options: `SimulateOptions` fields for every run (``rtol``, ``atol``, ...).
        max_evaluations: residual evaluations at most (each runs every recording once).
        tolerance: scipy's ``ftol``, ``xtol`` and ``gtol``.
        progress: a progress bar per evaluation on stderr (default: on a terminal).
        loss: the `Loss` (default the sum of squares).
        f_scale: the residual (in the weighted rows' unit, m for positions) beyond which a
            robust loss counts a row less (> 0).

    Returns:
        The `FitResult`.

    Raises:
        InvalidInputError, UnknownNameError: bad arguments (named, with valid options).
        FitError: a recording's run failed (at the start, or at a trial value).
    """
    started = time.perf_counter()
    recordings = list(recordings)
    if not recordings or not all(isinstance(r, Recording) for r in recordings):
        raise InvalidInputError("fit: recordings must be a non-empty list of contactdiff.fit.Recording")
    state = check_member("fit: state", state, StateFit)
    policy = check_member("fit: policy", policy, NonDifferentiablePolicy)
    jobs = check_count("fit", "jobs", jobs, minimum=1)
    max_evaluations = check_count("fit", "max_evaluations", max_evaluations, minimum=1)
    loss = check_member("fit: loss", loss, Loss)
    if not (isinstance(f_scale, (int, float)) and math.isfinite(f_scale) and f_scale > 0.0):
        raise InvalidInputError(f"fit: f_scale must be a number > 0, got {f_scale!r}")
    workers = _Workers(scene, jobs, backend, progress)
    base = workers.model_scene()
    plan = FitPlan(base, parameters, bounds)
    nv, n = base.nv, len(plan.names)
    s = len(state.columns(nv))
    theta0 = plan.start(base)
    x0 = np.concatenate([theta0, np.zeros(s * len(recordings))])
    if np.any(theta0 <= plan.lower) or np.any(theta0 >= plan.upper):
        theta0 = np.clip(theta0, plan.lower + 1e-12, plan.upper - 1e-12)
        x0[:n] = theta0
    options = dict(options or {})
    counts: list[int] = []
    cache: dict = {}
    active = list(range(len(recordings)))
    trials: list[str] = []  # trial values at which a run failed (the step is rejected)

    def run(x: np.ndarray) -> list[Evaluation] | None:
        if cache.get("x") is not None and np.array_equal(cache["x"], x):
            return cache["evals"]
        values = plan.values(x[:n])
        tasks = [
            Task(i, rec, values, x[n + s * i : n + s * (i + 1)], state, weights, options)
            for i, rec in enumerate(recordings)
        ]
        evals = workers.run(tasks, plan.parameters, f"fit evaluation {len(counts) + 1}")
        failed = [(recordings[e.index].name, e.error) for e in evals if e.error is not None]
        if failed:
            name, error = failed[0]
            message = (
                f"fit: the run of {name!r} failed at {values} ({error}); {len(failed)} of {len(evals)} runs failed"
            )
            if "x" not in cache:  # at the start: nothing to fall back on
                raise FitError(message)
            trials.append(message)
            return None
        counts.append(sum(not evals[i].differentiable for i in active))
        cache.update(x=x.copy(), evals=evals)
        return evals

    first = run(x0)
    assert first is not None  # a failed run at the start raises
    if policy is NonDifferentiablePolicy.EXCLUDE:
        active[:] = [i for i in active if first[i].differentiable]
        counts[-1] = 0
        if not active:
            raise InvalidInputError(
                "fit: policy 'exclude' leaves no recording: every one is not differentiable "
                "at the starting values (use policy 'keep')"
            )
    start_cost = loss.cost(np.concatenate([first[i].residual for i in active]), f_scale)
    rows = sum(len(first[i].residual) for i in active)

    def residuals(x):
        evals = run(x)
        if evals is None:  # a failed run: the trial counts as far worse than the start, its step is rejected
            return np.full(rows, FAILED_RESIDUAL * max(1.0, math.sqrt(2.0 * start_cost / rows)))
        return np.concatenate([evals[i].residual for i in active])

    def jacobian(x):
        evals = run(x)
        assert evals is not None  # asked for at accepted points only (a failed run's step is rejected)
        return _assemble(evals, active, plan.C, n, s, len(recordings))

    solution = least_squares(
        residuals,
        x0,
        jac=jacobian,
        bounds=(_bound(plan.lower, s, recordings), _bound(plan.upper, s, recordings, upper=True)),
        method="trf",
        x_scale="jac",
        ftol=tolerance,
        xtol=tolerance,
        gtol=tolerance,
        max_nfev=max_evaluations,
        loss=loss.value,
        f_scale=f_scale,
    )
    final = run(solution.x)  # the accepted point: cached, or run again if the last trial failed
    assert final is not None  # it ran at the accepted point before
    J = jacobian(solution.x)
    J = J.toarray() if sparse.issparse(J) else J
    w = np.sqrt(loss.weights(solution.fun, f_scale))  # a robust loss: rows weighed as its last step weighs them
    covariance, rank_deficient = _covariance(w[:, None] * J, w * solution.fun, n)
    if counts and counts[-1] and policy is NonDifferentiablePolicy.KEEP:
        warnings.warn(
            f"fit: {counts[-1]} of {len(recordings)} recordings are not differentiable at the fitted "
            "values (flagged events before their last sample; FitResult.recordings says which)",
            NotDifferentiableWarning,
            stacklevel=2,
        )
    fits = [
        _recording_fit(rec, ev, i not in active, solution.x[n + s * i : n + s * (i + 1)])
        for i, (rec, ev) in enumerate(zip(recordings, final))
    ]
    errors = np.sqrt(np.where(np.diag(covariance) >= 0.0, np.diag(covariance), np.inf))
    return FitResult(
        plan.names,
        theta0,
        solution.x[:n].copy(),
        errors,
        covariance,
        float(solution.cost),
        start_cost,
        fits,
        int(solution.njev or 0),
        int(solution.nfev),
        counts,
        trials,
        policy,
        bool(solution.success),
        str(solution.message),
        rank_deficient,
        time.perf_counter() - started,
    )


def _bound(values: np.ndarray, s: int, recordings, upper: bool = False) -> np.ndarray:
    return np.concatenate([values, np.full(s * len(recordings), np.inf if upper else -np.inf)])


def _assemble(evals: list[Evaluation], active: list[int], C: np.ndarray, n: int, s: int, count: int):
    """The residuals' Jacobian: the unknowns' columns, then each recording's state block."""
    blocks = [evals[i].parameter_jacobian @ C for i in active]
    if s == 0:
        return np.vstack(blocks)
    rows = []
    for i, block in zip(active, blocks):
        state = [None] * count
        state[i] = sparse.csr_matrix(evals[i].state_jacobian)
        rows.append([sparse.csr_matrix(block)] + state)
    for j in range(count):  # a recording left out still owns its (empty) columns
        if j not in active:
            rows[0][1 + j] = sparse.csr_matrix((blocks[0].shape[0], s))
    return sparse.bmat(rows, format="csr")


def _covariance(J: np.ndarray, r: np.ndarray, n: int) -> tuple[np.ndarray, bool]:
    """The unknowns' block of ``s² (JᵀJ)⁻¹`` (pseudo-inverse past `RANK_TOL`); inf on the
    diagonal where a direction has no information."""
    m, total = J.shape
    dof = max(m - total, 1)
    s2 = float(r @ r) / dof
    U, sigma, Vt = np.linalg.svd(J, full_matrices=False)
    keep = sigma > RANK_TOL * (sigma[0] if len(sigma) else 0.0)
    inverse = (Vt[keep].T / sigma[keep] ** 2) @ Vt[keep]
    covariance = s2 * inverse[:n, :n]
    null = Vt[~keep][:, :n]
    rank_deficient = bool(np.any(np.abs(null) > 1e-8))
    if rank_deficient:
        unseen = np.any(np.abs(null) > 1e-8, axis=0)
        covariance[unseen, unseen] = np.inf
    return covariance, rank_deficient


def _recording_fit(rec: Recording, ev: Evaluation, excluded: bool, offset: np.ndarray) -> RecordingFit:
    r = ev.residual
    return RecordingFit(
        rec.name,
        float(np.sqrt(np.mean(r**2))) if len(r) else 0.0,
        0.5 * float(r @ r),
        ev.differentiable,
        dict(Counter(ev.nonsmooth)),
        ev.events,
        excluded,
        offset.copy(),
        ev.q,
    )


__all__ = [
    "FitError",
    "FitResult",
    "NonDifferentiablePolicy",
    "NotDifferentiableWarning",
    "RecordingFit",
    "fit",
    "RANK_TOL",
]
