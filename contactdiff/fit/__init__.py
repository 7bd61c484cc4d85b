"""Identification of a scene's parameters from measured trajectories.

`Observations` are a measured trajectory of a scene (`contactdiff.fit.observations`),
read from CSV or ``.npz`` by `load_observations` (`contactdiff.fit.observation_files`;
the format: docs/observations.md); `toss_observations` turns a measured cube toss into
observations of `contactdiff.cube_scene`.
"""

from .observation_files import load_observations, save_observations
from .observations import Observations, joint_columns, toss_observations, valid_columns

__all__ = ["joint_columns", "load_observations", "Observations", "save_observations", "toss_observations",
           "valid_columns"]
