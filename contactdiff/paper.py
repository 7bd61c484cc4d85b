"""The paper's touchdown scenes at any initial pitch (docs/design.md §6).

`trot_touchdown("soft", pitch)` and `trot_touchdown("rigid", pitch)` return the
scenes of the paper's Fig. 1 with the body pitched by ``pitch`` (rad; positive
lifts the front), everything at rest:

* soft: body centre at (0, 1), each foot 0.5 below its hip along the body's
  own vertical (the leg springs at rest length);
* rigid: centre of mass at (0, 2/3).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from .errors import InvalidInputError
from .model.scene import Scene
from .scenes.scene_file import load_scene

TROT_MODELS = ("soft", "rigid")


def trot_touchdown(model: str = "soft", pitch: float = 0.0) -> Scene:
    """Touchdown scene of the planar trotter ``model`` ("soft" or "rigid") at ``pitch`` (rad)."""
    if model not in TROT_MODELS:
        raise InvalidInputError(f"model must be one of {', '.join(TROT_MODELS)}; got {model!r}")
    pitch = float(pitch)
    if not np.isfinite(pitch) or abs(pitch) >= np.pi / 2:
        raise InvalidInputError(f"pitch must be finite and below pi/2 in magnitude, got {pitch!r}")
    base = load_scene(f"planar_trot_{model}")
    if model == "rigid":
        return base.with_state({"body_pitch": pitch})
    robot = base.robot
    q = base.with_state({"body_pitch": pitch}).q0
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, q)
    feet = {}
    for side in ("rear", "front"):
        hip = data.oMf[robot.frame_id(f"{side}_hip")]
        foot = hip.translation + hip.rotation @ np.array([0.0, 0.0, -0.5])
        feet[f"{side}_foot_x"], feet[f"{side}_foot_z"] = foot[0], foot[2]
    return base.with_state({"body_pitch": pitch, **feet})
