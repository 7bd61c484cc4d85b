"""A face sliding to its stop whose corners stop within the slip-speed floor of each
other: the stop of one holds them all (`contactdiff.integration.friction_events`,
"Slips at rest stop together"), and the face sticks at once instead of creeping.

The start state is the measured cube (`contactdiff.cube_scene`, nominal μ and e) of
the first shipped toss run to t = 0.7858 s at rtol 1e-12: flat on its face (body +y
up, the four -y corners on the board), sliding at |v_c| = 6.0e-5 m/s and spinning
about the vertical at ω = 9.6e-6 rad/s. Each bottom corner at horizontal distance
r = b√2 from the centre slips at u_i = v_c + ω × p_i, within r|ω| = 7e-7 m/s of the
centre's velocity: below the slip-speed floor ε = ``zeno_speed`` (1e-6 m/s), so
which corner stops first, and the direction each one slips in at its stop, are
within the integration's noise.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import contactdiff as cd

P = cd.CubeParameters()
B, MU, G = P.edge / 2, P.friction, P.gravity
BOTTOM = {f"cube/{sx}x-y{sz}z" for sx in "+-" for sz in "+-"}
Q0 = np.array(
    [
        -0.22107589133449765,
        -0.1497725295242975,
        0.05239999999999952,
        0.3980661684967139,
        0.5844170817989068,
        0.5844170817988995,
        0.39806616849671367,
    ]
)
V0 = np.array(
    [
        -1.5885077365243404e-05,
        -2.4686696552472203e-15,
        -5.785621171452908e-05,
        2.139044965932445e-14,
        9.561341573460782e-06,
        -2.496243925920878e-14,
    ]
)
EPS = cd.SimulateOptions().zeno_speed  # m/s, the slip-speed floor


@pytest.mark.parametrize("tolerances", [{}, {"rtol": 1e-10, "atol": 1e-12}])
def test_face_slipping_below_the_floor_sticks_at_once(tolerances):
    """The cube's slide stops in a time fixed by μ g, and it then sticks for good.

    Stop time: the four bottom corners' normal loads sum to m g (the face stays on the
    board: no vertical acceleration of the centre), so the friction force on the body
    is at most μ m g and the centre's speed falls at most at μ g; a pure slide falls at
    exactly μ g (`test_face_friction`), and the friction of a translating face has no
    moment about the vertical through the centre (its load shift lies along the slide),
    so the spin changes each corner's slip by at most r|ω0| to first order. A corner
    stops when u_i = 0, so the first stop lies in
    [(|v_c0| - r|ω0|) / (μ g), (|v_c0| + r|ω0|) / (μ g)], and the stop that holds the
    others, whose slips are then below ε, shortens their slide by at most ε / (μ g):
    every corner sticks within [(|v_c0| - r|ω0| - ε), (|v_c0| + r|ω0| + ε)] / (μ g)
    of the start (3.30e-5 .. 3.50e-5 s). The integration's error in these times is
    ~rtol (1e-6 at the defaults) of them, below the window's width.

    Rest: on a level face at rest the sticking forces balance gravity alone, purely
    normal and strictly inside the cone, so the face stays stuck: no event follows and
    the velocity stays zero (to the state's round-off and the integration tolerance,
    far below the 6e-5 m/s it started with). Before the floor held the slow corners,
    the last corner crept in the band [ε, 2ε] until 0.19 s (defaults) or past 0.2 s
    (rtol 1e-10).
    """
    scene = cd.cube_scene().with_state(Q0, V0)
    rotation = pin.Quaternion(Q0[3:7]).matrix()
    assert rotation[:, 1] == pytest.approx([0.0, 0.0, 1.0], abs=1e-12)  # body +y up: on the -y face
    v_c = np.hypot(*(rotation @ V0[:3])[:2])
    spin = abs((rotation @ V0[3:])[2])
    r = B * np.sqrt(2.0)
    earliest = (v_c - r * spin - EPS) / (MU * G)
    latest = (v_c + r * spin + EPS) / (MU * G)
    # 200 steps: at rest the run steps to t_final at once; the creep took thousands
    traj = cd.simulate(scene, 0.2, max_steps=200, **tolerances)
    friction = [e for e in traj.events if e.kind in ("stick", "slip")]
    assert friction and friction[-1].kind == "stick"
    assert earliest <= friction[0].t and friction[-1].t <= latest
    last = traj.events[-1]
    assert set(last.mode_after) == BOTTOM and not last.sliding
    assert set().union(*(e.contacts for e in friction)) == BOTTOM
    # at rest from the stop: velocities of round-off and tolerance size (vs 6e-5 m/s)
    np.testing.assert_allclose(traj.v, 0.0, atol=1e-9)
