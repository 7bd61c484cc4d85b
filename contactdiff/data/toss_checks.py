"""What the measured tosses say of themselves: free-flight gravity, rest height, noise.

`length_check` compares the data's gravity and the cube's rest height with the
model's (`NOMINAL`): a data set in lengths of another unit, or a board at another
height, shows here before any fit. It also measures the data's noise in free
flight, from which `contactdiff.data.toss_evaluation.START_NOISE` is taken.
scripts/cube_tosses.py --length-check prints it.
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Mapping

import numpy as np
import pinocchio as pin

from .cube_recordings import WINDOW_CLEARANCE, lowest_corner
from .cube_tosses import NOMINAL, Toss


def length_check(tosses: Mapping[str, Toss]) -> dict:
    """The data's gravity and the cube's rest height, each against the model's: a parabola z(t) through
    each toss's first flight (at least 8 samples whose lowest corner clears the board by
    WINDOW_CLEARANCE) gives g; the centre's mean height over each toss's last 20 samples (at rest
    on a face) the rest height. Medians over tosses, and each as a ratio to 9.81 m/s² and edge / 2.
    Also the data's noise in free flight: the RMS of a parabola's residuals per axis (m; 3 of
    each axis's samples spent on the fit), and of the rotation vector between consecutive samples
    about its flight's mean over √2 (rad: the body-frame rate is constant in free flight, and
    each step's vector holds two samples' noise)."""
    g, rest, position_noise, rotation_noise = [], [], [], []
    for toss in tosses.values():
        free = lowest_corner(toss) > WINDOW_CLEARANCE
        k = int(np.argmin(free)) if not free.all() else len(toss)
        if k >= 8:
            g.append(-2.0 * np.polyfit(toss.t[:k], toss.position[:k, 2], 2)[0])
            V = np.vander(toss.t[:k], 3)
            coefficients, *_ = np.linalg.lstsq(V, toss.position[:k], rcond=None)
            position_noise.append(float(np.sqrt(np.sum((toss.position[:k] - V @ coefficients) ** 2) / (3 * (k - 3)))))
            R = [pin.Quaternion(*q).normalized().matrix() for q in toss.quaternion[:k]]
            steps = np.array([pin.log3(a.T @ b) for a, b in zip(R[:-1], R[1:])])  # constant in free flight
            rotation_noise.append(float(np.std(steps - steps.mean(axis=0)) / math.sqrt(2.0)))
        rest.append(float(np.mean(toss.position[-20:, 2])))
    g_median, rest_median = statistics.median(g), statistics.median(rest)
    return {
        "flights": len(g),
        "g_median": g_median,
        "g_quartiles": list(np.percentile(g, [25, 75])),
        "g_ratio": g_median / NOMINAL.gravity,
        "rest_median": rest_median,
        "rest_ratio": rest_median / (NOMINAL.edge / 2.0),
        "tosses": len(rest),
        "position_noise_median": statistics.median(position_noise),
        "rotation_noise_median": statistics.median(rotation_noise),
    }
