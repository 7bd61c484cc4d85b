"""Step collapse (`contactdiff.ode.step_collapse`), redundant contact rows, and
the step budget's edge cases."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
from helpers import assert_fd, fd_dv

import contactdiff as cd
from contactdiff.dynamics.mode import ModeDynamics
from contactdiff.ode.step_collapse import COLLAPSE_STEPS


@pytest.fixture(scope="module")
def solo8():
    return cd.load_source("solo8")


def _min_norm_reference(scene, q, v, mode):
    """Row forces and accelerations of a sticking mode, built here from Pinocchio directly:
    ``M ddq = tau - nle + A^T lam``, ``A ddq + drift = 0``, so ``G lam = b`` with
    ``G = A M^-1 A^T`` and ``b = -(drift + A M^-1 (tau - nle))``. With redundant rows ``G``
    is singular and, for a velocity that keeps the rows (``A v = 0``), every solution gives
    the same ``ddq``; the physical choice is the minimum-norm ``lam`` (`np.linalg.pinv`, an
    SVD with its own cut-off)."""
    dyn = ModeDynamics(scene)
    dyn.kin.update(q, v)
    contacts = [dyn.contact(k) for k in mode]
    A = np.vstack([c.rows(dyn.kin) for c in contacts])
    drift = np.concatenate([c.drift(dyn.kin) for c in contacts])
    model, data = scene.model, scene.model.createData()
    M = pin.crba(model, data, q)
    M = np.triu(M) + np.triu(M, 1).T
    nle = pin.nonLinearEffects(model, data, q, v)
    tau = scene.tau(dyn.kin, 0.0)
    Minv = np.linalg.inv(M)
    G = A @ Minv @ A.T
    lam = np.linalg.pinv(G, rcond=1e-10, hermitian=True) @ -(drift + A @ Minv @ (tau - nle))
    return lam, Minv @ (tau - nle + A.T @ lam), A


def test_redundant_rows_give_the_minimum_norm_forces(solo8):
    """solo8's legs are planar (no HAA joints): the lateral rows of its four sticking feet
    hold its base's lateral motion, roll and yaw with four rows (rank 11 of 12; 10 in its
    symmetric stance, where two more rows coincide). Their
    Delassus matrix is singular up to round-off; Pinocchio's Cholesky factorisation of it
    does not fail but returns forces made of round-off (0.2 N lateral at rest, 1e7 N
    while folding, accelerations off by 1e-2), a field no step size resolves. The mode now
    solves on its independent rows: the minimum-norm forces of the reference above.

    Tolerances: forces of ~0.5 N and accelerations of ~100 rad/s² from two eigen/SVD-based
    solves of an 18-dof system agree to ~1e-12 relative; 1e-9 leaves a margin. The
    reference's cut-off (1e-10 of the largest singular value of G) lies between the
    repeated rows' round-off (1e-15) and the independent rows' smallest (1e-3 here)."""
    mode = tuple(range(4))
    assert ModeDynamics(solo8).redundant(mode)
    rng = np.random.default_rng(3)
    dyn = ModeDynamics(solo8)
    for _ in range(3):
        q = solo8.q0.copy()
        q[7:] += rng.uniform(-0.3, 0.3, 8)
        dyn.kin.update(q, np.zeros(solo8.nv))
        rows = np.vstack([dyn.contact(k).rows(dyn.kin) for k in mode])
        _, singular, vt = np.linalg.svd(rows)
        null = vt[int(np.sum(singular > 1e-9 * singular[0])) :].T
        v = null @ rng.uniform(-1.0, 1.0, null.shape[1])  # A v = 0
        sol = dyn.solve(q, v, 0.0, mode)
        lam, ddq, A = _min_norm_reference(solo8, q, v, mode)
        assert np.linalg.matrix_rank(A, tol=1e-9 * np.linalg.norm(A, 2)) == 11
        np.testing.assert_allclose(sol.forces, lam, atol=1e-9 * max(1.0, np.max(np.abs(lam))))
        np.testing.assert_allclose(sol.ddq, ddq, atol=1e-9 * np.max(np.abs(ddq)))


def test_solo8_folds_through_its_knees_singular_pose(solo8):
    """solo8 has no efforts: from its standing pose on four sticking feet it folds under
    gravity, its knees reaching ±π (shank on thigh, the foot held) at about 0.2085 s.
    There the leg's rows lose rank and the forces holding the feet grow without bound
    (1e3 N at |knee| = π - 1e-4), but only as internal forces: the accelerations stay
    finite and continuous (the limit of the compatible-load solution), so the motion has
    a continuation and the fold goes on through the pose. The issue's run took 200,000
    steps and two minutes to end in TooManyStepsError: the repeated lateral rows' forces
    were round-off over a 1e-16 pivot (fixed above); it now runs its 0.5 s.

    Tolerances: the knee angle is that of a smooth run at default tolerances (~1e-8);
    the check is only that it passed π."""
    traj = cd.simulate(solo8, 0.5, dense=True)
    assert traj.t == 0.5 and traj.stats.steps <= 1000
    names = solo8.robot.configuration_names()
    knee = names.index("FL_KFE")
    before, _ = traj.at(0.2)
    after, _ = traj.at(0.22)
    assert abs(before[knee]) < math.pi < abs(after[knee])
    dyn = ModeDynamics(solo8)
    for t in (0.2084, 0.2085, 0.2086):  # across the singular pose: bounded accelerations
        q, v = traj.at(t)
        ddq = dyn.solve(q, v, t, tuple(range(4))).ddq
        assert np.all(np.isfinite(ddq)) and np.abs(ddq).max() < 1e3


def test_a_finite_time_blow_up_stops_with_a_step_collapse():
    """A unit ball (g = 1) pulled up by F = 2/(2 - z)² from rest at z = 1: by energy,
    ż²/2 = 2/(2 - z) - 2 - (z - 1), so it reaches z = 2 at infinite speed at the finite
    time t* = ∫₁² dz / ż (with z = 1 + s², a smooth integral over s in [0, 1]). The
    field has no continuation there; the steps collapse and the run must say so, where
    and in which mode, in a few hundred steps, not run out its step budget.

    Tolerances: the collapse is declared after `COLLAPSE_STEPS` steps each shorter than
    `COLLAPSE_RATIO` of the typical step, or where a step reaches the resolution of time,
    within (t* - 1e-3, t*] here (the speed near z = 2 grows as (2 - z)^(-1/2))."""
    from scipy.integrate import quad

    def pull(q, v, t):
        return np.array([2.0 / (2.0 - q[0]) ** 2])

    ball = cd.load_scene("ball")
    scene = cd.Scene(
        ball.robot,
        ball.contact_specs,
        [cd.UserEffort(pull, name="pull")],
        gravity=(0.0, 0.0, -1.0),
        q0=ball.q0,
        v0=np.zeros(ball.nv),
    )

    def dt_ds(s):
        z = 1.0 + s * s
        return 2.0 * s / np.sqrt(2.0 * (2.0 / (2.0 - z) - 2.0 - (z - 1.0))) if s > 0.0 else np.sqrt(2.0)

    t_star, _ = quad(dt_ds, 0.0, 1.0, limit=200)
    with pytest.raises(cd.StepCollapseError) as info:
        cd.simulate(scene, 10.0)
    err = info.value
    traj = err.trajectory
    assert traj.termination is cd.Termination.STEP_COLLAPSE and traj.t == err.t
    assert t_star - 1e-3 < err.t < t_star + 1e-6  # the run's time error near t*: ~rtol = 1e-8 relative
    assert err.mode == () and traj.stats.steps <= 1000
    assert f"t = {err.t:.12g}" in str(err) and "free flight" in str(err)
    # the steps shrink geometrically towards t*: either the count of short steps or the
    # resolution of time ends the run first, and the message says which
    assert f"{COLLAPSE_STEPS} steps" in str(err) or "resolution of time" in str(err)


def test_a_fast_spin_is_a_budget_not_a_collapse():
    """planar_trot_soft with its body pitching at 1e6 rad/s: the spin is free (the legs are
    prismatic springs to point feet), so it never slows and every step must resolve it,
    h ~ 1e-6 s from the very first step. That is a run beyond its budget, not a collapse:
    its steps are the mode's own. With max_steps = 2,000 it stops in TooManyStepsError
    (2 s of it need ~2e6 steps), naming its last step."""
    scene = cd.load_scene("planar_trot_soft").with_state(None, {"body_pitch": 1e6})
    with pytest.raises(cd.TooManyStepsError) as info:
        cd.simulate(scene, 2.0, max_steps=2000)
    assert not isinstance(info.value, cd.StepCollapseError)
    traj = info.value.trajectory
    assert traj.termination is cd.Termination.MAX_STEPS and traj.stats.steps == 2000
    # 2,000 steps cover a few ms: steps of order 1 / omega = 1e-6 s
    assert 1e-4 < traj.t < 1e-2


@pytest.mark.parametrize("max_steps", range(1, 8))
def test_step_budget_error_at_every_count(max_steps):
    """The ball's steps end at events and restarts: the budget may run out right after
    one (regression: the message read the step's start, which a restart clears, and
    raised TypeError). Each budget gives TooManyStepsError with the run so far."""
    with pytest.raises(cd.TooManyStepsError, match=r"last step [0-9.e+-]+ s") as info:
        cd.simulate(cd.load_scene("ball"), 20.0, max_steps=max_steps)
    assert info.value.trajectory.stats.steps == max_steps


@pytest.mark.parametrize("bad", [0, -1, 1.5, True])
def test_max_steps_must_be_a_positive_count(bad):
    with pytest.raises(cd.InvalidInputError, match=r"max_steps must be an integer >= 1, got"):
        cd.simulate(cd.load_scene("ball"), 1.0, max_steps=bad)


def test_redundant_mode_velocity_derivatives_match_finite_differences(solo8):
    """Redundant rows hold the velocities to a subspace smaller than their count: ``A v = 0``
    has solutions, but ``A ddq + drift = 0`` only while ``v`` keeps it (an arbitrary ``v``
    makes the drift inconsistent, and the forces are then a least-squares compromise).
    Along velocities that keep the constraints (``w`` in the null space of ``A``) the
    accelerations are unique and smooth: the analytic ``d ddq / d v`` (KKT differentiated,
    solved on G's independent eigen-directions) applied to such ``w`` against central
    differences (step 1e-6: truncation ~1e-12 and round-off ~1e-10 relative, asserted
    below 1e-6)."""
    mode = tuple(range(4))
    dyn = ModeDynamics(solo8)
    rng = np.random.default_rng(5)
    q = solo8.q0.copy()
    q[7:] += rng.uniform(-0.3, 0.3, 8)
    dyn.kin.update(q, np.zeros(solo8.nv))
    A = np.vstack([dyn.contact(k).rows(dyn.kin) for k in mode])
    _, singular, vt = np.linalg.svd(A)
    null = vt[int(np.sum(singular > 1e-9 * singular[0])) :].T  # (nv, nv - rank)
    v = null @ rng.uniform(-1.0, 1.0, null.shape[1])
    sol, der = dyn.solve(q, v, 0.0, mode, derivatives=True)
    dyn.kin.update(q, v)
    drift = np.concatenate([dyn.contact(k).drift(dyn.kin) for k in mode])
    assert np.max(np.abs(A @ sol.ddq + drift)) <= 1e-9 * np.max(np.abs(sol.ddq))  # consistent
    reference = fd_dv(lambda x: dyn.solve(q, v + null @ x, 0.0, mode).ddq, np.zeros(null.shape[1]))
    assert_fd("redundant ddq/dv along the constraints", der.ddq_dv @ null, reference, sol.ddq)
