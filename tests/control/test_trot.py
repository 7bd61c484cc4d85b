"""The trot controller and the trot scenes of the real quadrupeds.

Reference values come from the design of the gait (its schedule, the foot paths
written in closed form, the symmetry of the diagonal pairs), from finite
differences on the manifold and from mechanics (impulses never pull: the jump in
momentum ``M (v+ - v-)`` is ``A^T Λ`` with non-negative normal impulses).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from helpers import assert_fd, fd_dq, fd_dv

import contactdiff as cd
from contactdiff.analysis.gait.stances import stance_intervals
from contactdiff.control.legs import PAIR_A, PAIR_B, find_legs
from contactdiff.control.trot_controller import TrotController
from contactdiff.control.trot_scenes import TROT_PARAMETERS, trot_scene
from contactdiff.errors import InvalidInputError, UnknownNameError
from contactdiff.model.kinematics import Kinematics

T_FINAL = 3.0  # s: several strides (7.5 periods of solo12, 6 of anymal)


# -- the controller ------------------------------------------------------------------
@pytest.fixture(scope="module")
def solo():
    return cd.load_robot("solo12")


def test_legs_and_diagonal_pairs_from_the_kinematic_tree():
    """Every quadruped: four legs of three joints covering the actuated joints once,
    front/left read from the foot positions, pairs A = {front-left, hind-right}."""
    for name in cd.QUADRUPEDS:
        robot = cd.load_robot(name)
        legs = find_legs(robot)
        assert [leg.foot for leg in legs] == list(robot.feet)
        assert sorted(j for leg in legs for j in leg.joints) == sorted(robot.actuated)
        assert all(len(leg.joints) == 3 for leg in legs)
        kin = Kinematics(robot.model)
        kin.update(robot.q_ref, np.zeros(robot.nv))
        for leg in legs:
            x, y, _ = kin.position(robot.frame_id(leg.foot))  # base at the origin, unrotated
            assert (x > 0) == leg.front and (y > 0) == leg.left
            assert leg.pair == (PAIR_A if leg.front == leg.left else PAIR_B)
        assert sorted(leg.label for leg in legs if leg.pair == PAIR_A) == ["front-left", "hind-right"]


def test_schedule_alternates_diagonal_pairs(solo):
    ev = TrotController(period=0.4, duty=0.6, lag=0.03).bind(solo)
    pair = [leg.pair for leg in ev.legs]
    front = [leg.front for leg in ev.legs]
    # phase 0 is the middle of pair A's stance: A down, B in the air; half a period later the opposite
    assert [s for s in ev.scheduled_stance(0.0)] == [p == PAIR_A for p in pair]
    assert [s for s in ev.scheduled_stance(0.2)] == [p == PAIR_B for p in pair]
    for k in range(4):
        # closed forms of the schedule (module notes): c = (duty + lag) / 2
        c = 0.5 * (0.6 + 0.03)
        touchdown = (-c + (0.0 if front[k] else 0.03) + (0.0 if pair[k] == PAIR_A else 0.5)) % 1.0
        assert ev.scheduled_touchdown(k) == pytest.approx(touchdown, abs=1e-12)
        assert ev.scheduled_liftoff(k) == pytest.approx((touchdown + 0.6) % 1.0, abs=1e-12)
        assert ev.load(0.0) == pytest.approx(ev.spec.touchdown_load)
        assert ev.load(ev.spec.duty) == pytest.approx(0.0, abs=1e-12)  # the load crosses zero at lift-off
        assert ev.gain(ev.spec.duty) == pytest.approx(ev.spec.release_gain)
    # the clock: phase t / period mod 1
    assert ev.phase(0.5) == pytest.approx(0.25)


def test_feed_forward_carries_the_weight_on_average(solo):
    """Mean over a period of the vertical forces the feed-forward asks of the four feet
    (w s c m g each) is the weight: midpoint rule on a fine grid, independent of the
    trapezoidal integral the controller uses."""
    ev = TrotController().bind(solo)
    weight = pin.computeTotalMass(solo.model) * 9.81
    phis = (np.arange(20000) + 0.5) / 20000
    total = np.mean([sum(ev.load(ev.leg_phase(k, p)) * ev.shares[k] for k in range(4)) for p in phis])
    assert ev.load_scale * total * weight == pytest.approx(weight, rel=1e-4)
    assert np.allclose([ev.shares[k] + ev.shares[j] for k, j in ((0, 3), (1, 2))], 1.0)


def test_reference_realises_the_designed_foot_paths(solo):
    """Forward kinematics of q*(phi) puts each foot at its stance position plus the
    closed-form displacement (step_length 0.06 m, step_height 0.04 m): the spline
    through the inverse kinematics, checked to 20 µm (a cubic spline on 240 nodes)."""
    ev = TrotController(step_length=0.06, step_height=0.04, approach_height=0.01).bind(solo)
    model, data = solo.model, solo.model.createData()
    pin.framesForwardKinematics(model, data, ev.q_stance)
    home = [data.oMf[solo.frame_id(leg.foot)].translation.copy() for leg in ev.legs]
    for phi in np.linspace(0.0, 1.0, 37, endpoint=False) + 0.013:
        q = ev.q_stance.copy()
        q[ev.iq] = ev.reference(phi * ev.spec.period)[0]
        pin.framesForwardKinematics(model, data, q)
        for k, leg in enumerate(ev.legs):
            psi = ev.leg_phase(k, phi)
            dx, dz = (float(x) for x in ev.foot_offset(psi))
            expected = home[k] + [dx, 0.0, dz]
            assert np.allclose(data.oMf[solo.frame_id(leg.foot)].translation, expected, atol=2e-5), (phi, leg.foot)
            if psi < ev.spec.duty:
                assert dz == 0.0
    # the apex of the swing is the step height
    assert float(ev.foot_offset(ev.spec.duty + 0.3 * (1 - ev.spec.duty))[1]) == pytest.approx(0.04)


@pytest.mark.parametrize("t", [0.0, 0.113, 0.1155, 0.25, 0.3163])
def test_controller_derivatives_match_finite_differences(solo, t):
    """dtau/dq and dtau/dv on the manifold, at phases inside and outside the gain fades."""
    robot = solo.copy()
    ctrl = TrotController(kp=12.0, kd=0.3, step_length=0.03).bind(robot)
    rng = np.random.default_rng(1)
    q = robot.integrate(robot.q_ref, 0.2 * rng.standard_normal(robot.nv))
    v = rng.standard_normal(robot.nv)
    kin = Kinematics(robot.model)

    def tau(q_, v_):
        kin.update(q_, v_)
        return ctrl.tau(kin, t)

    kin.update(q, v, derivatives=True)
    dq, dv = ctrl.derivatives(kin, t)
    value = tau(q, v)
    assert_fd("trot controller dtau/dq", dq, fd_dq(lambda x: tau(x, v), robot.model, q), value)
    assert_fd("trot controller dtau/dv", dv, fd_dv(lambda x: tau(q, x), v), value)
    assert np.all(value[:6] == 0.0)  # no effort on the base


# -- scenes and files ------------------------------------------------------------------
def test_toml_scenes_equal_trot_scene():
    for name in ("solo12", "anymal"):
        loaded, built = cd.load_scene(f"{name}_trot"), trot_scene(name)
        assert loaded.contact_specs == built.contact_specs
        assert loaded.effort_specs == built.effort_specs
        assert np.allclose(loaded.q0, built.q0, atol=1e-15) and not loaded.v0.any()
        assert np.allclose(loaded.model.gravity.linear, [0, 0, -9.81])


def test_toml_trot_table_round_trip_and_errors(tmp_path):
    body = (
        'robot = "solo12"\nfloating_base = true\n[[contact]]\nframe = "FL_FOOT"\noffset = 0.0191\n'
        'friction = "stick"\n[initial]\nq = { root_joint = [0, 0, 0.3, 0, 0, 0, 1] }\n'
    )
    path = tmp_path / "s.toml"
    path.write_text(body + "[trot]\nperiod = 0.35\nduty = 0.65\nkp = 12\nkd = 0.25\nstance = { FL_KFE = -1.5 }\n")
    spec = cd.load_scene(path).effort_specs[0]
    assert spec == TrotController(period=0.35, duty=0.65, kp=12, kd=0.25, stance={"FL_KFE": -1.5})
    path.write_text(body + "[trot]\nperiod = 0.4\nspeed = 1.0\n")
    with pytest.raises(UnknownNameError, match="speed.*step_height"):
        cd.load_scene(path)
    path.write_text(body + '[trot]\nkp = "stiff"\n')
    with pytest.raises(InvalidInputError, match="kp must be a number, got 'stiff'"):
        cd.load_scene(path)
    path.write_text(body + "[trot]\nduty = 1.2\n")
    with pytest.raises(InvalidInputError, match="duty must be in"):
        cd.load_scene(path)
    path.write_text(body + "[trot]\nstance = 3\n")
    with pytest.raises(InvalidInputError, match="stance"):
        cd.load_scene(path)


def test_bad_controller_and_scene_inputs(solo):
    for kwargs, message in [
        (dict(period=0.0), "period must be > 0"),
        (dict(kp=-1.0), "kp must be >= 0"),
        (dict(kd=float("nan")), "kd must be finite"),
        (dict(lag=0.7), "lag must be below"),
        (dict(approach_height=0.1), "approach_height"),
        (dict(transfer=0.3), "too long"),
        (dict(release_gain=2.0), "release_gain must be in"),
        (dict(samples=4), "samples"),
        (dict(feedforward="yes"), "feedforward"),
    ]:
        with pytest.raises(InvalidInputError, match=message):
            TrotController(**kwargs)
    with pytest.raises(UnknownNameError, match="quadruped 'spot'.*solo12"):
        trot_scene("spot")
    with pytest.raises(UnknownNameError, match="speed.*period"):
        trot_scene("solo12", speed=1.0)
    with pytest.raises(UnknownNameError, match="joint of robot"):
        trot_scene("solo12", stance={"knee": 1.0})
    with pytest.raises(InvalidInputError, match="four feet"):
        TrotController().bind(cd.load_robot("ball"))
    with pytest.raises(InvalidInputError, match="cannot reach"):
        TrotController(step_height=1.0, approach_height=0.01).bind(solo)


# -- the trot itself -------------------------------------------------------------------
def _trot(name: str):
    scene = trot_scene(name)
    return scene, cd.simulate(scene, T_FINAL, dense=True)


@pytest.fixture(scope="module")
def solo12_trot():
    return _trot("solo12")


@pytest.fixture(scope="module")
def anymal_trot():
    return _trot("anymal")


def check_trot(scene, traj):
    """Strides, alternation of the diagonal pairs, upright body, unit quaternion,
    non-penetration and non-negative impulses of a trot run."""
    ev = next(e for e in scene.efforts if hasattr(e, "scheduled_stance"))
    period, names = ev.spec.period, scene.contact_names
    assert traj.t == pytest.approx(T_FINAL) and traj.termination == "t_final"

    # contact sequence per foot: gait-scale stances (flights below 2 ms closed)
    stances = {leg.foot: stance_intervals(traj, leg.foot) for leg in ev.legs}
    for k, leg in enumerate(ev.legs):
        touchdowns = [a for a, _ in stances[leg.foot] if a > traj.t0]
        # a touchdown per period after the first half period, each within a quarter
        # period of its scheduled phase; the touchdowns of one foot are a period apart
        assert len(touchdowns) >= int(T_FINAL / period) - 1, leg.foot
        lateness = [((ev.phase(t) - ev.scheduled_touchdown(k) + 0.5) % 1.0) - 0.5 for t in touchdowns]
        assert max(abs(x) for x in lateness) < 0.25, (leg.foot, lateness)
        assert np.allclose(np.diff(touchdowns)[1:], period, atol=0.1 * period), leg.foot
        # stance and swing alternate: every lift-off is followed by a swing of at
        # least a quarter of the scheduled swing
        for (_, off), (on, _) in zip(stances[leg.foot], stances[leg.foot][1:]):
            assert on - off > 0.25 * (1 - ev.spec.duty) * period
    # diagonal pairs: the front foot of a pair lifts off first and its hind partner
    # follows within the scheduled lag (+ 2 % of a period); partners land within 0.3
    # period of each other (the body's pitch lets front feet meet the ground early);
    # between two landings of a pair the other pair lands exactly once
    lag = ev.spec.lag * period
    for pair in (PAIR_A, PAIR_B):
        front, hind = (next(leg.foot for leg in ev.legs if leg.pair == pair and leg.front == f) for f in (True, False))
        other = [leg.foot for leg in ev.legs if leg.pair != pair]
        offs = {foot: [b for _, b in stances[foot] if b < traj.t] for foot in (front, hind)}
        for t in offs[front]:
            delay = min((b - t for b in offs[hind] if b >= t), default=np.inf)
            assert delay <= lag + 0.02 * period, (pair, t, delay)
        ons = {foot: [a for a, _ in stances[foot] if a > traj.t0] for foot in (front, hind)}
        for t in (t for t in ons[front] if t < traj.t - 0.3 * period):  # the partner had time to land
            assert min(abs(t - s) for s in ons[hind]) < 0.3 * period, (pair, t)
        for t0, t1 in zip(ons[front], ons[front][1:]):
            for foot in other:
                assert sum(t0 < a < t1 for a, _ in stances[foot]) == 1, (pair, t0, t1, foot)

    # body: upright and at height; quaternion unit to round-off; no penetration
    times = np.linspace(traj.t0, traj.t, 600)
    qs, _ = traj.sample(times)
    height = scene.q0[2]
    assert np.all(qs[:, 2] > 0.9 * height) and np.all(qs[:, 2] < 1.1 * height)
    rpy = np.array([pin.rpy.matrixToRpy(pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix()) for q in qs])
    assert np.abs(rpy[:, :2]).max() < 0.1  # rad
    assert np.abs(np.linalg.norm(qs[:, 3:7], axis=1) - 1.0).max() < 1e-12
    assert np.abs(np.linalg.norm(traj.q[3:7]) - 1.0) < 1e-12
    gaps = np.array([scene.gaps(q) for q in qs])
    # m: no foot sinks. A closed foot is held at the acceleration level and projected back
    # once its drift exceeds project_tol (= atol = 1e-10 m); an open one touches down
    # where its gap crosses zero on the dense output. 1e-9 m leaves 10 x project_tol for
    # the dense output between step ends; a foot let under the ground by the sinking
    # rule's band (10 (atol + rtol |q|_inf), 1e-7 m here) is far outside it
    assert gaps.min() > -1e-9
    # and at every landing, not only at sampled times: the gap just before the impact is
    # the located zero of the guard (Brent to 4 eps max(1, t) in time at a normal speed
    # below 1 m/s: 3e-15 m), above gap_tol = -1e-12 m (the integrator's "closed")
    for e in traj.events:
        if e.impulses:
            q_before, _ = traj.at(e.t, side="left")
            g = scene.gaps(q_before)
            assert min(g[names.index(c)] for c in e.contacts) > -1e-12, (e.t, e.kind, e.contacts)

    # a foot that slips (its release would let it sink) slides until its own lift-off,
    # and a lifted foot does not come straight back (the chatter of a released sticking
    # foot pressed into the ground by the tangential force it carried)
    for foot in names:
        own = [e for e in traj.events if foot in e.contacts]
        for e, after in zip(own, own[1:]):
            if e.kind == "slip":
                assert after.kind == "lift-off", (foot, e.t, after.kind)
            if e.kind == "lift-off":
                assert after.t - e.t > 1e-3, (foot, e.t, after.kind, after.t)

    # impulses: recorded ones never pull, and they explain the jump in momentum
    impacts = [e for e in traj.events if e.impulses]
    assert impacts
    model, data, kin = scene.model, scene.model.createData(), Kinematics(scene.model)
    for e in impacts:
        assert min(e.impulses.values()) >= -1e-12, e.impulses
        closed = [names.index(n) for n in e.impulses]
        kin.update(e.q, e.v_minus)
        rows = [scene.contacts[i].rows(kin) for i in closed]
        A = np.vstack(rows)
        jump = pin.crba(model, data, e.q) @ (e.v_plus - e.v_minus)  # = A^T Λ (N s)
        lam, *_ = np.linalg.lstsq(A.T, jump, rcond=None)
        assert np.allclose(A.T @ lam, jump, atol=1e-9 * max(1.0, np.abs(jump).max()))
        normal = lam[np.cumsum([0] + [r.shape[0] for r in rows[:-1]])]
        # tolerance: round-off, plus the largest impulse that keeping a contact whose
        # post-impact separation is below zeno_speed (1e-6 m/s) closed can take
        tol = 1e-8 * np.abs(lam).max() + pin.computeTotalMass(model) * 1e-6
        assert normal.min() >= -tol, (e.t, normal)


def test_solo12_trots(solo12_trot):
    check_trot(*solo12_trot)


def test_anymal_trots(anymal_trot):
    check_trot(*anymal_trot)


def test_gait_figure_says_what_its_ticks_mean(solo12_trot):
    """The timeline's red and green ticks (touchdowns, lift-offs) have a legend."""
    pytest.importorskip("matplotlib")
    from contactdiff.plotting import gait_figure

    scene, traj = solo12_trot
    fig = gait_figure(traj, scene, n_samples=50)
    timeline = fig.axes[0]
    assert [t.get_text() for t in timeline.get_legend().get_texts()] == ["touchdown", "lift-off"]
    assert all(ax.get_ylabel() for ax in fig.axes[1:])


def test_trot_cli_plot_and_json(tmp_path, capsys):
    import json

    from contactdiff.cli import main

    pytest.importorskip("matplotlib")
    png = tmp_path / "trot.png"
    assert main(["simulate", "solo12_trot", "--t-final", "0.5", "--plot", str(png), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert png.stat().st_size > 10_000
    assert out["events"] and all({"t", "kind", "contacts", "impulses", "mode_after"} <= set(e) for e in out["events"])
    assert out["stats"]["events"] == len(out["events"])


@pytest.mark.slow
@pytest.mark.quadrupeds
@pytest.mark.parametrize("name", [n for n in cd.QUADRUPEDS if n not in ("solo12", "anymal")])
def test_other_quadrupeds_trot(name):
    assert name in TROT_PARAMETERS
    check_trot(*_trot(name))


def test_reference_by_hand_is_the_cubic_spline(solo):
    """The controller evaluates its periodic cubic spline by hand (Horner on the
    pieces); SciPy's own evaluation of the same spline and of its derivative is the
    reference, to round-off of joint angles of order 1 rad (1e-13)."""
    ev = TrotController().bind(solo)
    derivative = ev._spline.derivative()
    for t in np.linspace(-0.3, 1.7, 4001):  # s: several periods, knots included
        q_ref, v_ref = ev.reference(t)
        phi = ev.phase(t)
        np.testing.assert_allclose(q_ref, ev._spline(phi), rtol=0, atol=1e-13)
        np.testing.assert_allclose(v_ref, derivative(phi) / ev.spec.period, rtol=0, atol=1e-12)


@pytest.mark.parametrize("options", [{}, dict(feedforward=False, release_gain=0.3, kp=3.0, kd=0.05)])
def test_torque_table_is_the_formulas(solo, options):
    """`tau` reads the schedule from a table of polynomial pieces; `tau_by_formula`
    evaluates the reference spline, the gain scale and the feed-forward themselves.
    They are the same polynomial on each piece, so they agree to the rounding of the
    table: 9 Chebyshev samples mapped to monomials by the inverse Vandermonde matrix,
    an error of at most (its condition number) x (9 terms) x eps x (size of the
    terms), at random times (several periods) and random states."""
    ev = TrotController(**options).bind(solo)
    kin = Kinematics(solo.model)
    n = ev._DEGREE + 1
    condition = ev._schedule.condition
    rng = np.random.default_rng(7)
    for t in rng.uniform(-0.5, 1.5, 300):
        q = solo.integrate(solo.q_ref, rng.normal(0.0, 0.3, solo.nv))
        v = rng.normal(0.0, 2.0, solo.nv)
        kin.update(q, v)
        terms = ev._schedule_terms_at_phases(np.array([ev.phase(t)]))[0]
        size = np.max(np.abs(terms)) * (1.0 + np.max(np.abs(q)) + np.max(np.abs(v)))
        bound = condition * n * np.finfo(float).eps * size
        np.testing.assert_allclose(ev.tau(kin, t), ev.tau_by_formula(kin, t), rtol=0, atol=bound)
        dq, dv = ev.derivatives(kin, t)
        np.testing.assert_allclose(np.diag(dq)[ev.iv], -ev.spec.kp * ev.gains(t), rtol=0, atol=bound)
        np.testing.assert_allclose(np.diag(dv)[ev.iv], -ev.spec.kd * ev.gains(t), rtol=0, atol=bound)
