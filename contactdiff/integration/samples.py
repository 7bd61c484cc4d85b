"""The state of a run at given times, with its flow Jacobian there, from the same run.

``simulate(scene, T, sample_times=ts, jacobian=True, parameters=[...])`` records, at
every time of ``ts``, the state and the flow Jacobian (d x(t_k) / d x0 and d x(t_k) / d p,
tangent space, as `Trajectory.jacobian`) on ``traj.samples``, a `Samples`.

How. The hybrid loop ends a step exactly on every sample time (as on an effort's
breakpoint: the stepper's ``t_bound``), so each sample is a point the stepper
accepted, with the state and the flow Jacobian it carries there: on vector spaces the
Jacobian is the exact derivative of the discrete flow that produced the sampled state,
on Lie groups its local error is controlled with the state's. Nothing is interpolated
(the dense output carries no Jacobian, and an interpolant's derivative would not be
the derivative of the interpolated state). A sample costs at most one step more
(the step cut short at it; the error control keeps the step it wanted for the next).
The steps differ from a run without samples, so its final state and Jacobian agree
with that run's to the integration tolerance, not to the last bit.

At an event. A sample time at which an event is located takes the state after the
event's reset (the right limit, as `Trajectory.at`'s default) and the flow Jacobian
after its saltation. Event times are located by root finding: a sample within
round-off of an event lies on the side the located time puts it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InvalidInputError


@dataclass(kw_only=True, eq=False)  # arrays: no element-wise ==
class Samples:
    """A run's state at its sample times (`SimulateOptions.sample_times`).

    Attributes:
        t: sample times (k,), s, non-decreasing.
        q: configurations (k, nq).
        v: velocities (k, nv), tangent space (joints' local frames).
        jacobian: with ``jacobian=True``, d x(t_k) / d x0 (k, 2nv, 2nv), tangent space
            (rows ``(δq, δv)`` at t_k with ``q ⊕ δq``; columns the same at t0); else None.
        parameter_jacobian: with ``parameters``, d x(t_k) / d p (k, 2nv, p), columns in
            the order of ``parameter_names``; else None.
        parameter_names: the parameters' names.

    A run that ends before its last sample time (a terminal event, or an error's
    ``.trajectory``) holds only the samples it reached: ``len(t)`` says how many.
    """

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    jacobian: np.ndarray | None = None
    parameter_jacobian: np.ndarray | None = None
    parameter_names: tuple[str, ...] = ()

    def __len__(self) -> int:
        return len(self.t)


def check_sample_times(times, t0: float, t_final: float) -> None:
    """Refuse sample times outside ``[t0, t_final]`` (s), naming the first such one."""
    for k, t in enumerate(times):
        if not t0 <= t <= t_final:
            raise InvalidInputError(
                f"simulate: sample_times[{k}] = {t!r} s is outside the run's [t0, t_final] = [{t0!r}, {t_final!r}] s"
            )


class SampleRecorder:
    """Collects the samples of one run as the hybrid loop reaches their times.

    Args:
        times: the sample times (s), non-decreasing, within the run (`check_sample_times`).
        n_state: the flow Jacobian's state columns (2nv with ``jacobian``, else 0).
        parameter_names: the parameters whose columns follow the state's.
    """

    def __init__(self, times, n_state: int, parameter_names: tuple[str, ...]):
        self.times = tuple(times)
        self.n_state, self.parameter_names = n_state, tuple(parameter_names)
        self._k = 0  # the next sample to take
        self._q: list[np.ndarray] = []
        self._v: list[np.ndarray] = []
        self._phi: list[np.ndarray] = []

    @property
    def next_time(self) -> float:
        """The next sample time (s); inf when every sample is taken."""
        return self.times[self._k] if self._k < len(self.times) else np.inf

    def take(self, stepper) -> None:
        """Record every pending sample at the stepper's current time (its state and ``phi``).

        The loop ends steps on sample times (the stepper's ``t_bound``), so a pending sample
        is never passed over; one that were would be a broken loop, not bad input."""
        while self._k < len(self.times) and self.times[self._k] <= stepper.t:
            if self.times[self._k] != stepper.t:
                raise AssertionError(f"sample time {self.times[self._k]!r} s passed over by a step to {stepper.t!r} s")
            self._q.append(np.array(stepper.q, dtype=float))
            self._v.append(np.array(stepper.v, dtype=float))
            if stepper.phi is not None:
                self._phi.append(np.array(stepper.phi, dtype=float))
            self._k += 1

    def samples(self, nq: int, nv: int) -> Samples | None:
        """The samples taken so far (None if no sample times were asked for)."""
        if not self.times:
            return None
        k, p = self._k, len(self.parameter_names)
        phi = np.array(self._phi).reshape(k, 2 * nv, self.n_state + p)
        return Samples(
            t=np.array(self.times[:k], dtype=float),
            q=np.array(self._q).reshape(k, nq),
            v=np.array(self._v).reshape(k, nv),
            jacobian=phi[:, :, : self.n_state].copy() if self.n_state else None,
            parameter_jacobian=phi[:, :, self.n_state :].copy() if p else None,
            parameter_names=self.parameter_names,
        )
