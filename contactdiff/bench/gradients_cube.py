"""Task 5 of the gradient benchmark: a measured cube toss's final pose in μ and e.

The cube (`contactdiff.cube_scene`, eight Coulomb corners in group ``cube``) starts
at the first sample of toss ``toss_000`` and runs for `HORIZON` s: its first landing,
corner bounces and then an edge bouncing down to rest. The pose's derivative in the
group's friction ``μ`` and restitution ``e`` has no closed form; its reference is the
Richardson extrapolation of central differences of contactdiff's own runs at tight
tolerances (`cube_reference`, `REFERENCE_STEPS`). `horizon_study` compares the two
at other horizons: it is how `HORIZON` was chosen.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ..data.cube_tosses import cube_scene, load_tosses
from ..integration.hybrid import simulate
from ..model.scene import Scene
from .gradients import Cost, Run, Stopwatch

TOSS = "toss_000"
"""The shipped toss the task starts from."""

HORIZON = 0.25
"""s: the first landing: three corner bounces (t ≈ 0.083, 0.142, 0.201 s), then bounces
of four corners, among them an impact cascade that the Zeno rule ends (0.237 s): 14
events, all differentiable (the next cascades end at 0.252 and 0.255 s). At 0.2565 s a
cascade ends with a corner landing against its resting neighbour (`NonSmooth`
``ZENO_CASCADE``, ``RESTING_CONTACT``) and from 0.276 s the opposite edge lands with
both corners at once (``ORDER``): past them the run has no gradient, only a
piecewise-linear derivative, and the central differences no longer match its
Jacobian (`horizon_study`)."""

REFERENCE_STEPS = (1e-5, 1e-6)
"""Steps of the reference's central differences: a kink of the cascades lies within
1e-4 of (μ, e) (the difference with 1e-4 is 4 % off at 0.24 s), none within 1e-5."""

PARAMETERS = ("group:cube:friction", "group:cube:restitution")
"""The columns of the gradient: μ and e of the eight corners."""


def toss_scene() -> Scene:
    """The cube at the toss's first sample (nominal μ 0.18, e 0.125)."""
    return cube_scene().with_state(*load_tosses()[TOSS].state(0))


def contactdiff_cube(
    scene: Scene | None = None, rtol: float = 1e-12, atol: float = 1e-13, horizon: float = HORIZON
) -> Run:
    """``d pose(T) / d(μ, e)`` (6 × 2, the pose's tangent at T = ``horizon`` s: the centre's
    displacement and rotation in the cube's frame, Pinocchio's ``integrate``) from one run."""
    scene = toss_scene() if scene is None else scene
    watch = Stopwatch()
    traj = simulate(scene, horizon, jacobian=False, parameters=list(PARAMETERS), rtol=rtol, atol=atol)
    cost = watch.read()
    assert traj.parameter_jacobian is not None  # asked for (parameters)
    return Run(
        traj.parameter_jacobian[0:6].copy(), cost, traj.differentiable, traj.q.copy(), traj.why_not_differentiable()
    )


def pose_difference(
    scene: Scene, q_nominal: np.ndarray, q_plus: np.ndarray, q_minus: np.ndarray, step: float
) -> np.ndarray:
    """Central difference of two final poses in the tangent space at ``q_nominal``
    (``(q+ ⊖ q) - (q- ⊖ q)) / 2h``): second order in ``step``."""
    model = scene.robot.model
    return (pin.difference(model, q_nominal, q_plus) - pin.difference(model, q_nominal, q_minus)) / (2.0 * step)


def cube_reference(
    step: float, rtol: float = 1e-12, atol: float = 1e-13, horizon: float = HORIZON
) -> tuple[np.ndarray, Cost]:
    """Central difference (6 × 2) of contactdiff's final pose at ``horizon`` s in (μ, e) with
    ``step``, and its `Cost` (four runs and the nominal one).

    Its error is ``O(step²)`` (truncation) plus ``~atol/step`` (the runs' error); see
    `REFERENCE_STEPS`.
    """
    scene = toss_scene()
    watch = Stopwatch()
    q_nominal = simulate(scene, horizon, rtol=rtol, atol=atol).q
    values = scene.parameter_values(list(PARAMETERS))
    columns = []
    for k, name in enumerate(PARAMETERS):
        ends = [
            simulate(scene.with_parameters({name: values[k] + sign * step}), horizon, rtol=rtol, atol=atol).q
            for sign in (1.0, -1.0)
        ]
        columns.append(pose_difference(scene, q_nominal, ends[0], ends[1], step))
    return np.array(columns).T, watch.read()


def extrapolated(coarse: np.ndarray, fine: np.ndarray, ratio: float = 10.0) -> np.ndarray:
    """Richardson extrapolation of two central differences whose steps differ by ``ratio``:
    their ``O(step²)`` terms cancel."""
    return (ratio**2 * fine - coarse) / (ratio**2 - 1.0)


def horizon_study(horizons, steps=REFERENCE_STEPS) -> list[dict]:
    """contactdiff's ``d pose(T)/d(μ, e)`` against central differences of its runs (rtol
    1e-12) at each horizon T (s): per horizon the verdict (``differentiable``, the reasons'
    names), the events, the Jacobian's norm and the relative difference of the central
    difference at each of ``steps`` and of their extrapolation (two steps, ratio 10)."""
    out = []
    for horizon in horizons:
        run = contactdiff_cube(horizon=horizon)
        traj = simulate(toss_scene(), horizon, rtol=1e-12, atol=1e-13)
        norm = float(np.linalg.norm(run.gradient))
        fds = {step: cube_reference(step, horizon=horizon)[0] for step in steps}
        errors = {f"{step:g}": float(np.linalg.norm(fd - run.gradient)) / norm for step, fd in fds.items()}
        if len(steps) == 2:
            coarse, fine = sorted(steps, reverse=True)
            best = extrapolated(fds[coarse], fds[fine], ratio=coarse / fine)
            errors["extrapolated"] = float(np.linalg.norm(best - run.gradient)) / norm
        out.append(
            {
                "horizon": horizon,
                "differentiable": run.differentiable,
                "events": len(traj.events),
                "reasons": sorted(
                    {r.name for e in traj.events for r in e.nonsmooth} | {r.name for r in traj.final_nonsmooth}
                ),
                "jacobian_norm": norm,
                "errors": errors,
            }
        )
    return out
