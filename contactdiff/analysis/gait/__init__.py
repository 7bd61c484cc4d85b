"""Gait stability: the stride map, its Jacobian and the Floquet multipliers.

`stride` holds the stride map of a foot (the state just before one of its
touchdowns to the state just before the next, on the section of that foot's
guard, tangent space) and its mathematics; `section` the section's coordinates,
the ground's neutral moves (x, y, yaw) and the Floquet multipliers of a stride;
`periodic` the search for a periodic gait up to those moves and the
stroboscopic period map of a clock-driven scene; `sensitivity` the derivatives of
a periodic gait with respect to the scene's parameters; `stances` a foot's
stance intervals in a run (`stride_result` holds a stride's result, `stride_loop`
the hybrid loop of one stride). The public names of all are importable from here.
"""

from ...errors import StrideError
from .period_map import PeriodMap, period_map
from .periodic import PeriodicGait, find_periodic_gait, floquet_multipliers
from .section import (
    NEUTRAL_NAMES,
    align,
    available_neutral,
    neutral_directions,
    onto_section,
    scene_period,
    section_basis,
)
from .sensitivity import GaitSensitivity, gait_sensitivity
from .stances import stance_intervals
from .stride import first_touchdown, stride_map
from .stride_loop import StrideLoop
from .stride_result import Stride

__all__ = [
    "GaitSensitivity",
    "NEUTRAL_NAMES",
    "PeriodMap",
    "PeriodicGait",
    "Stride",
    "StrideError",
    "StrideLoop",
    "align",
    "available_neutral",
    "find_periodic_gait",
    "first_touchdown",
    "floquet_multipliers",
    "gait_sensitivity",
    "neutral_directions",
    "onto_section",
    "period_map",
    "scene_period",
    "section_basis",
    "stance_intervals",
    "stride_map",
]
