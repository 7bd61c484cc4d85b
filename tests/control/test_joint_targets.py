"""`JointTargets`: PD tracking of a quintic-smooth joint schedule with gravity compensation.

Reference values come from the smooth step in closed form (``S(0) = 0``,
``S(1) = 1``, ``S(1/2) = 1/2``, ``S'(1/2) = 15/8``, ``S''(1/2) = 0``, ``S' = S'' = 0``
at both ends), from central finite differences (on the manifold for ``q``, through
``robot.integrate``) and from mechanics (gravity compensation at rest: no
acceleration).
"""

from __future__ import annotations

import math
import re
from dataclasses import fields

import numpy as np
import pinocchio as pin
import pytest
from helpers import assert_fd, fd_dv

from contactdiff.control.joint_targets import JointTargets
from contactdiff.errors import InvalidInputError, UnknownNameError
from contactdiff.model.efforts import BoundEffort, Effort
from contactdiff.model.kinematics import Kinematics
from contactdiff.model.robot import Robot
from contactdiff.model.robot_files import load_robot

TIMES = (0.5, 1.5, 2.5)  # s: pieces of 1 s each, so the midpoints have u = 1/2 exactly
H = 1e-6  # FD step (rad, m, rad/s, m/s or s)
# FD tolerance, relative to the larger of the derivative and tau (see helpers): truncation
# ~ H² |f'''| ~ 1e-12 relative and round-off ~ eps |tau| / H ~ 2e-10 relative for these
# O(1..100) N m efforts; 1e-6 leaves that margin, while a wrong sign, row or missing
# gravity term is an O(0.1..1) relative error.
FD_RTOL = 1e-6


@pytest.fixture(scope="module")
def panda() -> Robot:
    return load_robot("panda")


@pytest.fixture(scope="module")
def panda_box(panda) -> Robot:
    """The Panda with a free-flying box appended to the universe (its own subtree, a
    free-flyer joint after the arm's: quaternion coordinates)."""
    model = pin.Model(panda.model)
    jid = model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), "box")
    model.appendBodyToJoint(jid, pin.Inertia.FromBox(0.2, 0.04, 0.05, 0.05), pin.SE3.Identity())
    return Robot(model, "panda_box", q_ref=np.concatenate([panda.q_ref, [0.5, 0.0, 0.3, 0.0, 0.0, 0.0, 1.0]]))


OFFSETS = (0.0, 0.3, -0.1)  # rad or m: the rows of `_rows` from the start row


def _rows(robot: Robot, joints) -> tuple[tuple[float, ...], ...]:
    """One row per knot of TIMES: the reference pose of the joints, then offsets; a joint
    whose limits are closer than the offsets (a finger, 0-0.04 m) starts at the middle of
    its range with offsets scaled to 0.9 of its half range, so every row lies within the
    model's limits (targets outside them are refused)."""
    iq = [robot.scalar_joint(j)[0] for j in joints]
    base, scale = robot.q_ref[iq].copy(), np.ones(len(iq))
    lower, upper = robot.model.lowerPositionLimit[iq], robot.model.upperPositionLimit[iq]
    narrow = (base + min(OFFSETS) < lower) | (base + max(OFFSETS) > upper)
    base[narrow] = 0.5 * (lower + upper)[narrow]
    scale[narrow] = 0.9 * 0.5 * (upper - lower)[narrow] / max(abs(x) for x in OFFSETS)
    return tuple(tuple(base + offset * scale) for offset in OFFSETS)


def _tau(effort, robot: Robot, q, v, t: float) -> np.ndarray:
    kin = Kinematics(robot.model)
    kin.update(q, v, derivatives=True)
    return effort.tau(kin, t)


def _fd_q(f, robot: Robot, q: np.ndarray, h: float = H) -> np.ndarray:
    """Central differences of ``f(q)`` on the manifold: column k from ``q ⊕ ±h e_k``."""
    cols = []
    for k in range(robot.nv):
        e = np.zeros(robot.nv)
        e[k] = h
        cols.append((f(robot.integrate(q, e)) - f(robot.integrate(q, -e))) / (2.0 * h))
    return np.stack(cols, axis=-1)


# -- the schedule ------------------------------------------------------------------------
def test_schedule_matches_the_smooth_step_in_closed_form(panda):
    joints = panda.joint_names
    rows = np.array(_rows(panda, joints))
    ev = JointTargets(joints, TIMES, rows, stiffness=10.0).bind(panda)
    # at knots S(0) = 0 and S(1) = 1, S' = S'' = 0 (in floating point too): exact
    for t, row in zip(TIMES, rows):
        r, dr, ddr = ev.reference(t)
        np.testing.assert_array_equal(r, row)
        np.testing.assert_array_equal(dr, 0.0)
        np.testing.assert_array_equal(ddr, 0.0)
    # outside the knots the first / last row is held
    for t, row in ((-3.0, rows[0]), (0.0, rows[0]), (2.6, rows[-1]), (100.0, rows[-1])):
        r, dr, ddr = ev.reference(t)
        np.testing.assert_array_equal(r, row)
        np.testing.assert_array_equal(dr, 0.0)
        np.testing.assert_array_equal(ddr, 0.0)
    # midpoints: S(1/2) = 1/2, S'(1/2) = 15/8, S''(1/2) = 0; a few ulps of |r| ~ 3 rad
    for k in range(len(TIMES) - 1):
        width = TIMES[k + 1] - TIMES[k]
        r, dr, ddr = ev.reference(0.5 * (TIMES[k] + TIMES[k + 1]))
        np.testing.assert_allclose(r, 0.5 * (rows[k] + rows[k + 1]), rtol=0, atol=1e-14)
        np.testing.assert_allclose(dr, 15.0 / 8.0 * (rows[k + 1] - rows[k]) / width, rtol=0, atol=1e-14)
        np.testing.assert_allclose(ddr, 0.0, rtol=0, atol=1e-14)


def test_tau_is_the_pd_law_on_the_listed_joints_and_zero_elsewhere(panda):
    """Three joints listed out of model order, per-joint gains, no gravity: at a piece's
    midpoint ``tau_j = K_j ((r_k + r_k+1)/2 - q_j) + D_j (15/8 Δ_j / T - v_j)``."""
    joints = ("panda_joint4", "panda_joint2", "panda_finger_joint1")
    rows = np.array(_rows(panda, joints))
    K, D = np.array([40.0, 60.0, 200.0]), np.array([2.0, 3.0, 5.0])
    ev = JointTargets(joints, TIMES, rows, stiffness=tuple(K), damping=tuple(D)).bind(panda)
    rng = np.random.default_rng(3)
    q = panda.integrate(panda.q_ref, 0.2 * rng.standard_normal(panda.nv))
    v = rng.standard_normal(panda.nv)
    tau = _tau(ev, panda, q, v, 1.0)
    iv = [panda.scalar_joint(j)[1] for j in joints]
    expected = np.zeros(panda.nv)
    expected[iv] = K * (0.5 * (rows[0] + rows[1]) - q[iv]) + D * (15.0 / 8.0 * (rows[1] - rows[0]) - v[iv])
    np.testing.assert_allclose(tau, expected, rtol=1e-13, atol=1e-12)  # round-off of O(10) N m terms
    assert np.count_nonzero(tau) == len(joints)
    assert isinstance(ev.spec, Effort) and isinstance(ev, BoundEffort)  # what a Scene accepts


# -- derivatives -------------------------------------------------------------------------
@pytest.fixture(scope="module")
def panda_floating() -> Robot:
    """The Panda on a free-flyer base: its joints' q and v indices differ by one (the
    quaternion), which a mix-up of the two would show."""
    return load_robot("panda", floating_base=True)


@pytest.mark.parametrize("which", ["panda", "panda_box", "panda_floating"])
def test_derivatives_match_central_differences_on_the_manifold(which, request):
    robot = request.getfixturevalue(which)
    joints = robot.joint_names if which == "panda" else [f"panda_joint{i}" for i in range(1, 8)]
    stiffness = tuple(np.linspace(20.0, 80.0, len(joints)))
    effort = JointTargets(
        joints, TIMES, _rows(robot, joints), stiffness=stiffness, damping=4.0, gravity_compensation=True
    )
    ev = effort.bind(robot)
    rng = np.random.default_rng(7)
    # random q (the box's quaternion turned too), random v, inside a piece
    q = robot.integrate(robot.q_ref, 0.3 * rng.standard_normal(robot.nv))
    v, t = rng.standard_normal(robot.nv), 1.2
    kin = Kinematics(robot.model)
    kin.update(q, v, derivatives=True)
    dq, dv = ev.derivatives(kin, t)
    tau = ev.tau(kin, t)
    assert_fd(
        f"joint targets dtau/dq {which}",
        dq,
        _fd_q(lambda x: _tau(ev, robot, x, v, t), robot, q),
        value=tau,
        rtol=FD_RTOL,
    )
    assert_fd(
        f"joint targets dtau/dv {which}",
        dv,
        fd_dv(lambda x: _tau(ev, robot, q, x, t), v, eps=H),
        value=tau,
        rtol=FD_RTOL,
    )
    # the gravity rows are not diagonal: the test would miss nothing by the PD terms alone
    off_diagonal = dq - np.diag(np.diag(dq))
    assert np.abs(off_diagonal).max() > 1.0  # N m/rad


def test_time_derivative_and_breakpoints(panda):
    joints = panda.joint_names
    ev = JointTargets(joints, TIMES, _rows(panda, joints), stiffness=50.0, damping=7.0).bind(panda)
    rng = np.random.default_rng(11)
    q = panda.integrate(panda.q_ref, 0.2 * rng.standard_normal(panda.nv))
    v = rng.standard_normal(panda.nv)
    kin = Kinematics(panda.model)
    kin.update(q, v)
    # inside pieces and outside the knots, where tau is smooth in t
    for t in (0.0, 0.7, 1.0, 1.93, 3.0):
        fd = (ev.tau(kin, t + H) - ev.tau(kin, t - H)) / (2.0 * H)
        assert_fd(f"joint targets dtau/dt at {t}", ev.time_derivative(kin, t), fd, value=ev.tau(kin, t), rtol=FD_RTOL)
    # at a knot ṙ = r̈ = 0, so dtau/dt = 0 exactly; but the term D ṙ of tau is only C¹ there
    # (r''' jumps: ṙ ≈ 30 Δ s² / T³ on either side), so the central difference is O(H), not
    # O(H²): |FD| <= 15 D H (|Δ_k-1| + |Δ_k|) / T² <= 30 D H max|Δ| (T = 1 s), plus round-off
    # ~ eps |tau| / H ~ 1e-9 N m/s
    largest_step = np.abs(np.diff(np.array(_rows(panda, joints)), axis=0)).max()
    for t in TIMES:
        np.testing.assert_array_equal(ev.time_derivative(kin, t), 0.0)
        fd = (ev.tau(kin, t + H) - ev.tau(kin, t - H)) / (2.0 * H)
        assert np.abs(fd).max() <= 30.0 * 7.0 * H * largest_step + 1e-8
    assert np.abs(ev.time_derivative(kin, 1.0)).max() > 1.0  # N m/s: the check has something to see
    seen, t = [], -1.0
    while not math.isinf(t := ev.next_breakpoint(t)):
        seen.append(t)
    assert seen == list(TIMES)
    assert ev.next_breakpoint(0.6) == 1.5 and ev.next_breakpoint(1.5) == 2.5


# -- mechanics ---------------------------------------------------------------------------
def test_gravity_compensation_holds_the_arm_still(panda, panda_box):
    """At rest on the first row with every arm joint listed, ``aba(q, 0, tau) = 0`` on
    those joints: the arm stands still. Round-off: ~ eps |M^-1| |g| ~ 2e-16 * 150 * 22
    ~ 1e-12 rad/s²; 1e-10 keeps margin, against a fall of ~40 rad/s² without it."""
    for robot in (panda, panda_box):
        joints = panda.joint_names
        rows = _rows(robot, joints)
        q = robot.q_ref.copy()
        iv = [robot.scalar_joint(j)[1] for j in joints]
        q[[robot.scalar_joint(j)[0] for j in joints]] = rows[0]
        zero = np.zeros(robot.nv)
        for compensated in (True, False):
            ev = JointTargets(
                joints, TIMES, rows, stiffness=100.0, damping=10.0, gravity_compensation=compensated
            ).bind(robot)
            a = pin.aba(robot.model, robot.new_data(), q, zero, _tau(ev, robot, q, zero, TIMES[0]))
            if compensated:
                np.testing.assert_allclose(a[iv], 0.0, rtol=0, atol=1e-10)
            else:
                assert np.abs(a[iv]).max() > 1.0  # rad/s²: the arm falls
            if robot is panda_box:  # the box, not listed, falls at g whatever the arm does
                np.testing.assert_allclose(a[9:], [0.0, 0.0, -9.81, 0.0, 0.0, 0.0], rtol=0, atol=1e-12)


# -- inputs ------------------------------------------------------------------------------
def test_keys_are_the_fields():
    assert JointTargets.KEYS == tuple(f.name for f in fields(JointTargets))


def test_fields_are_normalised():
    e = JointTargets(["a", "b"], [0, 1], [[1, 2], [3, 4]], stiffness=[1, 2], damping=3)
    assert e.joints == ("a", "b") and e.times == (0.0, 1.0) and e.targets == ((1.0, 2.0), (3.0, 4.0))
    assert e.stiffness == (1.0, 2.0) and e.damping == 3.0 and isinstance(e.damping, float)
    assert hash(e) == hash(JointTargets(("a", "b"), (0.0, 1.0), ((1, 2), (3, 4)), (1.0, 2.0), 3.0))


GOOD = dict(joints=("j1", "j2"), times=(0.0, 1.0), targets=((0.0, 0.0), (1.0, 1.0)), stiffness=10.0)


@pytest.mark.parametrize(
    "change, shown",
    [
        (dict(times=(0.0, 1.0, 1.0), targets=((0, 0),) * 3), "times[2] = 1.0"),
        (dict(times=(1.0, 0.5)), "times[1] = 0.5"),
        (dict(times=()), "()"),
        (dict(times=(0.0, float("inf"))), "inf"),
        (dict(targets=((0.0, 0.0),)), "(1, 2)"),
        (dict(targets=((0.0, 0.0), (1.0, 1.0, 2.0))), "(1.0, 1.0, 2.0)"),
        (dict(targets=((0.0, 0.0), (1.0, float("nan")))), "targets[1][1] (j2) is nan"),
        (dict(stiffness=-1.5), "-1.5"),
        (dict(damping=(1.0, -2.0)), "-2.0"),
        (dict(stiffness=(1.0, 2.0, 3.0)), "(1.0, 2.0, 3.0)"),
        (dict(joints=("j1", "j1")), "'j1'"),
        (dict(joints="j1"), "'j1'"),
        (dict(joints=()), "()"),
        (dict(gravity_compensation="yes"), "'yes'"),
        (dict(name=""), "''"),
    ],
)
def test_bad_specs_are_refused_showing_the_value(change, shown):
    with pytest.raises(InvalidInputError, match=re.escape(shown)):
        JointTargets(**{**GOOD, **change})


def test_bad_joints_are_refused_at_bind(panda, panda_box):
    rows = ((0.0,), (1.0,))
    with pytest.raises(UnknownNameError, match=r"'panda_joint8'.*panda_joint1"):
        JointTargets(("panda_joint8",), (0.0, 1.0), rows, 1.0).bind(panda)
    with pytest.raises(InvalidInputError, match=r"'box' has nq=7, nv=6"):  # a free-flyer: not one number
        JointTargets(("box",), (0.0, 1.0), rows, 1.0).bind(panda_box)


def test_targets_outside_the_joint_limits_are_refused_at_bind(panda):
    """The Panda's URDF limits its fingers to [0, 0.04] m: a schedule driving them to
    0.485 m (a value past the stop, which the model would not enforce) is refused, naming
    the joint, the value and the limits; targets on the limits themselves are accepted."""
    fingers = ("panda_finger_joint1", "panda_finger_joint2")
    lower = panda.model.lowerPositionLimit[[panda.scalar_joint(j)[0] for j in fingers]]
    upper = panda.model.upperPositionLimit[[panda.scalar_joint(j)[0] for j in fingers]]
    np.testing.assert_array_equal(lower, 0.0)
    np.testing.assert_array_equal(upper, 0.04)
    JointTargets(fingers, (0.0, 1.0), ((0.04, 0.04), (0.0, 0.0)), 300.0).bind(panda)
    message = re.escape("targets[1][1] of joint 'panda_finger_joint2' is 0.485") + r".*\[0, 0\.04\]"
    with pytest.raises(InvalidInputError, match=message):
        JointTargets(fingers, (0.0, 1.0), ((0.03, 0.03), (0.03, 0.485)), 300.0).bind(panda)
    with pytest.raises(InvalidInputError, match=r"'panda_joint4' is 0\.5.*\[-3\.0718, -0\.0698\]"):
        JointTargets(("panda_joint4",), (0.0,), ((0.5,),), 300.0).bind(panda)
