"""Rules of the hybrid loop for contacts that close or open with no speed.

* A contact that opens with no separating speed and then sinks (it never rises
  above the ground) touches down again; it must not be skipped for want of a
  peak and left to fall through the ground.
* The Zeno rule for impact cascades: a closed contact that an impact elsewhere
  would lift slower than ``zeno_speed`` stays closed, its separating speed
  removed M-orthogonally.
* The same rule for a landing contact that its own impact lifts (a sticking
  foot whose slip only a pulling impulse could stop: the impact stops it with a
  tangential impulse alone and the foot leaves): its bounces form a geometric
  series, ended like a cascade.

References: closed forms (the unloaded ball; the rebound ratio of a relaxed
landing from the Delassus matrix and the free accelerations, computed with
Pinocchio) and the plastic-impact law with the feet held (the M-orthogonal
projection of the pre-impact velocity).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from helpers import assert_fd
from test_slip import LEG_URDF

import contactdiff as cd
from contactdiff.dynamics.impacts import resolve_impact
from contactdiff.dynamics.mode import ModeDynamics


def test_a_contact_opening_with_no_speed_that_sinks_touches_down_again():
    """A unit mass at rest on the ground under g = 1 and an upward force 1 - t (N): its
    acceleration -t is zero at t = 0, so it starts released (nothing pushes it into the
    ground) and then sinks as -t³/6. It must touch down at once (within the closed
    band 1e-12 m, i.e. by t = (6e-12)^(1/3) ≈ 2e-4 s, allowing for the step) and rest:
    without the rule it would fall through to z(1) = -1/6."""
    base = cd.load_scene("ball")
    unloading = cd.UserEffort(lambda q, v, t: np.array([1.0 - t]), name="unloading")
    scene = cd.Scene(base.robot, [cd.Contact("ball")], [unloading], gravity=[0, 0, -1], q0=[0.0])
    traj = cd.simulate(scene, 1.0, rtol=1e-10, atol=1e-12, dense=True)
    assert [e.kind for e in traj.events] == ["touchdown"]
    assert traj.events[0].t < 1e-3
    assert traj.modes[-1] == ("ball",)
    z, _ = traj.sample(np.linspace(0.0, 1.0, 201))
    assert z.min() > -1e-9  # never through the ground (m)
    assert abs(traj.q[0]) < 1e-9 and abs(traj.v[0]) < 1e-9


def _front_touchdown(zeno_speed: float):
    """The rigid trot at pitch 0.05 (frictionless, plastic): the rear foot lands first and
    the body pivots on it until the front foot lands; run just past that touchdown."""
    scene = cd.trot_touchdown("rigid", 0.05)
    traj = cd.simulate(scene, 2.0, rtol=1e-10, atol=1e-12, zeno_speed=zeno_speed)
    front = next(e for e in traj.events if "front_foot" in e.contacts)
    return scene, front


def test_impact_lifting_a_foot_slowly_keeps_it_closed_under_the_cascade_rule():
    scene, front = _front_touchdown(zeno_speed=1e-6)
    # the front impact lifts the rear foot (the body pivots onto the front foot)
    assert "rear_foot" in front.mode_before and "rear_foot" not in front.mode_after
    model, data = scene.model, scene.model.createData()
    pin.computeJointJacobians(model, data, front.q)
    pin.updateFramePlacements(model, data)
    A = np.array(
        [
            pin.getFrameJacobian(model, data, model.getFrameId(f), pin.LOCAL_WORLD_ALIGNED)[2]
            for f in ("rear_foot", "front_foot")
        ]
    )
    lift = float(A[0] @ front.v_plus)  # rear foot's separating speed (m/s)
    assert lift > 1e-3

    # with zeno_speed above that speed, the rear foot stays: both feet held
    _, held = _front_touchdown(zeno_speed=10 * lift)
    assert held.mode_after == ("rear_foot", "front_foot")
    assert not held.differentiable  # the rule's cut-off is not smooth
    # plastic impact with both feet held = M-orthogonal projection of v- onto A v = 0
    Minv = pin.computeMinverse(model, data, held.q)
    Minv = np.triu(Minv) + np.triu(Minv, 1).T
    W = Minv @ A.T @ np.linalg.inv(A @ Minv @ A.T)
    expected = held.v_minus - W @ (A @ held.v_minus)
    assert np.allclose(held.v_plus, expected, atol=1e-12)
    assert np.allclose(A @ held.v_plus, 0.0, atol=1e-12)


# -- a sticking foot lifted by its own impact: relaxed bounces ---------------------------
LEG_TILT, HIP_TORQUE = 0.6, -3.0  # rad, N m: the torque swings the foot forward and down


def _relaxed_bouncing_leg(tmp_path):
    """The planar leg of tests/dynamics/test_slip.py (body free in x and z, leg on a free hip), its
    foot a sticking contact 0.1 mm up, the body moving forward at 0.1 m/s, a constant hip
    torque. Landing, the foot slips forward fast enough that stopping it would need a
    pulling normal impulse (|Gnt w_t| > Gtt |w_n| with the foot's rows n = z, t = x): the
    impact stops the slip with a tangential impulse alone, which lifts the foot. In its
    flight the foot regains slip, and lands again the same way."""
    path = tmp_path / "leg.urdf"
    path.write_text(LEG_URDF)
    robot = cd.load_robot(path)
    torque = cd.UserEffort(
        lambda q, v, t: np.array([0.0, 0.0, HIP_TORQUE]),
        lambda q, v, t: (np.zeros((3, 3)), np.zeros((3, 3))),
        name="hip torque",
        time_derivative=lambda q, v, t: np.zeros(3),
    )
    q0 = np.array([0.0, 0.5 * np.cos(LEG_TILT) + 1e-4, LEG_TILT])
    return cd.Scene(
        robot,
        [cd.Contact("foot", friction="stick")],
        [torque],
        gravity=[0, 0, -9.81],
        q0=q0,
        v0=np.array([0.1, 0.0, 0.0]),
        name="relaxed bouncing leg",
    )


def _foot_rows(model, data, q, v, fid):
    """The foot's rows (normal z, tangent x; LOCAL_WORLD_ALIGNED) and their drift."""
    pin.forwardKinematics(model, data, q, v, np.zeros(model.nv))
    pin.updateFramePlacements(model, data)
    A = pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL_WORLD_ALIGNED)[[2, 0]]
    drift = pin.getFrameClassicalAcceleration(model, data, fid, pin.LOCAL_WORLD_ALIGNED).linear[[2, 0]]
    return A, drift


def test_a_foot_lifted_by_its_own_impact_ends_its_bounces_under_the_zeno_rule(tmp_path):
    """Closed form of the series: a relaxed impact of a foot arriving with row velocities
    (w_n < 0, w_t) takes the tangential impulse -w_t / Gtt only and leaves the foot at
    w_n - Gnt w_t / Gtt. Taking off at speed s with no slip under constant free
    accelerations (a_n < 0, a_t), the foot lands again after 2 s / |a_n| with w_n = -s,
    w_t = 2 s a_t / |a_n|; so each landing speed is r = 2 rho - 1 times the previous one,
    rho = -Gnt a_t / (Gtt |a_n|) (here about 0.77, r about 0.53; a sticking stance needs
    rho < 1, a relaxed landing rho > 1/2). The series must end at the first landing its
    impact would lift slower than zeno_speed, the foot held on the ground. Left to leave,
    its rise (s^2 / (2 |a_n|) < 1e-14 m) is below what the dense output resolves: the
    foot comes back through the sinking rule only, under the ground by the grazing band
    10 (atol + rtol |q|_inf) (6e-8 m here), and lands at sqrt(2 |a_n| band) (3 mm/s)."""
    scene = _relaxed_bouncing_leg(tmp_path)
    zeno = 1e-6  # m/s, simulate's default zeno_speed
    traj = cd.simulate(scene, 0.05, dense=True)
    model, data = scene.model, scene.model.createData()
    fid, tau = model.getFrameId("foot"), np.array([0.0, 0.0, HIP_TORQUE])

    # never under the ground: at every landing the gap before the impact is its located
    # zero (Brent to 4 eps in time at speeds <= 0.11 m/s: 1e-16 m; below gap_tol = 1e-12 m,
    # the integrator's "closed"), and along the dense output the drift of the closed foot
    # is projected away beyond project_tol = atol = 1e-10 m
    for e in traj.events:
        q_before, _ = traj.at(e.t, side="left")
        assert scene.gaps(q_before)[0] > -1e-12, e.t
    q, _ = traj.sample(np.linspace(0.0, 0.05, 2001))
    assert min(scene.gaps(x)[0] for x in q) > -1e-10

    *bounces, last = traj.events
    assert len(bounces) >= 3 and all(e.kind == "bounce" and e.mode_after == () for e in bounces)

    # the bounces are the relaxed series: landing speeds fall by r = 2 rho - 1 (Pinocchio's
    # ABA, frame acceleration and M^-1 at each take-off). The closed form holds for
    # constant accelerations; along a flight (1.2 ms at most) the leg turns and they
    # change by well below 1 %: a 1 % band (the sticking law would give r = 0)
    speeds = [-e.normal_speeds["foot"] for e in traj.events]
    for e, before, after in zip(bounces[1:], speeds[1:], speeds[2:]):
        A, drift = _foot_rows(model, data, e.q, e.v_plus, fid)
        a_n, a_t = A @ pin.aba(model, data, e.q, e.v_plus, tau) + drift
        G = A @ pin.computeMinverse(model, data, e.q) @ A.T
        rho = -G[0, 1] * a_t / (G[1, 1] * abs(a_n))
        assert 0.5 < rho < 1.0 and a_n < 0.0
        assert after / before == pytest.approx(2 * rho - 1, rel=1e-2), e.t

    # the end: the first landing whose impact would lift the foot slower than zeno_speed
    dyn = ModeDynamics(scene)
    lift = resolve_impact(dyn, last.q, last.v_minus, [0]).normal_speeds_after[0]
    assert 0.0 < lift < zeno
    A, _ = _foot_rows(model, data, bounces[-1].q, bounces[-1].v_plus, fid)
    assert A[0] @ bounces[-1].v_plus >= zeno
    assert last.mode_after == ("foot",) and not last.differentiable
    assert any("kept closed" in note for note in traj.notes)
    # held: the foot's rows stopped (the least kinetic-energy change), and it stays down
    A, _ = _foot_rows(model, data, last.q, last.v_plus, fid)
    np.testing.assert_allclose(A @ last.v_plus, 0.0, atol=1e-12)
    assert traj.modes[-1] == ("foot",) and traj.t == 0.05


def test_flow_jacobian_through_a_held_cascade_matches_finite_differences():
    """The reset of an impact that keeps a slowly lifted contact closed is the impact
    followed by holding that contact (an M-orthogonal velocity projection), so its
    Jacobian is the projection's derivative times the impact's. With zeno_speed ten
    times the rear foot's lift, every perturbed run stays on the held branch and the
    map is smooth there: central differences of whole runs (ε = 1e-6, rtol 1e-12,
    noise ~ 1e-12 / 1e-6 = 1e-6 of O(1) entries at worst, truncation ~ε²) must agree
    with the flow Jacobian to the suite's FD tolerance."""
    _, front = _front_touchdown(zeno_speed=1e-6)  # the lift speed, as in the test above
    scene = cd.trot_touchdown("rigid", 0.05)
    model, data = scene.model, scene.model.createData()
    pin.computeJointJacobians(model, data, front.q)
    pin.updateFramePlacements(model, data)
    rear = pin.getFrameJacobian(model, data, model.getFrameId("rear_foot"), pin.LOCAL_WORLD_ALIGNED)[2]
    zeno = 10 * float(rear @ front.v_plus)
    options = dict(rtol=1e-12, atol=1e-14, zeno_speed=zeno)
    T = front.t + 0.05  # s: past the held front touchdown, both feet on the ground
    traj = cd.simulate(scene, T, jacobian=True, **options)
    held = next(e for e in traj.events if "front_foot" in e.contacts)
    assert held.mode_after == ("rear_foot", "front_foot") and not held.differentiable
    nv, eps = scene.nv, 1e-6
    columns = []
    for k in range(2 * nv):
        e = np.zeros(2 * nv)
        e[k] = eps
        ends = [
            cd.simulate(scene, T, q0=scene.robot.integrate(scene.q0, s * e[:nv]), v0=scene.v0 + s * e[nv:], **options)
            for s in (1, -1)
        ]
        assert all(
            next(x for x in run.events if "front_foot" in x.contacts).mode_after == held.mode_after for run in ends
        )  # the same branch
        columns.append(
            np.concatenate([scene.robot.difference(ends[1].q, ends[0].q), ends[0].v - ends[1].v]) / (2 * eps)
        )
    assert_fd("flow Jacobian through a held cascade", traj.jacobian, np.array(columns).T)
