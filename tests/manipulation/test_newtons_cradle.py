"""Newton's cradle (robots/newtons_cradle.toml): three equal balls in a row, elastic contacts.

Ball 1 (mass m) strikes balls 2 and 3 at speed u; 2 and 3 touch at rest, so their
contact is closed with zero force: the impact meets a resting contact.

**Together** (the run: both contacts closed at the impact, Newton's law on each,
e = 1). With impulses P12, P23 >= 0, v1 = u - P12/m, v2 = (P12 - P23)/m,
v3 = P23/m, and both contacts active, the gap rates after are
v2 - v1 = -e (0 - u) = u and v3 - v2 = -e 0 = 0:
2 P12 - P23 = 2 m u and 2 P23 - P12 = 0, so P23 = 2mu/3, P12 = 4mu/3 (both > 0: the
solution of the impact's LCP, unique as G is positive definite) and

    (v1, v2, v3) = (-u/3, 2u/3, 2u/3).

**As a cascade** (any gap between 2 and 3): 1 and 2 exchange velocities, then 2 and 3:
(0, 0, u). Both outcomes keep the momentum m u and the energy m u²/2
(1/9 + 4/9 + 4/9 = 1), and differ by up to 2u/3. The coupling of the two contacts,
G = A M^-1 A^T = [[2, -1], [-1, 2]] / m, is G_12 / sqrt(G_11 G_22) = -1/2.
"""

from __future__ import annotations

import numpy as np
import pytest

import contactdiff as cd

U = 1.0  # m/s, the scene's initial speed of ball 1
MASS = 0.26  # kg, each ball
X = [0, 6, 12]  # tangent indices of the balls' x velocities (6 per free-flyer)
# the impact law's velocities are sums of a few O(u) terms: round-off ~1e-16 u
VEL_ATOL = 1e-12  # m/s


@pytest.fixture(scope="module")
def cradle():
    return cd.load_scene("newtons_cradle")


@pytest.fixture(scope="module")
def run(cradle):
    return cd.simulate(cradle, 0.3)


def _momentum_energy(v):
    speeds = v[X]
    return MASS * speeds.sum(), 0.5 * MASS * (speeds**2).sum()


def test_touching_balls_take_the_simultaneous_impact(run):
    (impact,) = run.events
    assert impact.contacts == ("ball1-ball2",)
    assert impact.t == pytest.approx(0.1, abs=1e-12)  # 0.1 m at 1 m/s
    np.testing.assert_allclose(run.v[X], [-U / 3, 2 * U / 3, 2 * U / 3], atol=VEL_ATOL)
    others = np.delete(run.v, X)  # no transverse or spin velocity: every normal is along x
    np.testing.assert_allclose(others, 0.0, atol=VEL_ATOL)


def test_the_impact_against_the_resting_balls_is_flagged_with_both_outcomes(run):
    (impact,) = run.events
    assert set(impact.nonsmooth) == {cd.NonSmooth.RESTING_CONTACT} and not run.differentiable
    assert "ball2-ball3" in impact.nonsmooth[cd.NonSmooth.RESTING_CONTACT]
    np.testing.assert_allclose(impact.outcomes["simultaneous"][X], [-U / 3, 2 * U / 3, 2 * U / 3], atol=VEL_ATOL)
    np.testing.assert_allclose(impact.outcomes["cascade"][X], [0.0, 0.0, U], atol=VEL_ATOL)


def test_a_tiny_gap_gives_the_cascade(cradle):
    opened = cd.simulate(cradle.with_state(q0={"ball3": [0.04 + 1e-9, 0, 0, 0, 0, 0, 1]}), 0.3)
    assert [e.contacts for e in opened.events] == [("ball1-ball2",), ("ball2-ball3",)]
    assert opened.events[1].t - opened.events[0].t == pytest.approx(1e-9, rel=1e-3)  # 1 nm at u
    np.testing.assert_allclose(opened.v[X], [0.0, 0.0, U], atol=VEL_ATOL)
    assert opened.differentiable  # each impact alone: nothing resting, nothing simultaneous


@pytest.mark.parametrize("gap", [0.0, 1e-9])
def test_momentum_and_energy_are_kept(cradle, gap):
    scene = cradle.with_state(q0={"ball3": [0.04 + gap, 0, 0, 0, 0, 0, 1]})
    traj = cd.simulate(scene, 0.3)
    p0, e0 = _momentum_energy(scene.v0)
    p1, e1 = _momentum_energy(traj.v)
    assert p1 == pytest.approx(p0, abs=1e-12 * MASS * U)
    assert e1 == pytest.approx(e0, abs=1e-12 * MASS * U**2)


def test_the_checker_finds_the_contacts_coupled_through_the_middle_ball(cradle):
    report = cd.check_decoupling(cradle, samples=4)
    (pair,) = report.pairs
    assert pair.reference == pytest.approx(0.5, abs=1e-12)  # |G_12| / sqrt(G_11 G_22), module doc
    assert report.verdict == "coupled"
