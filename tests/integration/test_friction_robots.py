"""Coulomb friction on a robot: the solo12 trot with μ = 0.8 on every foot.

From a four-foot stance at t = 0.09 s (all feet sticking) to 0.13 s the trot has
a stick → slip event on the cone and a lift-off while slipping, for a front and a
hind foot: 3-D slips of an articulated robot, the force direction of a slip
following its velocity. The flow Jacobian through them is checked against central
differences of the simulator along velocity directions that keep the stance
consistent (in the null space of the feet's rows, so the perturbed starts need
no projection), on the manifold of the base's SE(3) (`pinocchio.difference`).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from scipy.linalg import null_space

import contactdiff as cd
from contactdiff.dynamics.mode import ModeDynamics
from contactdiff.errors import InvalidInputError, UnknownNameError

T0, T1 = 0.09, 0.13  # s
TOL = dict(rtol=1e-11, atol=1e-12)
# Central differences with ε = 2e-3 (m/s, rad/s). Measured over ε in [1e-5, 1e-2] on this
# window (3 random directions each): the perturbed runs' noise is about 5e-10 |J δ| / ε
# (2.5e-7 here), the truncation grows as ε² (1.5e-6-3e-6 at ε = 1e-2, so about 1e-7 here),
# and a floor of 2e-7-7e-7 stays flat between ε = 1e-3 and 3e-3: a disagreement of the
# Jacobian itself at that level, whose source is not pinned down (it does not shrink with
# zeno_speed 1e-7 instead of 1e-6: 1.4e-7-3.2e-6). 2e-6 relative to |J δ| covers the three
# with margin; a missing or wrong saltation term is O(1) and cannot pass.
EPS, FD_RTOL = 2e-3, 2e-6


@pytest.fixture(scope="module")
def stance():
    scene = cd.load_scene("solo12_trot").with_friction(0.8)
    start = cd.simulate(scene, T0, **TOL)
    assert start.segments[-1].mode == ("FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT")
    assert start.segments[-1].sliding == ()
    traj = cd.simulate(scene, T1, start.q, start.v, t0=T0, jacobian=True, **TOL)
    return scene, start.q, start.v, traj


def test_slip_events_of_the_window(stance):
    _, _, _, traj = stance
    assert [(e.kind, e.contacts) for e in traj.events] == [
        ("slip", ("FL_FOOT",)),
        ("lift-off", ("FL_FOOT",)),
        ("slip", ("HR_FOOT",)),
        ("lift-off", ("HR_FOOT",)),
    ]
    assert all(not e.nonsmooth for e in traj.events)  # transversal crossings: differentiable
    assert [e.sliding for e in traj.events] == [("FL_FOOT",), (), ("HR_FOOT",), ()]


def test_flow_jacobian_through_3d_slips_matches_finite_differences(stance):
    scene, q0, v0, traj = stance
    model = scene.robot.model
    kin = scene.kinematics
    kin.update(q0, v0)
    rows = np.vstack([c.rows(kin) for c in scene.contacts])
    assert np.abs(rows @ v0).max() < 1e-12  # m/s: the stance holds
    directions = null_space(rows)
    rng = np.random.default_rng(7)
    nv = model.nv
    for _ in range(3):
        d = directions @ rng.standard_normal(directions.shape[1])
        d /= np.linalg.norm(d)
        plus = cd.simulate(scene, T1, q0, v0 + EPS * d, t0=T0, **TOL)
        minus = cd.simulate(scene, T1, q0, v0 - EPS * d, t0=T0, **TOL)
        for run in (plus, minus):  # the same events, or the difference is not a derivative
            assert [(e.kind, e.contacts) for e in run.events] == [(e.kind, e.contacts) for e in traj.events]
        fd = np.r_[pin.difference(model, minus.q, plus.q), plus.v - minus.v] / (2 * EPS)
        analytic = traj.jacobian[:, nv:] @ d
        assert np.abs(fd - analytic).max() <= FD_RTOL * np.abs(analytic).max()


def test_with_friction_replaces_the_contacts_friction_and_checks_the_value():
    scene = cd.load_scene("solo12_trot")
    assert [c.spec.mu for c in scene.with_friction(0.5).contacts] == [0.5] * 4
    assert all(c.spec.friction == "none" for c in scene.with_friction(0.0).contacts)
    assert [c.spec.friction for c in scene.contacts] == ["stick"] * 4  # the original is unchanged
    with pytest.raises(InvalidInputError, match="-1"):
        scene.with_friction(-1.0)
    # named contacts only: the others keep theirs
    names = scene.contact_names
    some = scene.with_friction(0.5, contacts=names[:2])
    assert [c.spec.friction for c in some.contacts] == [0.5, 0.5, "stick", "stick"]
    with pytest.raises(UnknownNameError, match=names[0]):
        scene.with_friction(0.5, contacts=["no_such_foot"])


def test_anymal_slip_onset_passes_trial_stages_outside_the_slip_domain():
    """The ANYmal trot with μ = 0.8: at the right hind foot's slip onset (t ≈ 0.157 s) the slip
    direction starts from the sticking force's and turns fast while the slip is slow, and a
    trial stage of a too-long step turns it where A_n M^-1 (A_n - μ s^T A_T)^T < 0, outside the
    slip mode's domain (Painlevé). Such a step is only rejected: the run goes on, and the
    accepted slip keeps a pushing normal force along the whole segment (each sample solved again
    in its mode, which would raise `PainleveError` outside the domain)."""
    scene = cd.load_scene("anymal_trot").with_friction(0.8)
    traj = cd.simulate(scene, 0.2, dense=True)
    onset = [e for e in traj.events if e.kind == "slip" and e.contacts == ("RH_FOOT",)]
    assert onset and onset[0].t == pytest.approx(0.1572, abs=1e-3)  # s
    dyn = ModeDynamics(scene)
    segment = next(s for s in traj.segments if s.t0 == onset[0].t)
    assert "RH_FOOT" in segment.sliding
    mode = tuple(
        sorted(
            dyn.sliding_key(i) if scene.contact_names[i] in segment.sliding else i
            for i in (scene.contact_names.index(n) for n in segment.mode)
        )
    )
    rh = mode.index(dyn.sliding_key(scene.contact_names.index("RH_FOOT")))
    for t in np.linspace(segment.t0, segment.t1, 7)[1:-1]:  # inside: the segment ends in a lift-off, λ_N = 0
        q, v = segment.at(t)
        dyn.slip_reference[scene.contact_names.index("RH_FOOT")] = None
        assert dyn.solve(q, v, t, mode).row_forces()[rh][0] > 0.0  # N: pushing
