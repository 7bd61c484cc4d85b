"""Task 5 of the gradient benchmark: a measured cube toss's final pose in μ and e.

The cube (`contactdiff.cube_scene`, eight Coulomb corners in group ``cube``) starts
at the first sample of toss ``toss_000`` and runs for `HORIZON` s, two bounces on
corners. The pose's derivative in the group's friction ``μ`` and restitution ``e``
has no closed form; its reference is a central difference of contactdiff's own
runs at tight tolerances (`cube_reference`), converged when two steps agree.
"""

from __future__ import annotations

import time

import numpy as np
import pinocchio as pin

from ..data.cube_tosses import cube_scene, load_tosses
from ..integration.hybrid import simulate
from ..model.scene import Scene
from .gradients import Run

TOSS = "toss_000"
"""The shipped toss the task starts from."""

HORIZON = 0.2
"""s: two corner bounces (t ≈ 0.083 s and 0.142 s), both differentiable."""

PARAMETERS = ("group:cube:friction", "group:cube:restitution")
"""The columns of the gradient: μ and e of the eight corners."""


def toss_scene() -> Scene:
    """The cube at the toss's first sample (nominal μ 0.18, e 0.125)."""
    return cube_scene().with_state(*load_tosses()[TOSS].state(0))


def contactdiff_cube(scene: Scene | None = None, rtol: float = 1e-12, atol: float = 1e-13) -> Run:
    """``d pose(T) / d(μ, e)`` (6 × 2, the pose's tangent at T: the centre's displacement and
    rotation in the cube's frame, Pinocchio's ``integrate``) from one run."""
    scene = toss_scene() if scene is None else scene
    start = time.perf_counter()
    traj = simulate(scene, HORIZON, jacobian=False, parameters=list(PARAMETERS), rtol=rtol, atol=atol)
    seconds = time.perf_counter() - start
    assert traj.parameter_jacobian is not None  # asked for (parameters)
    return Run(traj.parameter_jacobian[0:6].copy(), seconds, traj.differentiable, traj.q.copy(),
               traj.why_not_differentiable())


def pose_difference(scene: Scene, q_nominal: np.ndarray, q_plus: np.ndarray, q_minus: np.ndarray,
                    step: float) -> np.ndarray:
    """Central difference of two final poses in the tangent space at ``q_nominal``
    (``(q+ ⊖ q) - (q- ⊖ q)) / 2h``): second order in ``step``."""
    model = scene.robot.model
    return (pin.difference(model, q_nominal, q_plus) - pin.difference(model, q_nominal, q_minus)) / (2.0 * step)


def cube_reference(step: float, rtol: float = 1e-12, atol: float = 1e-13) -> tuple[np.ndarray, float]:
    """Central difference (6 × 2) of contactdiff's final pose in (μ, e) with ``step``, and
    its wall time (s, four runs and the nominal one).

    Its error is ``O(step²)`` (truncation) plus ``~atol/step`` (the runs' error): with
    rtol 1e-12, atol 1e-13, steps 1e-4 and 1e-5 bracket the best (module doc).
    """
    scene = toss_scene()
    start = time.perf_counter()
    q_nominal = simulate(scene, HORIZON, rtol=rtol, atol=atol).q
    values = scene.parameter_values(list(PARAMETERS))
    columns = []
    for k, name in enumerate(PARAMETERS):
        ends = [simulate(scene.with_parameters({name: values[k] + sign * step}), HORIZON, rtol=rtol, atol=atol).q
                for sign in (1.0, -1.0)]
        columns.append(pose_difference(scene, q_nominal, ends[0], ends[1], step))
    return np.array(columns).T, time.perf_counter() - start
