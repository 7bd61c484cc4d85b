"""Measured tosses as fit recordings: the free flight's velocity against a synthetic throw whose
velocity is known, the first possible touch, duplicate-safe splits, the published metrics, the
data's own gravity and noise (`length_check`) and the metrics over tosses (`error_summary`)."""

import math

import numpy as np
import pinocchio as pin
import pytest

from contactdiff.data.cube_recordings import (
    MARGIN_SAMPLES,
    WINDOW_CLEARANCE,
    Start,
    duplicate_groups,
    first_touch_sample,
    free_flight_velocity,
    lowest_corner,
    split,
    toss_errors,
    toss_recording,
    toss_windows,
)
from contactdiff.data.cube_tosses import NOMINAL, Toss
from contactdiff.errors import InvalidInputError
from contactdiff.fit import Windows

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
    short = Toss("toss_901", toss.t[44:], toss.position[44:], toss.quaternion[44:], toss.velocity[44:], toss.omega[44:])
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
    tosses["toss_103"] = Toss(
        "toss_103", twin.t, twin.position + [1e-3, 0, 1e-17], twin.quaternion, twin.velocity, twin.omega
    )
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


def test_lowest_corner_of_a_flat_and_a_tilted_cube():
    """Flat on a face with its centre at edge/2: the lowest corner is on the board (0). Turned by
    45° about x: the corners' reach along z is edge/2 (|0| + |cos 45°| + |sin 45°|) = edge/√2, so the
    lowest corner is at z − edge/√2."""
    t = np.arange(2) * DT
    half = NOMINAL.edge / 2.0
    c, s = math.cos(math.pi / 8), math.sin(math.pi / 8)  # the half-angle of 45° about x
    quats = np.array([[1.0, 0.0, 0.0, 0.0], [c, s, 0.0, 0.0]])
    position = np.array([[0.0, 0.0, half], [0.0, 0.0, 0.2]])
    toss = Toss("toss_901", t, position, quats, np.zeros((2, 3)), np.zeros((2, 3)))
    low = lowest_corner(toss)
    assert low[0] == pytest.approx(0.0, abs=1e-15)
    assert low[1] == pytest.approx(0.2 - NOMINAL.edge / math.sqrt(2.0), abs=1e-15)


def test_toss_windows_start_in_free_flight_before_the_touch():
    """A throw that falls onto the board: one window, starting ``lead`` samples before the last
    sample whose lowest corner clears the board by WINDOW_CLEARANCE, comparing ``length`` samples,
    with the throw's velocity (the parabola through the flight: exact for this flight, as in
    test_free_flight_velocity_of_a_known_throw, to 1e-9 m/s)."""
    toss = _throw(n=60)
    low = lowest_corner(toss)
    last = int(np.flatnonzero(low > WINDOW_CLEARANCE)[-1])
    assert last < len(toss) - 1  # the throw reaches the board within its samples
    (window,) = toss_windows(toss, Windows(8), lead=2)
    assert window.t0 == toss.t[last - 2] and len(window.t) == 9
    rotation = pin.Quaternion(*toss.quaternion[last - 2]).normalized().matrix()
    velocity = V0 - np.array([0.0, 0.0, 9.81]) * toss.t[last - 2]
    np.testing.assert_allclose(window.v0, np.r_[rotation.T @ velocity, OMEGA], atol=1e-9)
    with pytest.raises(InvalidInputError, match="lead must be a whole number of samples >= 0, got -1"):
        toss_windows(toss, Windows(8), lead=-1)
    with pytest.raises(InvalidInputError, match="clearance must be a length >= 0"):
        toss_windows(toss, Windows(8), clearance=-0.001)


def test_length_check_recovers_a_throws_gravity_and_finds_no_noise():
    """`length_check` on a noiseless throw under g = 9.5 m/s²: the parabola through its first
    flight is the throw's own, so g comes back to round-off (a 3-coefficient least-squares fit
    of a 0.4 s flight: ~1e-10 m/s² against a 1e-8 tolerance) and the residuals' RMS is
    round-off (positions ~0.5 m: < 1e-12 m); the body-frame rate is constant, so the rotation
    steps' spread is round-off (< 1e-12 rad). The rest height is the mean of the last 20
    samples' heights, z_k = Z0 + V0_z t_k - g t_k² / 2 (closed form)."""
    from contactdiff.data.toss_checks import length_check

    g = 9.5
    toss = _throw(n=60, g=g)
    c = length_check({toss.name: toss})
    assert c["flights"] == 1 and c["tosses"] == 1
    assert c["g_median"] == pytest.approx(g, abs=1e-8)
    assert c["g_ratio"] == pytest.approx(g / NOMINAL.gravity, abs=1e-8)
    t = toss.t[-20:]
    rest = float(np.mean(Z0 + V0[2] * t - 0.5 * g * t**2))
    assert c["rest_median"] == pytest.approx(rest, abs=1e-12)
    assert c["rest_ratio"] == pytest.approx(rest / (NOMINAL.edge / 2.0), abs=1e-10)
    assert c["position_noise_median"] < 1e-12 and c["rotation_noise_median"] < 1e-12


def test_error_summary_of_three_tosses():
    """Mean, population std and median of (1, 2, 4) % and (10, 20, 40) deg: 7/3, sqrt(14/9)
    (squared deviations 16/9 + 1/9 + 25/9 over 3), 2 and ten times those; no toss: a count of 0."""
    from contactdiff.data.toss_evaluation import error_summary

    s = error_summary([(1.0, 10.0), (2.0, 20.0), (4.0, 40.0)])
    assert s["tosses"] == 3
    assert s["position_mean"] == pytest.approx(7 / 3, rel=1e-15)
    assert s["position_std"] == pytest.approx(math.sqrt(14 / 9), rel=1e-15)
    assert s["position_median"] == 2.0
    assert s["rotation_mean"] == pytest.approx(70 / 3, rel=1e-15)
    assert s["rotation_std"] == pytest.approx(10 * math.sqrt(14 / 9), rel=1e-15)
    assert s["rotation_median"] == 20.0
    assert error_summary([]) == {"tosses": 0}
