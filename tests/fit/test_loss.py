"""Robust losses (`contactdiff.fit.Loss`): each ρ against its closed form, a fit of noisy bounces
with tracker glitches that recovers the truth within its standard errors, and the bad options."""

import math

import numpy as np
import pytest

import contactdiff as cd
from contactdiff.errors import InvalidInputError
from contactdiff.fit import Loss, Recording, fit

TRUE = {"contact:ball:restitution": 0.6, "scene:gravity_z": -9.7, "contact:ball:offset": 0.01}
NEAR = {"contact:ball:restitution": 0.55, "scene:gravity_z": -9.75, "contact:ball:offset": 0.008}
F = 0.003  # m: f_scale, three times the 1 mm noise
RTOL, ATOL = 1e-10, 1e-12


def test_each_loss_against_its_closed_form():
    """r = (F, 10 F): z = (1, 100). Half of F² Σ ρ(z): linear (1 + 100) / 2; soft_l1
    (2(√2 − 1) + 2(√101 − 1)) / 2; huber (1 + (2·10 − 1)) / 2; cauchy (ln 2 + ln 101) / 2; each
    times F². Weights ρ'(z): soft_l1 1/√(1+z), huber 1 then 1/√z, cauchy 1/(1+z). Tolerance
    1e-12 relative: a few floating-point operations."""
    r = np.array([F, -10 * F])
    expected = {
        Loss.LINEAR: 101 / 2,
        Loss.SOFT_L1: (2 * (math.sqrt(2) - 1) + 2 * (math.sqrt(101) - 1)) / 2,
        Loss.HUBER: (1 + 19) / 2,
        Loss.CAUCHY: (math.log(2) + math.log(101)) / 2,
    }
    for loss, value in expected.items():
        assert loss.cost(r, F) == pytest.approx(F**2 * value, rel=1e-12)
    weights = {
        Loss.LINEAR: [1, 1],
        Loss.SOFT_L1: [1 / math.sqrt(2), 1 / math.sqrt(101)],
        Loss.HUBER: [1, 1 / 10],
        Loss.CAUCHY: [1 / 2, 1 / 101],
    }
    for loss, value in weights.items():
        assert loss.weights(r, F) == pytest.approx(value, rel=1e-12)


def _glitched():
    """The ball dropped with the TRUE parameters, sampled at 100 Hz with 1 mm Gaussian noise,
    four samples lifted 5 cm (a tracker's glitches: 50 noise levels)."""
    scene = cd.load_scene("ball").with_parameters(TRUE)
    t = np.arange(0.0, 1.5, 0.01)
    q = cd.simulate(scene, t[-1], sample_times=t, rtol=RTOL, atol=ATOL).samples.q
    q = q + 1e-3 * np.random.default_rng(0).standard_normal(q.shape)
    q[[30, 60, 90, 120]] += 0.05
    return Recording("glitched", t, q, 0.0, scene.q0, scene.v0)


def test_soft_l1_recovers_the_truth_through_glitches():
    """From a start near the truth (a robust loss needs one), soft_l1 with f_scale 3 mm recovers
    e, g and the ground height within three of its standard errors (its covariance weighs each
    row by ρ', so the glitches' rows, z ≈ 280, count 1/17 of a clean row), and its cost is the
    loss's cost of its residuals."""
    scene = cd.load_scene("ball").with_parameters(NEAR)
    result = fit(scene, [_glitched()], list(TRUE), loss="soft_l1", f_scale=F, progress=False, options={"rtol": RTOL})
    truth = np.array(list(TRUE.values()))
    assert np.all(np.abs(result.values - truth) < 3 * result.standard_errors)
    assert np.all(np.isfinite(result.standard_errors))
    assert result.cost < result.start_cost


def test_bad_loss_options_are_named():
    scene = cd.load_scene("ball")
    rec = _glitched()
    with pytest.raises(InvalidInputError, match="loss must be one of linear, soft_l1, huber, cauchy; got 'l1'"):
        fit(scene, [rec], ["contact:ball:restitution"], loss="l1", progress=False)
    with pytest.raises(InvalidInputError, match="f_scale must be a number > 0, got 0"):
        fit(scene, [rec], ["contact:ball:restitution"], loss="huber", f_scale=0.0, progress=False)
