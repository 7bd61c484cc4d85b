"""What a fit compares against: a measured trajectory and the state its rollout starts from.

A `Recording` is one trajectory of measured configurations of a scene, at its
sample times, with the simulated rollout's start (time, configuration and
velocity); `contactdiff.fit.fit` runs the scene from that start and compares
the simulated configuration with the measured one at every sample from the
start on (`contactdiff.fit.residuals`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InvalidInputError


@dataclass(frozen=True, eq=False)  # arrays: no element-wise ==
class Recording:
    """One measured trajectory and where its rollout starts.

    Attributes:
        name: the trajectory's name (in reports and errors).
        t: sample times (k,), s, increasing.
        q: measured configurations (k, nq), the scene's convention (a free body:
            ``[x y z qx qy qz qw]``, position in m in the world frame).
        t0: the rollout's start time (s), at or before ``t[-1]``; samples before
            ``t0`` are not compared.
        q0, v0: the rollout's initial configuration (nq,) and velocity (nv,, tangent
            space, Pinocchio's convention).
        weights: a weight per sample (k,), >= 0, multiplying that sample's residual
            rows; None: 1 for every sample.
        mask: (nv,) bool, the tangent coordinates that were measured (residual rows of the
            others are zero); None: all of them.
    """

    name: str
    t: np.ndarray
    q: np.ndarray
    t0: float
    q0: np.ndarray
    v0: np.ndarray
    weights: np.ndarray | None = None
    mask: np.ndarray | None = None

    @classmethod
    def from_observations(cls, observations, *, start: int = 0, v0=None, name: str | None = None) -> Recording:
        """The recording of `contactdiff.fit.Observations` whose rollout starts at sample ``start``:
        its measured configuration, and ``v0`` (nv,) if given, else the measured velocity when
        every coordinate's was measured, else zero (fit it: ``state="velocity"``).

        Raises:
            InvalidInputError: ``start`` outside the samples, or ``v0`` not nv numbers.
        """
        k = len(observations.t)
        if not (isinstance(start, int) and -k <= start < k):
            raise InvalidInputError(f"recording: start must be a sample index in [0, {k}), got {start!r}")
        nv = len(observations.mask)
        if v0 is None:
            measured = observations.v is not None and bool(np.all(observations.v_mask))
            v0 = observations.v[start] if measured else np.zeros(nv)
        v0 = np.asarray(v0, dtype=float)
        if v0.shape != (nv,):
            raise InvalidInputError(f"recording: v0 must hold {nv} velocities, got shape {v0.shape}")
        return cls(
            name or observations.source or "observations",
            observations.t,
            observations.q,
            float(observations.t[start]),
            observations.q[start],
            v0,
            observations.weights,
            np.asarray(observations.mask, dtype=bool),
        )

    def __post_init__(self):
        t = np.asarray(self.t, dtype=float)
        q = np.asarray(self.q, dtype=float)
        label = f"recording {self.name!r}"
        if t.ndim != 1 or len(t) < 2 or q.ndim != 2 or len(q) != len(t):
            raise InvalidInputError(
                f"{label}: needs k >= 2 sample times and a (k, nq) array of configurations, "
                f"got t {t.shape} and q {q.shape}"
            )
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(q))):
            raise InvalidInputError(f"{label}: non-finite sample times or configurations")
        if np.any(np.diff(t) <= 0.0):
            raise InvalidInputError(f"{label}: sample times must increase")
        if not (np.isfinite(self.t0) and self.t0 <= t[-1]):
            raise InvalidInputError(
                f"{label}: the start t0 = {self.t0!r} s must be a time at or before the last sample ({t[-1]} s)"
            )
        if self.weights is not None:
            w = np.asarray(self.weights, dtype=float)
            if w.shape != t.shape or not np.all(np.isfinite(w)) or np.any(w < 0.0):
                raise InvalidInputError(f"{label}: weights must be {len(t)} finite numbers >= 0")
            object.__setattr__(self, "weights", w)
        if self.mask is not None:
            object.__setattr__(self, "mask", np.asarray(self.mask, dtype=bool))
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "q", q)
        object.__setattr__(self, "q0", np.asarray(self.q0, dtype=float))
        object.__setattr__(self, "v0", np.asarray(self.v0, dtype=float))

    @property
    def compared(self) -> np.ndarray:
        """Indices of the samples the fit compares: those at or after ``t0``."""
        return np.flatnonzero(self.t >= self.t0)

    def sample_weights(self) -> np.ndarray:
        """The compared samples' weights (ones without ``weights``)."""
        k = self.compared
        return np.ones(len(k)) if self.weights is None else self.weights[k]


__all__ = ["Recording"]
