"""A corner that slips from rest while the other corners of its face hold it at zero slip sticks
again once the push is gone (`contactdiff.integration.held`, "Slips held at zero").

The scene: the cube (`contactdiff.cube_scene`: m = 0.37 kg, half-edge b = 0.0524 m) flat on its
-z face at rest, μ = 0.5, e = 0, under a push fixed in the world frame whose amplitude rises and
falls: the force ``a(t) F0`` applied at the centre of the bottom face (no tipping moment about
the face) and the torque ``a(t) τ0`` about the vertical, with

    F0 = μ m g (0.6, 0.25, 0),   τ0 = 0.6 μ m g b,   a(t) = 1 - K (t - t_c)²,  K = 200 /s², t_c = 0.05 s.

Closed form. While every corner sticks the cube is at rest (its four sticking corners fix it),
so the accelerations vanish and the corner forces ``f_i`` (world frame, on the body) solve the
equilibrium ``Σ f_i = -(a F0 - m g e_z)``, ``Σ p_i × f_i = -(r_f × a F0 + a τ0 e_z)`` (``p_i`` the
corners from the centre, ``r_f = -b e_z`` the face's centre). Four sticking corners are redundant
(12 unknowns, 6 equations): the project's principle takes the compatible load, which for
sticking rows (a symmetric Delassus matrix) is the least-norm solution (`dynamics/redundant`):
``f = E⁺ w`` with ``E`` the 6 × 12 equilibrium matrix. It is linear in ``a``; corner i's cone
margin ``μ f_z - ||(f_x, f_y)||`` reaches 0 at the amplitude ``a*`` found by a scalar root search
on it. Corner +x-y is the first (a* = 0.948; the next, -x-y, at 1.109 > max a = 1): it slips from
rest at ``t1 = t_c - sqrt((1 - a*)/K)``, along the direction its sticking force resisted, while
the three others hold the cube (three sticking points fix a rigid body): its slip stays zero.
The force it would carry sticking is the four corners' least-norm load again (the state has not
moved), back inside its cone when ``a`` falls through ``a*`` at ``t2 = t_c + sqrt((1 - a*)/K)``:
there it sticks. Before the fix it slid on (friction saturated, slip zero) to the end.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from scipy.optimize import brentq

import contactdiff as cd

P = cd.CubeParameters()
B, MASS, G = P.edge / 2, P.mass, P.gravity
MU = 0.5
F0 = np.array([0.6, 0.25, 0.0]) * MU * MASS * G
TAU0 = 0.6 * MU * MASS * G * B
T_C, K = 0.05, 200.0
T_FINAL = 0.075  # s: past the stick (t2 = 0.066 s)
CORNERS = {f"cube/{sx}x{sy}y-z": np.array([float(sx + "1") * B, float(sy + "1") * B, -B]) for sx in "+-" for sy in "+-"}
# steps of at most 1 ms: at rest the steps' error estimates vanish, and a step over the whole
# rise of the push would not end near the cone's threshold (`guards.NEAR_FRACTION`)
OPTS = dict(max_step=1e-3)


def wrench(q, a):
    """The push of amplitude ``a`` in the free flyer's local frame (N, N m)."""
    R = pin.Quaternion(q[3:7]).matrix()
    force = a * F0
    moment = np.cross(R @ np.array([0.0, 0.0, -B]), force) + np.array([0.0, 0.0, a * TAU0])
    return np.r_[R.T @ force, R.T @ moment]


def pushed_cube() -> cd.Scene:
    push = cd.UserEffort(
        lambda q, v, t: wrench(q, 1.0 - K * (t - T_C) ** 2),
        name="push",
        time_derivative=lambda q, v, t: wrench(q, -2.0 * K * (t - T_C)),
    )
    base = cd.cube_scene(friction=MU, restitution=0.0)
    scene = cd.Scene(base.robot, base.contact_specs, efforts=[push])
    return scene.with_state(np.r_[0.0, 0.0, B, 0.0, 0.0, 0.0, 1.0], np.zeros(6))


def cone_margins(a: float) -> dict[str, float]:
    """Each bottom corner's cone margin (N) under the least-norm load at amplitude ``a`` (module doc)."""
    E = np.zeros((6, 12))
    for i, p in enumerate(CORNERS.values()):
        E[:3, 3 * i : 3 * i + 3] = np.eye(3)
        E[3:, 3 * i : 3 * i + 3] = np.array([[0.0, -p[2], p[1]], [p[2], 0.0, -p[0]], [-p[1], p[0], 0.0]])
    force = a * F0 - np.array([0.0, 0.0, MASS * G])
    moment = np.cross([0.0, 0.0, -B], a * F0) + np.array([0.0, 0.0, a * TAU0])
    f = (np.linalg.pinv(E) @ -np.r_[force, moment]).reshape(4, 3)
    return {name: MU * fi[2] - float(np.hypot(fi[0], fi[1])) for name, fi in zip(CORNERS, f)}


def threshold(name: str) -> float:
    """The amplitude ``a*`` where corner ``name``'s cone margin reaches 0 (module doc)."""
    return brentq(lambda a: cone_margins(a)[name], 0.0, 10.0, xtol=1e-15)


def test_the_held_slip_sticks_when_its_sticking_force_is_back_in_the_cone():
    """Events: the +x-y corner slips at t1 and sticks at t2 (module doc), no other event; the
    cube ends at rest where it started, every corner sticking.

    Tolerances. a* is a root of the least-norm margins to ~1e-15; the times depend on it through
    sqrt((1 - a*)/K), whose derivative 1/(2 K sqrt((1 - a*)/K)) = 0.16 s keeps that below 1e-15 s.
    The run's guards are the cube's forces at a state that only carries round-off (~1e-16 m), and
    margins of ~0.5 N computed to ~1e-16 N over their rate ~3 N/s (dmargin/da ≈ 0.5 N times
    |da/dt| = 2 K sqrt((1 - a*)/K) = 6.4 /s): ~1e-16 s. 1e-12 s keeps a wide margin, and tells a
    stick at t2 from any other (the push's window is 32 ms long)."""
    a_star = threshold("cube/+x-y-z")
    assert a_star < 1.0 < min(threshold(n) for n in CORNERS if n != "cube/+x-y-z")
    half = np.sqrt((1.0 - a_star) / K)
    traj = cd.simulate(pushed_cube(), T_FINAL, **OPTS)
    assert [(e.kind, e.contacts) for e in traj.events] == [
        (cd.EventKind.SLIP, ("cube/+x-y-z",)),
        (cd.EventKind.STICK, ("cube/+x-y-z",)),
    ]
    assert traj.events[0].t == pytest.approx(T_C - half, abs=1e-12)
    assert traj.events[1].t == pytest.approx(T_C + half, abs=1e-12)
    assert traj.segments[-1].sliding == ()
    assert set(traj.segments[-1].mode) == set(CORNERS)
    # at rest where it started: the state carries round-off only (a few 1e-16 m, rad, m/s)
    assert np.allclose(traj.q, pushed_cube().q0, rtol=0.0, atol=1e-12)
    assert np.allclose(traj.v, 0.0, rtol=0.0, atol=1e-12)


def test_the_stick_event_time_and_flow_jacobian_against_central_differences():
    """The flow Jacobian's columns of a shift along x and a turn about the vertical (the state's
    tangent directions that keep the face on the ground at rest), and both events' time
    gradients along them, against central differences of runs from the perturbed starts.

    A shift along x moves neither event (the push does not depend on x): time gradient 0, and the
    column is the unit shift. A turn by ψ turns the corners under the world-fixed push: a* and so
    t1, t2 move, with ``∂t2/∂ψ = -∂t1/∂ψ`` (a(t) is symmetric about t_c), and the column is the
    unit turn (the cube stays at rest).

    Tolerance. ε = 1e-6: each run's event times carry ~1e-16 s of round-off (first test) and its
    final state ~1e-16, so the differences' noise is ~2e-16 / 2ε = 1e-10; their truncation,
    ε² |t'''| / 6, is ~1e-13 for the O(1) third derivatives of sqrt((1 - a*(ψ))/K) here. The
    gradients are 0 or ~0.014 s/rad and the columns O(1): 1e-8 absolute is a 100x margin over the
    noise, while a saltation term or a time gradient off by a share of 1e-6 would show."""
    scene = pushed_cube()
    traj = cd.simulate(scene, T_FINAL, jacobian=True, **OPTS)
    kinds = [(e.kind, e.contacts) for e in traj.events]
    eps = 1e-6
    for column in (0, 5):  # tangent coordinates of the free flyer: x, then the turn about local z
        runs = []
        for sign in (1.0, -1.0):
            dq = np.zeros(6)
            dq[column] = sign * eps
            run = cd.simulate(scene.with_state(pin.integrate(scene.model, scene.q0, dq), np.zeros(6)), T_FINAL, **OPTS)
            assert [(e.kind, e.contacts) for e in run.events] == kinds
            runs.append(run)
        plus, minus = runs
        fd_state = np.r_[pin.difference(scene.model, minus.q, plus.q), plus.v - minus.v] / (2 * eps)
        fd_times = np.array([a.t - b.t for a, b in zip(plus.events, minus.events)]) / (2 * eps)
        assert np.allclose(traj.jacobian[:, column], fd_state, rtol=0.0, atol=1e-8)
        gradients = np.array([e.time_gradient[column] for e in traj.events])
        assert np.allclose(gradients, fd_times, rtol=0.0, atol=1e-8)
    turn = np.array([e.time_gradient[5] for e in traj.events])
    assert abs(turn[0]) > 1e-3 and turn[1] == pytest.approx(-turn[0], abs=1e-8)
    assert all(e.differentiable for e in traj.events)


def test_the_stick_event_time_moves_with_the_corners_friction_as_central_differences_say():
    """The events' time gradients in the slipping corner's μ (the parameters' block of the stick
    event, whose guard's cone grows with μ: ``∂h/∂μ = -λ_N`` at fixed forces) and in another
    corner's μ (which moves neither guard: 0), against central differences of runs at μ ± ε.
    ``∂t2/∂μ = -∂t1/∂μ`` (a(t) is symmetric about t_c).

    Tolerance: as for the state's columns (previous test): the differences' noise is ~1e-10 with
    ε = 1e-6, their truncation ~1e-13; the gradients are 0 or ~0.3 s: 1e-8 absolute."""
    scene = pushed_cube()
    names = ["contact:cube/+x-y-z:friction", "contact:cube/+x+y-z:friction"]
    traj = cd.simulate(scene, T_FINAL, parameters=names, **OPTS)
    kinds = [(e.kind, e.contacts) for e in traj.events]
    eps = 1e-6
    for j, name in enumerate(names):
        value = float(scene.parameter_values([name])[0])
        runs = [cd.simulate(scene.with_parameters({name: value + s * eps}), T_FINAL, **OPTS) for s in (1.0, -1.0)]
        assert all([(e.kind, e.contacts) for e in run.events] == kinds for run in runs)
        fd = np.array([a.t - b.t for a, b in zip(runs[0].events, runs[1].events)]) / (2 * eps)
        gradients = np.array([e.parameter_time_gradient[j] for e in traj.events])
        assert np.allclose(gradients, fd, rtol=0.0, atol=1e-8)
    own = [e.parameter_time_gradient[0] for e in traj.events]
    assert abs(own[0]) > 1e-2 and own[1] == pytest.approx(-own[0], abs=1e-8)
