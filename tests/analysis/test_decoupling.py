"""The decoupling checker against verdicts and couplings derived by hand."""

import json

import numpy as np
import pytest

import contactdiff as cd
from contactdiff.analysis.decoupling import COUPLED, DECOUPLED, ORTHOGONAL_ONLY


@pytest.mark.parametrize("name", ["planar_trot_soft", "two_limb"])
def test_decoupled_models_are_decoupled_to_machine_precision(name):
    report = cd.check_decoupling(name, samples=8)
    assert report.verdict == DECOUPLED
    assert report.max_coupling <= 1e-15  # diagonal mass matrix: G is diagonal exactly
    assert all(t.value <= 1e-15 for t in report.terms)
    assert all(p.verdict == DECOUPLED for p in report.pairs)


def test_soft_trot_partition_is_body_plus_one_limb_per_foot():
    report = cd.check_decoupling("planar_trot_soft", samples=0)
    assert report.body == ["body_x", "body_z", "body_pitch"]
    assert sorted(report.limbs["rear_foot"]) == ["rear_foot_x", "rear_foot_z"]
    assert sorted(report.limbs["front_foot"]) == ["front_foot_x", "front_foot_z"]


def test_rigid_trot_coupling_matches_hand_derivation():
    """Rows at pitch 0: d(foot z)/d(x, z, pitch) = (0, 1, x_b), x_b = -/+0.25;
    M^-1 = diag(1/3, 1/3, 24/31), so G_rr = G_ff = 1/3 + 1/16 * 24/31 and
    G_rf = 1/3 - 1/16 * 24/31; the feet touch the ground only at pitch 0."""
    report = cd.check_decoupling("planar_trot_rigid", samples=5)
    diag, off = 1 / 3 + 24 / 31 / 16, 1 / 3 - 24 / 31 / 16
    (pair,) = report.pairs
    assert pair.reference == pytest.approx(off / diag, rel=1e-12)
    assert pair.max == pytest.approx(off / diag, rel=1e-9)
    assert report.verdict == COUPLED and pair.verdict == COUPLED
    assert report.limbs == {"rear_foot": [], "front_foot": []}
    gap_terms = [t for t in report.terms if t.condition == "gap"]
    assert gap_terms and all(not t.ok for t in gap_terms)


def test_single_contact_has_no_verdict():
    """One contact: nothing couples, so there is no verdict (not a vacuous DECOUPLED)."""
    report = cd.check_decoupling("ball", samples=2)
    assert report.pairs == [] and report.verdict is None
    assert report.reason.startswith("fewer than two contacts (1: ball)")
    assert report.to_dict()["verdict"] is None
    assert "nothing to check" in report.format()


def test_coupling_by_springs_between_limbs_breaks_decoupling_but_not_orthogonality():
    """A spring between the two feet of the soft trot keeps M diagonal (orthogonal)
    but makes each limb's effort depend on the other limb."""
    base = cd.load_scene("planar_trot_soft")
    tie = cd.Spring("rear_foot", "front_foot", stiffness=3.0, rest_length=0.5)
    scene = cd.Scene(base.robot, base.contact_specs, base.effort_specs + (tie,), q0=base.q0, v0=base.v0)
    report = cd.check_decoupling(scene, samples=3)
    assert report.max_coupling <= 1e-15
    assert report.verdict == ORTHOGONAL_ONLY
    broken = {t.condition for t in report.failed_terms()}
    assert "limb effort" in broken


def test_body_effort_not_additive_is_detected():
    """f_body = k * z_rear * z_front: its mixed derivative across the limbs is k."""
    base = cd.load_scene("planar_trot_soft")
    robot = base.robot
    iz = robot.model.joints[robot.joint_id("body_z")].idx_v
    ir = robot.model.joints[robot.joint_id("rear_foot_z")].idx_q
    jf = robot.model.joints[robot.joint_id("front_foot_z")].idx_q

    def product(q, v, t):
        tau = np.zeros(robot.nv)
        tau[iz] = 0.5 * q[ir] * q[jf]
        return tau

    scene = cd.Scene(robot, base.contact_specs, base.effort_specs + (cd.UserEffort(product),), q0=base.q0)
    report = cd.check_decoupling(scene, samples=2)
    (term,) = [t for t in report.terms if t.condition == "body effort"]
    assert not term.ok and term.value > 1e-3
    assert report.verdict == ORTHOGONAL_ONLY


@pytest.mark.parametrize("name", cd.QUADRUPEDS)
def test_quadrupeds_are_nearly_but_not_exactly_orthogonal(name):
    report = cd.check_decoupling(name, samples=3)
    assert len(report.pairs) == 6
    assert 1e-9 < report.max_coupling < 0.1  # light legs on passive joints (notes §7)
    assert report.verdict == COUPLED


def test_armature_raises_the_coupling_of_solo12():
    plain = cd.check_decoupling("solo12", samples=3)
    heavy = cd.check_decoupling("solo12", samples=3, armature=0.01)
    assert heavy.max_coupling > 10 * plain.max_coupling
    assert heavy.armature == 0.01


def test_armature_on_a_model_without_motors_is_noted():
    report = cd.check_decoupling("two_limb", samples=1, armature=0.1)
    assert report.verdict == DECOUPLED and report.notes


def test_report_is_json_serialisable():
    d = cd.check_decoupling("planar_trot_rigid", samples=2).to_dict()
    assert json.loads(json.dumps(d))["verdict"] == COUPLED


def test_scene_without_contacts_has_nothing_to_check():
    report = cd.check_decoupling(cd.Scene(cd.load_robot("ball")), samples=1)
    assert report.verdict is None and report.reason == "fewer than two contacts (0)"
