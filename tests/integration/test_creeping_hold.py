"""A frictional impact whose slips end below the creeping limit: the reset holds them, and its
Jacobian holds them too.

A cube lands flat on its face with e = 0 and a horizontal speed ``v_x`` just above what the
face's friction impulse stops: ``μ |v_z|`` (the four corners' normal impulses total
``m |v_z|``, their friction at most ``μ`` of it, and a face landing with symmetric loads
turns nothing), so each corner slides on at ``v_x - μ |v_z|`` = 5e-6 m/s, between the
slip-speed floor (1e-6 m/s) and the creeping limit (10 floors). Such slips are held
(`held_velocity` of the creeping corners), which leaves the cube at rest: every
perturbation that keeps them creeping ends at rest too, so the reset's velocity block is
zero. Before the hold entered the reset's Jacobian, that block was the impact's own
(``dv_x+ / dv_x- = 1``).
"""

from __future__ import annotations

import numpy as np

import contactdiff as cd

MU, VZ = 0.18, -0.5  # the cube's μ; the landing's normal speed (m/s)
SLIP_AFTER = 5e-6  # m/s: between the floor (1e-6) and the creeping limit (1e-5)
EPS = 1e-9  # m/s, rad/s: moves each corner's slip by at most ~1e-10 m/s, inside the band


def _start(v0: np.ndarray):
    half = cd.CubeParameters().edge / 2
    q0 = np.r_[0.0, 0.0, half, 0.0, 0.0, 0.0, 1.0]  # on its face, the bottom corners at zero gap
    scene = cd.cube_scene(restitution=0.0).with_state(q0, v0)
    loop = cd.HybridLoop(scene, 0.0, 1.0, options=cd.SimulateOptions(jacobian=True))
    mode, v_after = loop.initial_mode(scene.q0.copy(), scene.v0.copy())
    return loop, mode, v_after


def test_creeping_slips_after_an_impact_are_held_in_the_reset_and_its_jacobian():
    v0 = np.r_[MU * abs(VZ) + SLIP_AFTER, 0.0, VZ, 0.0, 0.0, 0.0]
    loop, mode, v_after = _start(v0)
    names = loop.scene.contact_names
    bottom = sorted(i for i, n in enumerate(names) if n.endswith("-z"))
    assert sorted(mode) == bottom  # all four sticking: held, not sliding
    np.testing.assert_allclose(v_after, 0.0, atol=1e-15)  # m/s: round-off of the projection
    event = loop.events[-1]
    assert event.differentiable and event.saltation is not None
    nv = loop.scene.nv
    # central differences of the velocity after the start's impact in every velocity direction
    fd = np.empty((nv, nv))
    for j in range(nv):
        step = np.zeros(nv)
        step[j] = EPS
        fd[:, j] = (_start(v0 + step)[2] - _start(v0 - step)[2]) / (2 * EPS)
    np.testing.assert_allclose(fd, 0.0, atol=1e-6)  # every perturbation ends at rest (round-off / EPS)
    # the reset's Jacobian (the saltation of a start, which has no guard): its velocity block
    np.testing.assert_allclose(event.saltation[nv:, nv:], fd, atol=1e-6)
