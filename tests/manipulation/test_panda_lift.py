"""Panda lifts a box (robots/panda_lift.toml): a two-finger grasp on a table, then a 0.10 m lift.

The box (m = 0.2 kg, edges a, b, c = 0.04, 0.05, 0.05 m) rests on three frictionless
supports; the pads (sticking point contacts, normals ∓y) close on its faces at
y = ∓b/2 and squeeze it with N = K_f q_f (the fingers' PD on a target of 0, K_f =
300 N/m, q_f = b/2 = 0.025 m at the faces: N = 7.5 N); the arm lifts the tool centre
by 0.10 m. References:

* **statics of the held box**: the pads' vertical forces carry m g, their normal
  forces are equal and opposite (the box's y equation), each N = K_f q_f (the
  finger's); the friction needed is ||λ_T|| / λ_N = m g / (2 N) = 0.1308;
* **the arm's sag**: gravity compensation covers the robot, not the box, so at
  rest the arm's joints yield by q - r = K^-1 τ_box, τ_box = J_Lᵀ f + J_Rᵀ f with
  f = (0, 0, -m g / 2) at each pad, and the tool centre drops by J_tcp K^-1 τ_box
  (linear statics, 0.34 mm);
* **the grasp axis is a hinge**: two point contacts hold two points of the box,
  both on its y axis through its centre; their forces have no moment about that
  axis and gravity acts at the centre, so in the air the box's spin about its
  own y axis only changes by Euler's gyroscopic term
  I_yy ω̇_y = (I_zz - I_xx) ω_z ω_x;
* **inverse mass of the box** (the checker's couplings): a free box's inverse mass
  at points r_i along z is 1/m + (r_i × z)ᵀ I⁻¹ (r_j × z) with
  I = m diag(b² + c², a² + c², a² + b²) / 12; along y at the face centres (r ∥ y)
  it is ±1/m, translation only.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from helpers import load_script

import contactdiff as cd

MASS = 0.2  # kg, the box
A, B, C = 0.04, 0.05, 0.05  # m, its edges along x, y (the grasp width) and z
G = 9.81  # m/s², the scene's gravity
K_F = 300.0  # N/m, the fingers' stiffness
M_F = 0.015  # kg, each finger of the model
LIFT = 0.10  # m, the tool centre's rise
LIFT_START, LIFT_END, T_FINAL = 0.4, 0.9, 1.2  # s, the arm's knots and the run's end
FINGERS = ("left_finger", "right_finger")
TABLE = ("table1", "table2", "table3")
BOX = slice(9, 16)  # the box's free-flyer coordinates in q
BOX_V = slice(9, 15)  # ... and in v (linear, angular; its own frame)


@pytest.fixture(scope="module")
def scene():
    return cd.load_scene("panda_lift")


@pytest.fixture(scope="module")
def run(scene):
    return cd.simulate(scene, T_FINAL, dense=True)


@pytest.fixture(scope="module")
def kin(scene):
    model = scene.robot.model
    return model, model.createData()


def _frame(kin, q, name) -> pin.SE3:
    model, data = kin
    pin.framesForwardKinematics(model, data, q)
    return pin.SE3(data.oMf[model.getFrameId(name)])


def _coulomb(scene, mu):
    """The scene with Coulomb friction μ at the pads (the supports stay frictionless)."""
    return scene.with_friction(mu, contacts=FINGERS)


def _box_forces(scene, sol, active):
    """Forces (N, world) that the active contacts put on the box: a row of direction d and
    force λ pushes its ``frame`` along +λ d and its ``against`` frame (the box) along -λ d."""
    return {scene.contacts[i].name: -(f @ scene.contacts[i].directions) for i, f in zip(active, sol.row_forces())}


def _final_hold(scene, run):
    active = [scene.contact_index(name) for name in FINGERS]
    sol = cd.ModeDynamics(scene).solve(run.q, run.v, run.t, active)
    return active, sol


def _targets_script():
    return load_script("panda_lift_targets")


def test_the_arm_rows_lift_the_tool_centre_straight_up(scene, kin):
    arm = scene.effort_specs[0]
    start, held, lifted = (np.array(row) for row in arm.targets)
    assert arm.times == (0.0, LIFT_START, LIFT_END)
    np.testing.assert_array_equal(start, scene.q0[:7])  # the schedule starts where the arm is: no jump
    np.testing.assert_array_equal(held, start)
    q = scene.q0.copy()
    before = _frame(kin, q, "panda_hand_tcp")
    # the exact reference pose points the hand straight down: round-off of a few products of pi/4 terms
    np.testing.assert_allclose(before.rotation, np.diag([1.0, -1.0, -1.0]), atol=1e-12)
    q[:7] = lifted
    after = _frame(kin, q, "panda_hand_tcp")
    # the IK's residual is ~1e-14; 1e-9 m and 1e-9 rad leave room for the printed digits (repr, exact)
    np.testing.assert_allclose(after.translation - before.translation, [0.0, 0.0, LIFT], atol=1e-9)
    assert np.linalg.norm(pin.log3(before.rotation.T @ after.rotation)) <= 1e-9
    # the rows are the script's output (repr round-trips; 1e-12 rad allows another platform's last bits)
    np.testing.assert_allclose(_targets_script().lifted_pose(LIFT)[:7], lifted, rtol=0.0, atol=1e-12)


def test_the_mirror_fingers_land_together_and_the_landing_orders_disagree(scene, run):
    grasp = run.events[0]
    assert grasp.kind == "touchdown" and set(grasp.contacts) == set(FINGERS) and grasp.simultaneous
    assert 0.05 < grasp.t < 0.35  # while the fingers' targets close
    # mirror images: equal impulses, so the box takes no net push (its y velocity stays 0 to round-off)
    assert grasp.impulses["left_finger"] == pytest.approx(grasp.impulses["right_finger"], rel=1e-12)
    assert abs(grasp.v_plus[BOX_V][1]) <= 1e-12  # m/s, impulses ~2e-3 N s on 0.2 kg: round-off 1e-14
    assert set(grasp.mode_after) == set(FINGERS + TABLE)
    # the landing orders: one finger first pushes the box into the other, a different outcome; the
    # flow has only a piecewise-linear derivative there, which a plain run says as the Jacobian run does
    assert set(grasp.nonsmooth) == {cd.NonSmooth.ORDER} and not run.differentiable
    with_jacobian = cd.simulate(scene, 0.2, jacobian=True)
    (event,) = with_jacobian.events
    assert event.t == pytest.approx(grasp.t, abs=1e-9)
    assert set(event.nonsmooth) == {cd.NonSmooth.ORDER} and not with_jacobian.differentiable
    first, second = event.saltation_orders.values()
    assert np.abs(first - second).max() > 0.1 * np.abs(first).max()


def test_the_box_is_lifted_and_held(scene, run, kin):
    # events: the grasp, then the three supports leave, once each, after the lift begins
    liftoffs = run.events[1:]
    assert [e.kind for e in liftoffs] == ["lift-off"] * 3
    assert sorted(c for e in liftoffs for c in e.contacts) == list(TABLE)
    assert all(LIFT_START < e.t < LIFT_END for e in liftoffs)
    assert run.segments[-1].mode == FINGERS and run.segments[-1].sliding == ()
    assert np.all(scene.gaps(run.q)[2:] > 0.09)  # the supports ~0.10 m off the table

    # the arm's sag under the box: linear statics at the lifted targets (module notes)
    model, data = kin
    arm = scene.effort_specs[0]
    q_target = run.q.copy()
    q_target[:7] = arm.targets[-1]
    pin.computeJointJacobians(model, data, q_target)
    pin.framesForwardKinematics(model, data, q_target)
    J = {
        name: pin.getFrameJacobian(model, data, model.getFrameId(name), pin.LOCAL_WORLD_ALIGNED)[:3, :7]
        for name in ("left_pad", "right_pad", "panda_hand_tcp")
    }
    tau_box = -(MASS * G / 2) * (J["left_pad"][2] + J["right_pad"][2])
    sag = J["panda_hand_tcp"] @ (tau_box / np.array(arm.stiffness))
    assert -4e-4 < sag[2] < -3e-4  # m: 0.336 mm down
    tcp0, tcp1 = _frame(kin, scene.q0, "panda_hand_tcp"), _frame(kin, run.q, "panda_hand_tcp")
    rise = tcp1.translation - tcp0.translation
    # 0.3 s after the lift's end the arm is still settling (its damping and inertia forces at the end
    # are a few 1e-3 of the joints' static torques: 0.6 % of the sag here), and the linear statics
    # misses terms of relative size |q - r| ~ 1e-3: 2 % of the sag (7 µm) bounds both
    np.testing.assert_allclose(rise, [0.0, 0.0, LIFT] + sag, rtol=0.0, atol=0.02 * abs(sag[2]))

    # the box moves with the hand: its centre is the midpoint of the two pads (each pad sticks to a
    # face centre, and the face centres are symmetric about the box's centre); 1e-9 m bounds the drift
    # of the sticking rows (the run's largest drift is 1e-13 m)
    times = np.linspace(run.events[0].t, T_FINAL, 121)
    for t in times:
        q, _ = run.at(float(t))
        middle = 0.5 * (_frame(kin, q, "left_pad").translation + _frame(kin, q, "right_pad").translation)
        np.testing.assert_allclose(q[BOX][:3], middle, rtol=0.0, atol=1e-9)
    # ... so it rises as the tool centre does, to the pads' 0.25 mm height above the tool centre times
    # the hand's turn (the sag's ~1e-3 rad): 1e-6 m
    box_rise = run.q[BOX][:3] - scene.q0[BOX][:3]
    turn = np.linalg.norm(pin.log3(tcp0.rotation.T @ tcp1.rotation))
    assert turn < 2e-3
    np.testing.assert_allclose(box_rise, rise, rtol=0.0, atol=2.5e-4 * turn + 1e-9)

    # the box never falls: its centre never below its resting height (beyond the supports' drift)
    heights = run.sample(np.linspace(0.0, T_FINAL, 601))[0][:, 11]
    assert heights.min() >= scene.q0[11] - 1e-9


def test_in_the_air_the_box_turns_freely_about_the_grasp_axis(scene, run):
    """The supports leave one after another (the last ~50 µs alone under one corner, whose push
    turns the box about the grasp axis); after that nothing turns it: its spin about its own y
    axis keeps its value, up to the gyroscopic term of the module notes."""
    inertia = MASS * np.array([B**2 + C**2, A**2 + C**2, A**2 + B**2]) / 12.0
    t_air = run.events[-1].t
    times = np.linspace(t_air + 1e-6, T_FINAL, 400)
    omega = run.sample(times)[1][:, 12:15]  # the box's angular velocity, its own frame
    spin = omega[:, 1]
    assert abs(spin[0]) > 1e-5  # rad/s: it does turn (5e-4 rad/s)
    # |Δω_y| <= |I_zz - I_xx| / I_yy ∫ |ω_x ω_z| dt; the sampled max of |ω_x ω_z| doubled covers the
    # peaks between samples
    bound = abs(inertia[2] - inertia[0]) / inertia[1] * 2 * np.abs(omega[:, 0] * omega[:, 2]).max() * (T_FINAL - t_air)
    assert bound < 1e-2 * abs(spin[0])  # the bound is sharp enough to say something
    np.testing.assert_allclose(spin, spin[0], rtol=0.0, atol=bound)


def test_in_the_final_hold_the_pads_carry_the_weight_and_squeeze_equally(scene, run):
    active, sol = _final_hold(scene, run)
    forces = _box_forces(scene, sol, active)
    total = forces["left_finger"] + forces["right_finger"]
    # Newton on the box with the solve's acceleration (centre's classical acceleration, world frame):
    # the row conventions and the tangent basis are right to round-off
    R = pin.Quaternion(run.q[15], run.q[12], run.q[13], run.q[14]).toRotationMatrix()
    v_lin, omega = run.v[9:12], run.v[12:15]
    a_world = R @ (sol.ddq[9:12] + np.cross(omega, v_lin))
    np.testing.assert_allclose(total, MASS * (a_world - [0.0, 0.0, -G]), rtol=0.0, atol=1e-9)
    # the box is at rest (|a| below 1e-3 g), so the pads carry its weight: m g to 1e-3 m g
    assert np.linalg.norm(a_world) < 1e-3 * G
    np.testing.assert_allclose(total, [0.0, 0.0, MASS * G], rtol=0.0, atol=1e-3 * MASS * G)
    # each pad half of it (the mirror grasp): to the same 1e-3 m g
    for name in FINGERS:
        assert forces[name][2] == pytest.approx(MASS * G / 2, abs=1e-3 * MASS * G)
    # the squeeze: equal and opposite normal forces on the box (their difference is m a_y)
    normal_left, normal_right = (f[0] for f in sol.row_forces())
    assert normal_left == pytest.approx(normal_right, abs=1e-3 * MASS * G)
    # and each is the finger's own statics: N = K_f q_f; the finger's damping and inertia at the
    # end are D_f |v_f| ~ 5e-6 N and m_f |a| ~ 1e-5 N
    for normal, q_f in zip((normal_left, normal_right), run.q[7:9]):
        assert q_f == pytest.approx(B / 2, abs=1e-6)  # m: at the faces
        assert normal == pytest.approx(K_F * q_f, abs=1e-4)


@pytest.fixture(scope="module")
def coulomb_run(scene):
    slippery = _coulomb(scene, 0.8)
    return slippery, cd.simulate(slippery, T_FINAL)


def test_coulomb_pads_lift_the_box_inside_their_friction_cone(scene, run, coulomb_run):
    """μ = 0.8 is well above what the hold needs, m g / (2 N) = 0.131, and what the lift's
    largest acceleration needs, m (g + 5.77 h / T²) / (2 N) = 0.2 (9.81 + 2.31) / 15 = 0.162
    (the quintic step of h = 0.10 m over T = 0.5 s): the pads never slip and the run is the
    sticking one."""
    slippery, traj = coulomb_run
    assert [e.kind for e in traj.events] == ["touchdown"] + ["lift-off"] * 3
    assert traj.segments[-1].mode == FINGERS and traj.segments[-1].sliding == ()
    rise = traj.q[11] - slippery.q0[11]
    assert rise == pytest.approx(run.q[11] - scene.q0[11], abs=1e-9)  # the same lift, 0.0997 m
    assert rise > LIFT - 1e-3
    active, sol = _final_hold(slippery, traj)
    for name, f in zip(FINGERS, sol.row_forces()):
        normal, tangential = f[0], np.linalg.norm(f[1:])
        assert tangential <= 0.8 * normal, name
        # the needed friction: half the weight on N = K_f q_f (statics above; 1e-3 relative)
        assert tangential / normal == pytest.approx(MASS * G / (2 * K_F * B / 2), rel=1e-3)


def test_the_checker_finds_the_fingers_coupled_through_the_box(scene, run):
    report = cd.check_decoupling(scene, samples=4)
    assert report.verdict == "coupled"
    pairs = {p.contacts: p for p in report.pairs}
    # three supports on a free box (module notes): at the scene's pose the box is not turned
    inv = {k: 1.0 / m_k for k, m_k in zip("xyz", MASS * np.array([B**2 + C**2, A**2 + C**2, A**2 + B**2]) / 12)}
    supports = {"table1": (0.015, 0.02), "table2": (0.015, -0.02), "table3": (-0.015, 0.0)}

    def g(i, j):  # 1/m + (r_i × z)ᵀ I⁻¹ (r_j × z), r × z = (r_y, -r_x, 0)
        (xi, yi), (xj, yj) = supports[i], supports[j]
        return 1.0 / MASS + yi * yj * inv["x"] + xi * xj * inv["y"]

    for i, j in [("table1", "table2"), ("table1", "table3"), ("table2", "table3")]:
        assert pairs[(i, j)].reference == pytest.approx(abs(g(i, j)) / np.sqrt(g(i, i) * g(j, j)), rel=1e-9)
    # a pad's row moves the box along y only; a support's along z and about x, y: orthogonal on the
    # box, and nothing else links them at the scene's pose
    for finger in FINGERS:
        for support in TABLE:
            assert pairs[(finger, support)].reference <= 1e-12

    # the fingers: G = A M⁻¹ Aᵀ at the grasp (both closed), computed here from the model
    model = scene.robot.model
    data = model.createData()
    q = run.events[0].q
    pin.computeJointJacobians(model, data, q)
    pin.framesForwardKinematics(model, data, q)

    def jac(name):
        return pin.getFrameJacobian(model, data, model.getFrameId(name), pin.LOCAL_WORLD_ALIGNED)[:3]

    y = np.array([0.0, 1.0, 0.0])
    rows = np.array([-y @ (jac("left_pad") - jac("box/left")), y @ (jac("right_pad") - jac("box/right"))])
    Minv = pin.computeMinverse(model, data, q)
    Minv = np.triu(Minv) + np.triu(Minv, 1).T
    coupling = rows @ Minv @ rows.T
    (at_grasp,) = cd.check_decoupling(scene, states=[(q, np.zeros(model.nv))]).pairs[:1]
    assert at_grasp.contacts == FINGERS
    rho = coupling[0, 1] / np.sqrt(coupling[0, 0] * coupling[1, 1])
    assert at_grasp.reference == pytest.approx(abs(rho), rel=1e-9)
    # its box part is the closed form ±1/m; negative: a pad pushed outward drives the box into the other
    box = rows[:, BOX_V] @ Minv[BOX_V, BOX_V] @ rows[:, BOX_V].T
    np.testing.assert_allclose(box, np.array([[1.0, -1.0], [-1.0, 1.0]]) / MASS, rtol=0.0, atol=1e-12 / MASS)
    assert rho < 0.0
    # with the arm locked (hand fixed) a pad moves only with its 15 g finger: ρ = m_f / (m_f + m)
    free = [7, 8] + list(range(9, 15))
    locked = rows[:, free] @ np.linalg.inv(pin.crba(model, data, q)[np.ix_(free, free)]) @ rows[:, free].T
    fixed_hand = M_F / (M_F + MASS)
    assert abs(locked[0, 1]) / np.sqrt(locked[0, 0] * locked[1, 1]) == pytest.approx(fixed_hand, rel=1e-9)
    # the free arm adds a little: a y force 4.5 cm below a finger's joint rolls the hand, which moves
    # both pads along y (1.1 % here)
    assert fixed_hand < abs(rho) < 1.02 * fixed_hand
    # the checker's own reference pose: the scene's, projected onto both pads closed by minimum-norm
    # steps; the two rows' arm and box parts are opposite (mirror grasp), so the steps move the
    # fingers only, onto the grasp's pose
    assert pairs[FINGERS].reference == pytest.approx(abs(rho), rel=1e-9)


def test_a_box_off_the_centre_line_is_pushed_by_one_finger_first_and_rocks(scene):
    """0.25 mm towards the right finger: the right lands first, alone; its sticking pad holds the
    face point to the hand in x and z, so the arm's recoil from the finger's impact reaches the box
    as a vertical, rolling push, and the box rocks on its rigid supports (impacts that lift the
    others). The left finger lands after the remaining 0.5 mm, at most 0.5 mm / 0.13 m/s = 3.8 ms
    later (the box comes towards it)."""
    box = scene.q0[BOX].copy()
    box[1] = 2.5e-4
    traj = cd.simulate(scene.with_state(q0={"box": box}), 0.2)
    first = traj.events[0]
    assert first.contacts == ("right_finger",) and first.mode_after[0] == "right_finger"
    left = next(e for e in traj.events if "left_finger" in e.contacts)
    assert 1e-3 < left.t - first.t < 5e-4 / abs(first.normal_speeds["right_finger"])
    rocking = [e for e in traj.events if first.t < e.t < left.t]
    assert rocking and all(set(e.contacts) <= set(TABLE) for e in rocking)
    assert not traj.differentiable
    assert {reason for e in traj.events for reason in e.nonsmooth} == {cd.NonSmooth.ZENO_CASCADE}


def test_pads_below_the_lift_s_friction_need_slip_at_the_cone_and_lose_the_box(scene):
    """μ = 0.15 is below what the lift's largest acceleration needs (0.162, above): the pads
    start to slip during the lift, where each one's force reaches its cone's edge
    (||λ_T|| = μ λ_N, the slip's event condition), the box slides out of the grasp and falls
    back (only its bottom face's three supports are modelled, so it may pass the table)."""
    slippery = _coulomb(scene, 0.15)
    traj = cd.simulate(slippery, T_FINAL)
    slips = [e for e in traj.events if e.kind == "slip"]
    first = slips[0]
    assert LIFT_START < first.t < LIFT_END
    assert {c for e in slips for c in e.contacts} == set(FINGERS)
    (k,) = [slippery.contact_index(name) for name in first.contacts]
    active = [slippery.contact_index(name) for name in first.mode_before]
    sol = cd.ModeDynamics(slippery).solve(first.q, first.v_minus, first.t, active)
    f = sol.row_forces()[active.index(k)]
    # located to the guard's tolerance on a force of ~1 N: 1e-6 of the normal force
    assert np.linalg.norm(f[1:]) == pytest.approx(0.15 * f[0], rel=1e-6)
    released = [e for e in traj.events if e.kind == "lift-off" and set(e.contacts) & set(FINGERS)]
    assert {c for e in released for c in e.contacts} == set(FINGERS) and released[-1].t < T_FINAL
    assert traj.segments[-1].mode and set(traj.segments[-1].mode) <= set(TABLE)  # back on its supports
