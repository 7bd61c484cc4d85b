"""Stick → slip and slip → slip events of Coulomb friction in the loop, with their
saltation matrices.

Model: the planar leg of `helpers.LEG_URDF` (a body free in x and z with a rigid
leg on a hip hinge), landing inclined by 0.4 rad; from t = 0.1 s an upward force
on the body ramps at 30 N/s and unloads the foot, whose friction coefficient is μ.

* μ = 1: the foot lands sticking; as the load drops, the tangential force it needs
  reaches the cone (``|λ_T| = μ λ_N``) and it slips (event ``slip``), then lifts off.
* μ = 0.3: the frictional impact leaves it sliding; it stops, cannot stick, and
  slides back (an event ``slip`` on a slipping contact: the slip reverses).

References: the cone and the slip direction written out from the sticking forces
(the mode's Newton-Euler solve at the event state), ``Ξ = I`` where the field is
continuous, and central finite differences of the simulator.
"""

from __future__ import annotations

import numpy as np
import pytest
from helpers import LEG_RAMP, LEG_RAMP_START, LEG_URDF, assert_fd, leg_lift, leg_lift_jacobian, leg_lift_rate

import contactdiff as cd
from contactdiff.dynamics.mode import ModeDynamics

TILT, RAMP, RAMP_START = 0.4, LEG_RAMP, LEG_RAMP_START  # rad, N/s, s
T_FINAL = 0.6  # s
TOL = dict(rtol=1e-12, atol=1e-13)
FD_TOL = dict(rtol=1e-13, atol=1e-14)
# Central differences with ε = 1e-6: truncation ε² |x'''| ≈ 1e-12 |x'''| (|x'''| reaches 1e6 at the
# touchdown-time shift: measured 2.6e-5 at ε = 1e-4, 2.3e-9 at ε = 1e-6), and the perturbed runs'
# error 1e-13 |x| / ε ≈ 1e-7 |x|. Relative to the Jacobian's size (≈ 10), 2e-7 leaves 2x margin over
# both while a wrong saltation term (O(1)) cannot pass.
EPS, FD_RTOL = 1e-6, 2e-7


@pytest.fixture(scope="module")
def leg_robot(tmp_path_factory):
    path = tmp_path_factory.mktemp("leg") / "leg.urdf"
    path.write_text(LEG_URDF)
    return cd.load_robot(path)


def _scene(robot, mu, x0=None) -> cd.Scene:
    effort = cd.UserEffort(leg_lift, leg_lift_jacobian, name="lift", time_derivative=leg_lift_rate)
    q0, v0 = (np.array([0.0, 0.5 * np.cos(TILT) + 0.01, TILT]), np.zeros(3)) if x0 is None else (x0[:3], x0[3:])
    return cd.Scene(robot, [cd.Contact("foot", friction=mu)], [effort], gravity=[0, 0, -9.81], q0=q0, v0=v0)


def _fd_jacobian(robot, mu, x0):
    cols = []
    for k in range(6):
        d = np.zeros(6)
        d[k] = EPS
        plus = cd.simulate(_scene(robot, mu, x0 + d), T_FINAL, **FD_TOL)
        minus = cd.simulate(_scene(robot, mu, x0 - d), T_FINAL, **FD_TOL)
        cols.append((np.r_[plus.q, plus.v] - np.r_[minus.q, minus.v]) / (2 * EPS))
    return np.array(cols).T


@pytest.fixture(scope="module")
def sticking_run(leg_robot):
    scene = _scene(leg_robot, 1.0)
    return scene, cd.simulate(scene, T_FINAL, jacobian=True, **TOL)


def test_stick_to_slip_on_the_cone(sticking_run):
    scene, traj = sticking_run
    assert [e.kind for e in traj.events] == ["touchdown", "slip", "lift-off"]
    touchdown, slip, _ = traj.events
    assert touchdown.sliding == () and slip.sliding == ("foot",) and not slip.nonsmooth
    dyn = ModeDynamics(scene)
    # at the event the sticking force is on the cone: |λ_T| = μ λ_N to the located time's precision
    normal, tangential = dyn.solve(slip.q, slip.v_minus, slip.t, (0,)).forces
    assert abs(abs(tangential) - 1.0 * normal) < 1e-9 * normal  # N: Brent locates to ~1e-15 s
    # the slip then opposes the force that held the foot: it moves along -λ_T
    seg = traj.segments[2]
    assert seg.sliding == ("foot",)
    kin = scene.kinematics
    q, v = traj.events[2].q, traj.events[2].v_minus
    kin.update(q, v)
    assert np.sign(scene.contacts[0].rows(kin)[1] @ v) == -np.sign(tangential)


def test_stick_to_slip_saltation_is_identity(sticking_run):
    """The slip's friction equals the sticking force at the threshold: the field is
    continuous, so Ξ = I (up to the round-off of the two mode solves)."""
    _, traj = sticking_run
    assert np.max(np.abs(traj.events[1].saltation - np.eye(6))) < 1e-9


def test_stick_to_slip_jacobian_matches_fd(leg_robot, sticking_run):
    _, traj = sticking_run
    x0 = np.r_[traj.q0, traj.v0]
    assert_fd("loop stick->slip", traj.jacobian, _fd_jacobian(leg_robot, 1.0, x0), rtol=FD_RTOL)


def test_slip_reversal_jacobian_matches_fd(leg_robot):
    scene = _scene(leg_robot, 0.3)
    traj = cd.simulate(scene, T_FINAL, jacobian=True, **TOL)
    assert [e.kind for e in traj.events] == ["touchdown", "slip"]
    touchdown, reversal = traj.events
    assert touchdown.sliding == ("foot",) and reversal.mode_before == reversal.mode_after == ("foot",)
    # the foot's slip velocity changes sign at the reversal
    kin = scene.kinematics
    speeds = []
    for s in (reversal.t - 1e-3, reversal.t + 1e-3):
        run = cd.simulate(scene, s, **TOL)
        kin.update(run.q, run.v)
        speeds.append(scene.contacts[0].rows(kin)[1] @ run.v)
    assert speeds[0] * speeds[1] < 0.0, speeds
    x0 = np.r_[traj.q0, traj.v0]
    assert_fd("loop slip reversal", traj.jacobian, _fd_jacobian(leg_robot, 0.3, x0), rtol=FD_RTOL)
