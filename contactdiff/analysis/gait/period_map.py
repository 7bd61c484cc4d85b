"""The stroboscopic period map of a clock-driven scene (`period_map`, `PeriodMap`):
the state one clock period later, its flow Jacobian and multipliers, which
cross-check those of a periodic gait (`contactdiff.analysis.gait.periodic`)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ...errors import InvalidInputError, check_number
from ...integration.hybrid import simulate
from ...integration.trajectory import Trajectory
from ...model.scene import Scene
from .section import _check_neutral, _resolve_period, _sorted_eigenvalues, neutral_directions
from .stride import STRIDE_ATOL, STRIDE_RTOL


@dataclass(kw_only=True)
class PeriodMap:
    """The stroboscopic map ``x(t0) -> x(t0 + period)`` of a clock-driven scene.

    Attributes:
        t0, q0, v0, t, q, v: start and end.
        jacobian: the flow Jacobian over one period (2nv × 2nv, tangent space).
        multipliers: eigenvalues of ``Bᵀ J B`` with ``B`` orthonormal to the neutral
            moves, by decreasing modulus (the map of an autonomous scene has one
            more multiplier 1, along the flow).
        trajectory: the run.
    """

    t0: float
    q0: np.ndarray
    v0: np.ndarray
    t: float
    q: np.ndarray
    v: np.ndarray
    jacobian: np.ndarray
    multipliers: np.ndarray
    trajectory: Trajectory = field(repr=False)


def period_map(
    scene: Scene,
    q: ArrayLike | None = None,
    v: ArrayLike | None = None,
    t: float = 0.0,
    *,
    period: float | None = None,
    neutral: Sequence[str] | None = None,
    rtol: float = STRIDE_RTOL,
    atol: float = STRIDE_ATOL,
    **options: Any,
) -> PeriodMap:
    """The state after one clock period and its Jacobian (the stroboscopic Poincaré map).

    Args:
        scene: the `Scene`.
        q: start configuration (nq,); default the scene's initial one.
        v: start velocity (nv,), tangent space; default the scene's.
        t: start time (s).
        period: the period (s); default the scene's clock period (`scene_period`).
        neutral: neutral moves removed from the multipliers (default `available_neutral`).
        rtol: relative tolerance of the simulation.
        atol: absolute tolerance (m, rad, m/s).
        **options: further fields of `SimulateOptions`.
    """
    clock = _resolve_period(scene, period)
    if clock is None:
        raise InvalidInputError(f"scene {scene.name!r} has no clock-driven effort; pass period= (s)")
    q = scene.q0 if q is None else np.array(q, dtype=float)
    v = scene.v0 if v is None else np.array(v, dtype=float)
    t = check_number("period map", "t", t)
    traj = simulate(scene, t + clock, q, v, t0=t, jacobian=True, rtol=rtol, atol=atol, **options)
    assert traj.jacobian is not None  # asked for
    neutral = _check_neutral(scene, neutral, q, v, t)
    N = neutral_directions(scene, q, neutral)
    if N.shape[1]:
        _, s, vt = np.linalg.svd(N.T)
        B = vt[int(np.sum(s > 1e-10)) :].T
    else:
        B = np.eye(2 * scene.nv)
    return PeriodMap(
        t0=t,
        q0=traj.q0,
        v0=traj.v0,
        t=traj.t,
        q=traj.q,
        v=traj.v,
        jacobian=traj.jacobian,
        multipliers=_sorted_eigenvalues(B.T @ traj.jacobian @ B),
        trajectory=traj,
    )
