"""The frames of a run's replay: when they fall (a uniform grid and every event) and the
robot's configuration and closed contacts at each, read from the run's dense output.

The run is read through protocols (`ReplayedRun`, its events and segments): a
`contactdiff.integration.trajectory.Trajectory` is one, and its ``to_html`` calls
`contactdiff.replay.write_html`, which draws these frames.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from .errors import InvalidInputError


class ReplayedEvent(Protocol):
    """What a replay reads of an event (`contactdiff.integration.trajectory.Event`)."""

    @property
    def t(self) -> float:
        """Time (s)."""

    @property
    def kind(self) -> str:
        """The event's kind (a timeline mark's colour, `contactdiff.replay.EVENT_COLOURS`)."""

    @property
    def contacts(self) -> tuple[str, ...]:
        """Names of the contacts whose guard fired."""

    @property
    def q(self) -> np.ndarray:
        """Configuration at the event (nq,)."""


class ReplayedSegment(Protocol):
    """What a replay reads of a segment (`contactdiff.integration.trajectory.Segment`)."""

    @property
    def t0(self) -> float:
        """Start time (s)."""

    @property
    def mode(self) -> tuple[str, ...]:
        """Names of the active contacts (drawn closed)."""


class ReplayedRun(Protocol):
    """What a replay reads of a run (`contactdiff.integration.trajectory.Trajectory`,
    whose ``to_html`` calls `write_html`)."""

    @property
    def t0(self) -> float:
        """Initial time (s)."""

    @property
    def t(self) -> float:
        """Final time (s)."""

    @property
    def q0(self) -> np.ndarray:
        """Initial configuration (nq,)."""

    @property
    def dense(self) -> bool:
        """Whether the run kept its dense output (the states between events)."""

    @property
    def events(self) -> Sequence[ReplayedEvent]:
        """The events in time order."""

    @property
    def segments(self) -> Sequence[ReplayedSegment]:
        """The segments in time order."""

    def at(self, t: float, side: str = "right") -> tuple[np.ndarray, np.ndarray]:
        """The state ``(q, v)`` at time ``t`` (s) from the dense output."""


DEFAULT_FPS = 30.0
"""Frames per second of simulated time."""

MAX_FRAMES = 200_000
"""Refuse pages with more frames than this (a long run at a high ``fps``)."""

_EVENT_TOL = 1e-9  # s: a grid time this close to an event time is replaced by the event's


@dataclass(frozen=True)
class Frames:
    """The sampled animation.

    Attributes:
        times: frame times (s), increasing, from ``t0`` to ``t``.
        q: configurations (n, nq).
        modes: names of the closed contacts at each frame (right limit at events).
        event: True where the frame is an event time.
    """

    times: np.ndarray
    q: np.ndarray
    modes: list[tuple[str, ...]]
    event: np.ndarray


def frame_times(traj: ReplayedRun, fps: float = DEFAULT_FPS) -> tuple[np.ndarray, np.ndarray]:
    """Times of the frames (s) and whether each is an event time.

    A uniform grid ``t0 + k / fps`` up to ``traj.t`` (which is added if the grid
    misses it), merged with the event times; a grid time within 1e-9 s of an event
    is dropped for it.
    """
    fps = positive_option(fps, "fps", "frames per second")
    span = traj.t - traj.t0
    n = int(math.floor(span * fps + 1e-9)) + 1
    if n > MAX_FRAMES:
        raise InvalidInputError(
            f"replay: {span:g} s at fps = {fps:g} gives {n} frames, more than {MAX_FRAMES}; lower fps"
        )
    grid = traj.t0 + np.arange(n) / fps
    if traj.t - grid[-1] > _EVENT_TOL:
        grid = np.append(grid, traj.t)
    events = np.unique([e.t for e in traj.events if traj.t0 <= e.t <= traj.t])
    keep = np.array([not events.size or np.min(np.abs(events - t)) > _EVENT_TOL for t in grid], dtype=bool)
    times = np.concatenate([grid[keep], events])
    is_event = np.concatenate([np.zeros(keep.sum(), bool), np.ones(events.size, bool)])
    order = np.argsort(times, kind="stable")
    return times[order], is_event[order]


def sample_frames(traj: ReplayedRun, fps: float = DEFAULT_FPS) -> Frames:
    """The states and contact modes at the `frame_times` of ``traj`` (needs its dense output)."""
    if not traj.dense:
        raise InvalidInputError(
            "replay: this run kept no dense output, so the states between events are "
            "gone: simulate(..., dense=True) keeps them"
        )
    times, is_event = frame_times(traj, fps)
    by_time: dict[float, ReplayedEvent] = {}
    for e in traj.events:
        by_time.setdefault(e.t, e)  # the first event's q: q is continuous through a cascade
    starts = [s.t0 for s in traj.segments]
    qs, modes = [], []
    for t, at_event in zip(times, is_event):
        t = float(t)
        qs.append(by_time[t].q.copy() if at_event else traj.at(t)[0])
        i = bisect.bisect_right(starts, t) - 1  # the last segment starting at or before t
        modes.append(tuple(traj.segments[i].mode) if i >= 0 else ())
    return Frames(times, np.array(qs), modes, is_event)


def positive_option(value, name: str, unit: str = "m") -> float:
    """``value`` as a finite float > 0, else `InvalidInputError` naming it and its unit."""
    try:
        out = float(value)
    except (TypeError, ValueError):
        raise InvalidInputError(f"replay: {name} must be a number, got {value!r}") from None
    if not math.isfinite(out) or out <= 0:
        raise InvalidInputError(f"replay: {name} must be finite and > 0 ({unit}), got {value!r}")
    return out
