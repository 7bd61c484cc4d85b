"""When a contact stands in a run, on the scale of a gait (a foot's stances, its flights)."""

from __future__ import annotations

from ...integration.trajectory import Trajectory


def stance_intervals(traj: Trajectory, contact: str, min_duration: float = 2e-3) -> list[tuple[float, float]]:
    """Time intervals (s) during which ``contact`` is active in ``traj``, on the scale of
    a gait: flights shorter than ``min_duration`` (a stance foot nudged off the ground
    by another foot's impact, back within microseconds) are closed, and stances
    shorter than it are dropped.

    Args:
        traj: a `Trajectory`.
        contact: contact name.
        min_duration: shortest flight or stance kept (s), >= 0.
    """
    raw: list[list[float]] = []
    for segment in traj.segments:
        if contact in segment.mode and segment.t1 > segment.t0:
            if raw and segment.t0 - raw[-1][1] <= min_duration:
                raw[-1][1] = segment.t1
            else:
                raw.append([segment.t0, segment.t1])
    return [(a, b) for a, b in raw if b - a >= min_duration or b >= traj.t]


__all__ = ["stance_intervals"]
