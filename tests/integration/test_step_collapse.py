"""Step collapse (`contactdiff.integration.step_collapse`), redundant contact rows, and
the step budget's edge cases."""

from __future__ import annotations

import math
import time

import numpy as np
import pinocchio as pin
import pytest
from helpers import assert_fd, fd_dv

import contactdiff as cd
from contactdiff.dynamics.mode import ModeDynamics
from contactdiff.integration.step_collapse import COLLAPSE_RATIO, COLLAPSE_STEPS


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
    assert ModeDynamics(solo8)._redundant_rank([ModeDynamics(solo8).contact(k) for k in range(4)], 12) == 10
    mode = tuple(range(4))
    rng = np.random.default_rng(3)
    dyn = ModeDynamics(solo8)
    for _ in range(3):
        q = solo8.q0.copy()
        q[7:] += rng.uniform(-0.3, 0.3, 8)
        dyn.kin.update(q, np.zeros(solo8.nv))
        rows = np.vstack([dyn.contact(k).rows(dyn.kin) for k in mode])
        _, singular, vt = np.linalg.svd(rows)
        null = vt[int(np.sum(singular > 1e-9 * singular[0])):].T
        v = null @ rng.uniform(-1.0, 1.0, null.shape[1])  # A v = 0
        sol = dyn.solve(q, v, 0.0, mode)
        lam, ddq, A = _min_norm_reference(solo8, q, v, mode)
        assert np.linalg.matrix_rank(A, tol=1e-9 * np.linalg.norm(A, 2)) == 11
        np.testing.assert_allclose(sol.forces, lam, atol=1e-9 * max(1.0, np.max(np.abs(lam))))
        np.testing.assert_allclose(sol.ddq, ddq, atol=1e-9 * np.max(np.abs(ddq)))


def test_solo8_folding_stops_with_a_step_collapse(solo8):
    """solo8 has no efforts: from its standing pose on four sticking feet it folds under
    gravity. Its knees fold until the shank lies on the thigh (knee angle ±π): there the
    leg, its foot held, is at a singular pose, the contact rows lose rank and the forces
    holding the feet grow without bound (1e3 N at |knee| = π - 1e-4, for a 1-kg-scale
    robot). The rigid model (no joint limits, no self-contact) has no continuation, so
    the steps collapse; the run must say so, where and in which mode, in a few hundred
    steps (it took 200,000 steps and two minutes to end in TooManyStepsError). Close to
    the fold the forces pass through zero and back, so some feet slip or lift off there
    (events within microseconds of the collapse); the collapse follows in the next mode.

    Tolerances: the collapse happens within the last hundred steps before the fold, where
    the forces are already beyond 1e3 N; the knee angle is then π to within 1e-3 rad
    (the fold is approached at 13 rad/s and the last steps are below 1e-8 s)."""
    start = time.perf_counter()
    with pytest.raises(cd.StepCollapseError) as info:
        cd.simulate(solo8, 0.5)
    elapsed = time.perf_counter() - start
    err = info.value
    traj = err.trajectory
    assert traj.termination is cd.Termination.STEP_COLLAPSE and traj.t == err.t
    assert err.mode == traj.modes[-1] and set(err.mode) <= set(solo8.contact_names)
    # the forces pass through zero and back near the fold: slips and lift-offs there only
    assert all(abs(event.t - err.t) <= 1e-5 for event in traj.events)
    assert err.step < COLLAPSE_RATIO * 1e-2  # the run's steps were 1e-2 to 4e-2 s long
    names = solo8.robot.configuration_names()
    knees = [traj.q[names.index(f"{leg}_KFE")] for leg in ("FL", "FR", "HL", "HR")]
    for knee in knees:
        assert abs(abs(knee) - math.pi) <= 1e-3
    assert traj.stats.steps <= 1000  # the collapse counts COLLAPSE_STEPS steps; the fold takes ~100
    assert f"t = {err.t:.12g}" in str(err) and f"mode ({', '.join(err.mode)})" in str(err)
    assert f"{err.step:.3g} s" in str(err) and f"{COLLAPSE_STEPS} steps" in str(err)
    assert elapsed < 60  # seconds, not minutes (a loose bound for a shared machine)


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
    null = vt[int(np.sum(singular > 1e-9 * singular[0])):].T  # (nv, nv - rank)
    v = null @ rng.uniform(-1.0, 1.0, null.shape[1])
    sol, der = dyn.solve(q, v, 0.0, mode, derivatives=True)
    dyn.kin.update(q, v)
    drift = np.concatenate([dyn.contact(k).drift(dyn.kin) for k in mode])
    assert np.max(np.abs(A @ sol.ddq + drift)) <= 1e-9 * np.max(np.abs(sol.ddq))  # consistent
    reference = fd_dv(lambda x: dyn.solve(q, v + null @ x, 0.0, mode).ddq, np.zeros(null.shape[1]))
    assert_fd("redundant ddq/dv along the constraints", der.ddq_dv @ null, reference, sol.ddq)
