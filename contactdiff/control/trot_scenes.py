"""Trot scenes for the example-robot-data quadrupeds.

`trot_scene(robot)` puts a quadruped on flat ground with four sticking,
plastic foot contacts (each offset so the starting pose touches the ground,
as in ``solo12_drop.toml``) and drives it with a `TrotController`
(`contactdiff.control.trot_controller`): PD torques tracking a clock-driven,
periodic joint-space reference in which the diagonal pairs front-left +
hind-right and front-right + hind-left alternate stance and swing.

The scene starts at t = 0 at rest, the legs at the controller's reference of
that instant and the base at its reference placement (height and attitude of
the robot's standing pose). With the default ``t_start = 0`` that is phase 0:
pair A (front-left + hind-right) stands at mid-stance in the stance pose and
pair B (front-right + hind-left) is in mid-swing.

Per-robot parameters live in `TROT_PARAMETERS`; any of them can be overridden
by keyword.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import InvalidInputError, unknown_name
from ..model.contacts import Contact
from ..model.kinematics import Kinematics
from ..model.robot import Robot
from ..model.robot_files import QUADRUPEDS, load_robot
from ..model.scene import Scene
from .trot_controller import TrotController, TrotControllerEvaluator

GRAVITY = 9.81
"""Gravity of the trot scenes (m/s², along -z)."""

TROT_PARAMETERS: dict[str, dict[str, float]] = {
    # period (s), step_height (m), kp (N m/rad), kd (N m s/rad)
    "solo12": dict(period=0.4, step_height=0.035, kp=10.0, kd=0.2),
    "a1": dict(period=0.4, step_height=0.04, kp=80.0, kd=1.5),
    "go1": dict(period=0.4, step_height=0.04, kp=80.0, kd=1.5),
    "go2": dict(period=0.45, step_height=0.05, kp=100.0, kd=2.0),
    "anymal": dict(period=0.5, step_height=0.07, kp=200.0, kd=4.0),
    "hyq": dict(period=0.55, step_height=0.08, kp=800.0, kd=15.0),
}
"""Gait and gains per robot (keys are `TrotController` arguments; the others keep the
controller's defaults: duty 0.6, lag 0.03, approach_height 0.01 m, approach 0.15,
transfer 0.05, touchdown_load 0.2, liftoff_pull 0.1, release_gain 0). Standing
base heights 0.235 (solo12), 0.26 (a1, go1), 0.335 (go2), 0.48 (anymal) and 0.58 m
(hyq): the step heights are 14-16 % of them. Masses 2.5, 13.7, 13.1, 16.1, 30.5 and
86.8 kg: ``kp`` is 14-24 times the weight times the standing height (N m per rad),
``kd`` about kp / 50 s."""

_OVERRIDABLE = TrotController.KEYS


def trot_parameters(name: str) -> dict:
    """The `TROT_PARAMETERS` entry of robot ``name`` (a copy)."""
    if name not in TROT_PARAMETERS:
        raise unknown_name("robot with trot parameters", name, TROT_PARAMETERS)
    return dict(TROT_PARAMETERS[name])


def trot_scene(robot: str | Robot, *, name: str | None = None, **overrides) -> Scene:
    """A quadruped trotting on flat ground.

    Args:
        robot: one of `QUADRUPEDS` by name, or a loaded floating-base `Robot`
            with four feet (then every gait parameter its name lacks in
            `TROT_PARAMETERS` must be given: period, step_height, kp, kd).
        name: scene name (default ``"<robot>_trot"``).
        **overrides: `TrotController` arguments replacing the robot's entry of
            `TROT_PARAMETERS` (any of `TrotController.KEYS`: period (s), duty, lag,
            step_height (m), approach_height (m), approach, step_length (m),
            transfer, touchdown_load, liftoff_pull, release_gain, kp (N m/rad),
            kd (N m s/rad), t_start (s), feedforward, stance, samples).

    Returns:
        The `Scene`: four sticking, plastic ground contacts at the feet, gravity
        9.81 m/s² along -z, the controller as its only effort, and the initial
        state at rest at the reference of t = 0 (see the module notes).

    Raises:
        UnknownNameError: an unknown robot or keyword.
        InvalidInputError: a bad parameter value, or a robot that is not a quadruped.
    """
    for key in overrides:
        if key not in _OVERRIDABLE:
            raise unknown_name("trot_scene keyword", key, _OVERRIDABLE + ("name",))
    if isinstance(robot, str):
        if robot not in QUADRUPEDS:
            raise unknown_name("quadruped", robot, QUADRUPEDS)
        robot = load_robot(robot)
    elif not isinstance(robot, Robot):
        raise InvalidInputError(f"robot must be a quadruped name or a Robot, got {robot!r}")
    parameters: dict[str, Any] = dict(TROT_PARAMETERS.get(robot.name, {}))
    parameters.update(overrides)
    missing = [k for k in ("period", "step_height", "kp", "kd") if k not in parameters]
    if missing:
        raise InvalidInputError(
            f"robot {robot.name!r} has no entry in TROT_PARAMETERS; give {', '.join(missing)} "
            f"(robots with an entry: {', '.join(TROT_PARAMETERS)})"
        )
    controller = TrotController(**parameters)
    # ground: each foot's height in the stance pose, the base at its reference placement
    stance = robot.q_ref.copy()
    for joint, value in controller.stance:
        stance[robot.scalar_joint(joint)[0]] = value
    kin = Kinematics(robot.model)
    kin.update(stance, np.zeros(robot.nv))
    contacts = [
        Contact(foot, offset=float(kin.position(robot.frame_id(foot))[2]), friction="stick") for foot in robot.feet
    ]
    scene = Scene(
        robot, contacts, [controller], gravity=[0.0, 0.0, -GRAVITY], q0=stance, name=name or f"{robot.name}_trot"
    )
    evaluator = next(e for e in scene.efforts if isinstance(e, TrotControllerEvaluator))
    q0 = stance.copy()
    q0[evaluator.iq] = evaluator.reference(0.0)[0]
    return scene.with_state(q0=q0)


__all__ = ["trot_scene", "trot_parameters", "TROT_PARAMETERS", "GRAVITY"]
