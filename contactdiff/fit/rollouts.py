"""Plain rollouts of recordings (no derivatives): held-out evaluation of fitted parameters.

`rollouts` runs a scene from each recording's start, at given parameter
values, and keeps the simulated configurations at the recording's compared
samples, the events and the run's wall time, on the sweep engine's workers
like `contactdiff.fit.fit`. A run that fails is kept as a `Rollout` with its
error (and the samples it reached), never raised: an evaluation over hundreds
of recordings reports its failures.
"""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import ContactDiffError, StoppedRunError
from ..integration.hybrid import simulate
from .recordings import Recording


@dataclass(frozen=True, eq=False)
class Rollout:
    """One recording's plain run.

    Attributes:
        name: the recording's name.
        q: simulated configurations at the compared samples reached (k' × nq, k' <= k).
        events: events of the run, counted by kind.
        nonsmooth: flagged events' reasons before the last sample, counted (`NonSmooth` names).
        wall: wall time of the run (s).
        error: the run's error (``Type: message``), or None.
    """

    name: str
    q: np.ndarray
    events: dict
    nonsmooth: dict
    wall: float
    error: str | None = None

    @property
    def complete(self) -> bool:
        """The run reached every compared sample without error."""
        return self.error is None


def rollout(scene, recording: Recording, values: Mapping | None = None, options: Mapping | None = None) -> Rollout:
    """Run ``scene`` (with parameter ``values``) from ``recording``'s start to its last sample."""
    variant = scene.with_parameters(dict(values)) if values else scene
    k = recording.compared
    started = time.perf_counter()
    try:
        traj = simulate(
            variant.with_state(recording.q0, recording.v0),
            float(recording.t[-1]),
            t0=float(recording.t0),
            sample_times=recording.t[k],
            **dict(options or {}),
        )
        error = None
    except StoppedRunError as exc:
        traj, error = exc.trajectory, f"{type(exc).__name__}: {exc}"
    except (ContactDiffError, ValueError, np.linalg.LinAlgError) as exc:
        # ValueError, LinAlgError: a defect of the integrator on this run (reported as the run's
        # failure with its type, so that an evaluation of many recordings lists it and goes on)
        return Rollout(
            recording.name,
            np.zeros((0, len(recording.q0))),
            {},
            {},
            time.perf_counter() - started,
            f"{type(exc).__name__}: {exc}",
        )
    wall = time.perf_counter() - started
    samples = traj.samples
    q = samples.q if samples is not None else np.zeros((0, len(recording.q0)))
    last = recording.t[-1]
    return Rollout(
        recording.name,
        q,
        dict(Counter(e.kind for e in traj.events)),
        dict(Counter(r.name for e in traj.events if e.t <= last for r in e.nonsmooth)),
        wall,
        error,
    )


def _in_worker(source, recording: Recording, values, options) -> Rollout:
    return rollout(source.build(), recording, values, options)


def rollouts(
    scene,
    recordings: Sequence[Recording],
    values: Mapping | None = None,
    *,
    jobs: int = 1,
    backend: str = "loky",
    options: Mapping | None = None,
    progress: bool | None = None,
) -> list[Rollout]:
    """`rollout` of every recording, in order; ``scene`` as `contactdiff.fit.fit` takes it
    (a `Scene` with ``jobs=1``, else a source the workers rebuild)."""
    from ..sweeps.runner import _progress_bar
    from .problem import _Workers

    workers = _Workers(scene, jobs, backend, progress)
    out: list[Rollout | None] = [None] * len(recordings)
    with _progress_bar(len(recordings), "rollouts", progress) as bar:
        if workers.engine is None:
            for i, rec in enumerate(recordings):
                out[i] = rollout(workers.scene, rec, values, options)
                bar.update(1)
        else:
            tasks = [(i, (workers.source, rec, values, options)) for i, rec in enumerate(recordings)]
            with workers.engine.session() as run:
                for i, r in run(_indexed, tasks):
                    out[i] = r
                    bar.update(1)
    rollouts = [r for r in out if r is not None]
    assert len(rollouts) == len(recordings)  # every recording has its rollout
    return rollouts


def _indexed(i: int, task: tuple) -> tuple[int, Rollout]:
    return i, _in_worker(*task)


__all__ = ["Rollout", "rollout", "rollouts"]
