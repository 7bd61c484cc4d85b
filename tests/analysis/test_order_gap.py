"""The order gap of a simultaneous touchdown, the checker at given states, and the
diagonal touchdown of a quadruped.

Reference values:

* planar_trot_soft and two_limb (decoupled): the touchdown state after the free
  fall from the scenes' initial states is every height lowered by 1/2 and every
  vertical velocity -1 (g = 1, t = 1, springs at rest so the fall is rigid). The
  theorem says both orders give the same outcome and saltation matrix: zero to
  round-off (tolerance 1e-13 relative: a few dozen flops of O(1) numbers).
* planar_trot_rigid: the two-impact limits derived by hand below (mass 3, pitch
  inertia 31/24, feet at body (∓1/4, -1/6), plastic, frictionless).
* a quadruped's diagonal touchdown with sticking plastic feet: when both feet
  stay closed, each impact is the M-orthogonal projection of the velocity onto
  the null space of the closed rows, and projections onto nested subspaces
  compose to the innermost one, so both orders give that projection (computed
  here with numpy from the rows and M).
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
from helpers import assert_fd, load_script

import contactdiff as cd
from contactdiff.analysis.order_gap import GAP_TOL, diagonal_pairs, diagonal_touchdown, order_gap
from contactdiff.errors import InvalidInputError, UnknownNameError

TIGHT = dict(rtol=1e-12, atol=1e-14)


def planar_touchdown(name):
    """State of a paper model at its t = 1 touchdown (every *_z coordinate 1/2 lower, falling at 1)."""
    scene = cd.load_scene(name)
    q, v = scene.q0.copy(), np.zeros(scene.nv)
    for k, label in enumerate(scene.robot.tangent_names()):
        if label.endswith("_z"):
            q[k] -= 0.5
            v[k] = -1.0
    return scene, q, v


@pytest.mark.parametrize("name", ["planar_trot_soft", "two_limb"])
def test_decoupled_models_have_no_order_gap(name):
    scene, q, v = planar_touchdown(name)
    np.testing.assert_allclose(scene.gaps(q), 0.0, atol=1e-15)
    gap = order_gap(scene, q, v, scene.contact_names)
    assert gap.outcome <= 1e-13 and gap.outcome_vs_simultaneous <= 1e-13
    assert gap.saltation <= 1e-13 and gap.saltation_spread <= 1e-13
    assert gap.differentiable()
    # physically: each foot stops (plastic) and nothing else changes (diagonal M, own-limb gaps)
    for v_after in gap.v_after.values():
        for name_ in scene.contact_names:
            c = scene.contacts[scene.contact_index(name_)]
            scene.kinematics.update(q, v_after)
            assert abs(c.rows(scene.kinematics)[0] @ v_after) <= 1e-15


# -- the rigid trot: the hand-derived two-impact limits --------------------------------
# Coordinates (x, z, pitch), M = diag(3, 3, 31/24); at pitch 0 the gap rows are
# rear (0, 1, -1/4), front (0, 1, 1/4) (pitch turns about (0, -1, 0)); v- = (0, -1, 0).
# Rear first: a M^-1 a^T = 1/3 + (1/16)(24/31) = 71/186, impulse 186/71,
#   v1 = (0, -1 + 62/71, -(24/31)(1/4)(186/71)) = (0, -9/71, -36/71);
#   the front then approaches at -9/71 - 9/71 = -18/71. Both closed: both impulses
#   active would need rear = -159/142 < 0, so only the front acts: impulse
#   (18/71)(186/71) = 3348/5041, v2 = (0, 477/5041, -1908/5041), the rear
#   separating at 954/5041 (so it leaves the mode).
# Front first: the mirror image, pitch rate +1908/5041.
# Simultaneous: two independent rows span (z, pitch): v = 0 (impulses 3/2 each).
V_REAR_FIRST = np.array([0.0, 477 / 5041, -1908 / 5041])
V_FRONT_FIRST = np.array([0.0, 477 / 5041, 1908 / 5041])


@pytest.fixture(scope="module")
def rigid_gap():
    scene, q, v = planar_touchdown("planar_trot_rigid")
    return scene, q, v, order_gap(scene, q, v, ("rear_foot", "front_foot"), t=1.0, horizon=0.2, simulate_options=TIGHT)


def test_rigid_trot_outcomes_are_the_hand_limits(rigid_gap):
    scene, q, v, gap = rigid_gap
    np.testing.assert_allclose(q, [0.0, 1 / 6, 0.0], atol=1e-15)
    np.testing.assert_allclose(gap.v_after[("rear_foot", "front_foot")], V_REAR_FIRST, atol=1e-14)
    np.testing.assert_allclose(gap.v_after[("front_foot", "rear_foot")], V_FRONT_FIRST, atol=1e-14)
    np.testing.assert_allclose(gap.v_simultaneous, 0.0, atol=1e-14)
    assert gap.mode_after[("rear_foot", "front_foot")] == ("front_foot",)
    assert gap.mode_after[("front_foot", "rear_foot")] == ("rear_foot",)
    # relative gap: |Δv|_M / |v_sim - v-|_M = 2 (1908/5041) sqrt(31/24) / sqrt(3)
    assert gap.outcome == pytest.approx(2 * 1908 / 5041 * math.sqrt(31 / 24) / math.sqrt(3), rel=1e-13)
    assert gap.outcome_abs == pytest.approx(2 * 1908 / 5041 * math.sqrt(31 / 24), rel=1e-13)
    assert gap.outcome_max == pytest.approx(2 * 1908 / 5041, rel=1e-13)
    # each one-sided outcome against the simultaneous one (rest): |v2|_M / sqrt(3)
    ke = math.sqrt(3 * (477 / 5041) ** 2 + 31 / 24 * (1908 / 5041) ** 2)
    assert gap.outcome_vs_simultaneous == pytest.approx(ke / math.sqrt(3), rel=1e-13)
    # the saltation matrices of the two orders differ at O(1): not differentiable there
    assert gap.saltation > 0.1 and gap.saltation_spread >= gap.saltation
    assert not gap.differentiable()


def test_rigid_trot_outcome_later_matches_near_simultaneous_runs(rigid_gap):
    """Carried 0.2 s forward, each one-sided outcome is the limit of runs from pitch
    ±θ0 (the lower foot lands first): distance O(θ0) (see test_integrator), so
    θ0 = 1e-7 with tolerance 1e-6; and the pitch rate is about ∓0.28 rad/s."""
    scene, _, _, gap = rigid_gap
    for theta0, order in ((1e-7, ("rear_foot", "front_foot")), (-1e-7, ("front_foot", "rear_foot"))):
        zc = 0.5 + 0.25 * abs(math.sin(theta0)) + math.cos(theta0) / 6
        traj = cd.simulate(scene, 1.2, q0=[0.0, zc, theta0], **TIGHT)
        np.testing.assert_allclose(gap.v_later[order], traj.v, atol=1e-6)
        np.testing.assert_allclose(gap.q_later[order], traj.q, atol=1e-6)
        assert 0.25 < -math.copysign(1, theta0) * gap.v_later[order][2] < 0.3
    np.testing.assert_allclose(gap.v_later["simultaneous"], 0.0, atol=1e-12)
    assert gap.later > 0.3


def test_order_gap_to_dict_is_json_ready(rigid_gap):
    import json

    d = json.loads(json.dumps(rigid_gap[3].to_dict(matrices=True)))
    assert d["contacts"] == ["rear_foot", "front_foot"]
    assert set(d["v_after"]) == {"rear_foot->front_foot", "front_foot->rear_foot"}
    assert len(d["saltation_paper"]) == 6


def test_order_gap_later_derivative_against_finite_differences():
    """``Φ Ξ_order`` (the one-sided derivative of x(t + T) with respect to x(t-))
    composed with the free-fall flow Jacobian before the touchdown is d x(1.1) / d x0;
    checked column by column against central differences of whole simulations from
    perturbed initial states of the soft trot (decoupled: the map is C¹ although
    perturbed feet land at different times).

    FD error. A central difference of step ε of runs with errors δ+ and δ- has error
    ε² |f'''| / 6 + |δ+ - δ-| / (2 ε). With adaptive steps δ+ - δ- is not smooth in
    the perturbation: a step accepted in one run and rejected in the other changes
    that run's error by up to a step's local error, 5e-11 m/s here at rtol 1e-12
    (body_x + ε and - ε, mirror images of each other whose exact outcomes agree, took
    10 and 11 steps), which at ε = 1e-5 is 1.1e-6 of the Jacobian's scale and hinges
    on the last bits of the step-size control. So the perturbed runs use a step
    sequence that does not switch: DOP853 with every step at max_step = 0.02 s, below
    the 0.028 s its error control takes in stance at this tolerance, so each step's
    error norm is about (0.02 / 0.028)^8 = 0.07 of the limit and no step is rejected
    (asserted). The computed map x0 -> x(1.1) is then smooth in x0 (the grid moves
    with the event times), and the FD error is truncation, ε² |f'''| / 6 (1e-9
    relative here: 1e-7 at ε = 1e-4, falling as ε² when the step shrinks), plus
    round-off, N u |x| / ε (N ~ 60 steps: 1e-9), plus the gap between that map's
    derivative and the flow Jacobian of the adaptive run, a global error of order
    N rtol = 1e-10: far below tests/helpers.py's RTOL = 1e-6, at which a wrong term of
    a saltation matrix or a flow Jacobian would show."""
    scene = cd.load_scene("planar_trot_soft")
    _, q1, v1 = planar_touchdown("planar_trot_soft")
    gap = order_gap(scene, q1, v1, (0, 1), t=1.0, horizon=0.1, jacobian=True, simulate_options=TIGHT)
    assert gap.later_saltation <= 1e-12
    P = next(iter(gap.jacobian_later.values()))
    # free fall, no event before t = 1: Φ(1 - 1e-10) differs from Φ(1) by ~1e-10
    before = cd.simulate(scene, 1.0 - 1e-10, jacobian=True, **TIGHT).jacobian
    nv, eps = scene.nv, 1e-5
    robot = scene.robot

    def final(dx):
        traj = cd.simulate(
            scene,
            1.1,
            q0=robot.integrate(scene.q0, dx[:nv]),
            v0=scene.v0 + dx[nv:],
            method="DOP853",
            max_step=0.02,
            **TIGHT,
        )
        assert traj.stats.rejected_steps == 0  # the step sequence does not switch
        return traj.q, traj.v

    columns = []
    for k in range(2 * nv):
        e = np.zeros(2 * nv)
        e[k] = eps
        (qp, vp), (qm, vm) = final(e), final(-e)
        columns.append(np.concatenate([robot.difference(qm, qp), vp - vm]) / (2 * eps))
    assert_fd("order gap: Φ Ξ after touchdown", P @ before, np.array(columns).T)


def test_quadruped_diagonal_touchdown_outcome_is_the_nested_projection():
    scene = cd.Scene.from_robot(cd.load_robot("solo12")).with_armature(0.01)
    q, v, pair = diagonal_touchdown(scene)
    gap = order_gap(scene, q, v, pair)
    kin = scene.kinematics
    kin.update(q, v)
    A = np.vstack([scene.contacts[k].rows(kin) for k in pair])
    M = pin.crba(scene.model, scene.model.createData(), q)
    Minv_AT = np.linalg.solve(M, A.T)
    projected = v - Minv_AT @ np.linalg.solve(A @ Minv_AT, A @ v)
    for order, v_after in gap.v_after.items():
        assert gap.mode_after[order] == tuple(sorted(gap.contacts, key=scene.contact_names.index))
        np.testing.assert_allclose(v_after, projected, atol=1e-12 * np.abs(v).max())
        assert v_after @ M @ v_after <= v @ M @ v  # plastic impacts never add energy
    assert gap.outcome <= 1e-12
    # ... yet the two saltation matrices differ: the robot is not decoupled
    assert gap.saltation > 1e-3


def test_diagonal_touchdown_state():
    """Landing pair closed and moving straight down at down_speed, the other pair
    `lift` above the ground, the base moving (forward, 0, -down) in the world."""
    for name, expected in (("solo12", ("FL_FOOT", "HR_FOOT")), ("anymal", ("LF_FOOT", "RH_FOOT"))):
        scene = cd.Scene.from_robot(cd.load_robot(name))
        (fl, hr), (fr, hl) = diagonal_pairs(scene)
        assert (scene.contact_names[fl], scene.contact_names[hr]) == expected
        q, v, pair = diagonal_touchdown(scene, down_speed=0.3, forward_speed=0.5, lift=0.04)
        assert pair == (fl, hr)
        gaps = scene.gaps(q)
        assert abs(gaps[fl]) <= 1e-15 and abs(gaps[hr]) <= 1e-15
        assert gaps[fr] == pytest.approx(0.04, abs=1e-12) and gaps[hl] == pytest.approx(0.04, abs=1e-12)
        kin = scene.kinematics
        kin.update(q, v)
        for k in pair:
            np.testing.assert_allclose(kin.jacobian(scene.contacts[k].fid) @ v, [0, 0, -0.3], atol=1e-12)
        R = pin.Quaternion(q[3:7]).normalized().matrix()
        np.testing.assert_allclose(R @ v[:3], [0.5, 0.0, -0.3], atol=1e-15)


# -- the checker at given states -------------------------------------------------------
def test_check_decoupling_at_given_states():
    """Rigid trot at pitch 0: rows (1, ∓1/4) in (z, pitch) with M = diag(3, 31/24) give
    G = [[1/3 + 3/62, 1/3 - 3/62], ...]: coupling (1/3 - 3/62)/(1/3 + 3/62)."""
    scene, q, v = planar_touchdown("planar_trot_rigid")
    report = cd.check_decoupling(scene, states=[(q, v)])
    assert report.pairs[0].samples == 1 and report.samples == 0
    assert report.pairs[0].max == pytest.approx((1 / 3 - 3 / 62) / (1 / 3 + 3 / 62), rel=1e-13)
    assert report.verdict == "coupled" and any("given state" in n for n in report.notes)
    soft, qs, vs = planar_touchdown("planar_trot_soft")
    report = cd.check_decoupling(soft, states=[(qs, vs), (soft.q0, soft.v0)])
    assert report.verdict == "decoupled" and report.pairs[0].samples == 2
    assert all(t.value == 0 for t in report.terms)


def test_check_decoupling_at_states_agrees_with_sampled_reference():
    """At the scene's own (already closed) pose, the given-state coupling is the
    sampled report's reference value (projection leaves a closed pose unchanged)."""
    scene, q, v = planar_touchdown("planar_trot_rigid")
    scene = scene.with_state(q)
    sampled = cd.check_decoupling(scene, samples=0)
    given = cd.check_decoupling(scene, states=[(q, v)])
    assert given.pairs[0].max == pytest.approx(sampled.pairs[0].reference, rel=1e-12)


def test_check_decoupling_takes_each_state_time():
    """A clock-driven cross-limb effort ``tau_rear_z = K t q_front_z`` couples the
    limbs of the soft trot only at t != 0: the limb term is ``K t`` over the effort
    Jacobian's largest entry (set by the foot springs, larger than ``K t`` here), so
    it is 0 at t = 0 and doubles from t = 1 s to t = 2 s (up to the 1e-10 error of
    the effort's FD Jacobian); states given as pairs are at t = 0."""
    base = cd.load_scene("planar_trot_soft")
    names = [base.model.names[j] for j in range(1, base.model.njoints)]
    front_z, rear_z = names.index("front_foot_z"), names.index("rear_foot_z")
    gain = 7.0  # N/(m s)

    def cross(q, v, t):
        tau = np.zeros(base.nv)
        tau[rear_z] = gain * t * q[front_z]
        return tau

    scene = cd.Scene(
        base.robot,
        base.contact_specs,
        base.effort_specs + (cd.UserEffort(cross, name="cross"),),
        q0=base.q0,
        v0=base.v0,
    )
    q, v = base.q0, base.v0

    def rear_term(*state):
        report = cd.check_decoupling(scene, states=[state])
        return report, next(t.value for t in report.terms if t.where == "limb rear_foot depends on other limbs")

    (pair, zero_pair), (at_zero, zero) = rear_term(q, v), rear_term(q, v, 0.0)
    (_, one), (at_two, two) = rear_term(q, v, 1.0), rear_term(q, v, 2.0)
    assert zero == zero_pair == 0.0 and pair.verdict == at_zero.verdict == "decoupled"
    assert one > 1e-3 and two == pytest.approx(2 * one, rel=1e-8)
    assert at_two.verdict == "orthogonal only"


@pytest.mark.parametrize(
    "states, match",
    [
        ([], "at least one"),
        ([(np.zeros(3), np.zeros(3), np.nan)], "non-finite"),
        ([(np.zeros(3),)], "pairs or"),
        ([(np.zeros(2), np.zeros(3))], "shape"),
        ([(np.array([0.0, np.nan, 0.0]), np.zeros(3))], "non-finite"),
        (5, "pairs"),
    ],
)
def test_check_decoupling_rejects_bad_states(states, match):
    scene = cd.load_scene("planar_trot_rigid")
    with pytest.raises(InvalidInputError, match=match):
        cd.check_decoupling(scene, states=states)


# -- bad input ---------------------------------------------------------------------------
def test_order_gap_rejects_bad_input():
    scene, q, v = planar_touchdown("planar_trot_rigid")
    with pytest.raises(InvalidInputError, match="not closed"):
        order_gap(scene, q + np.array([0, 1e-3, 0]), v)
    with pytest.raises(InvalidInputError, match="does not approach"):
        order_gap(scene, q, -v)
    with pytest.raises(InvalidInputError, match="must differ"):
        order_gap(scene, q, v, ("rear_foot", 0))
    with pytest.raises(UnknownNameError, match="front_foot"):
        order_gap(scene, q, v, ("rear_foot", "nose"))
    with pytest.raises(InvalidInputError, match="out of range"):
        order_gap(scene, q, v, (0, 5))
    with pytest.raises(InvalidInputError, match="two contacts"):
        order_gap(scene, q, v, (0,))
    with pytest.raises(InvalidInputError, match="shape"):
        order_gap(scene, q[:2], v)
    with pytest.raises(InvalidInputError, match="finite"):
        order_gap(scene, q, v * np.nan)
    with pytest.raises(InvalidInputError, match="horizon"):
        order_gap(scene, q, v, horizon=0.0)
    with pytest.raises(InvalidInputError, match="already be active"):
        order_gap(scene, q, v, (0, 1), mode=(0,))
    with pytest.raises(InvalidInputError, match="jacobian=True"):
        order_gap(scene, q, v).later_saltation_on([0])
    assert GAP_TOL < 1e-3


# -- the table script over the six quadrupeds --------------------------------------------
@pytest.mark.slow
@pytest.mark.quadrupeds
def test_quadruped_decoupling_table_script():
    """The README table's script, with its standing-pose source: on every robot and
    armature the sticking diagonal touchdown keeps both feet closed, so the outcome
    gap is zero to round-off (the nested-projection argument above) while the
    saltation matrices differ; couplings
    are in [0, 1]; on solo12 with compliant feet the pair coupling falls with the
    foot mass at every stiffness and does not depend on the stiffness (the spring
    is at rest at touchdown: only M and the contact rows enter the coupling)."""
    script = load_script("quadruped_decoupling_table")
    rows = script.robot_table(cd.QUADRUPEDS, "standing")
    assert {r["robot"] for r in rows} == set(cd.QUADRUPEDS)
    for r in rows:
        assert 0 <= r["pair_coupling"] <= r["max_coupling"] <= 1
        assert r["outcome_gap"] <= 1e-12, r
        assert r["saltation_gap"] > 0 and r["gap_term"] == pytest.approx(1.0)
    trend = script.trend_table()
    for friction in ("stick", "none"):
        for k in script.TREND_STIFFNESSES:
            couplings = [
                next(
                    r["pair_coupling"]
                    for r in trend
                    if r["friction"] == friction and r["foot_mass"] == m and r["stiffness"] == k
                )
                for m in script.TREND_FOOT_MASSES
            ]
            assert all(a > b for a, b in zip(couplings, couplings[1:]))
        by_mass = {}
        for r in trend:
            if r["friction"] == friction and r["foot_mass"] is not None:
                by_mass.setdefault(r["foot_mass"], set()).add(round(r["pair_coupling"], 15))
        assert all(len(values) == 1 for values in by_mass.values())
