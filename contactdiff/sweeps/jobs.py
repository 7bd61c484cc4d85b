"""What a sweep runs at each point, and the outputs of a row.

Built-in jobs (`JobKind`), each a function of the point's scene:

* ``simulate``: `simulate` to ``t_final``; outputs `trajectory_outputs`: final
  time and state (``q_end:<coordinate>``, ``v_end:<coordinate>``), events by
  kind (``events:touchdown``, ...), whether every event is differentiable,
  steps, drift, why the run ended.
* ``jacobian``: the same with the flow Jacobian and, with the job option
  ``parameters``, the parameter Jacobian; adds their 2-norms (largest singular
  value, per tangent unit) and the Jacobian's condition number, the largest
  saltation matrix's 2-norm, and per parameter the 2-norm of its column
  (``parameter_jacobian_norm:<name>``).
* ``order-gap``: the same run, and the order gap
  (`contactdiff.analysis.order_gap`) at each simultaneous touchdown in it (two
  or more contacts in one event; every pair of them, or the pair of the job
  option ``contacts``): how many were measured, the largest outcome,
  saltation and spread gaps, and where (time, pair). A run with no
  simultaneous touchdown has ``order_gap_events`` 0 and no gaps (None).
* ``stride``: `find_periodic_gait` from the scene's initial state (job options
  ``foot``, the default the first contact, ``iterations`` of Newton, default 0,
  and the other keywords of `find_periodic_gait`); outputs the stride time,
  the last residual, convergence, the Floquet multipliers (``[real, imag]``
  pairs by decreasing modulus), their moduli and the largest.

A user job is a function ``f(scene, point) -> dict`` given as a callable or as
``"module:function"``; ``point`` holds the point's values by quantity name and
the sweep's run settings (``t_final`` and options) not swept. Its dict is the
row's outputs (JSON values: numbers, strings, lists, None).
"""

from __future__ import annotations

import itertools
from collections import Counter
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from enum import StrEnum

import numpy as np

from ..errors import InvalidInputError, unknown_name
from ..integration.trajectory import EVENT_KINDS, EventKind, Trajectory
from ..jsonable import to_jsonable
from ..model.scene import Scene
from .callables import import_callable, reference


class JobKind(StrEnum):
    """The built-in jobs (module docstring)."""

    SIMULATE = "simulate"
    JACOBIAN = "jacobian"
    ORDER_GAP = "order-gap"
    STRIDE = "stride"


JOB_OPTIONS: dict[JobKind, tuple[str, ...]] = {
    JobKind.SIMULATE: (),
    JobKind.JACOBIAN: ("parameters",),
    JobKind.ORDER_GAP: ("contacts",),
    JobKind.STRIDE: (
        "foot",
        "iterations",
        "tol",
        "neutral",
        "period",
        "t_max",
        "min_stride",
        "min_flight",
        "warmup",
        "line_search",
        "resolution",
    ),
}
"""Options of each built-in job (fixed with ``job_options``, swept as ``job:<name>``)."""

DEFAULT_OUTPUT = {
    JobKind.SIMULATE: "events",
    JobKind.JACOBIAN: "jacobian_norm",
    JobKind.ORDER_GAP: "order_gap_outcome",
    JobKind.STRIDE: "max_multiplier",
}
"""The output a plot shows unless told otherwise."""


@dataclass(frozen=True, eq=False)
class Job:
    """A job: a built-in `JobKind` or a user function, with its fixed options.

    Attributes:
        label: ``"simulate"``, ... or ``module:function``.
        kind: the built-in kind, or None for a user function.
        function: the user function, or None.
        options: the job's fixed options (built-in: `JOB_OPTIONS`).
    """

    label: str
    kind: JobKind | None = None
    function: Callable | None = None
    options: Mapping = field(default_factory=dict)

    @classmethod
    def of(cls, job, options: Mapping | None = None) -> Job:
        """The job named ``job`` (a `JobKind` value, ``"module:function"`` or a callable).

        Raises:
            UnknownNameError: an unknown job name (the built-in ones are listed) or
                an unknown option of a built-in job.
            InvalidInputError: a ``module:function`` that does not resolve.
        """
        options = dict(options or {})
        if isinstance(job, Job):
            return job
        if callable(job):
            return cls(reference(job), None, job, options)
        if not isinstance(job, str):
            raise InvalidInputError(
                f"sweep: job must be a name ({', '.join(JobKind)}), 'module:function' or a callable; got {job!r}"
            )
        if job in tuple(JobKind):
            kind = JobKind(job)
            for name in options:
                if name not in JOB_OPTIONS[kind]:
                    raise unknown_name(f"option of job {job!r}", name, JOB_OPTIONS[kind])
            return cls(job, kind, None, options)
        if ":" not in job:
            raise unknown_name("job", job, list(JobKind) + ["module:function"])
        return cls(job, None, import_callable(job, "job"), options)

    @property
    def argument_names(self) -> tuple[str, ...] | None:
        """Names a ``job:<name>`` quantity may take (None: any, a user job)."""
        return None if self.kind is None else JOB_OPTIONS[self.kind]

    @property
    def needs_t_final(self) -> bool:
        """Whether the job runs to a final time (every built-in job but ``stride``)."""
        return self.kind not in (None, JobKind.STRIDE)

    def default_output(self) -> str | None:
        """The output a plot shows by default (None for a user job: its first number)."""
        return None if self.kind is None else DEFAULT_OUTPUT[self.kind]

    def run(self, scene: Scene, point: Mapping, t_final: float | None, options: Mapping, arguments: Mapping) -> dict:
        """Run the job at one point.

        Args:
            scene: the point's scene.
            point: the point's values (and, for a user job, the run settings not swept).
            t_final: final time (s).
            options: `SimulateOptions` fields.
            arguments: the point's ``job:<name>`` values (on top of the fixed options).

        Returns:
            The row's outputs, JSON-ready.
        """
        settings = {**self.options, **arguments}
        if self.kind is None:
            assert self.function is not None  # a user job (kind None) has its function
            outputs = self.function(scene, dict(point))
            if not isinstance(outputs, Mapping) or not all(isinstance(k, str) for k in outputs):
                raise InvalidInputError(
                    f"job {self.label} must return a dict of outputs by name, got {type(outputs).__name__}"
                )
            return to_jsonable(dict(outputs))
        return to_jsonable(_BUILT_IN[self.kind](scene, t_final, dict(options), settings))


# -- the built-in jobs ---------------------------------------------------------------------
def trajectory_outputs(traj: Trajectory, scene: Scene) -> dict:
    """A run's row: final time and state, events by kind, differentiability, steps, drift."""
    robot = scene.robot
    counts = Counter(e.kind for e in traj.events)
    out = {"t_end": traj.t, "termination": str(traj.termination), "events": len(traj.events)}
    out |= {f"events:{kind}": counts.get(kind, 0) for kind in EVENT_KINDS}
    out |= {
        "simultaneous_events": sum(e.simultaneous for e in traj.events),
        "differentiable": traj.differentiable,
        "steps": traj.stats.steps,
        "rejected_steps": traj.stats.rejected_steps,
        "max_drift": traj.max_drift,
    }
    out |= {f"q_end:{label}": x for label, x in zip(robot.configuration_names(), traj.q.tolist())}
    out |= {f"v_end:{label}": x for label, x in zip(robot.tangent_names(), traj.v.tolist())}
    return out


def _simulate(scene: Scene, t_final, options: dict, settings: dict) -> dict:
    from ..integration.hybrid import simulate

    return trajectory_outputs(simulate(scene, t_final, **options), scene)


def _jacobian(scene: Scene, t_final, options: dict, settings: dict) -> dict:
    from ..integration.hybrid import simulate

    names = settings.get("parameters") or ()
    names = scene.parameter_names() if names == "all" else [names] if isinstance(names, str) else list(names)
    traj = simulate(scene, t_final, **{**options, "jacobian": True, "parameters": names})
    assert traj.jacobian is not None  # asked for
    out = trajectory_outputs(traj, scene)
    singular = np.linalg.svd(traj.jacobian, compute_uv=False)
    out["jacobian_norm"] = float(singular[0])
    out["jacobian_cond"] = float(singular[0] / singular[-1]) if singular[-1] > 0 else float("inf")
    saltations = [np.linalg.norm(e.saltation, 2) for e in traj.events if e.saltation is not None]
    out["saltation_norm_max"] = float(max(saltations)) if saltations else None
    if traj.parameter_jacobian is not None:
        P = traj.parameter_jacobian
        out["parameter_jacobian_norm"] = float(np.linalg.norm(P, 2))
        out |= {f"parameter_jacobian_norm:{n}": float(np.linalg.norm(P[:, k])) for k, n in enumerate(names)}
    return out


def _order_gap(scene: Scene, t_final, options: dict, settings: dict) -> dict:
    from ..analysis.order_gap import order_gap
    from ..integration.hybrid import simulate

    traj = simulate(scene, t_final, **options)
    out = trajectory_outputs(traj, scene)
    wanted = settings.get("contacts")
    if isinstance(wanted, str):
        wanted = [c.strip() for c in wanted.split(",")]
    if wanted is not None:
        if len(wanted) != 2:
            raise InvalidInputError(f"order-gap job: contacts must be two contact names, got {wanted!r}")
        for name in wanted:
            scene.contact_index(name)  # an unknown name lists the scene's contacts
    gaps, skipped = [], 0
    sliding = set(traj.segments[0].sliding) if traj.segments else set()
    for event in traj.events:  # an event's mode_after says which of its contacts slide
        sliding_before, sliding = sliding, set(event.sliding)
        if event.kind != EventKind.TOUCHDOWN or len(event.contacts) < 2:
            continue
        if sliding_before & set(event.mode_before):  # order_gap takes sticking modes
            skipped += 1
            continue
        for pair in itertools.combinations(event.contacts, 2):
            if wanted is None or set(pair) == set(wanted):
                gaps.append(order_gap(scene, event.q, event.v_minus, pair, mode=event.mode_before, t=event.t))
    out["order_gap_events"] = len(gaps)
    out["order_gap_skipped"] = skipped
    worst = max(gaps, key=lambda g: g.outcome, default=None)
    out["order_gap_outcome"] = None if worst is None else worst.outcome
    out["order_gap_saltation"] = max((g.saltation for g in gaps), default=None)
    out["order_gap_saltation_spread"] = max((g.saltation_spread for g in gaps), default=None)
    out["order_gap_t"] = None if worst is None else worst.t
    out["order_gap_pair"] = None if worst is None else ",".join(worst.contacts)
    return out


def _stride(scene: Scene, t_final, options: dict, settings: dict) -> dict:
    from ..analysis.gait import find_periodic_gait

    settings = dict(settings)
    foot = settings.pop("foot", None) or (scene.contact_names[0] if scene.contact_names else None)
    if foot is None:
        raise InvalidInputError(f"stride job: scene {scene.name!r} has no contacts")
    settings["iterations"] = int(settings.get("iterations", 0))
    gait = find_periodic_gait(scene, foot, **settings, **options)
    moduli = [abs(m) for m in gait.multipliers]
    return {
        "foot": foot,
        "stride_time": gait.stride.stride_time,
        "residual": gait.residuals[-1],
        "converged": gait.converged,
        "iterations": len(gait.steps) - 1,
        "multipliers": [[float(m.real), float(m.imag)] for m in gait.multipliers],
        "multiplier_moduli": moduli,
        "max_multiplier": max(moduli, default=None),
        "differentiable": gait.stride.differentiable,
    }


_BUILT_IN = {
    JobKind.SIMULATE: _simulate,
    JobKind.JACOBIAN: _jacobian,
    JobKind.ORDER_GAP: _order_gap,
    JobKind.STRIDE: _stride,
}

__all__ = ["Job", "JobKind", "JOB_OPTIONS", "DEFAULT_OUTPUT", "trajectory_outputs"]
