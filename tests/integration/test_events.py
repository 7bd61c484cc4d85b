"""Guard helpers and double crossings inside one step."""

import numpy as np
import pytest

import contactdiff as cd
from contactdiff.ode.crossings import _quadratic_roots, hermite_minimum, locate_crossing, simultaneous_group


def test_hermite_minimum_of_an_exact_cubic():
    """g(t) = (t - 0.3)(t - 0.6)(t + 1) on [0, 1]: the Hermite interpolant of a cubic
    is the cubic, whose interior minimum is at the root of g' in (0.3, 0.6)."""
    g = np.poly1d(np.poly([0.3, 0.6, -1.0]))
    dg = g.deriv()
    s, value = hermite_minimum(g(0), dg(0), g(1), dg(1), 1.0)
    s_exact = [r for r in dg.r if 0.3 < r < 0.6][0]
    assert s == pytest.approx(s_exact, abs=1e-12)
    assert value == pytest.approx(g(s_exact), abs=1e-12) and value < 0


def test_hermite_minimum_scales_with_the_step():
    """Same curve over a step of length h: rates are per second, so d0 h is the slope in s."""
    h = 0.01
    s, value = hermite_minimum(1.0, -300.0, 1.0, 300.0, h)  # p(s) = 1 - 3 s (1 - s) ... dips to 0.25
    assert s == pytest.approx(0.5) and value == pytest.approx(1 - 0.75, abs=1e-12)


@pytest.mark.parametrize("roots", [(0.3, 0.6), (-2.0, 1e-9), (1e8, 1e-8), (0.5, 0.5), (0.0, 3.0)])
@pytest.mark.parametrize("scale", [1.0, -1e-6, 1e6])
def test_quadratic_roots_recover_known_roots(roots, scale):
    """The coefficients of scale (x - r1)(x - r2) give back r1 and r2, each to a few
    ulps relative to itself (the cancellation-free form; np.roots loses the small
    root of (1e8, 1e-8) to cancellation)."""
    r1, r2 = roots
    found = sorted(_quadratic_roots(scale, -scale * (r1 + r2), scale * r1 * r2))
    for got, want in zip(found, sorted(roots)):
        assert got == pytest.approx(want, rel=1e-7 if r1 == r2 else 1e-14, abs=1e-300)


def test_quadratic_roots_degenerate_cases():
    assert _quadratic_roots(1.0, 0.0, 1.0) == []  # x^2 + 1: no real root
    assert _quadratic_roots(0.0, 2.0, -1.0) == [0.5]  # linear
    assert _quadratic_roots(0.0, 0.0, 1.0) == []  # constant


def test_no_dip_when_monotone():
    s, value = hermite_minimum(1.0, 1.0, 2.0, 1.0, 1.0)
    assert s == 0.0 and value == 1.0


def test_locate_crossing_to_full_precision():
    t = locate_crossing(lambda t: np.cos(t), 0.0, 3.0)
    assert abs(t - np.pi / 2) <= 4 * np.finfo(float).eps * 3


@pytest.mark.parametrize("shift, expected", [(0.1, 1.0), (-0.1, 0.0)])
def test_locate_crossing_where_round_off_moved_the_bracket(shift, expected):
    """The step's values bracket a crossing (1e-16 above zero at the start, below at the end)
    but the guard as evaluated does not: shifted up, it stays positive over the step, so the
    crossing is at the end; shifted down, it is already at or below zero at the start."""

    def guard(t):
        return 1e-16 - 2e-16 * t + shift

    assert locate_crossing(guard, 0.0, 1.0, g_a=1e-16, g_b=-1e-16) == expected


def test_locate_crossing_needs_a_bracket():
    with pytest.raises(ValueError, match="no bracket"):
        locate_crossing(lambda t: 1.0 + t, 0.0, 1.0)


def test_simultaneous_group():
    t, group = simultaneous_group([(1.0 + 5e-10, "b"), (1.0, "a"), (1.1, "c")], tol=1e-9)
    assert t == 1.0 and group == ["a", "b"]


@pytest.mark.parametrize("rtol", [1e-3, 1e-6])
def test_a_dip_below_the_ground_inside_one_step_is_found(rtol):
    """A ball on a spring (k = 100, rest 0.5, no gravity) from z = 0.5 with speed
    -5.0005: z(t) = 0.5 - 0.50005 sin(10 t) dips to -5e-5 for 2.8 ms. The same run
    without the contact shows that no step ends inside the dip (both ends of the
    step above ground), yet the touchdown is found, at sin(10 t) = 0.5 / 0.50005."""
    robot = cd.load_robot("ball")
    spring = [cd.JointSpring("z", stiffness=100.0, rest=0.5)]
    state = dict(gravity=[0, 0, 0], q0={"z": 0.5}, v0={"z": -5.0005})
    t_in = np.arcsin(0.5 / 0.50005) / 10
    t_out = (np.pi - np.arcsin(0.5 / 0.50005)) / 10
    free = cd.simulate(cd.Scene(robot, [], spring, **state), 0.2, rtol=rtol, atol=rtol * 1e-2)
    ends = [p.t for seg in free.segments for p in seg.pieces]
    assert not any(t_in <= t <= t_out for t in ends)
    scene = cd.Scene(robot, [cd.Contact("ball", restitution=1.0)], spring, **state)
    traj = cd.simulate(scene, 0.2, rtol=rtol, atol=rtol * 1e-2)
    assert [e.kind for e in traj.events] == ["bounce"]
    assert traj.events[0].t == pytest.approx(t_in, abs=1e3 * rtol)


def _stop_crossing(h, t_a, t_b, from_rest: bool):
    """Where `GuardFinder` locates the stop guard ``h(t)`` (m/s) of a slipping corner over
    one step ``[t_a, t_b]`` (the first after an event that started it from rest, if
    ``from_rest``): the cube with every corner in the mode (no gap to watch), the dense
    output and the mode's guard values replaced by ``h`` alone, the noise floor of the
    slip direction the hybrid loop's (``zeno_speed``)."""
    from types import SimpleNamespace

    from contactdiff.dynamics.mode import ModeDynamics
    from contactdiff.integration.guards import Guard, GuardFinder, GuardKind
    from contactdiff.integration.options import SimulateOptions

    scene = cd.cube_scene(friction=0.5)
    options = SimulateOptions()
    dyn = ModeDynamics(scene, slip_speed_floor=options.zeno_speed)
    mode = tuple(dyn.sliding_key(i) for i in range(len(scene.contacts)))
    field = SimpleNamespace(guards=[Guard(GuardKind.STOP, mode[0])], guard_values=lambda t, q, v: np.array([h(t)]))
    stepper = SimpleNamespace(t_old=t_a, t=t_b, q=scene.q0, q_old=scene.q0)
    zeros = np.zeros(len(scene.contacts))
    finder = GuardFinder(scene, dyn, options, 1e-12)
    finder.from_rest = {mode[0]} if from_rest else set()
    found, _ = finder.crossings(
        stepper,
        lambda t: (scene.q0, scene.v0),
        field,
        mode,
        (zeros, zeros, np.array([h(t_a)])),
        (zeros, zeros, np.array([h(t_b)])),
    )
    return [t for t, _ in found], options.zeno_speed


@pytest.mark.parametrize("start", [1e-17, 0.0, -1e-17])
def test_a_slip_restarted_from_rest_stops_only_past_the_noise_floor(start):
    """A slip an event restarted from rest (its velocity held to zero at a stop, then
    slipping on) starts at round-off of either sign, +1e-17 m/s seen on a measured toss
    (μ 0.5, e 0);
    below the floor ε (zeno_speed) its direction is noise, so its stop guard
    ``h = s · u_T`` fires only once h passes -ε (docs: a slip below the floor follows its
    reference). A dense output reversing from the start, h(t) = start - a (t - t_a)² with
    a = 4.1 m/s³ (2.8 mm/s over a 26 ms step, as there), then crosses -ε at
    t_a + sqrt((start + ε) / a) whatever the start's sign; located at h = 0 instead (at
    t_a + 1.6e-9 s for +1e-17), the stop repeated at the same instant after every restart
    and the run never advanced. Tolerance: the crossing is located to 4 ulp in time, where
    |dh/dt| = 2 sqrt(a ε) ~ 4e-3 m/s²: h to ~1e-18 m/s."""
    t_a, t_b, a = 0.3, 0.326, 4.1
    found, floor = _stop_crossing(lambda t: start - a * (t - t_a) ** 2, t_a, t_b, from_rest=True)
    assert found == [pytest.approx(t_a + np.sqrt((start + floor) / a), abs=1e-14)]


@pytest.mark.parametrize("speed, from_rest", [(1e-3, True), (1e-3, False), (5e-7, False)])
def test_a_slowing_slip_stops_at_zero(speed, from_rest):
    """A slip that was moving at the step start (faster than the floor, or slower but not
    just started from rest: it slowed down into the band), decelerating at 1 m/s², stops
    where its speed along its direction is zero: at t_a + speed / (1 m/s²), to the
    crossing's 4 ulp in time."""
    t_a = 0.3
    found, _ = _stop_crossing(lambda t: speed - (t - t_a), t_a, t_a + 0.01, from_rest)
    assert found == [pytest.approx(t_a + speed, abs=1e-14)]
