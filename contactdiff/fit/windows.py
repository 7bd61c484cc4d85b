"""Windowed residuals (multiple shooting): a long recording cut into short windows, each run from the data.

A whole recording through tens of impacts is a chaotic flow: its exact
Jacobian is the derivative of a map that folds over steps far smaller than
any useful change of a parameter, so a least-squares fit on whole recordings
does not move (docs/results/cube-fit.md). `cut` makes each window a short
`Recording` of its own: it starts at a measured sample ``k`` (the measured
configuration, and a velocity from the data) and compares the next
`Windows.length` samples. The windows share the scene's parameters and each
has its own initial-state offset when the fit is asked for one
(``state="velocity"``: the data's velocity is only an estimate), so
`contactdiff.fit.fit` on the windows is multiple shooting with the windows'
starts as (sparse) unknowns. A window's run is short enough that its flow
is differentiable more often, and its derivative describes the cost over a
useful step.

**Where windows start.** Evenly, every `Windows.stride` samples from sample
2 on, or at the sample indices the caller gives (`cut`'s ``starts``): a
window's run begins from a measured state, so it should start where the
model's state is consistent (for a body on a floor: in free flight, not
resting in the floor by the data's noise; `contactdiff.data.cube_recordings`
starts the cube's windows at the last free-flight sample before each touch).

**A window's start velocity** is, unless given, the backward second-order
difference of the measured configurations in the start's tangent space,
``v_k ≈ (d(k, k−2) − 4 d(k, k−1)) / (2 h)`` with ``d(k, j)`` Pinocchio's
``difference(q_k, q_j)`` and ``h`` the sample interval (exact for a constant
acceleration; it uses only samples up to ``k``, which are still in free
flight when ``k`` is the last sample before a touch). With measurement noise
σ it carries noise of about ``2.5 σ / h``: fit it (``state="velocity"``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ..errors import InvalidInputError
from .recordings import Recording

FIRST_START = 2
"""The first sample a window can start at: its velocity's difference needs the two samples before."""


@dataclass(frozen=True)
class Windows:
    """How `cut` windows a recording.

    Attributes:
        length: samples compared after each window's start (>= 1): the window covers
            ``t[k] .. t[k + length]`` (clipped to the recording's end).
        stride: samples between evenly spaced starts (>= 1; default ``length``:
            windows that meet end to start). Unused when `cut` is given the starts.
    """

    length: int
    stride: int | None = None

    def __post_init__(self):
        for name in ("length", "stride"):
            value = getattr(self, name)
            if name == "stride" and value is None:
                continue
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
                raise InvalidInputError(f"Windows: {name} must be a whole number of samples >= 1, got {value!r}")

    @property
    def step(self) -> int:
        """Samples between evenly spaced starts."""
        return int(self.stride if self.stride is not None else self.length)


def start_velocity(model: pin.Model, t: np.ndarray, q: np.ndarray, k: int) -> np.ndarray:
    """The velocity (nv,) at sample ``k`` from samples ``k−2, k−1, k`` (module doc), in
    Pinocchio's tangent convention (a free body's linear and angular velocity in its frame).
    Unequal intervals use the three-point formula for them.

    Raises:
        InvalidInputError: ``k`` < 2 (no two samples before it) or past the last sample.
    """
    if not FIRST_START <= k < len(t):
        raise InvalidInputError(
            f"start_velocity: sample {k} needs two samples before it; valid starts are {FIRST_START} .. {len(t) - 1}"
        )
    h1, h2 = t[k] - t[k - 1], t[k] - t[k - 2]
    d1 = pin.difference(model, q[k], q[k - 1])  # ≈ -h1 v + h1²/2 a
    d2 = pin.difference(model, q[k], q[k - 2])  # ≈ -h2 v + h2²/2 a
    # eliminate a: h2² d1 - h1² d2 = -(h1 h2² - h2 h1²) v
    return -(h2**2 * d1 - h1**2 * d2) / (h1 * h2 * (h2 - h1))


def evenly(recording: Recording, windows: Windows) -> list[int]:
    """Evenly spaced starts: every `Windows.step` samples from sample 2, each with at least one
    sample after it."""
    return list(range(FIRST_START, len(recording.t) - 1, windows.step))


def cut(
    recording: Recording,
    windows: Windows,
    model: pin.Model,
    starts: Sequence[int] | None = None,
    velocities: Sequence[np.ndarray] | None = None,
) -> list[Recording]:
    """The windows of ``recording`` (module doc), as recordings named ``NAME[k:e]`` (samples k..e).

    Args:
        recording: the measured trajectory (its own ``t0`` is ignored: the windows start where told).
        windows: the `Windows` (length, and stride for evenly spaced starts).
        model: the scene's Pinocchio model (for the velocity's tangent differences).
        starts: sample indices to start windows at (increasing); default `evenly` spaced.
        velocities: the start velocity of each window (nv,); default `start_velocity`.

    Raises:
        InvalidInputError: a start outside ``2 .. k−2`` (a window needs two samples before its
            start and one after), starts not increasing, velocities not one per start, or a
            recording too short for any window.
    """
    if not isinstance(windows, Windows):
        raise InvalidInputError(f"cut: windows must be a contactdiff.fit.Windows, got {windows!r}")
    k = len(recording.t)
    starts = evenly(recording, windows) if starts is None else [int(s) for s in starts]
    if not starts:
        raise InvalidInputError(
            f"cut: recording {recording.name!r} has {k} samples: too short for a window "
            f"(a start needs {FIRST_START} samples before it and one after)"
        )
    bad = [s for s in starts if not FIRST_START <= s <= k - 2]
    if bad:
        raise InvalidInputError(
            f"cut: window start(s) {bad} of {recording.name!r} outside the valid samples {FIRST_START} .. {k - 2}"
        )
    if any(b <= a for a, b in zip(starts, starts[1:])):
        raise InvalidInputError(f"cut: window starts must increase, got {starts}")
    if velocities is not None and len(velocities) != len(starts):
        raise InvalidInputError(f"cut: {len(velocities)} velocities for {len(starts)} window starts")
    out = []
    for i, s in enumerate(starts):
        e = min(s + windows.length, k - 1)
        v0 = start_velocity(model, recording.t, recording.q, s) if velocities is None else velocities[i]
        rows = slice(s, e + 1)
        weights = None if recording.weights is None else recording.weights[rows]
        out.append(
            Recording(
                f"{recording.name}[{s}:{e}]",
                recording.t[rows],
                recording.q[rows],
                float(recording.t[s]),
                recording.q[s],
                v0,
                weights,
                recording.mask,
            )
        )
    return out


__all__ = ["FIRST_START", "Windows", "cut", "evenly", "start_velocity"]
