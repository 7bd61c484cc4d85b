"""Long horizons: the outcome of a run does not depend on how far it is asked to go.

A run that comes to rest must stay at rest, with the same events, whether ``t_final``
is 100 s or 1e9 s. Regression: free flight under constant gravity is a polynomial,
which DOP853 integrates exactly (zero error estimate), so its steps grew tenfold each
time up to ``t_final``; a ball's last bounces (1e-6 m/s, flights of 2e-6 s) then fell
inside steps thousands of seconds long whose end lay 1e7 m below the ground, the
grazing band (10 rtol |q|) taken there was a metre wide, and the ball sank through the
ground and came back at 1.58 m/s (t_final = 5000) or bounced forever (1e4, 1e9).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import contactdiff as cd

E = 0.8  # the ball's restitution (robots/ball.toml; h = 1 m, g = 1 m/s²)
ZENO_SPEED = 1e-6  # SimulateOptions.zeno_speed's default (m/s)


def _ball_closed_form():
    """Impacts of robots/ball.toml up to the Zeno rule: ``(times, speeds)``.

    Dropped from h = 1 under g = 1 it lands at t_0 = sqrt(2h/g) = sqrt(2) with speed
    u_0 = sqrt(2 g h) = sqrt(2); each bounce leaves at e u_k and lands again after a
    flight of 2 e u_k / g at u_{k+1} = e u_k. The Zeno rule ends the sequence at the
    first impact slower than zeno_speed: k = ceil(ln(zeno / sqrt 2) / ln e) = 64
    (sqrt 2 · 0.8^63 = 1.1e-6, sqrt 2 · 0.8^64 = 8.9e-7), so 65 events, the last of
    kind "zeno", all before the Zeno time sqrt 2 (1 + 2e / (1 - e)) = 9 sqrt 2 = 12.728 s.
    """
    n = math.ceil(math.log(ZENO_SPEED / math.sqrt(2.0)) / math.log(E)) + 1
    speeds = [math.sqrt(2.0) * E ** k for k in range(n)]
    times = [math.sqrt(2.0)]
    for u in speeds[:-1]:
        times.append(times[-1] + 2.0 * E * u)
    return times, speeds


@pytest.mark.parametrize("t_final", [100.0, 5000.0, 1e4, 1e9])
def test_ball_rests_whatever_the_final_time(t_final):
    """The ball of robots/ball.toml bounces 65 times (closed form above) and rests on the
    ground at every final time; its energy never exceeds the initial g h = 1 J/kg.

    Tolerances: event times and speeds carry the integration error of rtol = 1e-8
    accumulated over 65 events (a few 1e-8 relative); 1e-6 s and 1e-7 m/s leave a wide
    margin. Energy: the speed at an impact is sqrt(2) (1 + O(1e-8)), so 1/2 v² <= 1 + 1e-7.
    At rest the contact is held on its manifold (project_tol = atol = 1e-10 m)."""
    times, speeds = _ball_closed_form()
    assert len(times) == 65
    traj = cd.simulate(cd.load_scene("ball"), t_final)
    assert traj.termination is cd.Termination.T_FINAL
    assert len(traj.events) == len(times)
    assert [e.kind for e in traj.events] == ["bounce"] * 64 + ["zeno"]
    for event, t_k, u_k in zip(traj.events, times, speeds):
        assert event.t == pytest.approx(t_k, abs=1e-6)
        assert -event.v_minus[0] == pytest.approx(u_k, abs=1e-7)
        for v in (event.v_minus[0], event.v_plus[0]):
            assert 0.5 * v * v + event.q[0] <= 1.0 + 1e-7
    assert traj.t == t_final
    assert abs(traj.q[0]) <= 1e-10 and traj.v[0] == 0.0
    assert traj.modes[-1] == ("ball",)
    # the rest costs a few steps, not steps in proportion to t_final
    assert traj.stats.steps <= 200


@pytest.fixture(scope="module")
def settled_solo():
    """solo12_drop run for 10 s: dropped 5 cm, it lands on its four sticking feet and its
    joint dampers remove the motion (test_hybrid.test_solo12_drop)."""
    scene = cd.load_scene("solo12_drop")
    return scene, cd.simulate(scene, 10.0)


def test_resting_quadruped_over_a_long_horizon(settled_solo):
    """solo12_drop to t_final = 1e4 s: the same landing, then it stands where it came to
    rest, on its four feet, and the run stays cheap.

    Regression: at rest Radau IIA (method auto switches to it there, the joint springs
    being stiff) failed Newton on steps longer than ~0.1 s: along the feet's constrained
    directions the field is a double integrator, so the contact forces' round-off
    (~1e-13 m/s²) gives Newton increments of h times it, which stop contracting at a few
    1e-4 of the tolerance; every such step was rejected, and 1e4 s took 12,958 steps and
    27,574 rejections. Newton now accepts an iteration stalled far below the tolerance
    (radau.NEWTON_STALL_TOL). The bound of 5,000 steps is half that old count; steps of
    several seconds take ~1,000 (seconds each, as long as the stalled increments stay
    below 0.03 of the tolerance: h ~ 0.03 atol / 1e-13 m/s² = 30 s at most).

    Tolerances: the pose it rests in is held on the contact manifold to project_tol =
    atol = 1e-10 m, and the drift between projections is of that size; 1e-8 m and 1e-8
    rad leave a margin of 100. Velocities: damped to 1e-12 m/s at 10 s (the run's own
    noise floor), 1e-9 m/s allows that noise to accumulate over 1e4 s."""
    scene, settled = settled_solo
    traj = cd.simulate(scene, 1e4)
    assert traj.termination is cd.Termination.T_FINAL and traj.t == 1e4
    assert [(e.t, e.kind) for e in traj.events] == [(e.t, e.kind) for e in settled.events]
    assert set(traj.modes[-1]) == set(scene.contact_names)
    np.testing.assert_allclose(traj.q, settled.q, atol=1e-8)
    assert np.max(np.abs(traj.v)) <= 1e-9
    assert np.max(np.abs(scene.gaps(traj.q))) <= 1e-8
    assert traj.stats.steps <= 5000
