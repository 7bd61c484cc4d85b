"""Impact law and mode choice (contactdiff.dynamics.impacts) on real scenes, by property.

States are random (hypothesis draws a seed; numpy builds the vectors): a random
configuration whose chosen contacts are projected onto the ground (gap 0), and a
random pre-impact velocity corrected so every chosen contact approaches
(``A_n v- = -s``, ``s`` in [0.1, 2]). All references (rows, mass matrix,
energy, the projector formula) are computed here from Pinocchio directly,
not from the package.

Tolerances: M and the Delassus matrices of these models are well conditioned
(cond <= ~1e5), so Cholesky solves are accurate to ~1e-11 relative; the
complementarity solver accepts a scaled residual of 1e-9 (lcp.DEFAULT_TOL). The
checks therefore use 1e-8 relative to the velocity/impulse scale of each case,
and 1e-10 relative for energy (its change is a smooth function of v+, which is
accurate to ~1e-11).
"""

from __future__ import annotations

import functools

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import contactdiff as cd
from contactdiff.dynamics.impacts import choose_mode, resolve_impact

REL = 1e-8
SETTINGS = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])


# ----------------------------------------------------------------------------------
# scenes and random impact states
# ----------------------------------------------------------------------------------
@functools.lru_cache(maxsize=None)
def _scene(key: str) -> cd.Scene:
    if key in ("planar_trot_rigid", "planar_trot_soft"):
        return cd.load_scene(key)
    base = cd.load_scene("solo12_drop")
    friction = "stick" if key == "solo12_stick" else "none"
    contacts = [cd.Contact(c.spec.frame, offset=c.spec.offset, friction=friction) for c in base.contacts]
    return cd.Scene(base.robot, contacts, gravity=[0, 0, -9.81], q0=base.q0)


@functools.lru_cache(maxsize=None)
def _dyn(key: str) -> cd.ModeDynamics:
    return cd.ModeDynamics(_scene(key))


def _frame_rows(scene, q, contacts, sticking):
    """Gaps and rows (normal first, then world x and y for sticking) from Pinocchio."""
    model = scene.model
    data = model.createData()
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    gaps, rows = [], []
    for i in contacts:
        c = scene.contacts[i]
        fid = model.getFrameId(c.spec.frame)
        gaps.append(data.oMf[fid].translation[2] - c.spec.offset)
        J = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)[:3]
        rows.append(J[[2, 0, 1]] if sticking else J[[2]])
    return np.array(gaps), rows


def _project(scene, q, contacts):
    """Gauss-Newton (minimum-norm steps) onto gap = 0 of ``contacts``."""
    for _ in range(50):
        gaps, rows = _frame_rows(scene, q, contacts, False)
        if np.max(np.abs(gaps)) <= 1e-14:
            return q
        A = np.vstack(rows)
        q = pin.integrate(scene.model, q, -np.linalg.pinv(A) @ gaps)
    raise AssertionError(f"projection did not converge: gaps {gaps}")


def _random_state(key: str, seed: int, subset: tuple[int, ...]):
    """Random (q, v-) with ``subset`` closed and approaching."""
    scene = _scene(key)
    rng = np.random.default_rng(seed)
    nv = scene.nv
    if key == "planar_trot_rigid":
        # (x, z, pitch); a single closed foot is the lower one; both closed needs pitch 0
        theta = 0.0 if len(subset) == 2 else rng.uniform(0.01, 0.6) * (1 if subset == (0,) else -1)
        sign = -1 if subset[0] == 0 else 1
        z = -(sign * 0.25 * np.sin(theta) - np.cos(theta) / 6)
        q = np.array([rng.uniform(-1, 1), z, theta])
    elif key == "planar_trot_soft":
        # body anywhere, closed feet on the ground, open feet above it
        q = scene.q0.copy()
        q[[0, 1, 2]] = [rng.uniform(-1, 1), rng.uniform(0.3, 1.0), rng.uniform(-0.5, 0.5)]
        for i, c in enumerate(scene.contacts):
            j = scene.model.joints[scene.model.getJointId(c.spec.frame + "_z")]
            q[j.idx_q] = 0.0 if i in subset else rng.uniform(0.01, 0.5)
            jx = scene.model.joints[scene.model.getJointId(c.spec.frame + "_x")]
            q[jx.idx_q] = rng.uniform(-1, 1)
    else:
        q = pin.integrate(scene.model, scene.q0, 0.3 * rng.standard_normal(nv))
        q = _project(scene, q, subset)
    v = rng.standard_normal(nv)
    _, rows = _frame_rows(scene, q, subset, False)
    An = np.vstack(rows)
    s = rng.uniform(0.1, 2.0, len(subset))
    v = v + np.linalg.pinv(An) @ (-s - An @ v)
    return scene, q, v


def _subsets(n):
    return st.lists(st.integers(0, n - 1), min_size=1, max_size=n, unique=True).map(lambda x: tuple(sorted(x)))


RIGID_SUBSETS = st.sampled_from([(0,), (1,), (0, 1)])
FRICTIONLESS = ["planar_trot_rigid", "planar_trot_soft", "solo12_none"]


def _case(key, seed, subset):
    scene, q, vm = _random_state(key, seed, subset)
    sticking = key == "solo12_stick"
    gaps, rows = _frame_rows(scene, q, subset, sticking)
    assert np.max(np.abs(gaps)) <= 1e-12
    M = pin.crba(scene.model, scene.model.createData(), q)
    return scene, q, vm, rows, M


def _kinetic(M, v):
    return 0.5 * v @ M @ v


def _check_law(scene, vm, rows, M, res, e, sticking):
    """Properties every impact must have; returns the normal speeds after."""
    An = np.array([r[0] for r in rows])
    A = np.vstack(rows)
    vp = res.v_plus
    v_scale = max(1.0, np.max(np.abs(A @ vm)))
    x_scale = max(1.0, np.max(np.abs(res.row_impulses)))
    # momentum balance: v+ = v- + M^-1 A^T x (rows stacked per contact, normal first)
    np.testing.assert_allclose(
        M @ (vp - vm), A.T @ res.row_impulses, rtol=0, atol=REL * x_scale * max(1, np.abs(A).max())
    )
    np.testing.assert_allclose(res.impulses, res.row_impulses[np.cumsum([0] + [len(r) for r in rows])[:-1]], atol=0)
    # impulses never pull
    assert np.all(res.impulses >= -REL * x_scale), res.impulses
    # post-impact normal velocity term w = A_n v+ + e A_n v- >= 0, complementary to the impulse
    np.testing.assert_allclose(res.normal_speeds_before, An @ vm, rtol=0, atol=REL * v_scale)
    np.testing.assert_allclose(res.normal_speeds_after, An @ vp, rtol=0, atol=REL * v_scale)
    w = An @ vp + e * (An @ vm)
    assert np.all(w >= -REL * v_scale), w
    assert np.all(np.abs(res.impulses * w) <= REL * x_scale * v_scale), (res.impulses, w)
    if sticking:
        # a contact that carries any impulse has its tangential velocity stopped
        for k, r in enumerate(rows):
            sl = slice(3 * k, 3 * k + 3)
            if np.max(np.abs(res.row_impulses[sl])) > REL * x_scale:
                np.testing.assert_allclose(r[1:] @ vp, 0.0, atol=REL * v_scale)
    return An @ vp


# ----------------------------------------------------------------------------------
# impact law properties
# ----------------------------------------------------------------------------------
@SETTINGS
@given(key=st.sampled_from(FRICTIONLESS), seed=st.integers(0, 2**32 - 1), e=st.floats(0.0, 1.0), data=st.data())
def test_frictionless_uniform_restitution(key, seed, e, data):
    """Uniform e, frictionless: impulses >= 0, complementarity, energy never
    increases (docs/design.md §2; the loss is ½ (1 - e) Σ x_k (-A_k v-) >= 0)."""
    subset = data.draw(RIGID_SUBSETS if key == "planar_trot_rigid" else _subsets(len(_scene(key).contacts)))
    scene, q, vm, rows, M = _case(key, seed, subset)
    res = resolve_impact(_dyn(key), q, vm, subset, np.full(len(subset), e))
    _check_law(scene, vm, rows, M, res, e, False)
    np.testing.assert_allclose(res.restitution, e)
    assert res.contacts == subset
    ke_m, ke_p = _kinetic(M, vm), _kinetic(M, res.v_plus)
    assert ke_p <= ke_m * (1 + 1e-10)
    # closed form of the loss (frictionless rows, w_k x_k = 0)
    An = np.array([r[0] for r in rows])
    loss = 0.5 * (1 - e) * res.impulses @ (-(An @ vm))
    assert ke_m - ke_p == pytest.approx(loss, abs=1e-9 * ke_m)


@SETTINGS
@given(key=st.sampled_from(FRICTIONLESS), seed=st.integers(0, 2**32 - 1), data=st.data())
def test_plastic_zeroes_normal_velocity(key, seed, data):
    """e = 0: contacts that take an impulse leave with zero normal velocity, the
    others with a non-negative one; energy never increases."""
    subset = data.draw(RIGID_SUBSETS if key == "planar_trot_rigid" else _subsets(len(_scene(key).contacts)))
    scene, q, vm, rows, M = _case(key, seed, subset)
    res = resolve_impact(_dyn(key), q, vm, subset, np.zeros(len(subset)))
    after = _check_law(scene, vm, rows, M, res, 0.0, False)
    v_scale = max(1.0, np.max(np.abs(res.normal_speeds_before)))
    x_scale = max(1.0, np.max(res.impulses))
    for x, w in zip(res.impulses, after):
        if x > REL * x_scale:
            assert abs(w) <= REL * v_scale
        else:
            assert w >= -REL * v_scale
    assert _kinetic(M, res.v_plus) <= _kinetic(M, vm) * (1 + 1e-10)


@SETTINGS
@given(key=st.sampled_from(FRICTIONLESS), seed=st.integers(0, 2**32 - 1), e=st.floats(0.0, 1.0), data=st.data())
def test_single_contact_projector_formula(key, seed, e, data):
    """One contact: v+ = (I - (1 + e) P) v-, P = M^-1 a^T (a M^-1 a^T)^-1 a."""
    contact = data.draw(st.integers(0, len(_scene(key).contacts) - 1))
    scene, q, vm, rows, M = _case(key, seed, (contact,))
    res = resolve_impact(_dyn(key), q, vm, (contact,), [e])
    a = rows[0]
    Minv_aT = np.linalg.solve(M, a.T)
    P = Minv_aT @ np.linalg.solve(a @ Minv_aT, a)
    np.testing.assert_allclose(
        res.v_plus, (np.eye(scene.nv) - (1 + e) * P) @ vm, rtol=0, atol=REL * max(1.0, np.abs(vm).max())
    )
    assert res.normal_speeds_after[0] == pytest.approx(-e * res.normal_speeds_before[0], abs=REL)


@SETTINGS
@given(seed=st.integers(0, 2**32 - 1), e=st.floats(0.0, 1.0))
def test_decoupled_projector_formula(seed, e):
    """planar_trot_soft, both feet closed: rows on different feet, diagonal M
    (decoupled), so the paper's v+ = (I - (1 + e) P_J) v- holds for the pair."""
    key = "planar_trot_soft"
    scene, q, vm, rows, M = _case(key, seed, (0, 1))
    A = np.vstack(rows)
    Minv_AT = np.linalg.solve(M, A.T)
    G = A @ Minv_AT
    assert abs(G[0, 1]) <= 1e-15  # decoupled
    P = Minv_AT @ np.linalg.solve(G, A)
    res = resolve_impact(_dyn(key), q, vm, (0, 1), [e, e])
    np.testing.assert_allclose(
        res.v_plus, (np.eye(scene.nv) - (1 + e) * P) @ vm, rtol=0, atol=REL * max(1.0, np.abs(vm).max())
    )


@SETTINGS
@given(key=st.sampled_from(FRICTIONLESS), seed=st.integers(0, 2**32 - 1), e=st.floats(0.0, 1.0), data=st.data())
def test_projector_formula_when_all_push(key, seed, e, data):
    """Whenever every closed contact takes an impulse (coupled or not), all rows
    satisfy A v+ = -e A v-, i.e. v+ = (I - (1 + e) P_J) v- for the whole set."""
    subset = data.draw(RIGID_SUBSETS if key == "planar_trot_rigid" else _subsets(len(_scene(key).contacts)))
    scene, q, vm, rows, M = _case(key, seed, subset)
    res = resolve_impact(_dyn(key), q, vm, subset, np.full(len(subset), e))
    if np.min(res.impulses) <= 1e-6 * max(1.0, np.max(res.impulses)):
        return
    A = np.vstack(rows)
    Minv_AT = np.linalg.solve(M, A.T)
    P = Minv_AT @ np.linalg.solve(A @ Minv_AT, A)
    np.testing.assert_allclose(
        res.v_plus, (np.eye(scene.nv) - (1 + e) * P) @ vm, rtol=0, atol=REL * max(1.0, np.abs(vm).max())
    )


@SETTINGS
@given(key=st.sampled_from(FRICTIONLESS), seed=st.integers(0, 2**32 - 1), data=st.data())
def test_elastic_single_contact_keeps_energy(key, seed, data):
    """e = 1, one contact: P is M-orthogonal, so ½ v+^T M v+ = ½ v-^T M v-."""
    contact = data.draw(st.integers(0, len(_scene(key).contacts) - 1))
    scene, q, vm, rows, M = _case(key, seed, (contact,))
    res = resolve_impact(_dyn(key), q, vm, (contact,), [1.0])
    assert _kinetic(M, res.v_plus) == pytest.approx(_kinetic(M, vm), rel=1e-10)
    assert res.normal_speeds_after[0] == pytest.approx(-res.normal_speeds_before[0], rel=1e-10)


@SETTINGS
@given(seed=st.integers(0, 2**32 - 1))
def test_elastic_decoupled_pair_keeps_energy(seed):
    """e = 1 on both decoupled feet of planar_trot_soft: energy kept too."""
    key = "planar_trot_soft"
    scene, q, vm, rows, M = _case(key, seed, (0, 1))
    res = resolve_impact(_dyn(key), q, vm, (0, 1), [1.0, 1.0])
    assert _kinetic(M, res.v_plus) == pytest.approx(_kinetic(M, vm), rel=1e-10)


@SETTINGS
@given(seed=st.integers(0, 2**32 - 1), subset=_subsets(4))
def test_sticking_plastic(seed, subset):
    """solo12, sticking feet, e = 0: impulses >= 0, complementarity, stuck feet stop
    in all three directions, energy never increases (change -½ x^T G x)."""
    key = "solo12_stick"
    scene, q, vm, rows, M = _case(key, seed, subset)
    res = resolve_impact(_dyn(key), q, vm, subset, np.zeros(len(subset)))
    assert res.row_impulses.shape == (3 * len(subset),)
    _check_law(scene, vm, rows, M, res, 0.0, True)
    assert _kinetic(M, res.v_plus) <= _kinetic(M, vm) * (1 + 1e-10)


def test_scene_restitution_is_the_default():
    """restitution=None uses each contact's own e (ball: 0.8): v+ = 0.8 * 1."""
    scene = cd.load_scene("ball")
    res = resolve_impact(cd.ModeDynamics(scene), np.array([0.0]), np.array([-1.0]), (0,))
    # x = (1 + e) m |v-| from a 1 x 1 solve and v+ = v- + x / m: a few roundings of O(1)
    # numbers, at most c eps (|v-| + |x|) with c = 4 (a fixed 1e-15 would be 2 to 4 ulps)
    tol = 4 * np.finfo(float).eps * (1.0 + 1.8)
    assert res.v_plus[0] == pytest.approx(0.8, abs=tol)
    assert res.impulses[0] == pytest.approx(1.8, abs=tol)
    np.testing.assert_allclose(res.restitution, [0.8])


# ----------------------------------------------------------------------------------
# mode choice
# ----------------------------------------------------------------------------------
def _rigid_with_pitch_torque(tau):
    base = cd.load_scene("planar_trot_rigid")
    effort = cd.UserEffort(lambda q, v, t: np.array([0.0, 0.0, tau]), name="pitch torque")
    return cd.Scene(base.robot, base.contact_specs, [effort], gravity=[0, 0, -1], q0=[0.0, 1 / 6, 0.0])


@pytest.mark.parametrize(
    "tau, expected",
    [(0.0, (0, 1)), (0.7, (0, 1)), (0.8, (0,)), (2.0, (0,)), (-0.7, (0, 1)), (-0.8, (1,)), (-2.0, (1,))],
)
def test_choose_mode_rigid_trot(tau, expected):
    """Rigid trot standing on both feet at rest with a pitch torque tau (positive
    lifts the front). Both active with zero acceleration needs
    l_r + l_f = 3 g = 3 and I*0 = tau + (l_f - l_r)/4, so l_f = 1.5 - 2 tau and
    l_r = 1.5 + 2 tau: the front releases for tau > 0.75, the rear for tau < -0.75.
    The foot that stays then carries a positive force (checked by the LCP)."""
    scene = _rigid_with_pitch_torque(tau)
    dyn = cd.ModeDynamics(scene)
    q, v = np.array([0.0, 1 / 6, 0.0]), np.zeros(3)
    assert choose_mode(dyn, q, v, 0.0, [0, 1]) == expected
    if expected == (0, 1):
        forces = dyn.solve(q, v, 0.0, (0, 1)).normal_forces()
        np.testing.assert_allclose(forces, [1.5 + 2 * tau, 1.5 - 2 * tau], atol=1e-12)
    # an empty candidate list is the empty mode
    assert choose_mode(dyn, q, v, 0.0, []) == ()


@pytest.mark.parametrize("pull, expected", [(0.5, (0, 1)), (1.5, (1,))])
def test_choose_mode_soft_trot_foot_pulled_up(pull, expected):
    """planar_trot_soft standing: body at z = 0.5 (springs at rest), feet on the
    ground, at rest. An upward force F on the rear foot: its normal force is
    m_f g - F = 1 - F, so F = 1.5 releases it, F = 0.5 keeps it."""
    base = cd.load_scene("planar_trot_soft")
    iv = base.model.joints[base.model.getJointId("rear_foot_z")].idx_v

    def pull_up(q, v, t):
        tau = np.zeros(base.nv)
        tau[iv] = pull
        return tau

    q0 = {"body_z": 0.5, "rear_foot_x": -0.25, "rear_foot_z": 0.0, "front_foot_x": 0.25, "front_foot_z": 0.0}
    scene = cd.Scene(
        base.robot, base.contact_specs, list(base.effort_specs) + [cd.UserEffort(pull_up)], gravity=[0, 0, -1], q0=q0
    )
    dyn = cd.ModeDynamics(scene)
    assert choose_mode(dyn, scene.q0, scene.v0, 0.0, [0, 1]) == expected
    forces = dyn.solve(scene.q0, scene.v0, 0.0, (0, 1)).normal_forces()
    np.testing.assert_allclose(forces, [1 - pull, 1.0], atol=1e-12)


def test_choose_mode_with_the_integrator():
    """The same release through simulate: a rigid trot standing on both feet with
    tau = 2 starts on the rear foot only and pivots front-up (pitch rate > 0)."""
    from contactdiff.integration.hybrid import simulate

    traj = simulate(_rigid_with_pitch_torque(2.0), 0.1, rtol=1e-12, atol=1e-14)
    assert traj.modes[0] == ("rear_foot",)
    assert traj.v[2] > 0
