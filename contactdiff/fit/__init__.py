"""Fitting scene parameters to measured trajectories with exact derivatives.

    metrics      position_error, rotation_error (the published cube-toss metrics)
    residuals    PoseResidual, ResidualWeights (residuals on the configuration manifold)
    recordings   Recording (a measured trajectory and its rollout's start)
    parameters   FitPlan, Scaled (the unknowns and the scene parameters they set)
    evaluation   evaluate (one recording's residuals and Jacobian from one run), StateFit
    problem      fit, FitResult, NonDifferentiablePolicy
"""

from .evaluation import StateFit
from .metrics import position_error, position_errors, rotation_error, rotation_errors
from .parameters import FitPlan, Scaled
from .problem import FitResult, NonDifferentiablePolicy, NotDifferentiableWarning, RecordingFit, fit
from .recordings import Recording
from .residuals import PoseResidual, ResidualWeights

__all__ = ["fit", "FitResult", "FitPlan", "NonDifferentiablePolicy", "NotDifferentiableWarning", "PoseResidual",
           "Recording", "RecordingFit", "ResidualWeights", "Scaled", "StateFit", "position_error",
           "position_errors", "rotation_error", "rotation_errors"]
