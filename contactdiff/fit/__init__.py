"""Fitting scene parameters to measured trajectories with exact derivatives (docs/fit.md).

observations       Observations, toss_observations (a measured trajectory of a scene)
observation_files  load_observations, save_observations (CSV and .npz; docs/observations.md)
column_files       write_columns (named columns as a CSV or .npz file)
recordings         Recording (a measured trajectory and its rollout's start)
residuals          PoseResidual, ResidualWeights (residuals on the configuration manifold)
parameters         FitPlan, Scaled (the unknowns and the scene parameters they set)
evaluation         evaluate (one recording's residuals and Jacobian from one run), StateFit
problem            fit, FitResult, NonDifferentiablePolicy
loss               Loss (least squares or a robust loss)
windows            Windows, cut (windowed residuals: multiple shooting over short windows)
rollouts           rollouts (plain runs for held-out evaluation)
rest               rest_height (the floor's height from resting samples, closed form)
metrics            position_error, rotation_error (the published cube-toss metrics)
cli, plot          the ``contactdiff fit`` command and its figure
"""

from .evaluation import StateFit
from .loss import Loss
from .metrics import position_error, position_errors, rotation_error, rotation_errors
from .observation_files import load_observations, save_observations
from .observations import Observations, joint_columns, toss_observations, valid_columns
from .parameters import FitPlan, Scaled
from .problem import FitResult, NonDifferentiablePolicy, NotDifferentiableWarning, RecordingFit, fit
from .recordings import Recording
from .residuals import PoseResidual, ResidualWeights
from .rest import RestHeight, rest_height
from .rollouts import Rollout, rollouts
from .windows import Windows, cut

__all__ = [
    "fit",
    "FitResult",
    "FitPlan",
    "Loss",
    "NonDifferentiablePolicy",
    "NotDifferentiableWarning",
    "PoseResidual",
    "Recording",
    "RecordingFit",
    "ResidualWeights",
    "RestHeight",
    "rest_height",
    "Rollout",
    "rollouts",
    "Scaled",
    "StateFit",
    "Windows",
    "cut",
    "position_error",
    "position_errors",
    "rotation_error",
    "rotation_errors",
    "joint_columns",
    "load_observations",
    "Observations",
    "save_observations",
    "toss_observations",
    "valid_columns",
]
