"""Windowed residuals (`contactdiff.fit.windows`): the start velocity against a closed form, the
windows' residual Jacobian against central differences, recovery of known parameters from noisy
windows, and the bad window options."""

import numpy as np
import pytest

import contactdiff as cd
from contactdiff.errors import InvalidInputError
from contactdiff.fit import Recording, Windows, cut, fit
from contactdiff.fit.evaluation import StateFit, Task, evaluate
from contactdiff.fit.parameters import FitPlan
from contactdiff.fit.residuals import ResidualWeights
from contactdiff.fit.windows import start_velocity

NOISE = 1e-3  # m: a motion-capture marker's noise
TRUE = {"contact:ball:restitution": 0.6, "scene:gravity_z": -9.7, "contact:ball:offset": 0.01}
RTOL, ATOL = 1e-10, 1e-12
FREE = 0.03  # m above the ground: a window starts in free flight (30 times the noise)


def _ball(seed: int, noise: float = NOISE, t_end: float = 1.5, rate: float = 100.0):
    """The ball (a prismatic z joint) dropped with the TRUE parameters, its height sampled at
    ``rate`` Hz with Gaussian noise of ``noise`` m; the scene and the recording."""
    scene = cd.load_scene("ball")
    truth = scene.with_parameters(TRUE)
    t = np.arange(0.0, t_end, 1.0 / rate)
    traj = cd.simulate(truth, t[-1], sample_times=t, rtol=RTOL, atol=ATOL)
    q = traj.samples.q + noise * np.random.default_rng(seed).standard_normal(traj.samples.q.shape)
    return scene, Recording(f"ball-{seed}", t, q, 0.0, scene.q0, scene.v0)


def _free_starts(rec: Recording, windows: Windows) -> list[int]:
    """Evenly spaced starts whose sample and the two before it are FREE above the true ground."""
    ground = TRUE["contact:ball:offset"]
    return [k for k in range(2, len(rec.t) - 1, windows.step) if np.all(rec.q[k - 2 : k + 1, 0] > ground + FREE)]


def test_start_velocity_is_exact_on_a_parabola():
    """Free flight z(t) = z0 + v0 t − g t²/2 sampled at unequal times: the three-point backward
    difference eliminates the constant acceleration exactly (d(k, j) = z_j − z_k = −(t_k − t_j) v_k
    − (t_k − t_j)² g/2 has no higher term), so v_k = v0 − g t_k up to round-off (1e-12 m/s at these
    magnitudes: z ~ 1 m over steps of 1e-2 s, 1e-16 / 1e-2 ≈ 1e-14 times a few)."""
    model = cd.load_scene("ball").model
    z0, v0, g = 1.0, 0.7, 9.7
    t = np.array([0.0, 0.013, 0.021, 0.04])
    q = (z0 + v0 * t - 0.5 * g * t**2)[:, None]
    for k in (2, 3):
        assert start_velocity(model, t, q, k)[0] == pytest.approx(v0 - g * t[k], abs=1e-12)


def test_windows_cover_their_samples_and_start_from_the_data():
    """Each window holds samples k..k+length of the recording, starts at t_k from q_k."""
    scene, rec = _ball(seed=0, noise=0.0)
    windows = Windows(20, stride=10)
    for w, k in zip(cut(rec, windows, scene.model), range(2, len(rec.t) - 1, 10)):
        e = min(k + 20, len(rec.t) - 1)
        assert w.name == f"ball-0[{k}:{e}]"
        np.testing.assert_array_equal(w.t, rec.t[k : e + 1])
        np.testing.assert_array_equal(w.q0, rec.q[k])
        assert w.t0 == rec.t[k]


def test_window_jacobian_matches_central_differences():
    """∂r/∂θ and ∂r/∂v0 of a window through a bounce, from one run, against central differences of
    whole window runs. The bounce's time moves smoothly with e, g, the offset and v0 (no event is
    flagged), so the FD error is O(h²) with h = 1e-6 relative, plus the runs' tolerance over h:
    rtol 1e-10 / 1e-6 = 1e-4 of the derivative's scale at worst; asserted at 1e-4 relative to the
    largest entry."""
    scene, rec = _ball(seed=0, noise=0.0, t_end=1.2)
    windows = Windows(25)
    starts = _free_starts(rec, windows)
    wins = cut(rec, windows, scene.model, starts)
    plan = FitPlan(scene, list(TRUE))
    theta = np.array([0.7, -9.81, 0.0])
    x = np.r_[theta, 0.05]  # the parameters, then the window's start-velocity offset (m/s)

    def run(window, y):
        return evaluate(
            scene,
            plan.parameters,
            Task(
                0, window, plan.values(y[:3]), y[3:], StateFit.VELOCITY, ResidualWeights(), {"rtol": RTOL, "atol": ATOL}
            ),
        )

    bouncing = 0
    for window in wins:
        ev = run(window, x)
        assert ev.error is None and ev.differentiable
        bouncing += ev.events > 0
        J = np.hstack([ev.parameter_jacobian @ plan.C, ev.state_jacobian])
        for j, scale in enumerate((1.0, 10.0, 0.1, 1.0)):
            h = 1e-6 * scale
            step = np.zeros(4)
            step[j] = h
            fd = (run(window, x + step).residual - run(window, x - step).residual) / (2 * h)
            assert np.max(np.abs(J[:, j] - fd)) <= 1e-4 * max(np.max(np.abs(fd)), 1e-12), (window.name, j)
    assert bouncing >= 1  # some window goes through an impact


def test_windowed_fit_recovers_known_parameters_within_three_standard_errors():
    """Noisy bounces (1 mm, 100 Hz, two drops) cut into windows of 20 samples that start in free
    flight, each window's start velocity fitted (its data estimate carries ~0.25 m/s of noise):
    the fitted restitution, gravity and ground height lie within three standard errors of the truth."""
    scene, _ = _ball(seed=0)
    windows = Windows(20, stride=10)
    recordings = []
    for seed in (1, 2):
        _, rec = _ball(seed)
        recordings += cut(rec, windows, scene.model, _free_starts(rec, windows))
    start = {"contact:ball:restitution": 0.75, "scene:gravity_z": -9.81, "contact:ball:offset": 0.0}
    result = fit(
        scene.with_parameters(start),
        recordings,
        list(TRUE),
        state="velocity",
        options={"rtol": RTOL, "atol": ATOL},
        progress=False,
    )
    truth = np.array(list(TRUE.values()))
    assert np.all(np.isfinite(result.standard_errors))
    assert np.all(np.abs(result.values - truth) < 3 * result.standard_errors), (result.values, result.standard_errors)


@pytest.mark.parametrize(
    "kwargs, fragment",
    [
        ({"length": 0}, "length must be a whole number of samples >= 1, got 0"),
        ({"length": 2.5}, "got 2.5"),
        ({"length": True}, "got True"),
        ({"length": 5, "stride": 0}, "stride must be a whole number of samples >= 1, got 0"),
    ],
)
def test_bad_window_options_are_refused_with_names(kwargs, fragment):
    with pytest.raises(InvalidInputError, match=fragment):
        Windows(**kwargs)


def test_bad_window_starts_are_refused_with_names():
    scene, rec = _ball(seed=0, noise=0.0, t_end=0.2)  # 20 samples
    model = scene.model
    with pytest.raises(InvalidInputError, match=r"start\(s\) \[1\] .* valid samples 2 \.\. 18"):
        cut(rec, Windows(5), model, starts=[1])
    with pytest.raises(InvalidInputError, match=r"start\(s\) \[19\]"):
        cut(rec, Windows(5), model, starts=[19])
    with pytest.raises(InvalidInputError, match="must increase"):
        cut(rec, Windows(5), model, starts=[6, 4])
    with pytest.raises(InvalidInputError, match="2 velocities for 1 window starts"):
        cut(rec, Windows(5), model, starts=[4], velocities=[np.zeros(1)] * 2)
    with pytest.raises(InvalidInputError, match="must be a contactdiff.fit.Windows"):
        cut(rec, 5, model)
    short = Recording("short", rec.t[:3], rec.q[:3], 0.0, scene.q0, scene.v0)
    with pytest.raises(InvalidInputError, match="3 samples: too short for a window"):
        cut(short, Windows(5), model)
    with pytest.raises(InvalidInputError, match="sample 1 needs two samples before it"):
        start_velocity(model, rec.t, rec.q, 1)


def test_a_rollout_that_fails_inside_the_integrator_is_reported_not_raised(monkeypatch):
    """A run that raises ValueError (a root finder's bracket lost inside the integrator) becomes
    that rollout's failure, named with its type, so an evaluation of many recordings goes on."""
    import importlib

    module = importlib.import_module("contactdiff.fit.rollouts")

    scene, rec = _ball(seed=0, noise=0.0, t_end=0.2)

    def broken(*args, **kwargs):
        raise ValueError("f(a) and f(b) must have different signs")

    monkeypatch.setattr(module, "simulate", broken)
    run = module.rollout(scene, rec)
    assert not run.complete and run.error == "ValueError: f(a) and f(b) must have different signs"
