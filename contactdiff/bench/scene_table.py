"""What the benchmark runs (`contactdiff.bench.runner`): its scenes with their
horizons, the tolerance and step sweeps of each method (full and quick), and the
tolerances of its derivative runs."""

from __future__ import annotations

from collections.abc import Callable

import pinocchio as pin

from ..model.scene import Scene
from ..paper import trot_touchdown
from ..scenes.scene_file import load_scene

# name -> (builder, t_final)
SCENES: dict[str, tuple[Callable[[], Scene], float]] = {
    "ball": (lambda: load_scene("ball"), 5.2),
    "two_limb": (lambda: load_scene("two_limb"), 2.0),
    "planar_trot_soft": (lambda: load_scene("planar_trot_soft"), 1.8),
    "planar_trot_rigid": (lambda: trot_touchdown("rigid", 0.05), 1.6),  # off-centre
    "solo12_tilted": (lambda: solo12_tilted(), 0.112),  # three single-foot touchdowns
    "solo12_trot": (lambda: _solo12_trot(), 0.05),  # controlled stance of the trot, no event
}


def _solo12_trot() -> Scene:
    from ..control.trot_scenes import trot_scene  # the trot's robot table loads only when benchmarked

    return trot_scene("solo12")


def solo12_tilted() -> Scene:
    """solo12_drop with the base rolled 0.03 rad, pitched 0.05 rad and raised 1 cm:
    the feet land one at a time (FR at t ≈ 0.0964, FL at ≈ 0.1068, FR again 8 µs
    later), so the flow is differentiable, unlike the symmetric four-foot landing
    of solo12_drop whose landing orders differ."""
    scene = load_scene("solo12_drop")
    q = scene.q0.copy()
    roll, pitch = 0.03, 0.05  # rad; base quaternion (x, y, z, w) of R = Rx(roll) Ry(pitch)
    rot = pin.utils.rpyToMatrix(roll, pitch, 0.0)
    q[3:7] = pin.Quaternion(rot).coeffs()
    q[2] += 0.01
    return scene.with_state(q)


FULL_SWEEP = {
    "ours-DOP853": [1e-3, 1e-4, 1e-6, 1e-8, 1e-10, 1e-12],
    "ours-Radau": [1e-4, 1e-6, 1e-8, 1e-10],
    "solve_ivp-DOP853": [1e-3, 1e-4, 1e-6, 1e-8, 1e-10, 1e-12],
    "time-stepping": [1e-2, 3e-3, 1e-3, 3e-4, 1e-4],
}


QUICK_SWEEP = {
    "ours-DOP853": [1e-6, 1e-9],
    "ours-Radau": [1e-6],
    "solve_ivp-DOP853": [1e-6, 1e-9],
    "time-stepping": [1e-2, 3e-3],
}


QUICK_SCENES = ("ball", "planar_trot_rigid")


FULL_DERIV_TOL = dict(rtol=1e-12, atol=1e-13)


QUICK_DERIV_TOL = dict(rtol=1e-9, atol=1e-10)
