"""contactdiff: differentiability through contact for legged robots and manipulators.

The public names, by concept (each lives in the subpackage named beside it):

    model        load_robot, Robot, QUADRUPEDS, Scene, load_scene, load_source,
                 Contact, FrictionLaw, JointSpring, Spring, UserEffort, Effort,
                 SceneObject, RobotFrame, add_objects (objects beside a robot)
    control      trot_scene (the trot controller's scenes of the quadrupeds), JointTargets
                 (a manipulator's PD tracking of a joint-space schedule)
    paper        trot_touchdown (the paper's Fig. 1 scenes at any initial pitch)
    dynamics     ModeDynamics (accelerations and contact forces in any contact mode)
    integration  simulate, SimulateOptions, HybridLoop, Trajectory, Event, EventKind,
                 Segment, NonSmooth, Termination, RunStats, Samples
    analysis     check_decoupling, DecouplingReport, order_gap, stride_map,
                 find_periodic_gait, first_touchdown, period_map
    sweep        sweep (one scene over many points, on many cores or a cluster)
    data         cube_scene, load_tosses, Toss, CubeParameters (measured cube tosses)
    fit          Observations, load_observations, toss_observations (measured trajectories)
    errors       ContactDiffError and its subclasses
"""

from .analysis.decoupling import DecouplingReport, check_decoupling
from .analysis.gait import find_periodic_gait, first_touchdown, period_map, stride_map
from .analysis.order_gap import order_gap
from .control.joint_targets import JointTargets
from .control.trot_scenes import trot_scene
from .data.cube_tosses import CubeParameters, Toss, cube_scene, load_tosses
from .dynamics.mode import ModeDynamics
from .errors import (
    ContactDiffError,
    GrazingError,
    GroupMismatchError,
    InconsistentStateError,
    IntegrationError,
    InvalidInputError,
    MissingExtraError,
    ModelLoadError,
    ObservationFileError,
    OutputFileError,
    OutsideDomainError,
    PainleveError,
    SolverError,
    StepBudgetError,
    StepCollapseError,
    StepSizeUnderflowError,
    StoppedRunError,
    StrideError,
    TooManyEventsError,
    TooManyStepsError,
    UnknownNameError,
    UnknownRobotError,
)
from .fit import Observations, load_observations, toss_observations
from .integration.hybrid import HybridLoop, simulate
from .integration.options import SimulateOptions
from .integration.samples import Samples
from .integration.trajectory import Event, EventKind, NonSmooth, RunStats, Segment, Termination, Trajectory
from .model.contacts import Contact, FrictionLaw
from .model.efforts import Effort, JointSpring, Spring, UserEffort
from .model.objects import RobotFrame, SceneObject, add_objects
from .model.robot import Robot
from .model.robot_files import QUADRUPEDS, load_robot
from .model.scene import Scene
from .paper import trot_touchdown
from .scenes.scene_file import load_scene, load_source
from .sweeps import sweep

__version__ = "0.1.0"

__all__ = [
    "add_objects",
    "check_decoupling",
    "Contact",
    "CubeParameters",
    "cube_scene",
    "load_tosses",
    "Toss",
    "ContactDiffError",
    "DecouplingReport",
    "Effort",
    "Event",
    "EventKind",
    "find_periodic_gait",
    "first_touchdown",
    "FrictionLaw",
    "GrazingError",
    "GroupMismatchError",
    "HybridLoop",
    "InconsistentStateError",
    "IntegrationError",
    "InvalidInputError",
    "JointSpring",
    "JointTargets",
    "load_robot",
    "MissingExtraError",
    "load_observations",
    "load_scene",
    "load_source",
    "ModeDynamics",
    "ModelLoadError",
    "NonSmooth",
    "ObservationFileError",
    "Observations",
    "order_gap",
    "OutputFileError",
    "OutsideDomainError",
    "PainleveError",
    "period_map",
    "QUADRUPEDS",
    "Robot",
    "RobotFrame",
    "RunStats",
    "Samples",
    "Scene",
    "SceneObject",
    "Segment",
    "simulate",
    "SimulateOptions",
    "SolverError",
    "Spring",
    "StepBudgetError",
    "StepCollapseError",
    "StepSizeUnderflowError",
    "StoppedRunError",
    "stride_map",
    "StrideError",
    "sweep",
    "Termination",
    "TooManyEventsError",
    "TooManyStepsError",
    "toss_observations",
    "Trajectory",
    "trot_scene",
    "trot_touchdown",
    "UnknownNameError",
    "UnknownRobotError",
    "UserEffort",
]
