"""Measured tosses as fit recordings: the free flight's velocity against a synthetic throw whose
velocity is known, the first possible touch, duplicate-safe splits, the published metrics."""

import math

import numpy as np
import pinocchio as pin
import pytest

from contactdiff.data.cube_recordings import (
    MARGIN_SAMPLES,
    Start,
    duplicate_groups,
    first_touch_sample,
    free_flight_velocity,
    split,
    toss_errors,
    toss_recording,
)
from contactdiff.data.cube_tosses import NOMINAL, Toss
from contactdiff.errors import InvalidInputError

DT = 1.0 / 148.0  # s, the data's sample time
V0 = np.array([0.8, -0.3, 0.5])  # m/s, world frame
OMEGA = np.array([3.0, -2.0, 5.0])  # rad/s, body frame (constant: equal moments)
Z0 = 0.4  # m


def _throw(name="toss_900", n=60, g=9.81):
    """A cube thrown in free flight: p(t) = p0 + V0 t - g t² ez / 2, R(t) = Exp(OMEGA t) (body-frame
    rate, equal moments), sampled at 148 Hz; velocities as upstream's backward differences."""
    t = np.arange(n) * DT
    p = np.array([0.1, 0.2, Z0]) + np.outer(t, V0) - 0.5 * g * np.outer(t**2, [0, 0, 1])
    quats = []
    for tk in t:
        q = pin.Quaternion(pin.exp3(OMEGA * tk))
        quats.append([q.w, q.x, q.y, q.z])
    v = np.vstack([np.gradient(p[:, j], t) for j in range(3)]).T
    return Toss(name, t, p, np.array(quats), v, np.tile(OMEGA, (n, 1)))


def test_first_touch_is_where_the_centre_comes_within_half_a_diagonal():
    """z(t_k) <= sqrt(3) edge / 2 first at the sample the closed form gives."""
    toss = _throw()
    reach = math.sqrt(3.0) * NOMINAL.edge / 2.0
    k = first_touch_sample(toss)
    assert toss.position[k, 2] <= reach < toss.position[k - 1, 2]


def test_free_flight_velocity_of_a_known_throw():
    """The parabola's slope at sample k0 is V0 - g t_k0 ez exactly (a parabola fits a parabola:
    round-off only, ~1e-12 m/s); the body-frame rate is OMEGA to round-off; the linear velocity
    is returned in the cube's frame, R(t_k0)^T v."""
    toss = _throw()
    k_touch = first_touch_sample(toss)
    k0 = k_touch - MARGIN_SAMPLES
    v = free_flight_velocity(toss, k0, k_touch)
    R = pin.exp3(OMEGA * toss.t[k0])
    world = V0 - np.array([0.0, 0.0, 9.81 * toss.t[k0]])
    assert v[:3] == pytest.approx(R.T @ world, abs=1e-9)
    assert v[3:] == pytest.approx(OMEGA, abs=1e-9)
    rec = toss_recording(toss, Start.BEFORE_TOUCH)
    assert rec.t0 == toss.t[k0] and rec.v0 == pytest.approx(v)


def test_a_short_flight_starts_at_the_first_sample():
    toss = _throw()
    short = Toss("toss_901", toss.t[44:], toss.position[44:], toss.quaternion[44:], toss.velocity[44:],
                 toss.omega[44:])
    assert first_touch_sample(short) < 3
    rec = toss_recording(short, "before-touch")
    assert rec.t0 == short.t[0]
    with pytest.raises(InvalidInputError, match="a parabola needs three"):
        free_flight_velocity(short, 0, 2)
    with pytest.raises(InvalidInputError, match="first, before-touch"):
        toss_recording(short, "middle")


def test_split_keeps_duplicates_on_one_side():
    """Duplicates (identical heights to round-off) are grouped and never split."""
    tosses = {f"toss_{i:03d}": _throw(f"toss_{i:03d}", g=9.0 + 0.1 * i) for i in range(10)}
    twin = tosses["toss_003"]
    tosses["toss_103"] = Toss("toss_103", twin.t, twin.position + [1e-3, 0, 1e-17], twin.quaternion,
                              twin.velocity, twin.omega)
    groups = duplicate_groups(tosses)
    assert ["toss_003", "toss_103"] in groups and len(groups) == 10
    for seed in range(5):
        train, test = split(tosses, 4, seed)
        assert sorted(train + test) == sorted(tosses)
        assert ("toss_003" in train) == ("toss_103" in train)
    with pytest.raises(InvalidInputError, match="between 1 and"):
        split(tosses, 11)


def test_toss_errors_of_a_rollout_against_itself_and_shifted():
    """Zero against itself; a rollout 1 cm off in x everywhere is 1/0.1048 x 100 % of the edge."""
    toss = _throw()
    rec = toss_recording(toss, Start.FIRST)
    q = rec.q[rec.compared]
    assert toss_errors(rec, q) == pytest.approx((0.0, 0.0), abs=1e-9)
    shifted = q.copy()
    shifted[:, 0] += 0.01
    assert toss_errors(rec, shifted)[0] == pytest.approx(100 * 0.01 / NOMINAL.edge, rel=1e-12)
