"""The event-driven hybrid integrator against closed forms derived by hand.

Every reference number below comes from a closed form (or, where stated, from
scipy on an ODE written out here from first principles), never from the code's
own output. Tolerances and the reason for each are given next to the asserts.

Models (docs/design.md §6, robots/*.toml; units with g = 1 unless stated):

* ball: mass 1 on the vertical joint ``z``, dropped from h = 1;
* planar_trot_soft: body (m_b = 1) on two leg springs (k = 27, rest 0.5) to two
  point-mass feet (m_f = 1), plastic frictionless feet;
* planar_trot_rigid: one body (m = 3, I = 31/24) with feet at body-frame
  (∓0.25, -1/6), plastic frictionless;
* two_limb: body (m_b = 1) on two springs (k = 10, rest 0.5) to two limbs
  (m_f = 0.1);
* solo12_drop: free-flyer, sticking plastic feet, passive PD joints, g = 9.81.
"""

from __future__ import annotations

import itertools
import json
import math

import numpy as np
import pinocchio as pin
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

import contactdiff as cd
from contactdiff.errors import GrazingError, TooManyEventsError
from contactdiff.integration.hybrid import simulate
from contactdiff.ode.factory import METHODS

TIGHT = dict(rtol=1e-12, atol=1e-14)
SQ2 = math.sqrt(2.0)


# ----------------------------------------------------------------------------------
# helpers
# ----------------------------------------------------------------------------------
def _idx(scene, joint):
    """(idx_q, idx_v) of a one-coordinate joint."""
    j = scene.model.joints[scene.model.getJointId(joint)]
    return j.idx_q, j.idx_v


@pytest.fixture(scope="module")
def ball_robot():
    return cd.load_scene("ball").robot


def _ball(robot, e, z0=1.0):
    return cd.Scene(robot, [cd.Contact("ball", restitution=e)], gravity=[0, 0, -1], q0={"z": z0})


def _ball_events_closed_form(e, n, h=1.0, g=1.0):
    """Impact k = 0..n-1 of a ball dropped from h: time, v-, v+.

    Flight k (after impact k) lasts 2 e^(k+1) sqrt(2gh)/g, so
    t_k = sqrt(2h/g) (1 + 2 sum_{j=1..k} e^j); v-_k = -e^k sqrt(2gh); v+_k = -e v-_k.
    """
    t = [math.sqrt(2 * h / g) * (1 + 2 * sum(e**j for j in range(1, k + 1))) for k in range(n)]
    vm = [-(e**k) * math.sqrt(2 * g * h) for k in range(n)]
    return np.array(t), np.array(vm), -e * np.array(vm)


# ----------------------------------------------------------------------------------
# 1. ball
# ----------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def ball_run():
    scene = cd.load_scene("ball")
    return scene, simulate(scene, 11.4, **TIGHT, dense=True)  # t_9 = 11.209..., t_10 = 11.513...


def test_ball_event_times_and_velocities(ball_run):
    """First 10 bounces vs the closed form to <= 1e-10.

    Tolerance 1e-10 (docs/design.md §7 target): each flight is a quadratic that DOP853
    integrates exactly up to rounding, Brent locates each root to ~4 eps in
    time, so the only error is rounding accumulated over 10 bounces (~1e-14).
    """
    _, traj = ball_run
    t_ref, vm_ref, vp_ref = _ball_events_closed_form(0.8, 10)
    events = traj.events
    assert len(events) == 10
    assert all(ev.kind == "bounce" and ev.contacts == ("ball",) and not ev.simultaneous for ev in events)
    t = np.array([ev.t for ev in events])
    vm = np.array([ev.v_minus[0] for ev in events])
    vp = np.array([ev.v_plus[0] for ev in events])
    np.testing.assert_allclose(t, t_ref, rtol=0, atol=1e-10)
    np.testing.assert_allclose(vm, vm_ref, rtol=0, atol=1e-10)
    np.testing.assert_allclose(vp, vp_ref, rtol=0, atol=1e-10)
    # impulse of a unit mass = v+ - v- = (1 + e) e^k sqrt(2)
    imp = np.array([ev.impulses["ball"] for ev in events])
    np.testing.assert_allclose(imp, vp_ref - vm_ref, rtol=0, atol=1e-10)
    np.testing.assert_allclose([ev.normal_speeds["ball"] for ev in events], vm_ref, rtol=0, atol=1e-10)
    # a bounce keeps the mode: free flight before and after
    assert all(ev.mode_before == () and ev.mode_after == () for ev in events)


def test_ball_located_gap(ball_run):
    """|z| <= 1e-12 at every located touchdown (docs/design.md §7), both the event's q and
    the dense output's left limit (the located root itself, before any closing)."""
    _, traj = ball_run
    for ev in traj.events:
        assert abs(ev.q[0]) <= 1e-12
        q_left, _ = traj.at(ev.t, side="left")
        assert abs(q_left[0]) <= 1e-12


def test_ball_dense_output_between_bounces(ball_run):
    """at(t) between bounces is the parabola z = v+_k s - s^2/2, v = v+_k - s.

    Tolerance 1e-10: the interpolant of an order-8 method reproduces a quadratic
    exactly up to rounding; the remaining error is that of the event time t_k
    (<= 1e-10 by the test above) times the speed (<= 1.5)."""
    _, traj = ball_run
    t_ref, vm_ref, vp_ref = _ball_events_closed_form(0.8, 10)
    # before the first impact: free fall from 1
    for t in (0.0, 0.3, 1.0, 1.4):
        q, v = traj.at(t)
        assert q[0] == pytest.approx(1 - t * t / 2, abs=1e-12)
        assert v[0] == pytest.approx(-t, abs=1e-12)
    for k in range(9):
        flight = t_ref[k + 1] - t_ref[k]
        for frac in (0.1, 0.5, 0.77):
            s = frac * flight
            q, v = traj.at(t_ref[k] + s)
            assert q[0] == pytest.approx(vp_ref[k] * s - s * s / 2, abs=1e-10)
            assert v[0] == pytest.approx(vp_ref[k] - s, abs=1e-10)


def test_ball_left_right_limits_at_events(ball_run):
    """at(t_event, side=...) gives the velocity before / after the jump."""
    _, traj = ball_run
    _, vm_ref, vp_ref = _ball_events_closed_form(0.8, 10)
    for k, ev in enumerate(traj.events):
        _, v_left = traj.at(ev.t, side="left")
        _, v_right = traj.at(ev.t, side="right")
        assert v_left[0] == pytest.approx(vm_ref[k], abs=1e-10)
        assert v_right[0] == pytest.approx(vp_ref[k], abs=1e-10)
    with pytest.raises(cd.InvalidInputError, match="side"):
        traj.at(1.0, side="middle")
    with pytest.raises(cd.InvalidInputError):
        traj.at(traj.t + 1.0)


def test_ball_sample_and_exports(ball_run, tmp_path):
    _, traj = ball_run
    t_ref, _, vp_ref = _ball_events_closed_form(0.8, 10)
    times = np.linspace(0.0, traj.t, 57)
    qs, vs = traj.sample(times)
    assert qs.shape == (57, 1) and vs.shape == (57, 1)
    # closed form of the whole piecewise parabola (right limits)
    k = np.searchsorted(t_ref, times, side="right") - 1
    s = np.where(k < 0, times, times - t_ref[np.maximum(k, 0)])
    z = np.where(k < 0, 1 - s * s / 2, vp_ref[np.maximum(k, 0)] * s - s * s / 2)
    v = np.where(k < 0, -s, vp_ref[np.maximum(k, 0)] - s)
    np.testing.assert_allclose(qs[:, 0], z, rtol=0, atol=1e-10)
    np.testing.assert_allclose(vs[:, 0], v, rtol=0, atol=1e-10)

    npz = tmp_path / "ball.npz"
    traj.save_npz(npz, n_samples=101)
    data = np.load(npz)
    grid = np.linspace(traj.t0, traj.t, 101)
    np.testing.assert_array_equal(data["t"], grid)
    q_grid, v_grid = traj.sample(grid)
    np.testing.assert_array_equal(data["q"], q_grid)
    np.testing.assert_array_equal(data["v"], v_grid)
    assert float(data["t_final"]) == traj.t
    np.testing.assert_array_equal(data["q_final"], traj.q)
    np.testing.assert_array_equal(data["v_final"], traj.v)
    np.testing.assert_array_equal(data["event_t"], [ev.t for ev in traj.events])
    assert list(data["event_kind"]) == [ev.kind for ev in traj.events]
    assert list(data["event_contacts"]) == ["ball"] * len(traj.events)

    js = tmp_path / "ball.json"
    traj.save_json(js)
    loaded = json.loads(js.read_text())
    assert loaded == json.loads(json.dumps(traj.summary()))
    assert loaded["t"] == traj.t and loaded["termination"] == "t_final"
    assert [e["t"] for e in loaded["events"]] == [ev.t for ev in traj.events]  # exact: repr round trip
    assert [e["kind"] for e in loaded["events"]] == ["bounce"] * 10
    assert loaded["events"][0]["v_minus"] == [float(traj.events[0].v_minus[0])]
    assert loaded["modes"] == [[] for _ in traj.modes]


ZENO_E = [0.5, 0.8, 0.9, 0.99]  # 0.99: ~1400 bounces, ~1.5 s: fast enough, not slow-marked


@pytest.mark.parametrize("e", ZENO_E)
def test_ball_zeno(ball_robot, e):
    """The bounce sequence ends with a "zeno" event near the limit time t_Z.

    The bounces accumulate at t_Z = sqrt(2h/g) (1 + 2e/(1-e)). The sequence ends
    at the first impact with incoming speed u < zeno_speed; what remains of the
    geometric series of flights after it is 2 u e/(g(1 - e)) and u >= e zeno_speed
    (the impact before was still a bounce), hence
        2 e^2 zeno/(g(1-e)) <= t_Z - t_zeno <= 2 e zeno/(g(1-e)) (<= 2 zeno/(g(1-e))).
    Slack 1e-9 for the rounding accumulated over up to 1400 bounces.
    """
    zeno = 1e-6
    t_z = SQ2 * (1 + 2 * e / (1 - e))
    traj = simulate(_ball(ball_robot, e), t_z + 1.0, **TIGHT, zeno_speed=zeno, max_events=100_000, dense=True)
    last = traj.events[-1]
    assert last.kind == "zeno"
    assert [ev.kind for ev in traj.events[:-1]] == ["bounce"] * (len(traj.events) - 1)
    gap = t_z - last.t
    assert 2 * e * e * zeno / (1 - e) - 1e-9 <= gap <= 2 * e * zeno / (1 - e) + 1e-9
    assert gap <= 2 * zeno / (1 - e)
    assert abs(last.v_minus[0]) < zeno <= abs(traj.events[-2].v_minus[0])
    # expected number of events: impacts k = 0..K with K the first k such that
    # e^k sqrt(2) < zeno, i.e. K = floor(k*) + 1 (unless k* is on the boundary)
    k_star = math.log(zeno / SQ2) / math.log(e)
    if abs(k_star - round(k_star)) > 1e-3:
        assert len(traj.events) == math.floor(k_star) + 2
    # after Zeno: resting in contact, exactly
    assert last.v_plus[0] == 0.0 and last.mode_after == ("ball",)
    assert traj.modes[-1] == ("ball",)
    assert abs(traj.q[0]) <= 1e-12 and abs(traj.v[0]) <= 1e-12
    q_mid, v_mid = traj.at(0.5 * (last.t + traj.t))
    assert abs(q_mid[0]) <= 1e-12 and abs(v_mid[0]) <= 1e-12
    assert any("Zeno" in note for note in traj.notes)


def test_ball_elastic_keeps_energy(ball_robot):
    """e = 1: every flight lasts 2 sqrt(2), every impact at speed sqrt(2), and the
    energy v^2/2 + z = 1 holds along the dense output. 10 bounces; tolerance 1e-9
    (rounding accumulated over the bounces, each exact up to rounding)."""
    n = 10
    traj = simulate(_ball(ball_robot, 1.0), SQ2 * 2 * n, **TIGHT, dense=True)
    assert [ev.kind for ev in traj.events] == ["bounce"] * n
    np.testing.assert_allclose([ev.t for ev in traj.events], SQ2 * (1 + 2 * np.arange(n)), rtol=0, atol=1e-9)
    np.testing.assert_allclose([ev.v_minus[0] for ev in traj.events], -SQ2, rtol=0, atol=1e-9)
    np.testing.assert_allclose([ev.v_plus[0] for ev in traj.events], SQ2, rtol=0, atol=1e-9)
    qs, vs = traj.sample(np.linspace(0, traj.t, 400))
    energy = 0.5 * vs[:, 0] ** 2 + qs[:, 0]
    np.testing.assert_allclose(energy, 1.0, rtol=0, atol=1e-9)


def test_ball_plastic_single_touchdown(ball_robot):
    """e = 0: one touchdown at sqrt(2) with v- = -sqrt(2), then rest (z = v = 0)."""
    traj = simulate(_ball(ball_robot, 0.0), 5.0, **TIGHT)
    assert len(traj.events) == 1
    ev = traj.events[0]
    assert ev.kind == "touchdown" and ev.mode_after == ("ball",)
    assert ev.t == pytest.approx(SQ2, abs=1e-12)
    assert ev.v_minus[0] == pytest.approx(-SQ2, abs=1e-12)
    assert ev.v_plus[0] == 0.0
    assert ev.impulses["ball"] == pytest.approx(SQ2, abs=1e-12)
    assert traj.modes == [(), ("ball",)]
    assert abs(traj.q[0]) <= 1e-12 and abs(traj.v[0]) <= 1e-12


# ----------------------------------------------------------------------------------
# 2./4. body on two leg springs: planar_trot_soft at pitch 0, two_limb
# ----------------------------------------------------------------------------------
class SpringHopper:
    """Closed form of a body (m_b) on two identical springs (k, rest 0.5) to two
    point-mass limbs (m_f) that hang at rest length and fall from body height 1.

    * free fall to t = 1 (limbs at 0.5 land together, everything at speed -1);
    * plastic impact stops the limbs, the body keeps -1 (diagonal M, rows only on
      the limb coordinates: decoupled);
    * stance: m_b z'' = -m_b g + 2 k (0.5 - z), so with w^2 = 2k/m_b, c = g/w^2,
      z(s) = 0.5 - c + c cos(ws) - sin(ws)/w (z(0) = 0.5, z'(0) = -1);
      a limb's normal force is k (0.5 - z) + m_f g: lift-off at z = 0.5 + m_f g/k
      (the first upward crossing);
    * flight: the centre of mass Z = (m_b z_b + 2 m_f z_f)/M falls freely and the
      stretch d = z_b - z_f - 0.5 obeys d'' = -k (2/m_b + 1/m_f) d, both from
      the lift-off state (limbs at 0 at rest, d = m_f g/k, d' = z_b');
      z_f = Z - m_b (0.5 + d)/M, z_b = z_f + 0.5 + d; next touchdown: z_f = 0.
    """

    def __init__(self, m_b, m_f, k, g=1.0):
        self.m_b, self.m_f, self.k, self.g = m_b, m_f, k, g
        self.w = math.sqrt(2 * k / m_b)
        self.c = g / self.w**2
        self.z_lo = 0.5 + m_f * g / k
        grid = np.linspace(0.0, 2 * np.pi / self.w, 4001)
        f = self.stance(grid)[0] - self.z_lo
        i = np.nonzero((f[:-1] < 0) & (f[1:] >= 0))[0][0]
        self.s_lo = brentq(lambda s: self.stance(s)[0] - self.z_lo, grid[i], grid[i + 1], xtol=1e-15, rtol=1e-15)
        self.t_lo = 1.0 + self.s_lo
        self.M = m_b + 2 * m_f
        self.W = math.sqrt(k * (2 / m_b + 1 / m_f))
        self.d0 = m_f * g / k
        self.dd0 = self.stance(self.s_lo)[1]
        # first root of z_f after lift-off (z_f ~ s^3 at first: start the scan past 0)
        grid = np.linspace(1e-6, 20.0, 400001)
        f = self.flight(grid)[1]
        i = np.nonzero((f[:-1] > 0) & (f[1:] <= 0))[0][0]
        self.s_td = brentq(lambda s: self.flight(s)[1], grid[i], grid[i + 1], xtol=1e-15, rtol=1e-15)
        self.t_td = self.t_lo + self.s_td

    def stance(self, s):
        w, c = self.w, self.c
        return (0.5 - c + c * np.cos(w * s) - np.sin(w * s) / w, -c * w * np.sin(w * s) - np.cos(w * s))

    def flight(self, s):
        """(z_b, z_f, z_b', z_f') at time s after lift-off."""
        g, M, m_b, W = self.g, self.M, self.m_b, self.W
        Z0, Zd0 = m_b * (0.5 + self.d0) / M, m_b * self.dd0 / M
        Z, Zd = Z0 + Zd0 * s - g * s * s / 2, Zd0 - g * s
        d = self.d0 * np.cos(W * s) + self.dd0 / W * np.sin(W * s)
        dd = -self.d0 * W * np.sin(W * s) + self.dd0 * np.cos(W * s)
        z_f, zd_f = Z - m_b * (0.5 + d) / M, Zd - m_b * dd / M
        return z_f + 0.5 + d, z_f, zd_f + dd, zd_f


HOPPERS = {
    "planar_trot_soft": (
        SpringHopper(1.0, 1.0, 27.0),
        "body_z",
        ("rear_foot_z", "front_foot_z"),
        ("rear_foot", "front_foot"),
    ),
    "two_limb": (SpringHopper(1.0, 0.1, 10.0), "body_z", ("left_foot_z", "right_foot_z"), ("left_foot", "right_foot")),
}


@pytest.fixture(scope="module", params=sorted(HOPPERS))
def hopper_run(request):
    name = request.param
    ref = HOPPERS[name][0]
    scene = cd.load_scene(name)
    return name, scene, simulate(scene, ref.t_td + 0.2, **TIGHT, dense=True)


def test_hopper_event_sequence(hopper_run):
    """touchdown (both, t = 1) -> lift-off (both) -> touchdown (both), times vs the
    closed form. Tolerance 1e-9 on the times: the references are brentq roots of
    closed forms to ~1e-15; the simulation at rtol 1e-12 accumulates ~1e-12."""
    name, scene, traj = hopper_run
    ref, _, _, contacts = HOPPERS[name]
    kinds = [ev.kind for ev in traj.events]
    assert kinds == ["touchdown", "lift-off", "touchdown"], kinds
    for ev in traj.events:
        assert set(ev.contacts) == set(contacts) and ev.simultaneous
    td1, lo, td2 = traj.events
    assert td1.t == pytest.approx(1.0, abs=1e-10)
    assert lo.t == pytest.approx(ref.t_lo, abs=1e-9)
    assert td2.t == pytest.approx(ref.t_td, abs=1e-9)
    assert set(td1.mode_after) == set(contacts) and lo.mode_after == ()
    assert set(td2.mode_after) == set(contacts)
    assert traj.modes == [(), td1.mode_after, (), td2.mode_after]


def test_hopper_touchdown_impact_is_decoupled(hopper_run):
    """Plastic impact: limb velocities -> 0, body velocity unchanged (-1), impulse
    m_f * 1 per limb. Tolerance 1e-10 (free fall is exact up to rounding)."""
    name, scene, traj = hopper_run
    ref, body, limbs, contacts = HOPPERS[name]
    ev = traj.events[0]
    _, vb = _idx(scene, body)
    assert ev.v_minus[vb] == pytest.approx(-1.0, abs=1e-10)
    assert ev.v_plus[vb] == pytest.approx(-1.0, abs=1e-10)
    for limb, contact in zip(limbs, contacts):
        _, vi = _idx(scene, limb)
        assert ev.v_minus[vi] == pytest.approx(-1.0, abs=1e-10)
        assert ev.v_plus[vi] == pytest.approx(0.0, abs=1e-12)
        assert ev.impulses[contact] == pytest.approx(ref.m_f, abs=1e-10)
    # everything else (x, pitch of the soft trot) untouched and zero
    others = [i for i in range(scene.nv) if i not in [vb] + [_idx(scene, j)[1] for j in limbs]]
    assert np.all(np.abs(ev.v_plus[others]) <= 1e-12)


def test_hopper_stance_and_flight_states(hopper_run):
    """Dense output in stance and in flight vs the closed form. Tolerance 1e-9:
    smooth flow at rtol 1e-12 over ~3 oscillation periods (global error ~1e-11)."""
    name, scene, traj = hopper_run
    ref, body, limbs, _ = HOPPERS[name]
    qb, vb = _idx(scene, body)
    li = [_idx(scene, j) for j in limbs]
    for frac in (0.1, 0.37, 0.5, 0.9):
        s = frac * ref.s_lo
        q, v = traj.at(1.0 + s)
        z, zd = ref.stance(s)
        assert q[qb] == pytest.approx(z, abs=1e-9) and v[vb] == pytest.approx(zd, abs=1e-9)
        for iq, iv in li:
            assert abs(q[iq]) <= 1e-12 and abs(v[iv]) <= 1e-12
    for frac in (0.05, 0.3, 0.6, 0.95):
        s = frac * ref.s_td
        q, v = traj.at(ref.t_lo + s)
        zb, zf, zdb, zdf = ref.flight(s)
        assert q[qb] == pytest.approx(zb, abs=1e-9) and v[vb] == pytest.approx(zdb, abs=1e-9)
        for iq, iv in li:
            assert q[iq] == pytest.approx(zf, abs=1e-9) and v[iv] == pytest.approx(zdf, abs=1e-9)
    # second touchdown: limbs land at the flight's z_f' and stop; body unchanged
    ev = traj.events[2]
    _, _, zdb, zdf = ref.flight(ref.s_td)
    assert ev.v_minus[vb] == pytest.approx(zdb, abs=1e-9) and ev.v_plus[vb] == pytest.approx(zdb, abs=1e-9)
    for _, iv in li:
        assert ev.v_minus[iv] == pytest.approx(zdf, abs=1e-9) and ev.v_plus[iv] == pytest.approx(0, abs=1e-12)


def test_soft_trot_flight_matches_solve_ivp():
    """Cross-check of the flight closed form itself (so a slip in the algebra above
    cannot hide): solve_ivp of the same linear 2-body ODE at rtol 1e-13."""
    ref = HOPPERS["planar_trot_soft"][0]
    m_b, m_f, k, g = ref.m_b, ref.m_f, ref.k, ref.g

    def f(t, y):
        zb, zf, vb, vf = y
        d = zb - zf - 0.5
        return [vb, vf, -g - 2 * k * d / m_b, -g + k * d / m_f]

    y0 = [0.5 + ref.d0, 0.0, ref.dd0, 0.0]
    sol = solve_ivp(f, (0, ref.s_td), y0, method="DOP853", rtol=1e-13, atol=1e-15, dense_output=True)
    for s in np.linspace(0, ref.s_td, 7):
        np.testing.assert_allclose(sol.sol(s), ref.flight(s), rtol=0, atol=1e-10)


# ----------------------------------------------------------------------------------
# 3. rigid trot: the discontinuity at pitch 0
# ----------------------------------------------------------------------------------
M_R, I_R = 3.0, 31.0 / 24.0
MINV = np.diag([1 / M_R, 1 / I_R])  # (z, pitch); x is decoupled and stays 0


def _foot_h(theta, sign):
    """Height of a foot below/above the COM: body-frame (sign*0.25, -1/6), pitch about
    (0, -1, 0): world z offset = sign*0.25 sin(theta) - cos(theta)/6."""
    return sign * 0.25 * np.sin(theta) - np.cos(theta) / 6


def _foot_row(theta, sign):
    """Gap row in (z, pitch)."""
    return np.array([1.0, sign * 0.25 * np.cos(theta) + np.sin(theta) / 6])


def _plastic(v, rows):
    """Plastic impact LCP (frictionless, e = 0) by enumeration of active sets."""
    rows = [np.asarray(r) for r in rows]
    for n in range(len(rows), 0, -1):
        for S in itertools.combinations(range(len(rows)), n):
            A = np.array([rows[i] for i in S])
            lam = np.linalg.solve(A @ MINV @ A.T, -A @ v)
            vp = v + MINV @ A.T @ lam
            if np.all(lam >= 0) and all(rows[i] @ vp >= -1e-14 for i in range(len(rows))):
                return vp, S, lam
    raise AssertionError("no valid active set")


def _pivot(sign, theta0, omega0, t0, t1, stop_at_level=False):
    """Body pivoting on one foot (frictionless, gap 0): z = -h(theta), one DOF.

    T = (3 z'^2 + I) thd^2 / 2, V = 3 g z with z = Z(theta) = -h(theta):
    (3 Z'^2 + I) thdd + 3 Z' Z'' thd^2 + 3 g Z' = 0.
    Optionally stops when theta = 0 (the other foot's gap 0.5 |sin theta| closes).
    """

    def Z(th):
        return -_foot_h(th, sign)

    def Zp(th):
        return -(sign * 0.25 * np.cos(th) + np.sin(th) / 6)

    def Zpp(th):
        return -(-sign * 0.25 * np.sin(th) + np.cos(th) / 6)

    def f(t, y):
        th, w = y
        return [w, -(3 * Zp(th) * Zpp(th) * w * w + 3 * Zp(th)) / (3 * Zp(th) ** 2 + I_R)]

    def level(t, y):
        return y[0]

    level.terminal, level.direction = True, 0
    sol = solve_ivp(
        f,
        (t0, t1),
        [theta0, omega0],
        method="DOP853",
        rtol=1e-13,
        atol=1e-15,
        events=level if stop_at_level else None,
        dense_output=True,
    )
    th, w = sol.y[:, -1]
    t_end = sol.t[-1]
    # the normal force 3 (z'' + g) stays positive (the pivot holds)
    for tt in np.linspace(t0, t_end, 50):
        a, b = sol.sol(tt)
        thdd = f(tt, [a, b])[1]
        assert 3 * (Zp(a) * thdd + Zpp(a) * b * b + 1.0) > 0
    return t_end, th, w, Z(th), Zp(th) * w, sol


def _rigid_reference(theta0, t_final):
    """The rigid trot from pitch theta0 (lower foot at height 0.5, at rest), by hand.

    Free fall: the lower foot lands at t = 1 with speed 1. Plastic impact of that
    foot alone (closed form of the single-contact law). Pivot on it until the
    other foot's gap 0.5|sin theta| closes at theta = 0. Plastic impact with both
    feet closed (LCP by enumeration: the first foot lifts, see
    test_rigid_trot_limit_closed_form). Pivot on the second foot to t_final.
    theta0 = 0 with a sign (+0.0 / -0.0) gives the theta0 -> 0± limit sequence.
    Returns (z, theta, z', theta') at t_final.
    """
    first = -1 if math.copysign(1, theta0) > 0 else 1  # rear (-1) lands first for theta0 > 0
    v = np.array([-1.0, 0.0])
    v1, S, _ = _plastic(v, [_foot_row(theta0, first)])
    if theta0 != 0:
        t2, th2, w2, _, zd2, _ = _pivot(first, theta0, v1[1], 1.0, 2.0, stop_at_level=True)
        assert abs(th2) < 1e-12
        v1 = np.array([zd2, w2])
    else:
        t2 = 1.0
    v2, S2, _ = _plastic(v1, [_foot_row(0.0, -1), _foot_row(0.0, 1)])
    second = [-1, 1][S2[0]]
    assert S2 == ((0,) if second == -1 else (1,)) and second == -first
    _, th, w, z, zd, _ = _pivot(second, 0.0, v2[1], t2, t_final)
    return z, th, zd, w, t2


def test_rigid_trot_simultaneous_landing():
    """Pitch 0: both feet land at t = 1 and the body stops (two independent rows
    span z and pitch; plastic: both normal speeds 0 -> v = 0; x unaffected)."""
    scene = cd.load_scene("planar_trot_rigid")
    traj = simulate(scene, 1.5, **TIGHT)
    assert len(traj.events) == 1
    ev = traj.events[0]
    assert ev.kind == "touchdown" and ev.simultaneous and set(ev.contacts) == {"rear_foot", "front_foot"}
    assert ev.t == pytest.approx(1.0, abs=1e-10)
    np.testing.assert_allclose(ev.v_plus, 0.0, atol=1e-12)
    # impulses: 3 = sum, 0 = difference (moment about the COM): 1.5 each
    assert ev.impulses["rear_foot"] == pytest.approx(1.5, abs=1e-10)
    assert ev.impulses["front_foot"] == pytest.approx(1.5, abs=1e-10)
    np.testing.assert_allclose(traj.v, 0.0, atol=1e-12)
    np.testing.assert_allclose(traj.q, [0.0, 1 / 6, 0.0], atol=1e-12)
    assert set(traj.modes[-1]) == {"rear_foot", "front_foot"}


def test_rigid_trot_limit_closed_form():
    """The theta0 -> 0+ sequence by hand (rear first), in exact fractions.

    Rear alone: row a = (1, -1/4) in (z, pitch), a M^-1 a^T = 1/3 + (1/16)(24/31) = 71/186,
    impulse 186/71, v+ = (-1 + 62/71, -(24/31)(1/4)(186/71)) = (-9/71, -36/71).
    The front then approaches at (1, 1/4).v+ = -18/71 and closes after a time -> 0.
    Both closed: both-active would need impulses (rear, front) = (-159/142, 3/2):
    rejected. Front alone: impulse (18/71)(186/71) = 3348/5041,
    v++ = (477/5041, -1908/5041), rear speed (1, -1/4).v++ = 954/5041 >= 0: valid.
    So the rear lifts off and the body pitches down at 1908/5041 ~ 0.3785.
    """
    v1, S1, lam1 = _plastic(np.array([-1.0, 0.0]), [_foot_row(0.0, -1)])
    np.testing.assert_allclose(v1, [-9 / 71, -36 / 71], atol=1e-15)
    assert lam1[0] == pytest.approx(186 / 71, abs=1e-14)
    v2, S2, lam2 = _plastic(v1, [_foot_row(0.0, -1), _foot_row(0.0, 1)])
    assert S2 == (1,)
    np.testing.assert_allclose(v2, [477 / 5041, -1908 / 5041], atol=1e-15)
    assert lam2[0] == pytest.approx(3348 / 5041, abs=1e-14)
    assert _foot_row(0.0, -1) @ v2 == pytest.approx(954 / 5041, abs=1e-15)


RIGID_T_FINAL = 1.2  # after both impacts (t2 - 1 ~ 2 theta0 <= 0.1) and well before the rear comes back (t ~ 2.6)


@pytest.fixture(scope="module")
def rigid_scene():
    return cd.load_scene("planar_trot_rigid")


@pytest.mark.parametrize("theta0", [1e-3, -1e-3, 1e-5, -1e-5, 0.05, -0.05])
def test_rigid_trot_order_of_landing(rigid_scene, theta0):
    """theta0 != 0: the lower foot (rear for theta0 > 0) lands first at t = 1, the
    other at the end of the pivot, then the first lifts off; the state at
    t = 1.2 vs the hand-derived sequence (ODE of the pivot by solve_ivp at
    rtol 1e-13). Tolerance 1e-9 (1e-10 on the event times): both sides are
    accurate to ~1e-11."""
    zc = 0.5 + 0.25 * abs(math.sin(theta0)) + math.cos(theta0) / 6  # lower foot at 0.5
    traj = simulate(rigid_scene, RIGID_T_FINAL, q0=[0.0, zc, theta0], **TIGHT)
    first, second = ("rear_foot", "front_foot") if theta0 > 0 else ("front_foot", "rear_foot")
    assert [ev.contacts for ev in traj.events] == [(first,), (second,)]
    assert [ev.kind for ev in traj.events] == ["touchdown", "touchdown"]
    assert traj.events[0].t == pytest.approx(1.0, abs=1e-10)
    assert traj.events[0].mode_after == (first,)
    assert traj.events[1].mode_after == (second,)
    assert traj.events[1].impulses[first] == pytest.approx(0.0, abs=1e-12)
    assert traj.events[1].impulses[second] > 0
    z, th, zd, w, t2 = _rigid_reference(theta0, RIGID_T_FINAL)
    assert traj.events[1].t == pytest.approx(t2, abs=1e-10)
    np.testing.assert_allclose(traj.q, [0.0, z, th], rtol=0, atol=1e-9)
    np.testing.assert_allclose(traj.v, [0.0, zd, w], rtol=0, atol=1e-9)


@pytest.mark.parametrize("theta0", [1e-3, -1e-3, 1e-5, -1e-5])
def test_rigid_trot_discontinuity_at_zero(rigid_scene, theta0):
    """As theta0 -> 0± the outcome tends to the one-sided limit (rear-then-front or
    front-then-rear), which differs from the simultaneous outcome (rest, pitch
    rate 0) by ~0.28 rad/s at t = 1.2 (0.38 right after the impacts): the flow is discontinuous at theta0 = 0.

    The limit at t = 1.2 is the v++ of test_rigid_trot_limit_closed_form carried
    by the front-pivot ODE from t = 1. The distance to it is O(theta0) (the
    pivot lasts ~2 theta0 and the start pitch is theta0): tolerance 3 |theta0|.
    """
    zc = 0.5 + 0.25 * abs(math.sin(theta0)) + math.cos(theta0) / 6
    traj = simulate(rigid_scene, RIGID_T_FINAL, q0=[0.0, zc, theta0], **TIGHT)
    z, th, zd, w, _ = _rigid_reference(math.copysign(0.0, theta0), RIGID_T_FINAL)
    assert math.copysign(1, w) == -math.copysign(1, theta0)  # the pitch turns back through 0
    assert abs(traj.v[2] - w) <= 3 * abs(theta0)
    assert abs(traj.v[1] - zd) <= 3 * abs(theta0)
    assert abs(traj.q[2] - th) <= 3 * abs(theta0)
    # right after the second impact: v++ -> (0, 477/5041, -1908/5041) * sign(theta0)
    sign = math.copysign(1, theta0)
    v_pp = traj.events[1].v_plus
    assert abs(v_pp[2] - (-sign * 1908 / 5041)) <= 3 * abs(theta0)
    assert abs(v_pp[1] - 477 / 5041) <= 3 * abs(theta0)
    # the simultaneous outcome (theta0 = 0) is rest: a jump of |w| ~ 0.28 at t = 1.2
    simultaneous = simulate(rigid_scene, RIGID_T_FINAL, **TIGHT)
    assert abs(simultaneous.v[2]) <= 1e-12
    assert abs(w) > 0.25
    assert abs(traj.v[2] - simultaneous.v[2]) >= abs(w) - 3 * abs(theta0)


# ----------------------------------------------------------------------------------
# 5. solo12 drop (free-flyer, sticking feet)
# ----------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def solo_run():
    scene = cd.load_scene("solo12_drop")
    return scene, simulate(scene, 1.5, dense=True)


def test_solo12_drop(solo_run):
    scene, traj = solo_run
    model = scene.model
    # free fall of the whole robot (springs at rest, no velocity: a rigid fall)
    # until the lowest foot closes its gap h: t = sqrt(2 h / g), feet heights
    # computed here from Pinocchio directly
    data = model.createData()
    pin.framesForwardKinematics(model, data, scene.q0)
    h = [data.oMf[model.getFrameId(c.spec.frame)].translation[2] - c.spec.offset for c in scene.contacts]
    t_touch = math.sqrt(2 * min(h) / 9.81)
    assert traj.events[0].t == pytest.approx(t_touch, abs=1e-9)  # polynomial flight: exact up to rounding
    # all four feet touch down (one simultaneous event or several)
    touched = set()
    for ev in traj.events:
        if ev.kind in ("touchdown", "zeno", "grazing"):
            touched |= set(ev.contacts)
        # impulses never pull (LCP acceptance 1e-9 relative)
        for name, x in ev.impulses.items():
            assert x >= -1e-9 * max(1.0, max(abs(y) for y in ev.impulses.values())), (ev.t, name, x)
    assert touched == set(scene.contact_names)
    # ends at rest on all four feet: passive PD damping over ~1.4 s removes the
    # impact's motion; |v| <= 1e-3 is a loose bound (>= 99.9 % of the ~1 m/s impact speed gone)
    assert set(traj.modes[-1]) == set(scene.contact_names)
    assert np.max(np.abs(traj.v)) <= 1e-3
    # unit quaternion at the end and along the dense output (Lie-group stepping)
    assert abs(np.linalg.norm(traj.q[3:7]) - 1) <= 1e-12
    qs, _ = traj.sample(np.linspace(0, traj.t, 300))
    assert np.max(np.abs(np.linalg.norm(qs[:, 3:7], axis=1) - 1)) <= 1e-12
    # active gaps: drift before projection small, final gaps closed
    assert traj.max_drift <= 1e-8
    assert np.max(np.abs(scene.gaps(traj.q))) <= 1e-8


# ----------------------------------------------------------------------------------
# 7. admissibility and errors
# ----------------------------------------------------------------------------------
def test_penetrating_initial_state(ball_robot):
    scene = cd.load_scene("ball")
    with pytest.raises(cd.InconsistentStateError, match="ball"):
        simulate(scene, 1.0, q0=[-0.01])
    with pytest.raises(cd.InconsistentStateError):
        _ball(ball_robot, 0.5, z0=-0.1)


@pytest.mark.parametrize("t_final", [np.inf, np.nan, -np.inf, 0.0, -1.0])
def test_bad_t_final(t_final):
    with pytest.raises(cd.InvalidInputError, match="t_final"):
        simulate(cd.load_scene("ball"), t_final)


@pytest.mark.parametrize("bad", [[np.nan], [np.inf], {"z": np.nan}])
def test_non_finite_q0(bad):
    with pytest.raises(cd.InvalidInputError):
        simulate(cd.load_scene("ball"), 1.0, q0=bad)
    with pytest.raises(cd.InvalidInputError):
        simulate(cd.load_scene("ball"), 1.0, v0=bad)


def test_unknown_method_lists_valid():
    with pytest.raises(cd.InvalidInputError) as info:
        simulate(cd.load_scene("ball"), 1.0, method="Euler-ish")
    msg = str(info.value)
    assert "Euler-ish" in msg
    assert all(m in msg for m in METHODS)


def test_too_many_events():
    """max_events = 3: the 4th event raises, with the run so far attached."""
    with pytest.raises(TooManyEventsError) as info:
        simulate(cd.load_scene("ball"), 20.0, max_events=3, **TIGHT)
    traj = info.value.trajectory
    assert isinstance(info.value, cd.IntegrationError)
    assert "max_events" in str(info.value)
    assert traj.termination == "max_events"
    assert len(traj.events) == 4
    t_ref, _, _ = _ball_events_closed_form(0.8, 4)
    np.testing.assert_allclose([ev.t for ev in traj.events], t_ref, rtol=0, atol=1e-10)
    assert traj.t == pytest.approx(t_ref[-1], abs=1e-10)


def _grazing_scene(ball_robot, delta):
    """No gravity; a joint spring (k = 1) about rest r on the ball started at
    z0 = 2A at rest: z(t) = r + (z0 - r) cos t. With A = 1e-8 and r = A - delta the
    lowest point is -2 delta, reached at t = pi; the gap crosses 0 at
    cos t = -r/(z0 - r) with speed sqrt(z0^2 - 2 z0 r)... = sqrt((z0-r)^2 - r^2)
    ~ sqrt(4 A delta): for delta = 2.5e-13, 1e-10 m/s < grazing_speed = 1e-9.
    The small scale keeps the 5e-13 dip far above the integration error."""
    A = 1e-8
    r = A - delta
    scene = cd.Scene(
        ball_robot, [cd.Contact("ball")], [cd.JointSpring("z", 1.0, 0.0, r)], gravity=[0, 0, 0], q0={"z": 2 * A}
    )
    t_cross = math.acos(-r / (2 * A - r))
    speed = math.sqrt((2 * A - r) ** 2 - r * r)
    return scene, t_cross, speed


def test_grazing_recorded_and_raised(ball_robot):
    scene, t_cross, speed = _grazing_scene(ball_robot, 2.5e-13)
    assert speed < 1e-9
    opts = dict(rtol=1e-12, atol=1e-20, max_step=0.05)
    traj = simulate(scene, 3.3, **opts)
    assert len(traj.events) >= 1
    ev = traj.events[0]
    assert ev.kind == "grazing" and ev.contacts == ("ball",)
    assert ev.t == pytest.approx(t_cross, abs=1e-6)
    assert abs(ev.normal_speeds["ball"]) <= 1e-9
    assert any("grazing" in note for note in traj.notes)
    with pytest.raises(GrazingError, match="grazing"):
        simulate(scene, 3.3, on_grazing="raise", **opts)
    with pytest.raises(cd.InvalidInputError, match="on_grazing"):
        simulate(scene, 3.3, on_grazing="ignore")


def test_grazing_threshold_on_a_slow_drop(ball_robot):
    """A ball dropped from 5e-9 lands at 1e-4 m/s: a touchdown by default, grazing
    when grazing_speed = 1e-3."""
    scene = _ball(ball_robot, 0.0, z0=5e-9)
    assert simulate(scene, 1e-3, **TIGHT).events[0].kind == "touchdown"
    ev = simulate(scene, 1e-3, grazing_speed=1e-3, **TIGHT).events[0]
    assert ev.kind == "grazing"
    assert ev.t == pytest.approx(1e-4, rel=1e-8)
    with pytest.raises(GrazingError):
        simulate(scene, 1e-3, grazing_speed=1e-3, on_grazing="raise", **TIGHT)


def test_start_closed_at_rest(ball_robot):
    """Ball at z = 0 at rest: consistent mode ("ball",) from t0, no events, stays."""
    traj = simulate(_ball(ball_robot, 0.8, z0=0.0), 2.0, **TIGHT)
    assert traj.events == []
    assert traj.modes == [("ball",)]
    assert traj.q[0] == 0.0 and traj.v[0] == 0.0


def test_start_closed_approaching(ball_robot):
    """Ball at z = 0 moving down at 1 with e = 0.5: an impact at t0 first
    (v+ = 0.5, recorded as a bounce at t0), then a flight of 2 * 0.5 / g = 1 s,
    then the next bounce (v- = -0.5, v+ = 0.25, next flight 0.5 s)."""
    scene = _ball(ball_robot, 0.5, z0=0.0)
    traj = simulate(scene, 1.4, v0=[-1.0], **TIGHT, dense=True)
    assert [ev.kind for ev in traj.events] == ["bounce", "bounce"]
    first, second = traj.events
    # v+ = v- + x / m, x = (1 + e) m |v-| from a 1 x 1 solve: a few roundings of O(1)
    # numbers, at most c eps (|v-| + |x|) with c = 4
    assert first.t == 0.0 and first.v_minus[0] == -1.0
    assert first.v_plus[0] == pytest.approx(0.5, abs=4 * np.finfo(float).eps * (1.0 + 1.5))
    q, v = traj.at(0.25)
    assert q[0] == pytest.approx(0.5 * 0.25 - 0.25**2 / 2, abs=1e-12)
    assert v[0] == pytest.approx(0.25, abs=1e-12)
    assert second.t == pytest.approx(1.0, abs=1e-10)
    assert second.v_minus[0] == pytest.approx(-0.5, abs=1e-10)
    assert second.v_plus[0] == pytest.approx(0.25, abs=1e-10)


def test_start_on_both_feet_rigid_trot(rigid_scene):
    """Rigid trot standing on both feet at rest: mode both from t0, stays at rest."""
    traj = simulate(rigid_scene, 1.0, q0=[0.0, 1 / 6, 0.0], **TIGHT)
    assert traj.events == []
    assert set(traj.modes[0]) == {"rear_foot", "front_foot"}
    np.testing.assert_allclose(traj.v, 0.0, atol=1e-12)


def test_no_touchdown_lost_without_grouping():
    """planar_trot_soft at pitch 0 with simultaneous_tol = 0: the two feet's roots
    differ by rounding, so the second foot may not be grouped with the first; it
    is then closed (gap ~1e-16) and approaching at 1 m/s at the first impact and
    must take part in it (docs/design.md §2: all closed contacts take part), not be lost.
    Regression: it used to be skipped forever (no gap peak after the event) and
    the foot fell through the ground (gap -0.5 at t = 1.5)."""
    scene = cd.load_scene("planar_trot_soft")
    traj = simulate(scene, 1.4, simultaneous_tol=0.0, **TIGHT, dense=True)
    assert traj.events[0].t == pytest.approx(1.0, abs=1e-10)
    assert set(traj.events[0].mode_after) == {"rear_foot", "front_foot"}
    for name in ("rear_foot", "front_foot"):
        assert traj.events[0].impulses[name] == pytest.approx(1.0, abs=1e-10)
    qs, _ = traj.sample(np.linspace(0, traj.t, 200))
    assert min(scene.gaps(q).min() for q in qs) >= -1e-12


def test_start_closed_with_tiny_normal_speed(ball_robot):
    """Ball at z = 0 with v = -1e-12 (below grazing_speed = 1e-9): taken as at rest,
    mode ("ball",) from t0, no event. Its residual normal speed may only move it
    by grazing_speed * T before the active-gap projection (project_tol = atol)."""
    traj = simulate(_ball(ball_robot, 0.8, z0=0.0), 5.0, v0=[-1e-12])
    assert traj.events == [] and traj.modes == [("ball",)]
    assert abs(traj.q[0]) <= 1e-9 * 5.0


def _row_speeds(scene, q, v, contacts):
    """|A v| of all rows (normal z, tangents x, y) of the given contacts, from Pinocchio."""
    model = scene.model
    data = model.createData()
    pin.computeJointJacobians(model, data, q)
    out = []
    for name in contacts:
        J = pin.getFrameJacobian(model, data, model.getFrameId(name), pin.LOCAL_WORLD_ALIGNED)[:3]
        out.append(np.abs(J @ v))
    return np.concatenate(out) if out else np.zeros(0)


def test_start_sliding_on_sticking_feet():
    """Rigid trot standing on both feet (sticking) with body x velocity 1: a
    consistent start must stop the tangential velocity of every foot that stays
    active (docs/design.md §2: sticking rows are bilateral while active; at touchdown the
    tangential velocity is stopped plastically). Whatever the impact outcome,
    every active contact must have zero row velocity in every segment."""
    base = cd.load_scene("planar_trot_rigid")
    scene = cd.Scene(
        base.robot,
        [cd.Contact("rear_foot", friction="stick"), cd.Contact("front_foot", friction="stick")],
        gravity=[0, 0, -1],
        q0=[0.0, 1 / 6, 0.0],
        v0=[1.0, 0.0, 0.0],
    )
    traj = simulate(scene, 0.5, **TIGHT, dense=True)
    for seg in traj.segments:
        if not seg.mode or seg.t1 <= seg.t0:
            continue
        for t in np.linspace(seg.t0, seg.t1, 5)[1:-1]:
            q, v = seg.at(t)
            assert np.max(_row_speeds(scene, q, v, seg.mode)) <= 1e-8, (t, seg.mode, v)
