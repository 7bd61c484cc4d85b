"""`contactdiff.fit`: the residuals' exact Jacobian against finite differences, recovery of known
parameters from noisy synthetic data, the policies and the bad inputs."""

import numpy as np
import pytest

import contactdiff as cd
from contactdiff.errors import InvalidInputError, UnknownNameError
from contactdiff.fit import NonDifferentiablePolicy, Recording, ResidualWeights, Scaled, fit
from contactdiff.fit.evaluation import StateFit, Task, evaluate
from contactdiff.fit.parameters import FitPlan

NOISE = 1e-3  # m: a motion-capture marker's noise
TRUE = {"contact:ball:restitution": 0.6, "scene:gravity_z": -9.7, "contact:ball:offset": 0.01}
RTOL, ATOL = 1e-10, 1e-12


def _ball_recording(seed: int, noise: float = NOISE, t_end: float = 1.5, rate: float = 100.0):
    """The ball (a prismatic z joint) dropped from the scene's start with the TRUE parameters,
    its height sampled at ``rate`` Hz with Gaussian noise of ``noise`` m."""
    scene = cd.load_scene("ball").with_parameters(TRUE)
    t = np.arange(0.0, t_end, 1.0 / rate)
    traj = cd.simulate(scene, t[-1], sample_times=t, rtol=RTOL, atol=ATOL)
    rng = np.random.default_rng(seed)
    q = traj.samples.q + noise * rng.standard_normal(traj.samples.q.shape)
    return Recording(f"ball-{seed}", t, q, 0.0, scene.q0, scene.v0)


def test_residual_jacobian_matches_finite_differences():
    """∂r/∂θ from one run against central differences of whole runs. The bounces' times move
    smoothly with e, g and the offset (no event is flagged), so the FD error is O(h²) with
    h = 1e-6 relative, plus the runs' tolerance over h: rtol 1e-10 / 1e-6 = 1e-4 of the
    derivative's scale at worst; asserted at 1e-4 relative to the largest entry."""
    scene = cd.load_scene("ball")
    rec = _ball_recording(seed=0, noise=0.0, t_end=1.2)
    plan = FitPlan(scene, list(TRUE))
    theta = np.array([0.7, -9.81, 0.0])

    def run(th):
        return evaluate(
            scene,
            plan.parameters,
            Task(0, rec, plan.values(th), np.zeros(0), StateFit.NONE, ResidualWeights(), {"rtol": RTOL, "atol": ATOL}),
        )

    ev = run(theta)
    assert ev.error is None and ev.differentiable
    J = ev.parameter_jacobian @ plan.C
    for j, scale in enumerate((1.0, 10.0, 0.1)):
        h = 1e-6 * scale
        step = np.zeros(3)
        step[j] = h
        fd = (run(theta + step).residual - run(theta - step).residual) / (2 * h)
        assert np.max(np.abs(J[:, j] - fd)) < 1e-4 * np.max(np.abs(fd))


def test_fit_recovers_known_parameters_within_three_standard_errors():
    """Noisy synthetic bounces (1 mm noise, 100 Hz, two drops): the fitted restitution, gravity
    and ground height lie within three of their own standard errors of the truth."""
    scene = cd.load_scene("ball")
    recordings = [_ball_recording(seed) for seed in (1, 2)]
    start = {"contact:ball:restitution": 0.75, "scene:gravity_z": -9.81, "contact:ball:offset": 0.0}
    result = fit(
        scene.with_parameters(start), recordings, list(TRUE), options={"rtol": RTOL, "atol": ATOL}, progress=False
    )
    assert result.success
    truth = np.array(list(TRUE.values()))
    assert np.all(np.isfinite(result.standard_errors))
    assert np.all(np.abs(result.values - truth) < 3 * result.standard_errors), (result.values, result.standard_errors)
    # the noise level comes back: rms residual ≈ 1 mm (the model fits; chi-square on ~300 samples)
    for r in result.recordings:
        assert 0.8 * NOISE < r.rms < 1.2 * NOISE
        assert r.differentiable


def test_initial_velocity_is_fitted_too():
    """The ball thrown up at 1.0 m/s, the fit told it started at rest: with state="velocity" it
    finds the throw within three standard errors... of the residual noise: the velocity's own
    error is not reported per recording, so assert 3 cm/s (the velocity is seen in ~30 samples of
    1 mm noise over 0.3 s: σ_v ≈ 1e-3 / (0.3 sqrt(30)) ≈ 6e-4 m/s)."""
    scene = cd.load_scene("ball").with_parameters(TRUE)
    thrown = scene.with_state(None, np.array([1.0]))
    t = np.arange(0.0, 1.0, 0.01)
    traj = cd.simulate(thrown, t[-1], sample_times=t, rtol=RTOL, atol=ATOL)
    q = traj.samples.q + NOISE * np.random.default_rng(5).standard_normal(traj.samples.q.shape)
    rec = Recording("thrown", t, q, 0.0, scene.q0, np.zeros(1))
    result = fit(
        scene,
        [rec],
        ["contact:ball:restitution"],
        state="velocity",
        options={"rtol": RTOL, "atol": ATOL},
        progress=False,
    )
    assert abs(result.recordings[0].state_offset[0] - 1.0) < 3e-2
    assert abs(result.values[0] - TRUE["contact:ball:restitution"]) < 3 * result.standard_errors[0]


def test_scaled_unknown_moves_its_members_together():
    """A scale of the ball's restitution: its derivative is base x the member's (chain rule)."""
    scene = cd.load_scene("ball")
    plan = FitPlan(scene, [Scaled("e_scale", {"contact:ball:restitution": 0.5}), "scene:gravity_z"])
    assert plan.values(np.array([1.2, -9.0])) == {"contact:ball:restitution": 0.6, "scene:gravity_z": -9.0}
    assert plan.start(scene)[0] == 1.0
    assert plan.C[:, 0] == pytest.approx([0.5, 0.0])


def test_bad_fits_are_refused_with_names():
    scene = cd.load_scene("ball")
    rec = _ball_recording(seed=0, t_end=0.3)
    with pytest.raises(UnknownNameError):
        fit(scene, [rec], ["contact:ball:bounciness"], progress=False)
    with pytest.raises(InvalidInputError, match="at least one parameter"):
        fit(scene, [rec], [], progress=False)
    with pytest.raises(InvalidInputError, match="policy must be one of keep, exclude"):
        fit(scene, [rec], ["scene:gravity_z"], policy="drop", progress=False)
    with pytest.raises(InvalidInputError, match="not fitted"):
        fit(scene, [rec], ["scene:gravity_z"], bounds={"contact:ball:offset": (0, 1)}, progress=False)
    with pytest.raises(InvalidInputError, match="jobs=2 needs a scene the workers can rebuild"):
        fit(scene, [rec], ["scene:gravity_z"], jobs=2, progress=False)
    with pytest.raises(InvalidInputError, match="recordings"):
        fit(scene, [], ["scene:gravity_z"], progress=False)
    assert NonDifferentiablePolicy("exclude") is NonDifferentiablePolicy.EXCLUDE
