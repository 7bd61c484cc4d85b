"""A contact that touches at the final time: the verdict flags it (`NonSmooth.FINAL_TIME`),
and the final state's one-sided derivatives.

The scene: a ball of radius r dropped from rest at height z0 = r + h under gravity g
onto the ground (restitution e, frictionless). It lands at ``t1 = sqrt(2 h / g)`` at
speed ``s = g t1 = sqrt(2 g h)``. Run to ``T = t1`` it touches at the final time.

One-sided derivatives of ``z(T)`` in z0 at ``T = t1``: from higher up (z0 + δ) the
ball has not landed by T and ``z(T) = z0 - g T²/2``: the right derivative is 1. From
lower down it landed at ``t1(h) < T`` and rose for ``τ = T - t1`` at ``e s``:
``z(T) = r + e s τ - g τ²/2``; with ``ds/dh = g/s`` and ``dt1/dh = 1/s``,
``dz(T)/dh = (1 + e) g τ / s - e``, which is ``-e`` at ``τ = 0``: the left derivative.
Its second derivative there is ``-(1 + e) g / s² = -(1 + e) / (2 h)``.
"""

import math

import pytest

from contactdiff import NonSmooth, simulate
from contactdiff.model.contacts import Contact
from contactdiff.model.objects import SceneObject, add_objects, empty_robot
from contactdiff.model.scene import Scene

R, H, G, E = 0.1, 1.0, 9.81, 0.8
T_LAND = math.sqrt(2.0 * H / G)
S_LAND = G * T_LAND
RTOL, ATOL = 1e-12, 1e-13


def _drop(z0: float, horizon: float):
    robot = add_objects(
        empty_robot(), [SceneObject("ball", shape="sphere", radius=R, mass=1.0, position=(0.0, 0.0, z0))]
    )
    scene = Scene(robot, [Contact("ball", restitution=E, name="ground")], gravity=(0.0, 0.0, -G), name="drop")
    return simulate(scene, horizon, jacobian=True, rtol=RTOL, atol=ATOL)


def test_a_landing_at_the_final_time_is_flagged():
    """At T = t1 the verdict is not differentiable with `NonSmooth.FINAL_TIME` (its remark in
    the notes and in ``why_not_differentiable``); no event has a reason of its own."""
    traj = _drop(R + H, T_LAND)
    assert not traj.differentiable
    assert set(traj.final_nonsmooth) == {NonSmooth.FINAL_TIME}
    remark = traj.final_nonsmooth[NonSmooth.FINAL_TIME]
    assert "ground" in remark and remark in traj.notes and traj.why_not_differentiable() == [remark]
    assert all(e.differentiable for e in traj.events)
    assert traj.summary()["final_nonsmooth"] == {"final_time": remark}


@pytest.mark.parametrize("shift", [-1e-6, 1e-6])
def test_a_landing_a_microsecond_from_the_final_time_is_not_flagged(shift):
    """At T = t1 ± 1e-6 s the landing is 1e-6 s after or before T, a thousand times
    ``simultaneous_tol`` (1e-9 s): differentiable, and the Jacobian is the closed form's
    (module doc: 1 before the landing, (1 + e) g τ / s - e with τ = 1e-6 s after it),
    within 1e-9 (the variational equation at rtol 1e-12 over O(1) growth, with margin)."""
    traj = _drop(R + H, T_LAND + shift)
    assert traj.differentiable and not traj.final_nonsmooth
    assert len(traj.events) == (1 if shift > 0 else 0)
    exact = 1.0 if shift < 0 else (1.0 + E) * G * shift / S_LAND - E
    assert traj.jacobian[2, 2] == pytest.approx(exact, abs=1e-9)


def test_one_sided_derivatives_at_the_final_time_against_finite_differences():
    """One-sided differences of the final height at T = t1 with step δ = 1e-5 m: the
    right one is 1 (z(T) is linear in z0 there), the left one -e (module doc), each within
    1e-5: the left difference's truncation is δ |z''| / 2 = δ (1 + e) / (4 h) = 4.5e-6, and the
    runs' position error (rtol 1e-12 on O(1) m, x100 for its growth over the run: 1e-10 m)
    over δ adds 1e-5 at most. The run's own Jacobian is one of the two, the one of the side
    its remark names."""
    delta = 1e-5

    def z_final(z0):
        return _drop(z0, T_LAND).q[2]

    z_mid = z_final(R + H)
    right = (z_final(R + H + delta) - z_mid) / delta
    left = (z_mid - z_final(R + H - delta)) / delta
    assert right == pytest.approx(1.0, abs=1e-5)
    assert left == pytest.approx(-E, abs=1e-5)
    traj = _drop(R + H, T_LAND)
    remark = traj.final_nonsmooth[NonSmooth.FINAL_TIME]
    side = -E if "has landed" in remark else 1.0
    assert "not landed yet" in remark or "has landed" in remark
    assert traj.jacobian[2, 2] == pytest.approx(side, abs=1e-9)


@pytest.mark.parametrize("shift", [-1e-10, 1e-10])
def test_a_landing_within_the_simultaneity_tolerance_of_the_final_time_is_flagged(shift):
    """At T = t1 ± 1e-10 s, a tenth of ``simultaneous_tol``: flagged either way. Before the
    landing (T < t1) the ball is open and closing at s = 4.4 m/s, 4.4e-10 m up, the Jacobian
    the right derivative 1; after it (T > t1) the bounce is an event 1e-10 s before T (located
    to ~1e-16 s), the Jacobian the left derivative (1 + e) g τ / s - e = -e + 4e-10; each
    within 1e-9, and the remark names its side."""
    traj = _drop(R + H, T_LAND + shift)
    assert not traj.differentiable
    remark = traj.final_nonsmooth[NonSmooth.FINAL_TIME]
    assert len(traj.events) == (1 if shift > 0 else 0)
    assert ("has landed" if shift > 0 else "not landed yet") in remark
    exact = 1.0 if shift < 0 else (1.0 + E) * G * shift / S_LAND - E
    assert traj.jacobian[2, 2] == pytest.approx(exact, abs=1e-9)
