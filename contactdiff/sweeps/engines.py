"""Where a sweep's points run: local processes, a Dask cluster or Ray, all through joblib.

Every engine is a joblib backend; the sweep's code is the same ``Parallel``
call on each (`Engine.session`):

* ``loky`` (default): local worker processes, no server (joblib's process
  backend). One worker runs the points in this process. Workers are limited
  to one BLAS thread each (the simulations' matrices are small; threads would
  only compete for the cores), and are kept between sweeps of one session.
* ``dask``: the workers of a Dask cluster, through ``parallel_config(backend="dask")``
  and a ``distributed.Client``: the scheduler at ``scheduler`` (an address
  such as ``tcp://10.0.0.1:8786``), or a local cluster of ``n_jobs`` one-thread
  worker processes started for the sweep. Needs ``contactdiff[dask]``.
* ``ray``: Ray's joblib backend (``ray.util.joblib.register_ray``): the Ray
  cluster at ``scheduler`` (``ray.init(address=...)``, e.g. ``auto``), or a
  local one started for the sweep. Needs ``contactdiff[ray]``. Ray's backend
  returns whole lists, so rows arrive chunk by chunk (`RAY_CHUNK`).

Workers must import contactdiff (and a user job's module): on a cluster, the
same environment on every node, and a scene file at the same path.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from enum import StrEnum

from ..errors import InvalidInputError, check_count, require_extra, unknown_name

CONNECT_TIMEOUT = 10.0
"""Seconds a sweep waits for a Dask scheduler or a Ray cluster to answer."""


RAY_CHUNK = 4
"""Ray's joblib backend returns a whole list at once: a sweep on Ray submits its points in
chunks of this many per worker and writes each chunk's rows when it is done."""


class Backend(StrEnum):
    """The engines (module docstring)."""

    LOKY = "loky"
    DASK = "dask"
    RAY = "ray"


_EXTRAS = {Backend.DASK: ("distributed", "dask"), Backend.RAY: ("ray", "ray")}


@dataclass(frozen=True)
class Engine:
    """A backend, how many workers, and a cluster's address.

    Attributes:
        backend: the `Backend`.
        n_jobs: worker processes (local engines); None: one per core. Ignored with a
            ``scheduler`` (the cluster has its own workers).
        scheduler: a Dask scheduler's or Ray cluster's address; None starts a local one.
    """

    backend: Backend
    n_jobs: int | None = None
    scheduler: str | None = None

    @classmethod
    def of(cls, backend: str = "loky", n_jobs: int | None = None, scheduler: str | None = None) -> Engine:
        """Check and build an engine.

        Raises:
            UnknownNameError: an unknown backend (the valid ones are listed).
            InvalidInputError: ``n_jobs`` < 1, or a scheduler for the local backend.
            MissingExtraError: the backend's package is missing (with the extra that installs it).
        """
        if backend not in tuple(Backend):
            raise unknown_name("backend", backend, list(Backend))
        backend = Backend(backend)
        if n_jobs is not None and n_jobs != -1:
            n_jobs = check_count("sweep", "n_jobs (workers)", n_jobs, minimum=1)
        if scheduler is not None and backend is Backend.LOKY:
            raise InvalidInputError(
                f"sweep: a scheduler ({scheduler!r}) applies to the dask and ray backends; loky runs local processes"
            )
        if backend in _EXTRAS:
            module, extra = _EXTRAS[backend]
            require_extra(module, extra, f"backend {backend.value!r}")
        return cls(backend, None if n_jobs == -1 else n_jobs, scheduler)

    @property
    def workers(self) -> int:
        """Local worker processes: ``n_jobs``, or one per core."""
        from joblib import cpu_count

        return self.n_jobs or cpu_count()

    @contextlib.contextmanager
    def session(self) -> Iterator[Callable[[Callable, Iterable[tuple]], Iterator]]:
        """Start the engine; yield ``run(function, argument_tuples)``, an iterator over
        the results in the order they finish. A cluster started here is stopped on exit.

        Raises:
            InvalidInputError: the scheduler or cluster does not answer (address and reason given).
        """
        from joblib import Parallel, delayed, parallel_config

        def run(function, tasks):
            if self.backend is not Backend.RAY:
                return Parallel(return_as="generator_unordered")(delayed(function)(*t) for t in tasks)
            return _chunked(Parallel(), function, list(tasks), RAY_CHUNK * self.workers)

        if self.backend is Backend.LOKY:
            with parallel_config(backend="loky", n_jobs=self.workers, inner_max_num_threads=1):
                yield run
        elif self.backend is Backend.DASK:
            with _dask_client(self) as client, parallel_config(backend="dask", n_jobs=-1, client=client):
                yield run
        else:
            with _ray_cluster(self), parallel_config(backend="ray", n_jobs=-1 if self.scheduler else self.workers):
                yield run


def _chunked(parallel, function, tasks: list, size: int) -> Iterator:
    """Results chunk by chunk, for a backend that returns lists only (Ray's)."""
    from joblib import delayed

    for start in range(0, len(tasks), size):
        yield from parallel(delayed(function)(*t) for t in tasks[start : start + size])


@contextlib.contextmanager
def _dask_client(engine: Engine):
    from distributed import Client, LocalCluster

    if engine.scheduler is None:
        with (
            LocalCluster(
                n_workers=engine.workers, threads_per_worker=1, processes=True, dashboard_address=None
            ) as cluster,
            Client(cluster) as client,
        ):
            yield client
        return
    try:
        client = Client(engine.scheduler, timeout=CONNECT_TIMEOUT)
    except (OSError, TimeoutError, ValueError, TypeError) as exc:
        raise InvalidInputError(
            f"sweep: no Dask scheduler answers at {engine.scheduler!r} within "
            f"{CONNECT_TIMEOUT:g} s ({type(exc).__name__}: {exc}); start one with "
            "'dask scheduler', or leave out the scheduler for a local cluster"
        ) from None
    with client:
        yield client


@contextlib.contextmanager
def _ray_cluster(engine: Engine):
    import ray
    from ray.util.joblib import register_ray

    register_ray()
    started = not ray.is_initialized()
    if started:
        try:
            if engine.scheduler is None:
                ray.init(num_cpus=engine.workers, include_dashboard=False, log_to_driver=False)
            else:
                ray.init(address=engine.scheduler, log_to_driver=False)
        except (ConnectionError, RuntimeError, ValueError) as exc:
            raise InvalidInputError(
                f"sweep: cannot reach the Ray cluster at {engine.scheduler!r} ({type(exc).__name__}: {exc})"
            ) from None
    try:
        yield
    finally:
        if started:
            ray.shutdown()


__all__ = ["Backend", "Engine", "CONNECT_TIMEOUT"]
