"""The gradient benchmark's tasks: their exact gradients (closed forms of
`contactdiff.bench.gradients`) against contactdiff's flow Jacobians, and the MuJoCo
adapters' convergence (``mujoco`` extra)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from contactdiff.bench import gradients as g
from contactdiff.errors import InvalidInputError

RUN_TOL = 1e-8
"""Relative gradient error allowed of a run at rtol 1e-12, atol 1e-13: the flow Jacobian
is integrated with the state, so its error is of the tolerance times the growth of
perturbations through the events (O(1) to O(10) here: impacts of restitution <= 1
and free flight over 1 s), far below 1e-8; 1e-8 is the benchmark's target."""


def rel(a, b) -> float:
    return float(np.linalg.norm(np.asarray(a) - b) / np.linalg.norm(b))


def central(f, x, h):
    """Central differences of ``f`` (vector valued) at ``x`` (columns: inputs)."""
    x = np.asarray(x, dtype=float)
    cols = []
    for k in range(len(x)):
        dx = np.zeros_like(x)
        dx[k] = h
        cols.append((f(x + dx) - f(x - dx)) / (2 * h))
    return np.array(cols).T


@pytest.mark.parametrize("task", [g.BOUNCE, g.WALL, g.WALL_FRICTION], ids=["bounce", "wall", "wall_friction"])
def test_closed_form_gradient_against_its_finite_differences(task):
    """The complex-step gradient of the closed form is its derivative: central differences
    with h = 1e-6 m/s agree to O(h² f''') + O(eps |f| / h) ~ 1e-10, allowed 1e-7."""
    exact = g.ball_gradient(task)
    fd = central(lambda v: g.ball_outcome(task, v)[:2].real, task.velocity, 1e-6)
    assert rel(fd, exact) < 1e-7


def test_bounce_formula_matches_the_complex_step():
    """Task 1's hand-derived gradient (module doc: dx/dvx = T, dz/dvz = e τ vz/s - (e s - g τ) t1/s)
    equals the complex step of the closed form to round-off (1e-14)."""
    assert rel(g.bounce_gradient(g.BOUNCE), g.ball_gradient(g.BOUNCE)) < 1e-14
    assert g.bounce_gradient(g.BOUNCE)[0, 0] == g.BOUNCE.horizon


def test_wall_without_friction_has_dx_dvx_minus_e_wall_T():
    """Frictionless, x(T) = W - r - e_w (vx T - (W - r - x0)): dx/dvx = -e_w T exactly."""
    assert math.isclose(g.ball_gradient(g.WALL)[0, 0], -g.WALL.wall_restitution * g.WALL.horizon, rel_tol=1e-14)


@pytest.mark.parametrize("task", [g.BOUNCE, g.WALL, g.WALL_FRICTION], ids=["bounce", "wall", "wall_friction"])
def test_contactdiff_ball_gradient_is_exact(task):
    """Tasks 1 and 2: contactdiff's d(x, z)(T)/d(vx, vz) within RUN_TOL of the closed form's,
    its outcome within 1e-9 m of the closed form (rtol 1e-12 on O(1) m), and differentiable."""
    run = g.contactdiff_ball(task)
    assert run.differentiable
    assert np.allclose(run.outcome, g.ball_outcome(task)[:2].real, rtol=0, atol=1e-9)
    assert rel(run.gradient, g.ball_gradient(task)) < RUN_TOL


def test_friction_task_sticks_on_the_ground_and_slides_on_the_wall():
    """The friction task's impacts are in the intended regimes: after the ground's impact the
    ball rolls (slip vx - r ω = 0), and the wall's slides: its outcome differs from the
    frictionless wall's and from a sticking one's (μ = 1), and it is affine in the wall's μ
    (a sliding impulse is μ P_n: the outcome at μ is the mean of those at μ ± 0.01)."""
    before_wall = replace(g.WALL_FRICTION, wall=None, horizon=0.6)  # after the ground's impact, before the wall
    x, z, vx, vz, wy = g.ball_outcome(before_wall).real
    assert abs(vx - g.WALL_FRICTION.radius * wy) < 1e-12
    mu = g.WALL_FRICTION.wall_friction
    finals = {
        m: g.ball_outcome(replace(g.WALL_FRICTION, wall_friction=m))[:2].real
        for m in (0.0, mu - 0.01, mu, mu + 0.01, 1.0)
    }
    assert np.linalg.norm(finals[mu] - finals[0.0]) > 1e-3 and np.linalg.norm(finals[mu] - finals[1.0]) > 1e-3
    assert np.allclose(finals[mu], (finals[mu - 0.01] + finals[mu + 0.01]) / 2, rtol=0, atol=1e-12)


def test_nimble_two_balls_gradient_is_one_zero_one_zero():
    """Task 3 (Nimble's case): d x2(T)/d(x1, x2, v1, v2) = (1, 0, T, 0) with T = 1, and
    d x1(T)/d(...) = (0, 1, 0, T) (module doc), from contactdiff's run within RUN_TOL."""
    run = g.contactdiff_two_balls()
    assert run.differentiable
    assert np.array_equal(g.two_ball_gradient()[1], [1.0, 0.0, 1.0, 0.0])
    assert rel(run.gradient, g.two_ball_gradient()) < RUN_TOL


def test_brax_case_gradient_and_verdict():
    """Task 4: dz(T)/dz0 = -1 below the kink (landed by T), +1 above, within RUN_TOL; the
    verdict is differentiable everywhere but at the kink z0 = r + c T, where the ball
    lands at T exactly (no event of the run: the verdict's `NonSmooth.FINAL_TIME`)."""
    task = g.BRAX
    for k in (-4, -1, 0, 1, 4):
        z0 = task.kink + 0.05 * k
        run = g.contactdiff_brax(task, z0)
        z_exact, d_exact = g.brax_outcome(task, z0)
        assert math.isclose(run.outcome[0], z_exact, abs_tol=1e-9)
        if k == 0:
            assert d_exact is None and not run.differentiable and any("final time" in n for n in run.notes)
        else:
            assert run.differentiable and abs(run.gradient[0, 0] - d_exact) < RUN_TOL


def test_cube_pose_gradient_against_central_differences():
    """Task 5 (the first landing, 14 events to T = 0.25 s): contactdiff's d pose(T)/d(μ, e)
    against central differences of its own runs at rtol 1e-12, atol 1e-13, h = 1e-6 (the
    impact cascades have kinks within 1e-4 of (μ, e), `REFERENCE_STEPS`). Run error: each
    final pose to ~1e-12 (atol + rtol |q|, |q| <= 1), so the quotient to 2e-12 / 2h = 1e-6
    on a gradient of norm ~1: 1e-6 relative; truncation O(h²) = 1e-12 times the third
    derivative; allowed 1e-5."""
    from contactdiff.bench import gradients_cube as cube

    run = cube.contactdiff_cube()
    assert run.differentiable
    fd, _ = cube.cube_reference(1e-6)
    assert rel(run.gradient, fd) < 1e-5


# -- MuJoCo adapters --------------------------------------------------------------------


def _mujoco():
    return pytest.importorskip("mujoco", reason="the MuJoCo baselines need the mujoco extra")


def test_mujoco_contact_restitution():
    """The solref of a contact of restitution e makes MuJoCo bounce a dropped ball with
    e within 2 % (the spring-damper's e; the impedance 0.99 and dt = 1e-4 s against a
    contact lasting π τ = 63 ms move it by less)."""
    mujoco = _mujoco()
    from contactdiff.bench import gradients_mujoco as mj

    task = replace(g.BOUNCE, position=(0.0, 0.2))
    model = mj.ball_model(task, mj.Variant(1e-4, 0.02))
    data = mujoco.MjData(model)
    data.qpos[:] = [0.0, 0.0, 0.2, 1.0, 0.0, 0.0, 0.0]
    data.qvel[:] = [0.0, 0.0, -3.0, 0.0, 0.0, 0.0]
    incoming = None
    for _ in range(5000):
        mujoco.mj_step(model, data)
        if data.ncon and incoming is None:
            incoming = data.qvel[2]
        if incoming is not None and not data.ncon:
            break
    assert abs(-data.qvel[2] / incoming - task.restitution) < 0.02 * task.restitution


def test_mujoco_gradients_converge_as_the_time_step_shrinks():
    """On the tasks whose soft-contact limit has the rigid gradient (no gravity, elastic: a
    linear spring's bounce lasts π τ whatever the speed, so the outcome only shifts),
    MuJoCo's gradients (rollout differences and transition products) approach the exact
    one as dt shrinks: semi-implicit Euler is first order, so dividing dt by 10 must at
    least halve the error (margin 5)."""
    _mujoco()
    from contactdiff.bench import gradients_mujoco as mj

    errors = {
        method: [abs(mj.mujoco_brax(g.BRAX, mj.Variant(dt, 0.02), 0.6, method)[0][0, 0] + 1.0) for dt in (1e-3, 1e-4)]
        for method in ("fd", "transition")
    }
    for method, (coarse, fine) in errors.items():
        assert fine < coarse / 2, (method, coarse, fine)
    exact = g.two_ball_gradient()
    coarse, fine = (rel(mj.mujoco_two_balls(g.NIMBLE, mj.Variant(dt, 0.02), "fd")[0], exact) for dt in (1e-3, 1e-4))
    assert fine < coarse / 2


def test_two_ball_gradient_against_differences_of_its_closed_form():
    """The closed form of task 3 (module doc): tc = (x2 - x1 - 2r)/(v1 - v2), then x1(T) = x1 + v1 tc
    + v2 (T - tc) and x2(T) = x2 + v2 tc + v1 (T - tc) (velocities swapped); central differences
    (h = 1e-6) of it agree with `two_ball_gradient` to round-off over h (1e-9)."""
    task = g.NIMBLE

    def final(x):
        x1, x2, v1, v2 = x
        tc = (x2 - x1 - 2 * task.radius) / (v1 - v2)
        return np.array([x1 + v1 * tc + v2 * (task.horizon - tc), x2 + v2 * tc + v1 * (task.horizon - tc)])

    fd = central(final, [task.x1, task.x2, task.v1, task.v2], 1e-6)
    assert np.allclose(fd, g.two_ball_gradient(task), rtol=0, atol=1e-9)


def test_mujoco_transition_product_equals_rollout_differences():
    """Both MuJoCo gradients estimate the same local derivative of the time-stepped map:
    at dt = 1e-3 s a rollout difference of h = 1e-5 m stays within one smooth piece (the
    contact starts a step later when z0 moves by c dt = 1e-3 m), so they agree to the
    differences' errors (h² f''' ~ 1e-10, eps/h ~ 1e-11 and 1000 steps of centred eps = 1e-6
    Jacobians, ~1e-9): allowed 1e-6 relative."""
    _mujoco()
    from contactdiff.bench import gradients_mujoco as mj

    variant = mj.Variant(1e-3, 0.02)
    fd = mj.mujoco_brax(g.BRAX, variant, 0.6, "fd")[0]
    product = mj.mujoco_brax(g.BRAX, variant, 0.6, "transition")[0]
    assert rel(product, fd) < 1e-6
    with pytest.raises(InvalidInputError, match="method must be"):
        mj.mujoco_brax(g.BRAX, variant, 0.6, "adjoint")
    with pytest.raises(InvalidInputError, match="does not divide"):
        mj.mujoco_brax(g.BRAX, mj.Variant(3e-3, 0.02), 0.6, "fd")
