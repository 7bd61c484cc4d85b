"""contactdiff: differentiability through contact for legged robots and manipulators.

Public names (stable):

    load_robot, Robot              robot models (URDF, robots/ names, example-robot-data)
    Scene, load_scene, load_source scenes: robot + contacts + efforts + gravity + x0
    Contact, Spring, JointSpring, UserEffort
    ModeDynamics                   accelerations and contact forces in any contact mode
    check_decoupling               the paper's assumptions, measured
    simulate, Trajectory           event-driven hybrid simulation
    trot_touchdown                 the paper's Fig. 1 scenes at any initial pitch
    stride_map, find_periodic_gait gait stability: stride map, periodic gait, Floquet multipliers
"""

from .analysis.decoupling import DecouplingReport, check_decoupling
from .model.contacts import Contact
from .dynamics.mode import ModeDynamics
from .model.efforts import JointSpring, Spring, UserEffort
from .errors import (ContactDiffError, InconsistentStateError, IntegrationError,
                     InvalidInputError, ModelLoadError, SolverError, StoppedRunError,
                     TooManyStepsError, UnknownNameError, UnknownRobotError)
from .integration.hybrid import GrazingError, TooManyEventsError, simulate
from .paper import trot_touchdown
from .model.robot import QUADRUPEDS, Robot, load_robot
from .model.scene import Scene, load_scene, load_source
from .analysis.gait.stride import StrideError, find_periodic_gait, stride_map
from .integration.trajectory import Event, Segment, Trajectory

__version__ = "0.1.0"

__all__ = [
    "Contact", "ContactDiffError", "DecouplingReport", "Event", "GrazingError", "Segment",
    "TooManyEventsError", "Trajectory", "simulate", "trot_touchdown", "InconsistentStateError", "IntegrationError",
    "InvalidInputError", "JointSpring", "ModeDynamics", "ModelLoadError", "QUADRUPEDS", "Robot",
    "Scene", "SolverError", "Spring", "UnknownNameError", "UserEffort", "check_decoupling",
    "load_robot", "load_scene", "load_source",
    "StrideError", "find_periodic_gait", "stride_map",
    "StoppedRunError", "TooManyStepsError", "UnknownRobotError",
]
