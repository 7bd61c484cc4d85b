"""`sweep`: one scene over many points, one row per point, on any engine.

The sweep checks everything it can before the first run (the scene loads,
every swept name means something, values are numbers where they must be, the
run settings, the backend, the results file); then sends each worker
``(context, index, values)`` (`run_point`): the scene's source, never the
scene. A worker rebuilds the scene once (`SceneSource.build`), derives the
point's variant (`contactdiff.sweeps.quantities.apply`), runs the job and
returns the row, or the run's error: a failed point does not stop the sweep.
Rows are appended to the results file as they arrive and returned in the
order of the points.
"""

from __future__ import annotations

import hashlib
import json
import re
import sys
import time
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from ..errors import ContactDiffError, InvalidInputError, ModelLoadError, check_number, write_failed
from ..integration.options import SimulateOptions, field_names
from . import quantities as Q
from .engines import Engine
from .files import Damage, ResultsFile
from .jobs import Job
from .points import PointSet, as_points, key
from .rows import RESERVED, Row, RunError, SweepResult
from .sources import SceneSource

if TYPE_CHECKING:
    from ..model.scene import Scene

JOB_OWNED = ("jacobian", "parameters", "dense", "progress")
"""`SimulateOptions` fields the job sets, not the sweep's options."""

IDENTITY = re.compile(r"[0-9a-f]{16}")
"""The form of a sweep's identity (`_context`): 16 hexadecimal digits."""


class DamagedRowsWarning(UserWarning):
    """A results file holds damaged lines among good rows: they are left out and removed
    from the file, and their points run again."""


@dataclass(frozen=True)
class Context:
    """What every point of a sweep shares (sent to the workers with each point).

    Attributes:
        source: where the scene comes from.
        quantities: the swept quantities, in the points' column order.
        job: the job.
        t_final: final time (s) unless swept.
        options: `SimulateOptions` fields fixed for every point.
        sweep: the sweep's identity (`identity`).
    """

    source: SceneSource
    quantities: tuple[Q.Quantity, ...]
    job: Job
    t_final: float | None
    options: dict
    sweep: str


def run_point(context: Context, index: int, values: tuple) -> Row:
    """Run one point (in a worker): its scene, its job, its row; an error is recorded
    in the row, not raised."""
    point = dict(zip((q.name for q in context.quantities), values))
    started = time.perf_counter()
    try:
        by_kind = Q.split(context.quantities, values)
        scene = Q.apply(context.source.build(by_kind[Q.QuantityKind.SCENE_ARG]), by_kind)
        swept = Q.run_options(by_kind[Q.QuantityKind.OPTION])
        t_final = swept.pop("t_final", context.t_final)
        options = {**context.options, **swept}
        given = {**({"t_final": t_final} if t_final is not None else {}), **options, **point}
        outputs = context.job.run(scene, given, t_final, options, by_kind[Q.QuantityKind.JOB_ARG])
        clash = sorted(set(outputs) & (set(RESERVED) | set(point)))
        if clash:
            raise InvalidInputError(
                f"job {context.job.label} returned outputs named like the row's own columns: " + ", ".join(clash)
            )
        error = None
    except Exception as exc:  # every failure of a run is the row's, and the sweep goes on
        outputs, error = {}, RunError.of(exc)
    return Row(index, point, outputs, time.perf_counter() - started, error, context.sweep)


def sweep(
    scene: str | Path | Callable[..., Scene],
    points: PointSet | Mapping | Sequence[Mapping],
    job="simulate",
    *,
    t_final: float | None = None,
    options: SimulateOptions | Mapping | None = None,
    job_options: Mapping | None = None,
    fixed: Mapping | None = None,
    backend: str = "loky",
    n_jobs: int | None = None,
    scheduler: str | None = None,
    out: str | Path | None = None,
    retry_failed: bool = False,
    progress: bool | None = None,
) -> SweepResult:
    """Run ``job`` on ``scene`` at every point; one row per point.

    Args:
        scene: a scene name or TOML path, a robot name (its feet get ground contacts),
            ``"module:function"`` or a callable that returns a `Scene` (its keyword
            arguments are swept as ``arg:<name>``). Not a `Scene` object: workers
            rebuild the scene, Pinocchio objects do not pickle.
        points: a `PointSet` (`grid`, `point_list`, `random_points`), a mapping
            ``{name: values or "lo:hi:n"}`` (a grid) or a list of mappings. Names are
            quantities (`contactdiff.sweeps.quantities`).
        job: ``"simulate"`` (default), ``"jacobian"``, ``"order-gap"``, ``"stride"``
            (`contactdiff.sweeps.jobs`), ``"module:function"`` or a callable
            ``f(scene, point) -> dict``.
        t_final: final time (s) of every run, unless swept (required by the
            simulate, jacobian and order-gap jobs).
        options: `SimulateOptions` (or a mapping of its fields) for every run.
        job_options: the job's own options (`contactdiff.sweeps.jobs.JOB_OPTIONS`).
        fixed: quantities with one value for every point (``{name: value}``); they
            are columns of the rows like the swept ones.
        backend: ``"loky"`` (local processes, default), ``"dask"`` or ``"ray"``
            (`contactdiff.sweeps.engines`).
        n_jobs: worker processes (default: one per core; 1 runs in this process).
        scheduler: a Dask scheduler's or Ray cluster's address (default: a local one).
        out: a results file (``.jsonl`` or ``.csv``) the rows are appended to as
            runs finish; points whose rows it already holds (from the same sweep)
            are not run again but read back.
        retry_failed: run again the points whose row in ``out`` is an error.
        progress: draw a progress bar with the time left on stderr (default: when
            stderr is a terminal).

    Returns:
        The `SweepResult`: the rows in the order of the points.

    Raises:
        UnknownNameError: an unknown quantity, job, job option or backend (the valid ones listed).
        InvalidInputError: an empty range, a bad value, a missing ``t_final``, a
            results file of another sweep, an unreachable scheduler, a backend not installed.
        OutputFileError: ``out`` cannot be written (checked before the first run); or it
            failed during the sweep: every point still runs, and ``.result`` holds the
            `SweepResult`.
        ModelLoadError: ``out`` holds damaged lines and no row of this sweep (damaged
            lines among good rows are a `DamagedRowsWarning`: their points run again).
    """
    started = time.perf_counter()
    source = SceneSource.of(scene)
    points = as_points(points).with_fixed(fixed or {})
    job = Job.of(job, job_options)
    engine = Engine.of(backend, n_jobs, scheduler)
    settings = _options(options)
    if t_final is not None:
        t_final = check_number("sweep", "t_final", t_final)
    context = _context(source, points, job, t_final, settings)
    results = ResultsFile(out) if out is not None else None
    done, damaged = _done(results, points, context, retry_failed) if results is not None else ({}, [])
    todo = [(context, i, values) for i, values in enumerate(points.values) if key(values) not in done]
    rows = {
        i: Row.from_dict({**done[key(values)], "index": i}, points.names)
        for i, values in enumerate(points.values)
        if key(values) in done
    }
    lost = None  # the results file's failed write: the sweep runs on, the rows are returned in the error
    if results is not None and (todo or damaged):
        lost = _write(lambda: results.start(d.line for d in damaged))
    if todo:
        with engine.session() as run, _progress_bar(len(todo), source.label, progress) as bar:
            for row in run(run_point, todo):
                rows[row.index] = row
                if results is not None and lost is None:
                    lost = _write(lambda: results.append(row.to_dict()))
                bar.update(1)
    result = SweepResult(
        [rows[i] for i in range(len(points))],
        points.names,
        skipped=len(points) - len(todo),
        wall_time=time.perf_counter() - started,
        default_output=job.default_output(),
    )
    if lost is not None:
        assert results is not None  # only a write to it is lost
        raise write_failed("--out", results.path, lost, result)
    return result


def _write(write) -> OSError | None:
    """Call ``write()`` (of the results file); its OSError returned: the file is no longer written."""
    try:
        write()
    except OSError as exc:
        return exc
    return None


def _options(options) -> dict:
    """The fixed run options as `SimulateOptions` fields (validated once, here)."""
    if options is None:
        return {}
    if isinstance(options, SimulateOptions):
        options = {f: getattr(options, f) for f in field_names() if f not in JOB_OWNED}
    if not isinstance(options, Mapping):
        raise InvalidInputError(f"sweep: options must be SimulateOptions or a mapping of its fields, got {options!r}")
    SimulateOptions().replace(**options)  # unknown names and bad values raise here, before any run
    for name in JOB_OWNED:
        if name in options:
            raise InvalidInputError(
                f"sweep: option {name!r} is the job's to set (jobs: simulate, jacobian with "
                "job_options={'parameters': [...]}, ...)"
            )
    return dict(options)


def _context(source: SceneSource, points: PointSet, job: Job, t_final, options: dict) -> Context:
    """Check the sweep in this process (scene, names, values, settings) and describe it."""
    source.check_arguments(points.names)
    arguments = {n[4:]: v for n, v in points[0].items() if n.startswith("arg:")}
    scene: Scene | Callable[[], Scene]
    if source.factory is None:
        scene = source.build()  # a name or file: loading it here checks it (cheap), and one worker uses it
    else:

        def scene() -> Scene:  # a factory may be expensive (a trot simulated): built here only if a name needs it
            try:
                return source.build(arguments)
            except ContactDiffError:
                raise
            except Exception as exc:  # the factory's own failure, named with its arguments
                raise InvalidInputError(
                    f"sweep: scene factory {source.label} failed with arguments {arguments} "
                    f"({type(exc).__name__}: {exc})"
                ) from None

    quantities = Q.resolve(points.names, scene, source.argument_names(), job.argument_names)
    Q.check_values(quantities, points.values)
    swept_t = "t_final" in points.names
    if job.needs_t_final and t_final is None and not swept_t:
        raise InvalidInputError(f"sweep: job {job.label!r} runs to a final time: give t_final (s), or sweep it")
    if not job.needs_t_final and job.kind is not None and (t_final is not None or swept_t):
        raise InvalidInputError(f"sweep: job {job.label!r} has no final time; leave t_final out")
    identity = {
        "scene": source.label,
        "job": job.label,
        "job_options": job.options,
        "t_final": t_final,
        "options": options,
        "names": list(points.names),
    }
    text = json.dumps(identity, sort_keys=True, default=str)
    return Context(source, quantities, job, t_final, options, hashlib.sha256(text.encode()).hexdigest()[:16])


def _done(
    results: ResultsFile, points: PointSet, context: Context, retry_failed: bool
) -> tuple[dict[str, dict], list[Damage]]:
    """Rows of this sweep already in the results file, by point key (the last row of a point
    wins), and the file's damaged lines (warned about: their points run again).

    Raises:
        InvalidInputError: the file holds rows of another sweep.
        ModelLoadError: the file has damaged lines and no row of this sweep.
    """
    done = {}
    lines = results.lines()
    damaged = list(results.damaged)
    for n, row in lines:
        if row["sweep"] == context.sweep:
            done[key([row.get(nm) for nm in points.names])] = row
        elif IDENTITY.fullmatch(row["sweep"]):
            raise InvalidInputError(
                f"results file {str(results.path)!r} holds rows of another sweep (line {n}: scene, job, run settings "
                "or swept names differ); give another file, or delete this one"
            )
        else:
            damaged.append(Damage(n, f"its sweep {row['sweep']!r} is not a sweep's identity"))
    damaged.sort(key=lambda d: d.line)
    if damaged and not done:
        raise ModelLoadError(
            f"results file {str(results.path)!r} holds no row of this sweep, and {_listed(damaged)}; "
            "give another file, or delete this one"
        )
    if damaged:
        warnings.warn(
            f"results file {str(results.path)!r}: {_listed(damaged)}; left out: their points run again, "
            "and the damaged lines are removed from the file",
            DamagedRowsWarning,
            stacklevel=3,
        )
    if retry_failed:
        done = {k: row for k, row in done.items() if row.get("error") is None}
    return done, damaged


def _listed(damaged: list[Damage]) -> str:
    """The damaged lines as text: the first three with what is wrong, and how many more."""
    first = "; ".join(map(str, damaged[:3])) + (f"; and {len(damaged) - 3} more" if len(damaged) > 3 else "")
    return f"{len(damaged)} damaged line{'s' if len(damaged) > 1 else ''} ({first})"


class _NoBar:
    def update(self, n: int) -> None:
        pass


def _progress_bar(total: int, label: str, progress: bool | None):
    """A tqdm bar on stderr: runs done, elapsed and time left; None: only on a terminal."""
    import contextlib

    if progress is False:
        return contextlib.nullcontext(_NoBar())
    from tqdm import tqdm

    return tqdm(
        total=total,
        desc=f"sweep {Path(label).name}",
        unit="run",
        file=sys.stderr,
        disable=None if progress is None else False,
        dynamic_ncols=True,
        bar_format="{desc} {n_fmt}/{total_fmt} |{bar}| [{elapsed}<{remaining}]",
    )


__all__ = ["sweep", "run_point", "Context", "DamagedRowsWarning", "IDENTITY"]
