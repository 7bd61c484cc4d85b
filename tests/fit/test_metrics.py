"""The published cube-toss metrics against values worked out by hand on two samples."""

import math

import numpy as np
import pinocchio as pin
import pytest

from contactdiff.errors import InvalidInputError
from contactdiff.fit.metrics import position_error, position_errors, rotation_error, rotation_errors

EDGE = 0.1048  # m, the measured cube's edge


def test_position_error_of_two_samples():
    """Sample 1: the same point (0 m); sample 2: off by (0.03, 0.04, 0) m, a 3-4-5 triangle
    whose hypotenuse is 0.05 m. Mean 0.025 m; as a percentage of the edge 0.025/0.1048 x 100."""
    simulated = [[0.0, 0.0, 0.05], [0.13, 0.04, 0.05]]
    measured = [[0.0, 0.0, 0.05], [0.10, 0.0, 0.05]]
    assert position_errors(simulated, measured) == pytest.approx([0.0, 0.05], abs=1e-15)
    assert position_error(simulated, measured) == pytest.approx(0.025, rel=1e-14)
    assert position_error(simulated, measured, scale=EDGE) == pytest.approx(100 * 0.025 / EDGE, rel=1e-14)


def test_rotation_error_of_two_samples():
    """Sample 1: a quarter turn about z against none (90 deg); sample 2: q and -q, the same
    rotation (0 deg). Mean 45 deg. Quaternions [qx qy qz qw]."""
    quarter = [0.0, 0.0, math.sin(math.pi / 4), math.cos(math.pi / 4)]
    identity = [0.0, 0.0, 0.0, 1.0]
    simulated = [quarter, [0.0, 0.0, 0.0, -1.0]]
    measured = [identity, identity]
    assert rotation_errors(simulated, measured) == pytest.approx([90.0, 0.0], abs=1e-12)
    assert rotation_error(simulated, measured) == pytest.approx(45.0, abs=1e-12)


def test_small_rotation_angles_keep_their_digits():
    """A 1e-9 rad turn: the angle is recovered to relative 1e-6 (acos of a cosine near 1 would give 0 or ~2e-8)."""
    angle = 1e-9
    q = pin.Quaternion(pin.exp3(np.array([0.3, -0.4, 0.5]) / np.linalg.norm([0.3, -0.4, 0.5]) * angle))
    simulated = [q.coeffs()]
    assert rotation_errors(simulated, [[0.0, 0.0, 0.0, 1.0]])[0] == pytest.approx(math.degrees(angle), rel=1e-6)


def test_bad_inputs_are_named():
    with pytest.raises(InvalidInputError, match="same shape"):
        position_error([[0.0, 0.0, 0.0]], [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    with pytest.raises(InvalidInputError, match="non-finite"):
        position_error([[np.nan, 0.0, 0.0]], [[0.0, 0.0, 0.0]])
    with pytest.raises(InvalidInputError, match="zero norm"):
        rotation_error([[0.0, 0.0, 0.0, 0.0]], [[0.0, 0.0, 0.0, 1.0]])
    with pytest.raises(InvalidInputError, match="scale"):
        position_error([[0.0, 0.0, 0.0]], [[0.0, 0.0, 0.0]], scale=0.0)
