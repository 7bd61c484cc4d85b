"""Two rules of the hybrid loop for contacts that close or open with no speed.

* A contact that opens with no separating speed and then sinks (it never rises
  above the ground) touches down again; it must not be skipped for want of a
  peak and left to fall through the ground.
* The Zeno rule for impact cascades: a closed contact that an impact elsewhere
  would lift slower than ``zeno_speed`` stays closed, its separating speed
  removed M-orthogonally.

References: a closed form (the unloaded ball) and the plastic-impact law with
both feet held (the M-orthogonal projection of the pre-impact velocity).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

import contactdiff as cd


def test_a_contact_opening_with_no_speed_that_sinks_touches_down_again():
    """A unit mass at rest on the ground under g = 1 and an upward force 1 - t (N): its
    acceleration -t is zero at t = 0, so it starts released (nothing pushes it into the
    ground) and then sinks as -t³/6. It must touch down at once (within the closed
    band 1e-12 m, i.e. by t = (6e-12)^(1/3) ≈ 2e-4 s, allowing for the step) and rest:
    without the rule it would fall through to z(1) = -1/6."""
    base = cd.load_scene("ball")
    unloading = cd.UserEffort(lambda q, v, t: np.array([1.0 - t]), name="unloading")
    scene = cd.Scene(base.robot, [cd.Contact("ball")], [unloading], gravity=[0, 0, -1], q0=[0.0])
    traj = cd.simulate(scene, 1.0, rtol=1e-10, atol=1e-12)
    assert [e.kind for e in traj.events] == ["touchdown"]
    assert traj.events[0].t < 1e-3
    assert traj.modes[-1] == ("ball",)
    z, _ = traj.sample(np.linspace(0.0, 1.0, 201))
    assert z.min() > -1e-9  # never through the ground (m)
    assert abs(traj.q[0]) < 1e-9 and abs(traj.v[0]) < 1e-9


def _front_touchdown(zeno_speed: float):
    """The rigid trot at pitch 0.05 (frictionless, plastic): the rear foot lands first and
    the body pivots on it until the front foot lands; run just past that touchdown."""
    scene = cd.trot_touchdown("rigid", 0.05)
    traj = cd.simulate(scene, 2.0, rtol=1e-10, atol=1e-12, zeno_speed=zeno_speed)
    front = next(e for e in traj.events if "front_foot" in e.contacts)
    return scene, front


def test_impact_lifting_a_foot_slowly_keeps_it_closed_under_the_cascade_rule():
    scene, front = _front_touchdown(zeno_speed=1e-6)
    # the front impact lifts the rear foot (the body pivots onto the front foot)
    assert "rear_foot" in front.mode_before and "rear_foot" not in front.mode_after
    model, data = scene.model, scene.model.createData()
    pin.computeJointJacobians(model, data, front.q)
    pin.updateFramePlacements(model, data)
    A = np.array([pin.getFrameJacobian(model, data, model.getFrameId(f), pin.LOCAL_WORLD_ALIGNED)[2]
                  for f in ("rear_foot", "front_foot")])
    lift = float(A[0] @ front.v_plus)  # rear foot's separating speed (m/s)
    assert lift > 1e-3

    # with zeno_speed above that speed, the rear foot stays: both feet held
    _, held = _front_touchdown(zeno_speed=10 * lift)
    assert held.mode_after == ("rear_foot", "front_foot")
    assert not held.differentiable  # the rule's cut-off is not smooth
    # plastic impact with both feet held = M-orthogonal projection of v- onto A v = 0
    Minv = pin.computeMinverse(model, data, held.q)
    Minv = np.triu(Minv) + np.triu(Minv, 1).T
    W = Minv @ A.T @ np.linalg.inv(A @ Minv @ A.T)
    expected = held.v_minus - W @ (A @ held.v_minus)
    assert np.allclose(held.v_plus, expected, atol=1e-12)
    assert np.allclose(A @ held.v_plus, 0.0, atol=1e-12)
