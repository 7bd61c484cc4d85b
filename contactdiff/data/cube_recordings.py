"""Measured cube tosses as recordings to fit and evaluate: starts, splits and the published metrics.

Two rollout starts, as the two published studies of these tosses start theirs:

* `Start.FIRST` (ContactNets): the toss's first sample, with its measured
  velocity (a backward difference of the poses, lagging half a sample).
* `Start.BEFORE_TOUCH` (Acosta, Yang and Posa): three samples before the cube
  can first touch the board, with the velocity of a fit of the free flight
  before it: the centre's position by a parabola in time per axis (its
  derivative at the start), the orientation by a constant body-frame angular
  velocity (the mean of the rotation vectors between consecutive samples over
  the sample time: a cube whose three moments are equal turns at a constant
  body-frame rate in free flight). The cube *can* touch once its centre is
  within half a space diagonal (√3 edge / 2) of the board: no orientation
  reaches the board from higher up. A toss with fewer than three samples of free
  flight starts at its first sample, as measured.

`toss_windows` cuts a toss into short windows that start in free flight just
before each touch (windowed residuals, `contactdiff.fit.windows`).

`split` keeps the tosses that upstream holds twice (the same recording
processed again with another yaw: identical heights z(t)) on one side.
"""

from __future__ import annotations

import math
from collections import defaultdict
from enum import StrEnum

import numpy as np
import pinocchio as pin

from ..errors import InvalidInputError, check_member
from ..fit.metrics import position_error, rotation_error
from ..fit.recordings import Recording
from ..fit.windows import FIRST_START, Windows, cut
from .cube_tosses import NOMINAL, CubeParameters, Toss, cube_scene

MARGIN_SAMPLES = 3
"""Samples between `Start.BEFORE_TOUCH`'s start and the first sample at which the cube can touch."""


class Start(StrEnum):
    """Where a toss's rollout starts (module doc)."""

    FIRST = "first"
    BEFORE_TOUCH = "before-touch"


def first_touch_sample(toss: Toss, parameters: CubeParameters = NOMINAL) -> int:
    """The first sample whose centre is within half a space diagonal of the board (module doc);
    the last sample if none is."""
    reach = parameters.ground + math.sqrt(3.0) * parameters.edge / 2.0
    close = np.flatnonzero(toss.position[:, 2] <= reach)
    return int(close[0]) if len(close) else len(toss) - 1


def free_flight_velocity(toss: Toss, k0: int, k_touch: int, first: int = 0) -> np.ndarray:
    """The velocity at sample ``k0`` from a fit of the free flight (samples ``first`` to
    ``k_touch − 1``), as the cube scene's ``v`` (linear and angular, both in the cube's frame).

    Raises:
        InvalidInputError: fewer than three free-flight samples (a parabola needs three).
    """
    flight = np.arange(first, max(k_touch, first))
    if len(flight) < 3:
        raise InvalidInputError(
            f"{toss.name}: {len(flight)} samples of free flight before the cube can touch; "
            "a parabola needs three (use the first sample's velocity)"
        )
    t = toss.t[flight]
    V = np.vander(t - toss.t[k0], 3)  # columns (t - t0)^2, (t - t0), 1
    coefficients, *_ = np.linalg.lstsq(V, toss.position[flight], rcond=None)
    velocity = coefficients[1]  # d/dt at t0
    R = [pin.Quaternion(w, x, y, z).normalized().matrix() for w, x, y, z in toss.quaternion[flight]]
    steps = [pin.log3(a.T @ b) / dt for a, b, dt in zip(R[:-1], R[1:], np.diff(t))]
    omega = np.mean(steps, axis=0)
    rotation = pin.Quaternion(*toss.quaternion[k0]).normalized().matrix()
    return np.r_[rotation.T @ velocity, omega]


def toss_recording(toss: Toss, start: Start | str = Start.FIRST, parameters: CubeParameters = NOMINAL) -> Recording:
    """The toss as a `Recording` of the cube scene from the chosen `Start`.

    Raises:
        InvalidInputError: an unknown start (the valid ones listed).
    """
    start = check_member("toss start", start, Start)
    q = toss.configurations()
    if start is Start.FIRST:
        k0 = 0
        q0, v0 = toss.state(0)
    else:
        k_touch = first_touch_sample(toss, parameters)
        k0 = max(0, k_touch - MARGIN_SAMPLES)
        if k_touch >= 3:
            q0, v0 = q[k0], free_flight_velocity(toss, k0, k_touch)
        else:  # fewer than three samples of free flight: no parabola, the first sample as measured
            k0 = 0
            q0, v0 = toss.state(0)
    return Recording(toss.name, toss.t, q, float(toss.t[k0]), q0, v0)


WINDOW_CLEARANCE = 0.003
"""m: a sample is in free flight when the cube's lowest corner is this far above the board
(three times the data's ~1 mm noise, and above the board's ~1 mm offset in the data)."""


def lowest_corner(toss: Toss, parameters: CubeParameters = NOMINAL) -> np.ndarray:
    """The height (n,) of the cube's lowest corner above the board at each sample (m):
    the centre's height less half the edge times the sum of ``|R[2, j]|`` (the corners'
    reach along the board's z)."""
    R = np.array([pin.Quaternion(w, x, y, z).normalized().matrix() for w, x, y, z in toss.quaternion])
    return toss.position[:, 2] - parameters.ground - parameters.edge / 2.0 * np.abs(R[:, 2, :]).sum(axis=1)


def toss_windows(
    toss: Toss,
    windows: Windows,
    parameters: CubeParameters = NOMINAL,
    clearance: float = WINDOW_CLEARANCE,
    lead: int = 0,
    model=None,
) -> list[Recording]:
    """The toss cut into windows (`contactdiff.fit.windows`) that start in free flight just
    before a touch: one ``lead`` samples before the last sample of every run of at least three
    free-flight samples (`lowest_corner` above ``clearance``) that a touch ends (not before
    the run's third sample), each with the velocity of a parabola through that run
    (`free_flight_velocity`), each comparing `Windows.length` samples. A toss without such a
    run has no window (an empty list).

    Raises:
        InvalidInputError: ``clearance`` not a length >= 0, ``lead`` not a count >= 0.
    """
    if not (isinstance(clearance, (int, float)) and np.isfinite(clearance) and clearance >= 0.0):
        raise InvalidInputError(f"toss_windows: clearance must be a length >= 0 (m), got {clearance!r}")
    if isinstance(lead, bool) or not isinstance(lead, (int, np.integer)) or lead < 0:
        raise InvalidInputError(f"toss_windows: lead must be a whole number of samples >= 0, got {lead!r}")
    free = lowest_corner(toss, parameters) > clearance
    starts, velocities = [], []
    k = 0
    while k < len(toss):
        if not free[k]:
            k += 1
            continue
        first = k
        while k < len(toss) and free[k]:
            k += 1
        last = k - 1  # the run's last free sample; k: the first in touch (or the end)
        start = max(last - lead, first + 2, FIRST_START)
        if k < len(toss) and last - first >= 2 and start <= len(toss) - 2:
            starts.append(start)
            velocities.append(free_flight_velocity(toss, start, last + 1, first))
    if not starts:
        return []
    model = model if model is not None else cube_scene(parameters).model
    whole = Recording(toss.name, toss.t, toss.configurations(), 0.0, *toss.state(0))
    return cut(whole, windows, model, starts, velocities)


def duplicate_groups(tosses: dict[str, Toss]) -> list[list[str]]:
    """The tosses grouped by identical heights z(t) (upstream's re-processed duplicates: equal to
    round-off, 1e-16 m, after the unit conversion; compared at 1 nm), in file order."""
    groups: dict[bytes, list[str]] = defaultdict(list)
    for name, toss in tosses.items():
        groups[np.round(toss.position[:, 2], 9).tobytes()].append(name)
    return list(groups.values())


def split(tosses: dict[str, Toss], train: int, seed: int = 0) -> tuple[list[str], list[str]]:
    """A training set of about ``train`` tosses and the held-out rest, each duplicate group on
    one side (module doc); drawn with ``seed``.

    Raises:
        InvalidInputError: ``train`` not between 1 and the number of tosses - 1.
    """
    if not 1 <= train < len(tosses):
        raise InvalidInputError(f"split: train must be between 1 and {len(tosses) - 1} tosses, got {train!r}")
    groups = duplicate_groups(tosses)
    order = np.random.default_rng(seed).permutation(len(groups))
    chosen: list[str] = []
    for g in order:
        if len(chosen) >= train:
            break
        chosen += groups[g]
    picked = set(chosen)
    return [n for n in tosses if n in picked], [n for n in tosses if n not in picked]


def toss_errors(recording: Recording, q_simulated: np.ndarray, edge: float = NOMINAL.edge) -> tuple[float, float]:
    """The published metrics of one rollout: the time-averaged position error in percent of
    the edge and the time-averaged rotation error in degrees, over the compared samples
    (``q_simulated``, one row per `Recording.compared` sample)."""
    measured = recording.q[recording.compared]
    if q_simulated.shape != measured.shape:
        raise InvalidInputError(
            f"{recording.name}: {len(q_simulated)} simulated samples for {len(measured)} measured ones"
        )
    return (
        position_error(q_simulated[:, :3], measured[:, :3], scale=edge),
        rotation_error(q_simulated[:, 3:7], measured[:, 3:7]),
    )


__all__ = [
    "MARGIN_SAMPLES",
    "WINDOW_CLEARANCE",
    "Start",
    "lowest_corner",
    "toss_windows",
    "duplicate_groups",
    "first_touch_sample",
    "free_flight_velocity",
    "split",
    "toss_errors",
    "toss_recording",
]
