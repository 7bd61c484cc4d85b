"""Slips that started from rest while the mode holds them at zero: their stop guard
must not fire on round-off (`contactdiff.integration.guards.GuardFinder.keep_resting`).

The scene: the cube flat on its face (μ = 1.5, e = 0) under a push fixed in the world
frame, ``f = (0.8 - t/s) m g (cos 0.6, sin 0.6, 0)`` at the centre, and a torque about the
world vertical ``τ_z = 18 t² N m/s²``. The trailing corner, released at the start (its
compatible load would pull), bears again at t ≈ 0.081 s slipping from rest, and a second
corner's sticking force reaches its cone at t ≈ 0.085 s: it slips from rest too. Two
corners still stick, and two sticking points of a
face fix its planar motion: the slipping corners' slip stays at round-off (1e-17 m/s)
until a third corner's cone is reached (t ≈ 0.112 s) and the face turns.

The scene does not change under a shift of the world x axis, so runs from states
shifted by δ along x are the same run shifted by δ: the same events at the same times,
and final states that differ by δ e_x only. Before the fix a round-off slip's stop fired
whenever round-off changed sign within a step (from δ = 1e-5 m: six stop events at
0.099 - 0.113 s, none at δ = 0, each resetting the slip's reference at a time set by the
last bits of the state), so a central difference in x missed the flow Jacobian's column,
the unit shift, by 1.3e-3 in the final yaw.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

import contactdiff as cd

P = cd.CubeParameters()
B, MASS, G = P.edge / 2, P.mass, P.gravity
DIRECTION = np.array([np.cos(0.6), np.sin(0.6), 0.0])
T = 0.125  # s: past the turn of the face (t ≈ 0.112 s) and its last corner's slip (0.122 s)
OPTS = dict(rtol=1e-10, atol=1e-12, max_step=1e-3)


def push(q, v, t):
    """The world-frame push and torque, in the free flyer's local frame (N, N m)."""
    R = pin.Quaternion(q[3:7]).matrix()
    return np.r_[R.T @ ((0.8 - t) * MASS * G * DIRECTION), R.T @ np.array([0.0, 0.0, 18.0 * t * t])]


def push_rate(q, v, t):
    """∂/∂t of `push` at fixed state."""
    R = pin.Quaternion(q[3:7]).matrix()
    return np.r_[R.T @ (-MASS * G * DIRECTION), R.T @ np.array([0.0, 0.0, 36.0 * t])]


def test_a_shift_along_x_gives_the_same_events_and_the_shifted_state():
    """Runs from x = 0 and x = ±1e-5 m: the same events (kind, contacts) at times within
    1e-9 s, and final states equal after the shift.

    Tolerance: the runs integrate the same equations with steps chosen from error
    estimates that differ only by round-off; each run's global error is at most a few
    hundred steps times the local bound atol + rtol |x| ≈ 1e-12 + 1e-10 · 0.05, i.e.
    below 1e-9 in metres, radians, m/s and rad/s, and event times located to full
    precision agree to that over the guards' rates (≥ 1 per second here). A stop on
    round-off moved the final yaw by 2e-8 rad and added events."""
    base = cd.cube_scene(friction=1.5, restitution=0.0)
    scene = cd.Scene(
        base.robot, base.contact_specs, efforts=[cd.UserEffort(push, name="push", time_derivative=push_rate)]
    )
    q0 = np.r_[0.0, 0.0, B, 0.0, 0.0, 0.0, 1.0]
    runs = {}
    for dx in (0.0, 1e-5, -1e-5):
        q = q0.copy()
        q[0] += dx
        runs[dx] = cd.simulate(scene.with_state(q, np.zeros(6)), T, **OPTS)
    ref = runs[0.0]
    assert any(e.kind is cd.EventKind.SLIP for e in ref.events)  # the corners do slip from rest
    for dx in (1e-5, -1e-5):
        run = runs[dx]
        assert [(e.kind, e.contacts) for e in run.events] == [(e.kind, e.contacts) for e in ref.events]
        assert np.allclose([e.t for e in run.events], [e.t for e in ref.events], rtol=0.0, atol=1e-9)
        q_back = run.q.copy()
        q_back[0] -= dx
        assert np.allclose(pin.difference(scene.model, ref.q, q_back), 0.0, rtol=0.0, atol=1e-9)
        assert np.allclose(run.v, ref.v, rtol=0.0, atol=1e-9)
