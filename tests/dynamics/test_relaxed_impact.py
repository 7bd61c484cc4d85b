"""The impact reset's Jacobian where a sticking contact is in the relaxed
(tangential-only) state of the infinite-friction impact law.

Stopping such a contact's slip would need a pulling normal impulse, and a
plastic release lets it sink: the impact stops its slip with a tangential
impulse alone (normal impulse 0, normal speed after >= 0). Its tangential rows
carry impulse, so they belong to the differentiated impact equations; the
reference is central FD of ``v+(q, v-)`` on the manifold (tests/helpers.py),
with the states of every contact checked unchanged at each perturbed point
(the reset is smooth only there).
"""

from __future__ import annotations

import numpy as np
import pytest
from helpers import assert_fd, fd_dq, fd_dv
from test_slip import LEG_URDF

import contactdiff as cd
from contactdiff.control.trot_scenes import trot_scene
from contactdiff.dynamics.impacts import resolve_impact
from contactdiff.dynamics.mode import ModeDynamics
from contactdiff.integration.sensitivity import impact_reset_jacobian

TRIES = 400  # random pre-impact velocities searched for a relaxed case


def _first_relaxed(dyn, q_of, v_scale, keys, want_active, seed=0):
    """First seeded random (q, v-) whose impact of ``keys`` has a tangential-only
    contact (and an active one too if ``want_active``)."""
    rng = np.random.default_rng(seed)
    for _ in range(TRIES):
        q, v = q_of(rng), v_scale * rng.standard_normal(dyn.model.nv)
        impact = resolve_impact(dyn, q, v, keys)
        if impact.tangential_only and (impact.active or not want_active):
            return q, v, impact
    pytest.fail(f"no relaxed impact in {TRIES} random states")


def _check_reset_jacobian(dyn, q, v, keys, impact):
    nv = dyn.model.nv
    states = (impact.active, impact.tangential_only)

    def v_plus(qq, vv):
        other = resolve_impact(dyn, qq, vv, keys)
        assert (other.active, other.tangential_only) == states  # same smooth branch
        return other.v_plus

    DR = impact_reset_jacobian(dyn, q, v, impact)
    assert_fd("relaxed impact dv+/dq", DR[nv:, :nv], fd_dq(lambda qq: v_plus(qq, v), dyn.model, q), impact.v_plus)
    assert_fd("relaxed impact dv+/dv-", DR[nv:, nv:], fd_dv(lambda vv: v_plus(q, vv), v), impact.v_plus)
    np.testing.assert_array_equal(DR[:nv], np.eye(2 * nv)[:nv])  # q is not reset


def _check_relaxed_law(dyn, q, v, keys, impact):
    """Tangential-only contacts: zero normal impulse, slip stopped, not sinking."""
    dyn.kin.update(q, v)
    offsets = np.cumsum([0] + [dyn.contact(k).n_rows for k in keys])
    for k in impact.tangential_only:
        A = dyn.contact(keys[k]).rows(dyn.kin)
        assert impact.row_impulses[offsets[k]] == 0.0
        assert np.abs(impact.row_impulses[offsets[k] + 1 : offsets[k + 1]]).max() > 1e-3  # N s: carries impulse
        np.testing.assert_allclose(A[1:] @ impact.v_plus, 0.0, atol=1e-12)
        assert A[0] @ impact.v_plus >= -1e-12


def test_relaxed_single_contact_planar_leg(tmp_path):
    path = tmp_path / "leg.urdf"
    path.write_text(LEG_URDF)
    robot = cd.load_robot(path)
    scene = cd.Scene(
        robot,
        [cd.Contact("foot", friction="stick")],
        [],
        gravity=[0, 0, -9.81],
        q0=np.array([0.0, 0.5, 0.0]),
        v0=np.zeros(3),
    )
    dyn = ModeDynamics(scene)

    def q_on_ground(rng):
        hip = 0.8 * rng.standard_normal()
        return np.array([0.0, 0.5 * np.cos(hip), hip])  # foot (0.5 m below the hip) at z = 0

    q, v, impact = _first_relaxed(dyn, q_on_ground, 2.0, [0], want_active=False)
    assert impact.tangential_only == (0,) and impact.active == ()
    _check_relaxed_law(dyn, q, v, [0], impact)
    _check_reset_jacobian(dyn, q, v, [0], impact)


def test_relaxed_and_active_contacts_solo12():
    """A diagonal pair of spatial sticking feet, one relaxed and one active."""
    scene = trot_scene("solo12")
    dyn = ModeDynamics(scene)
    keys = [0, 3]  # FL_FOOT, HR_FOOT
    q, v, impact = _first_relaxed(dyn, lambda rng: scene.q0.copy(), 0.5, keys, want_active=True, seed=1)
    assert len(impact.tangential_only) == 1 and len(impact.active) == 1
    _check_relaxed_law(dyn, q, v, keys, impact)
    _check_reset_jacobian(dyn, q, v, keys, impact)
