"""The state and its flow Jacobian at sample times, from one run (``sample_times``).

References, never the code's own output:

* **Central finite differences of the sampled states**, on the manifold (``pin.difference``
  for q): each state column perturbs the initial state along one tangent direction by
  ``±EPS`` (1e-6), each parameter column perturbs the parameter by ``±h``, ``h = 1e-5 |p|``
  (1e-5 where p = 0), through `Scene.with_parameters`; every perturbed run is sampled at
  the same times and must keep the nominal event sequence (else the difference straddles
  a mode change). Runs use rtol 1e-12, atol 1e-13 (`TOL`). Error of a difference quotient:
  the truncation ~ step² |x'''| (≤ 1e-10 relative for these O(1) scenes) and the noise of
  the two runs' integration errors, each about ``NOISE`` = 1e-11 max(1, |x|) after a few
  events (as in test_parameter_sensitivity.py), over the step: ``NOISE max(1, |x|) / step``.
  A sample's Jacobian is compared to ``JAC_RTOL`` (1e-6) of its own largest entry plus
  that noise, so a wrong term (a missing saltation, a wrong sign) of relative size ≥ 1e-5
  cannot pass.
* **Closed forms** for the bouncing ball (g = 1 m/s², dropped from z = 1 m, e = 0.8, at
  rest): derived in each test's docstring.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
from coulomb_models import BLOCK3_URDF, MU, G, load

import contactdiff as cd
from contactdiff.errors import InvalidInputError

TOL = dict(rtol=1e-12, atol=1e-13)
EPS = 1e-6
REL_STEP = 1e-5
JAC_RTOL = 1e-6
NOISE = 1e-11


def _events(traj):
    return [(e.kind, e.contacts) for e in traj.events]


def _block(tmp_path_factory):
    """A point mass (2 kg) sliding on flat ground with μ = 0.5 from (1.2, -0.9) m/s: it slips
    to a stop at V / (μ g) = 0.306 s and sticks (a slip → stick event)."""
    robot = load(tmp_path_factory, "block3", BLOCK3_URDF)
    return cd.Scene(
        robot, [cd.Contact("block", friction=MU)], gravity=[0, 0, -G], q0=np.zeros(3), v0=np.array([1.2, -0.9, 0.0])
    )


def _cube(_):
    """The first shipped cube toss from its first sample, with its measured sample times: two
    frictional single-corner impacts (0.083 s, 0.142 s) within the 0.18-s horizon."""
    toss = cd.load_tosses()["toss_000"]
    return cd.cube_scene().with_state(*toss.state(0))


# scene builder, horizon (s), sample times (s), parameters, the initial-state tangent
# directions differenced (None: all; the block's along its contact only, since lifting it
# or moving it down starts it in the air or below the ground)
CASES = {
    "ball": (
        lambda _: cd.load_scene("ball"),
        5.2,
        np.linspace(0.25, 5.0, 20),
        ["contact:ball:restitution", "scene:gravity_z", "contact:ball:offset"],
        None,
    ),
    "block": (_block, 0.6, np.linspace(0.05, 0.6, 12), ["scene:gravity_z"], [0, 1, 3, 4]),
    "cube": (
        _cube,
        0.18,
        lambda: cd.load_tosses()["toss_000"].t[1:27],
        ["scene:gravity_z", "contact:cube/+x-y+z:offset"],
        None,
    ),
}


def _columns(scene, runs_plus, runs_minus, step):
    """Central differences of every sample (k, 2nv) from runs at ``+step`` and ``-step``."""
    model = scene.model
    p, m = runs_plus.samples, runs_minus.samples
    dq = np.array([pin.difference(model, a, b) for a, b in zip(m.q, p.q)])
    return np.hstack([dq, p.v - m.v]) / (2 * step)


@pytest.fixture(scope="module", params=list(CASES))
def study(request, tmp_path_factory):
    build, T, times, names, directions = CASES[request.param]
    scene = build(tmp_path_factory)
    times = np.asarray(times() if callable(times) else times)
    traj = cd.simulate(scene, T, jacobian=True, parameters=names, sample_times=times, **TOL)
    kinds = _events(traj)
    nv = scene.nv
    fd = np.full((len(times), 2 * nv, 2 * nv + len(names)), np.nan)  # NaN: a column not differenced
    for k in range(2 * nv) if directions is None else directions:
        runs = []
        for sign in (1.0, -1.0):
            d = np.zeros(2 * nv)
            d[k] = sign * EPS
            s = scene.with_state(scene.robot.integrate(scene.q0, d[:nv]), scene.v0 + d[nv:])
            run = cd.simulate(s, T, sample_times=times, **TOL)
            assert _events(run) == kinds, (k, sign)
            runs.append(run)
        fd[:, :, k] = _columns(scene, *runs, EPS)
    values = scene.parameter_values(names)
    steps = []
    for j, (name, value) in enumerate(zip(names, values)):
        h = REL_STEP * abs(value) if value else REL_STEP
        runs = [
            cd.simulate(scene.with_parameters({name: value + sign * h}), T, sample_times=times, **TOL)
            for sign in (1.0, -1.0)
        ]
        assert all(_events(r) == kinds for r in runs), name
        fd[:, :, 2 * nv + j] = _columns(scene, *runs, h)
        steps.append(h)
    return request.param, scene, traj, fd, np.array(steps)


def test_each_sample_jacobian_matches_central_differences(study):
    name, scene, traj, fd, _ = study
    s = traj.samples
    nv = scene.nv
    assert len(s) == fd.shape[0] and traj.events, name
    for k in range(len(s)):
        J = s.jacobian[k]
        # module doc: JAC_RTOL of the sample's largest entry plus the runs' noise over EPS
        tol = JAC_RTOL * np.abs(J).max() + NOISE * max(1.0, np.abs(np.r_[s.q[k], s.v[k]]).max()) / EPS
        done = ~np.isnan(fd[k, 0, : 2 * nv])
        assert done.sum() >= min(4, 2 * nv)
        assert np.abs(J[:, done] - fd[k, :, : 2 * nv][:, done]).max() <= tol, (name, s.t[k])


def test_each_sample_parameter_jacobian_matches_central_differences(study):
    name, scene, traj, fd, steps = study
    s = traj.samples
    nv = scene.nv
    for k in range(len(s)):
        size = NOISE * max(1.0, np.abs(np.r_[s.q[k], s.v[k]]).max())
        for j, h in enumerate(steps):
            col = s.parameter_jacobian[k, :, j]
            tol = JAC_RTOL * np.abs(col).max() + size / h  # module doc
            assert np.abs(col - fd[k, :, 2 * nv + j]).max() <= tol, (name, s.t[k], s.parameter_names[j])


def test_sampling_leaves_the_final_state_and_jacobians_as_they_were(study):
    """Steps end on the sample times, so the run differs from one without samples by its
    integration error only: states within NOISE max(1, |x|), Jacobians within 1e-8 of their
    size (their error is controlled with the state's at the same rtol; 1e-8 leaves a 1000x
    margin over the ~1e-11 relative error after a few events). The last sample, at the final
    time, is the final point itself."""
    name, scene, traj, _, _ = study
    plain = cd.simulate(scene, traj.t, jacobian=True, parameters=list(traj.parameter_names), **TOL)
    assert _events(plain) == _events(traj)
    x, x0 = np.r_[traj.q, traj.v], np.r_[plain.q, plain.v]
    assert np.abs(x - x0).max() <= NOISE * max(1.0, np.abs(x0).max())
    for a, b in ((traj.jacobian, plain.jacobian), (traj.parameter_jacobian, plain.parameter_jacobian)):
        assert np.abs(a - b).max() <= 1e-8 * max(1.0, np.abs(b).max()), name
    at_end = cd.simulate(
        scene, traj.t, jacobian=True, parameters=list(traj.parameter_names), sample_times=[traj.t], **TOL
    )
    assert np.array_equal(at_end.samples.jacobian[0], at_end.jacobian)
    assert np.array_equal(at_end.samples.parameter_jacobian[0], at_end.parameter_jacobian)
    assert np.array_equal(at_end.samples.q[0], at_end.q) and np.array_equal(at_end.samples.v[0], at_end.v)


def test_samples_without_jacobian_are_the_dense_states():
    """Without a Jacobian a sample holds the state alone, the run's state at that time: the
    dense output of a run without samples gives it within the integration error (NOISE)."""
    scene = cd.load_scene("ball")
    times = [0.5, 1.0, 2.0, 4.0]
    traj = cd.simulate(scene, 4.5, sample_times=times, **TOL)
    assert traj.samples.jacobian is None and traj.samples.parameter_jacobian is None
    dense = cd.simulate(scene, 4.5, dense=True, **TOL)
    q, v = dense.sample(times)
    assert np.abs(traj.samples.q - q).max() <= NOISE and np.abs(traj.samples.v - v).max() <= NOISE


@pytest.mark.parametrize("times", [(), None])
def test_no_sample_times_no_samples(times):
    assert cd.simulate(cd.load_scene("ball"), 1.0, sample_times=times).samples is None


# ---------------------------------------------------------------------------------------
# samples at events
# ---------------------------------------------------------------------------------------
E = 0.8  # the ball scene's restitution
U = math.sqrt(2.0)  # its impact speed sqrt(2 g h), g = 1, h = 1
T1 = math.sqrt(2.0)  # its first bounce, sqrt(2 h / g)


def test_a_sample_at_the_start_impact_takes_the_state_after_it():
    """The ball at z = 0 falling at 1 m/s takes an impact at t0: a sample at t0 is the state after
    it, v = e · 1, with the reset's Jacobian diag(1, -e) (z kept, v+ = -e v- at the fixed time t0)."""
    scene = cd.load_scene("ball").with_state([0.0], [-1.0])
    traj = cd.simulate(scene, 0.5, jacobian=True, sample_times=[0.0, 0.0, 0.25], **TOL)
    s = traj.samples
    assert traj.events[0].t == 0.0 and len(s) == 3
    assert s.v[0] == pytest.approx([E], rel=1e-15) and s.v[1] == s.v[0]
    assert np.abs(s.jacobian[0] - np.diag([1.0, -E])).max() <= 1e-15


def test_a_sample_at_a_bounce_takes_the_state_after_it():
    """The ball from z = 1 at rest (g = 1) bounces at t1 = sqrt(2) with speed u = sqrt(2).

    Before the bounce Φ = [[1, t], [0, 1]] (free fall). The saltation of the bounce (guard z,
    reset v+ = -e v-, fields f± = (v±, -g)) is Ξ = R + (f+ - R f-) nᵀ / (n·f-) with R = diag(1, -e),
    n = (1, 0): Ξ = [[-e, 0], [(1 + e) g / u, -e]]. The right limit is Ξ Φ(t1) =
    [[-e, -e t1], [(1 + e)/√2, (1 + e) - e]] = [[-e, -e√2], [(1 + e)/√2, 1]]; the left limit is
    Φ(t1) = [[1, √2], [0, 1]].

    The sample time is the bounce time of a run without samples; the sampled run locates the
    bounce by root finding again, so the sample is after the bounce when the located time is at
    or before it (the documented rule), else before: each case is held to its closed form
    (1e-9: the bounce time's error, ~rtol, times the O(1) slopes, with margin).
    """
    scene = cd.load_scene("ball")
    t_s = cd.simulate(scene, 2.0, **TOL).events[0].t
    assert t_s == pytest.approx(T1, rel=1e-12)
    traj = cd.simulate(scene, 2.0, jacobian=True, sample_times=[t_s], **TOL)
    s, event = traj.samples, traj.events[0]
    if event.t <= t_s:
        expected_v, expected = E * U, np.array([[-E, -E * math.sqrt(2)], [(1 + E) / math.sqrt(2), 1.0]])
    else:
        expected_v, expected = -U, np.array([[1.0, math.sqrt(2)], [0.0, 1.0]])
    assert s.v[0, 0] == pytest.approx(expected_v, abs=1e-9)
    assert np.abs(s.jacobian[0] - expected).max() <= 1e-9
    if event.t == t_s:  # exactly at the event: the state its reset gave
        assert np.array_equal(s.v[0], event.v_plus) and np.array_equal(s.q[0], event.q)


# ---------------------------------------------------------------------------------------
# bad sample times
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "times, message",
    [
        ([-0.1, 0.5], r"sample_times\[0\] = -0.1 s is outside the run's \[t0, t_final\] = \[0.0, 1.0\]"),
        ([0.5, 1.5], r"sample_times\[1\] = 1.5 s is outside"),
        ([0.5, 0.25], r"non-decreasing; sample_times\[1\] = 0.25 s comes after sample_times\[0\] = 0.5 s"),
        ([0.5, float("nan")], r"sample_times\[1\] = nan is not a finite time"),
        ([[0.1, 0.2]], r"1-D sequence"),
        ("soon", r"sequence of times"),
    ],
)
def test_bad_sample_times_are_refused_by_name(times, message):
    with pytest.raises(InvalidInputError, match=message):
        cd.simulate(cd.load_scene("ball"), 1.0, sample_times=times)


def test_samples_before_t0_are_refused_with_a_later_start():
    with pytest.raises(
        InvalidInputError,
        match=r"sample_times\[0\] = 0.5 s is outside the run's "
        r"\[t0, t_final\] = \[1.0, 2.0\]",
    ):
        cd.simulate(cd.load_scene("ball"), 2.0, t0=1.0, sample_times=[0.5, 1.5])


def test_radau_samples_agree_with_dop853():
    """The samples are the steppers' own points: Radau IIA's (third-order error estimate, its
    Jacobian good to ~1e-7 at rtol 1e-12, see test_parameter_sensitivity.py) and DOP853's agree
    within 1e-6 of the Jacobians' size (a wrong saltation or a sample off its time is O(1))."""
    scene = cd.load_scene("ball")
    times = [0.5, 1.0, 2.0, 3.0, 4.0]
    names = ["contact:ball:restitution"]
    runs = [
        cd.simulate(scene, 4.5, jacobian=True, parameters=names, sample_times=times, method=m, **TOL)
        for m in ("DOP853", "Radau")
    ]
    a, b = (r.samples for r in runs)
    assert np.abs(a.jacobian - b.jacobian).max() <= 1e-6 * np.abs(a.jacobian).max()
    assert np.abs(a.parameter_jacobian - b.parameter_jacobian).max() <= 1e-6 * np.abs(a.parameter_jacobian).max()


def test_a_run_stopped_early_holds_the_samples_it_reached():
    """The ball's event budget of 1 runs out at its second bounce (t = √2 + 2 e √2 = 3.68 s): the
    run on the error holds the samples before it, not the one at 4 s."""
    with pytest.raises(cd.TooManyEventsError) as info:
        cd.simulate(cd.load_scene("ball"), 4.5, jacobian=True, sample_times=[0.5, 2.0, 4.0], max_events=1, **TOL)
    s = info.value.trajectory.samples
    assert s.t.tolist() == [0.5, 2.0] and s.jacobian.shape == (2, 2, 2) and s.q.shape == (2, 1)
