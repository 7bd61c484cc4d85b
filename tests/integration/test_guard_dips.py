"""A force-level guard that crosses its threshold and comes back within one step is found
(`contactdiff.integration.guards.GuardFinder._dip`), as a gap's dip is.

The scene: the point mass ``block3`` (m = 2 kg, `coulomb_models`) at rest on flat ground with
one Coulomb contact (μ = 0.5), pushed along +x by

    f(t) = μ m g + A - k (t - t_c)²,   k = A / w²,

a parabola that exceeds the stick threshold μ λ_N = μ m g (the normal force is m g: no vertical
effort) by at most A = 3e-6 N, at t_c = 5 ms, on the window |t - t_c| < w = 85 µs only. At rest
the state does not move, so the steps' error estimates vanish and the steps grow to milliseconds:
before the fix no step ended inside the window and the block never slipped (it did with
``max_step=1e-5``).

Closed forms. The sticking force is ``λ_T = -f`` (the block at rest), so the cone margin
``h = μ m g - f = k (t - t_c)² - A`` reaches 0 downward at ``t1 = t_c - w``: there the block slips
from rest along +x (the direction its sticking force resisted). While slipping, friction is
``-μ m g`` along +x (below the slip-speed floor ε the direction is the onset's, +x, also past the
stop, `contactdiff.dynamics.slip`), so with s = t - t_c

    m u(s) = ∫_{-w}^{s} (A - k σ²) dσ = A (s + w) - (k / 3)(s³ + w³),

which peaks at s = w (1.7e-10 m/s, below ε = zeno_speed = 1e-6 m/s), returns to 0 at s = 2w and
goes negative as f keeps falling. A slip from rest fires its stop past -ε (`GuardFinder`), so it
sticks at the root s_s > w of ``A (s + w) - (k/3)(s³ + w³) + m ε = 0`` (a cubic: `numpy.roots`),
and stays stuck: after it f < μ m g for the rest of the run.
"""

from __future__ import annotations

import numpy as np
import pytest
from coulomb_models import MASS, MU, G

import contactdiff as cd

A, W, T_C = 3e-6, 8.5e-5, 5e-3  # N, s, s
K = A / W**2  # N/s²
T_FINAL = 0.01  # s: the push stays below the threshold after the window (f(t_final) = μ m g - 0.0104 N)
EPS = cd.SimulateOptions().zeno_speed  # m/s, the slip-speed floor


def pushed_block(block3, peak):
    """``block3`` at rest on the ground under the push of the module doc, ``peak`` (N) in place of A."""
    k = abs(peak) / W**2

    def push(q, v, t):
        return np.array([MU * MASS * G + peak - k * (t - T_C) ** 2, 0.0, 0.0])

    def push_rate(q, v, t):
        return np.array([-2.0 * k * (t - T_C), 0.0, 0.0])

    effort = cd.UserEffort(
        push, lambda q, v, t: (np.zeros((3, 3)), np.zeros((3, 3))), name="push", time_derivative=push_rate
    )
    return cd.Scene(
        block3, [cd.Contact("block", friction=MU)], [effort], gravity=[0, 0, -G], q0=np.zeros(3), v0=np.zeros(3)
    )


def stop_time() -> float:
    """The root ``t_c + s_s`` of the module doc's cubic in ``s`` with ``s_s > w``."""
    roots = np.roots([-K / 3.0, 0.0, A, A * W - K * W**3 / 3.0 + MASS * EPS])
    return T_C + max(r.real for r in roots if abs(r.imag) < 1e-12 and r.real > W)


@pytest.mark.parametrize("max_step", [np.inf, 1e-3])
def test_a_push_over_the_threshold_between_step_ends_starts_the_slip(block3, max_step):
    """The slip starts at t1 = t_c - w and stops at the closed form's stop (module doc), with
    steps (default: unbounded) far longer than the window.

    Tolerances. t1 is the root of the cone margin, computed from forces of ~μ m g = 9.8 N with
    round-off ~1e-15 N, over its rate 2 k w = 2 A / w = 0.07 N/s: ~1e-14 s; 1e-12 s keeps a 100x
    margin, while the window's half-width is 8.5e-5 s. The stop: the slip's acceleration
    (f - μ m g)/m is a quadratic in t, which every stepper's order (>= 3) integrates exactly (the
    error estimates vanish, hence the long steps), so u carries round-off only, ~1e-15 N / m over
    the 2.4 ms of the slip: < 1e-17 m/s; over the stop's rate (f - μ m g)/m = -1.2e-3 m/s² that
    is < 1e-14 s, and its location to full precision in time adds ~1e-18 s: 1e-12 s keeps a 100x
    margin and tells the stop at -ε from one at u = 0 (at t_c + 2w, 2.3 ms earlier)."""
    traj = cd.simulate(pushed_block(block3, A), T_FINAL, max_step=max_step)
    assert [e.kind for e in traj.events] == [cd.EventKind.SLIP, cd.EventKind.STICK]
    assert traj.stats.steps < 100  # the steps do not resolve the window: the guard's model does
    assert traj.events[0].t == pytest.approx(T_C - W, abs=1e-12)
    assert traj.events[1].t == pytest.approx(stop_time(), abs=1e-12)


def test_a_push_under_the_threshold_starts_no_slip(block3):
    """The same push with its peak A below the threshold instead, ``f = μ m g - A - k (t - t_c)²``:
    the cone margin ``A + k (t - t_c)²`` stays positive, so the search of the guard's model (which
    runs: the margin ends steps within a tenth of the cone) finds no crossing, and the block stays
    at rest (no event; x exactly 0: a sticking contact holds it)."""
    traj = cd.simulate(pushed_block(block3, -A), T_FINAL)
    assert traj.events == []
    assert np.all(traj.q == 0.0) and np.all(traj.v == 0.0)


def test_a_pull_over_the_weight_between_step_ends_lifts_the_block_off(block3):
    """A normal force's dip: the frictionless block at rest pulled up by
    ``f_z = m g + A_z - k (t - t_c)²`` (A_z = 0.1 N, w_z = 2 ms, k = A_z / w_z²) on a contact of the
    same block: its normal force ``m g - f_z = k (t - t_c)² - A_z`` (at rest the contact carries the
    rest of the weight) reaches 0 at ``t_c - w_z``, where it lifts off; in flight
    ``m z'' = A_z - k s²`` (s = t - t_c), so from z = z' = 0 at s = -w_z

        m z(s) = A_z (s + w_z)²/2 - (k/3) [(s⁴ - w_z⁴)/4 + w_z³ (s + w_z)],

    which factors as ``-(k/12)(s + w_z)³ (s - 3 w_z)``: it lands at ``t_c + 3 w_z`` with
    ``m z' = -(16/3) A_z w_z`` (5.3e-4 m/s), far above the grazing speed. Before the fix the
    steps (4 of them over 20 ms) stepped over the whole pulse: no event.

    Tolerances (rtol = atol = 1e-12, which the steps before the fix stepped over too). The lift-off
    is the root of a force computed to ~1e-15 of m g = 19.6 N (2e-14 N) over its rate
    2 k w_z = 100 N/s: ~1e-16 s; 1e-12 s keeps a wide margin. The landing: the gap carries at most
    the steps' error bound, atol + rtol |q| ≈ 1e-12 m per step (|q| < 1e-6 m) over < 10 steps,
    over the landing speed 5.3e-4 m/s: < 2e-8 s; 1e-7 s, while the pulse lasts 4 ms."""
    a_z, w_z = 0.1, 2e-3
    k = a_z / w_z**2

    def pull(q, v, t):
        return np.array([0.0, 0.0, MASS * G + a_z - k * (t - T_C) ** 2])

    def pull_rate(q, v, t):
        return np.array([0.0, 0.0, -2.0 * k * (t - T_C)])

    effort = cd.UserEffort(
        pull, lambda q, v, t: (np.zeros((3, 3)), np.zeros((3, 3))), name="pull", time_derivative=pull_rate
    )
    scene = cd.Scene(block3, [cd.Contact("block")], [effort], gravity=[0, 0, -G], q0=np.zeros(3), v0=np.zeros(3))
    traj = cd.simulate(scene, 0.02, rtol=1e-12, atol=1e-12)
    assert [e.kind for e in traj.events] == [cd.EventKind.LIFT_OFF, cd.EventKind.TOUCHDOWN]
    assert traj.stats.steps < 100
    assert traj.events[0].t == pytest.approx(T_C - w_z, abs=1e-12)
    assert traj.events[1].t == pytest.approx(T_C + 3.0 * w_z, abs=1e-7)
