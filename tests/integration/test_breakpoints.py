"""Breakpoints of time-dependent efforts: the integrator ends a step exactly on each.

Reference values are closed forms: the ball (mass 1, g = 1, vertical joint ``z``)
in free flight under a force ramped up linearly and then held (continuous, with a
kink), whose motion is a cubic in time on each piece; and the trot controller's torques, which between two
consecutive breakpoints are one polynomial in time (smooth steps are quintics,
the reference spline's pieces cubics: a product of degree at most 8).
"""

from __future__ import annotations

import numpy as np
import pytest

import contactdiff as cd
from contactdiff.errors import InvalidInputError

T_SWITCH = 0.3  # s: the ramp ends here (the force's time derivative jumps)
FORCE = 0.5  # N, upwards, reached at T_SWITCH and held
T_FINAL = 0.9  # s: before the ball lands (z stays above 0.7)


def _ball(breakpoints=()):
    def push(q, v, t):
        return np.array([FORCE * min(t / T_SWITCH, 1.0)])

    effort = cd.UserEffort(
        push, jacobian=lambda q, v, t: (np.zeros((1, 1)), np.zeros((1, 1))), name="push", breakpoints=breakpoints
    )
    base = cd.load_scene("ball")
    return cd.Scene(base.robot, base.contact_specs, [effort], gravity=[0.0, 0.0, -1.0], q0=base.q0)


def _closed_form(t):
    """Height and velocity of the ball at ``t`` >= T_SWITCH (z0 = 1, at rest): on the
    ramp ``z'' = -1 + FORCE t / T_SWITCH``, then ``z'' = FORCE - 1``."""
    r = FORCE / T_SWITCH
    z1 = 1.0 - T_SWITCH**2 / 2 + r * T_SWITCH**3 / 6
    v1 = -T_SWITCH + r * T_SWITCH**2 / 2
    a2, s = FORCE - 1.0, t - T_SWITCH
    return z1 + v1 * s + 0.5 * a2 * s**2, v1 + a2 * s


@pytest.mark.parametrize("method", ["DOP853", "RK45", "Radau"])
def test_a_step_ends_on_the_breakpoint_and_the_cubic_pieces_are_exact(method):
    traj = cd.simulate(_ball(breakpoints=(T_SWITCH,)), T_FINAL, dense=True, method=method)
    ends = [p.t for seg in traj.segments for p in seg.pieces]
    assert T_SWITCH in ends
    # Each piece of the motion is a cubic in t, which every method here (order 5 or
    # 8; Radau's collocation polynomial has degree 3) integrates exactly: the error
    # estimate is round-off, no step is rejected, and the end state is the closed
    # form up to round-off (a few eps times the O(1) state, over ~10 steps).
    assert traj.stats.rejected_steps == 0
    z, v = _closed_form(T_FINAL)
    assert abs(traj.q[0] - z) < 1e-13 and abs(traj.v[0] - v) < 1e-13
    assert traj.events == []


def test_without_the_breakpoint_the_stepper_trips_over_the_kink():
    """The contrast that makes breakpoints worth declaring: the same run, the kink not
    declared, rejects steps across it (the third derivative of z jumps there) and is
    accurate only to its tolerance."""
    traj = cd.simulate(_ball(), T_FINAL)
    assert traj.stats.rejected_steps > 0
    z, v = _closed_form(T_FINAL)
    # the default tolerances (rtol 1e-8, atol 1e-10) over a few steps across the jump
    assert abs(traj.q[0] - z) < 1e-6 and abs(traj.v[0] - v) < 1e-6


def test_user_breakpoints_are_checked():
    with pytest.raises(InvalidInputError, match="breakpoint"):
        cd.UserEffort(lambda q, v, t: q, breakpoints=("soon",))
    with pytest.raises(InvalidInputError, match="breakpoints must be a sequence"):
        cd.UserEffort(lambda q, v, t: q, breakpoints=0.3)
    effort = cd.UserEffort(lambda q, v, t: q, breakpoints=(0.5, 0.2, 0.5)).bind(cd.load_scene("ball").robot)
    assert [effort.next_breakpoint(t) for t in (0.0, 0.2, 0.3, 0.5)] == [0.2, 0.5, 0.5, np.inf]


def test_trot_torques_are_one_polynomial_between_breakpoints():
    """Between consecutive breakpoints of the trot schedule the torques at a fixed state
    are one polynomial of degree <= 8 in t (module docstring): a least-squares fit of
    that degree through 13 points of the interval leaves only round-off. A breakpoint
    missing from the list would leave a jump of the third derivative inside an interval,
    and a residual of the order of that jump times the interval cubed (~1e-2 of the
    torques on solo12, far above the bound)."""
    scene = cd.load_scene("solo12_trot")
    controller = scene.efforts[0]
    kin = scene.kinematics
    kin.update(scene.q0, np.zeros(scene.nv))
    period = controller.spec.period
    t, worst, n_intervals = 0.0, 0.0, 0
    while t < period:
        t_next = controller.next_breakpoint(t)
        assert t_next > t
        # Chebyshev points of the interval (the fit is then well conditioned)
        x = np.cos(np.pi * (np.arange(13) + 0.5) / 13)
        times = t + (t_next - t) * (x + 1) / 2
        tau = np.array([controller.tau(kin, s) for s in times])
        fit = np.polynomial.chebyshev.chebfit(x, tau, 8)
        residual = tau - np.polynomial.chebyshev.chebval(x, fit).T
        # round-off: the torques (~1 N m) are sums of a few terms of size kp*|q| ~ 20
        worst = max(worst, np.max(np.abs(residual)) / 20.0)
        t, n_intervals = t_next, n_intervals + 1
    assert worst < 1e-12
    assert n_intervals >= controller.spec.samples  # at least the spline's knots


def test_trot_breakpoints_are_the_knots_and_the_smooth_step_ends():
    scene = cd.load_scene("solo12_trot")
    controller = scene.efforts[0]
    spec, period = controller.spec, controller.spec.period
    breaks = []
    t = -1e-12
    while (t := controller.next_breakpoint(t)) < period:
        breaks.append(t / period)
    breaks = np.array(breaks)
    # every knot of the reference spline, k / samples
    knots = np.arange(spec.samples) / spec.samples
    assert np.all(np.min(np.abs(breaks[:, None] - knots[None, :]), axis=0) < 1e-12)
    # every leg's scheduled lift-off (the gain's kink at psi = duty) and touchdown
    # (where the load starts to rise at psi = 0)
    for leg in range(4):
        for phase in (controller.scheduled_liftoff(leg), controller.scheduled_touchdown(leg)):
            assert np.min(np.abs(breaks - phase % 1.0)) < 1e-12


def test_breakpoints_move_where_steps_end_not_the_trot():
    """Ending steps on the trot schedule's breakpoints changes the steps, not the
    solution: one period of the solo12 trot (about 30 events) with and without them, both
    at rtol 1e-10, has the same events and, within the integration error, the same
    times and final state. Bounds: each run's state error is of order 10 rtol per
    unit size, amplified over the period by at most 10 (the trot is a stable gait:
    its Floquet multipliers are below 0.4), i.e. 1e-8 in q (rad, m); event times
    within that gap error over approach speeds of order 0.1 m/s, 1e-7 s;
    velocities within 100 times the q bound, 1e-6 (the legs' PD and impacts act on
    the 1e-2-s scale)."""
    scene = cd.load_scene("solo12_trot")
    options = dict(rtol=1e-10, atol=1e-12)
    with_breaks = cd.simulate(scene, 0.4, **options)
    controller = scene.efforts[0]
    controller.next_breakpoint = lambda t: np.inf  # the schedule's kinks stepped across, as before
    try:
        without = cd.simulate(scene, 0.4, **options)
    finally:
        del controller.next_breakpoint
    assert without.stats.rejected_steps > 3 * with_breaks.stats.rejected_steps
    assert [(e.kind, e.contacts) for e in with_breaks.events] == [(e.kind, e.contacts) for e in without.events]
    times = np.array([[a.t, b.t] for a, b in zip(with_breaks.events, without.events)])
    assert np.max(np.abs(times[:, 0] - times[:, 1])) < 1e-7
    dq = scene.robot.difference(without.q, with_breaks.q)
    assert np.max(np.abs(dq)) < 1e-8 and np.max(np.abs(with_breaks.v - without.v)) < 1e-6


def test_a_breakpoint_that_is_not_ahead_is_named():
    scene = _ball(breakpoints=(T_SWITCH,))
    scene.efforts[0].next_breakpoint = lambda t: t  # a broken effort of one's own
    with pytest.raises(InvalidInputError, match="next_breakpoint"):
        cd.simulate(scene, T_FINAL)
