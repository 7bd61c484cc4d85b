"""The floor height from resting samples (`contactdiff.fit.rest_height`): a synthetic cube at rest
on a face gives the board's height back in closed form, and bad arguments are named."""

import math

import numpy as np
import pinocchio as pin
import pytest

import contactdiff as cd
from contactdiff.data.cube_tosses import NOMINAL
from contactdiff.errors import InvalidInputError
from contactdiff.fit import Recording, rest_height

BOARD = -0.0023  # m: the board's true height
HALF = NOMINAL.edge / 2  # m


def _resting(tilts, yaws, board=BOARD, name="rest"):
    """A cube whose centre is at ``board + HALF`` (one face down), turned by each yaw about z and
    tilted by the matching angle about its x axis, one sample per pair (148 Hz)."""
    q = []
    for tilt, yaw in zip(tilts, yaws):
        R = pin.exp3(np.array([0.0, 0.0, yaw])) @ pin.exp3(np.array([tilt, 0.0, 0.0]))
        quat = pin.Quaternion(R)
        q.append(np.r_[0.3, -0.1, board + HALF, quat.x, quat.y, quat.z, quat.w])
    q = np.array(q)
    t = np.arange(len(q)) / 148.0
    return Recording(name, t, q, 0.0, q[0], np.zeros(6))


def test_a_flat_cube_at_rest_gives_the_board_height_exactly():
    """Flat on a face (no tilt), any yaw: the four bottom corners are at z_c − edge/2 = BOARD, the
    other four an edge higher (outside the 3 mm support), so the mean supporting height is BOARD;
    whatever offset the scene's contacts hold (0.05 m here) does not enter. Tolerance 1e-12 m:
    round-off of corner positions of size 0.3 m."""
    scene = cd.cube_scene(ground=0.05)
    recs = [_resting([0.0] * 6, np.linspace(0.0, 3.0, 6), name=f"r{i}") for i in range(3)]
    result = rest_height(scene, recs, group="cube", samples=5)
    assert result.offset == pytest.approx(BOARD, abs=1e-12)
    assert result.points == 3 * 5 * 4  # four supporting corners per sample
    assert result.standard_error < 1e-12
    assert set(result.per_recording) == {"r0", "r1", "r2"}


def test_tilts_of_either_sign_cancel_to_first_order():
    """Tilted by ±θ about the cube's x axis with the centre at BOARD + edge/2: the bottom corners
    at y = ±edge/2 sit at BOARD + (edge/2)(1 − cos θ) ± (edge/2) sin θ, so their mean is
    BOARD + (edge/2)(1 − cos θ) (second order in θ), while the lowest corner alone would be
    BOARD + (edge/2)(1 − cos θ − sin θ): at θ = 0.01 rad the mean is off by 2.6 μm, the lowest
    alone by 0.52 mm. Tolerance 1e-12 m (round-off)."""
    theta = 0.01
    scene = cd.cube_scene()
    rec = _resting([theta, -theta] * 3, [0.4] * 6)
    expected = BOARD + HALF * (1 - math.cos(theta))
    assert rest_height(scene, [rec], samples=6).offset == pytest.approx(expected, abs=1e-12)
    lowest_only = rest_height(scene, [rec], samples=6, support=0.0).offset
    assert lowest_only == pytest.approx(expected - HALF * math.sin(theta), abs=1e-12)


def test_bad_arguments_are_named():
    scene = cd.cube_scene()
    rec = _resting([0.0] * 4, [0.0] * 4)
    with pytest.raises(InvalidInputError, match="fewer than the 20"):
        rest_height(scene, [rec])
    with pytest.raises(InvalidInputError, match="group 'feet'.*cube"):
        rest_height(scene, [rec], group="feet", samples=2)
    with pytest.raises(InvalidInputError, match="samples must be"):
        rest_height(scene, [rec], samples=0)
    with pytest.raises(InvalidInputError, match="support must be"):
        rest_height(scene, [rec], samples=2, support=float("nan"))
    with pytest.raises(InvalidInputError, match="non-empty list"):
        rest_height(scene, [])
