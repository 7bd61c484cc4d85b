"""Sliding at zero normal force (event ``slip``) and force guards under time-dependent efforts.

Model: a planar leg, a body free in x and z (1 kg) with a rigid leg (0.2 kg,
0.5 m) on a hip hinge, its foot a sticking contact. It lands inclined by 0.4 rad;
from t = 0.1 s an upward force on the body ramps at 30 N/s and unloads the foot.
The tangential force the sticking foot carries presses it down through the
inclined leg, so when its normal force reaches zero, releasing it would let it
sink: it slides (normal row only) until its frictionless normal force reaches
zero too, and lifts off.

References: Pinocchio's ABA and frame accelerations for the free and the
normal-row-only dynamics (not the project's mode solver), the closed form
``Ξ = I`` where the field is continuous, and central finite differences of the
simulator (ε = 1e-5, perturbed runs at rtol 1e-13: see `test_slip_jacobian_matches_fd`).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from helpers import LEG_RAMP, LEG_RAMP_START, LEG_URDF, assert_fd, leg_lift, leg_lift_jacobian, leg_lift_rate

import contactdiff as cd
from contactdiff.dynamics.mode import ModeDynamics
from contactdiff.integration.sensitivity import force_time_rate

TILT, RAMP, RAMP_START = 0.4, LEG_RAMP, LEG_RAMP_START  # rad, N/s, s
T_FINAL = 0.6  # s: touchdown ~0.045, slip ~0.325, lift-off ~0.487
TOL = dict(rtol=1e-12, atol=1e-13)
FD_TOL = dict(rtol=1e-13, atol=1e-14)  # perturbed runs of the FD (test_slip_jacobian_matches_fd)
EPS = 1e-5


@pytest.fixture(scope="module")
def leg_robot(tmp_path_factory):
    path = tmp_path_factory.mktemp("leg") / "leg.urdf"
    path.write_text(LEG_URDF)
    return cd.load_robot(path)


def _scene(robot, exact_rate: bool = True) -> cd.Scene:
    effort = cd.UserEffort(
        leg_lift, leg_lift_jacobian, name="lift", time_derivative=leg_lift_rate if exact_rate else None
    )
    q0 = np.array([0.0, 0.5 * np.cos(TILT) + 0.01, TILT])  # foot 1 cm up
    return cd.Scene(
        robot,
        [cd.Contact("foot", friction="stick")],
        [effort],
        gravity=[0, 0, -9.81],
        q0=q0,
        v0=np.zeros(3),
        name="slipping leg",
    )


@pytest.fixture(scope="module")
def leg_run(leg_robot):
    scene = _scene(leg_robot)
    return scene, cd.simulate(scene, T_FINAL, jacobian=True, dense=True, **TOL)


def _foot_normal_row(model, data, q, v, fid):
    """Normal (z) row of the foot and its drift (classical acceleration at ddq = 0)."""
    pin.forwardKinematics(model, data, q, v, np.zeros(model.nv))
    pin.updateFramePlacements(model, data)
    J = pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL_WORLD_ALIGNED)[2]
    drift = pin.getFrameClassicalAcceleration(model, data, fid, pin.LOCAL_WORLD_ALIGNED).linear[2]
    return J, drift


def test_slip_sequence_and_physics(leg_run):
    scene, traj = leg_run
    assert [(e.kind, e.contacts) for e in traj.events] == [
        ("touchdown", ("foot",)),
        ("slip", ("foot",)),
        ("lift-off", ("foot",)),
    ]
    touchdown, slip, liftoff = traj.events
    assert slip.sliding == ("foot",) and slip.mode_after == ("foot",)
    assert liftoff.mode_after == () and liftoff.sliding == ()
    assert [s.sliding for s in traj.segments] == [(), (), ("foot",), ()]

    model = scene.model
    data = model.createData()
    fid = model.getFrameId("foot")

    def tau(q, v, t):
        return leg_lift(q, v, t)

    # at the slip: released, the foot would accelerate into the ground (ABA, no contact)
    q, v, t = slip.q, slip.v_plus, slip.t
    ddq_free = pin.aba(model, data, q, v, tau(q, v, t))
    J, drift = _foot_normal_row(model, data, q, v, fid)
    assert J @ ddq_free + drift < -1e-3  # m/s²: clearly sinking, not round-off

    # while sliding: on the ground, pushed (lam_n >= 0 from the normal row alone), and moving
    # tangentially (the tangents are free)
    seg = traj.segments[2]
    for s in np.linspace(seg.t0, seg.t1, 9)[1:-1]:
        q, v = seg.at(s)
        J, drift = _foot_normal_row(model, data, q, v, fid)
        pin.computeAllTerms(model, data, q, v)
        Minv = np.linalg.inv(data.M)
        a_free = Minv @ (tau(q, v, s) - data.nle)
        lam = -(J @ a_free + drift) / (J @ Minv @ J)
        assert lam > 0.0, (s, lam)
        assert abs(data.oMf[fid].translation[2]) < 1e-9
    q, v = seg.at(seg.t1)
    pin.forwardKinematics(model, data, q, v)
    slide_speed = pin.getFrameVelocity(model, data, fid, pin.LOCAL_WORLD_ALIGNED).linear[0]
    assert abs(slide_speed) > 1e-3  # m/s


def test_liftoff_from_sliding_has_identity_saltation(leg_run):
    """The sliding foot's release has no force jump (its only row's force is zero at
    the event), so the field is continuous there and Ξ = I (docs/design.md §2)."""
    _, traj = leg_run
    slip, liftoff = traj.events[1:]
    np.testing.assert_allclose(liftoff.saltation, np.eye(6), atol=1e-12)
    # the slip itself drops a tangential force: the field jumps
    assert np.abs(slip.saltation - np.eye(6)).max() > 1e-2


def test_slip_jacobian_matches_fd(leg_run):
    """Flow Jacobian through touchdown, slip and lift-off under a time-dependent
    effort (the force guards' explicit time rate enters both event saltations).

    FD error: truncation ε² |f'''| / 6 plus noise |δ+ - δ-| / (2 ε), δ+ and δ- the
    errors of the two perturbed runs. Those are not smooth in the perturbation: the
    adaptive steps (about 20 of the 60 tried are rejected, around the events) switch
    discretely, so δ+ - δ- is of the size of the runs' errors, set by which steps
    switch, i.e. by the last bits of the arithmetic: at rtol 1e-12 the noise was 3e-7
    of the Jacobian's scale at ε = 1e-5 (and 5e-4 at ε = 1e-6). The perturbed runs
    therefore use rtol 1e-13, atol 1e-14, ten times below the nominal run's: the noise
    falls in proportion (1e-8 at ε = 1e-5), while the truncation (2e-7 at ε = 1e-4,
    so 2e-9 at 1e-5) and the nominal Jacobian's own error (of order N rtol = 1e-10
    over N ~ 50 steps) stay far below the tolerance 1e-6: the noise may grow a
    hundredfold before the comparison fails."""
    scene, traj = leg_run
    kinds = [(e.kind, e.contacts) for e in traj.events]
    cols = []
    for k in range(6):
        runs = []
        for sign in (1.0, -1.0):
            dx = np.zeros(6)
            dx[k] = sign * EPS
            run = cd.simulate(scene.with_state(scene.q0 + dx[:3], scene.v0 + dx[3:]), T_FINAL, **FD_TOL)
            assert [(e.kind, e.contacts) for e in run.events] == kinds
            runs.append(np.concatenate([run.q, run.v]))
        cols.append((runs[0] - runs[1]) / (2 * EPS))
    assert_fd("flow jacobian through slip and lift-off", traj.jacobian, np.array(cols).T, rtol=1e-6)


def test_time_rate_fallback_matches_exact(leg_robot, leg_run):
    """Without ``time_derivative`` the effort's time rate is a central difference in t:
    the Jacobian agrees with the exact rate's to the difference's error (~1e-10)."""
    _, exact = leg_run
    fallback = cd.simulate(_scene(leg_robot, exact_rate=False), T_FINAL, jacobian=True, **TOL)
    assert np.abs(fallback.jacobian - exact.jacobian).max() <= 1e-8 * np.abs(exact.jacobian).max()


def test_force_time_rate_matches_fd(leg_run):
    """``∂lam/∂t`` at fixed state against a central difference of the mode's forces in t."""
    scene, traj = leg_run
    dyn = ModeDynamics(scene)
    seg = traj.segments[1]  # sticking stance
    t = 0.5 * (seg.t0 + seg.t1)
    q, v = seg.at(t)
    h = 1e-4  # the forces are affine in t here (ramp): the difference is exact up to round-off
    for row in range(2):
        fd = (dyn.solve(q, v, t + h, (0,)).forces[row] - dyn.solve(q, v, t - h, (0,)).forces[row]) / (2 * h)
        assert force_time_rate(dyn, q, v, t, (0,), row) == pytest.approx(fd, rel=1e-8, abs=1e-9)
    assert force_time_rate(dyn, q, v, 0.05, (0,), 0) == 0.0  # before the ramp: autonomous


def test_user_effort_time_derivative_is_validated(leg_robot):
    with pytest.raises(cd.InvalidInputError, match="time_derivative"):
        cd.UserEffort(leg_lift, time_derivative=3.0)
    bad = cd.UserEffort(leg_lift, leg_lift_jacobian, time_derivative=lambda q, v, t: np.array([np.nan, 0.0, 0.0]))
    scene = cd.Scene(
        leg_robot, [cd.Contact("foot", friction="stick")], [bad], gravity=[0, 0, -9.81], q0=_scene(leg_robot).q0
    )
    kin = scene.kinematics
    kin.update(scene.q0, np.zeros(3))
    with pytest.raises(cd.InvalidInputError, match="time_derivative returned"):
        scene.tau_time_derivative(kin, 0.2)


def test_mode_choice_slides_where_sticking_has_no_solution(leg_run):
    """Mid-slide, sticking would pull (lam_n < 0) and releasing would sink (ABA): the
    acceleration-level problem has no sticking solution, and choose_mode slides."""
    scene, traj = leg_run
    seg = traj.segments[2]
    t = 0.5 * (seg.t0 + seg.t1)
    q, v = seg.at(t)
    dyn = ModeDynamics(scene)
    assert dyn.solve(q, v, t, (0,)).normal_forces()[0] < 0.0  # sticking pulls
    model, data = scene.model, scene.model.createData()
    J, drift = _foot_normal_row(model, data, q, v, model.getFrameId("foot"))
    assert J @ pin.aba(model, data, q, v, leg_lift(q, v, t)) + drift < 0.0  # free sinks
    from contactdiff.dynamics.impacts import choose_mode

    assert choose_mode(dyn, q, v, t, [0]) == (dyn.sliding_key(0),)
    assert dyn.solve(q, v, t, (dyn.sliding_key(0),)).forces.shape == (1,)
