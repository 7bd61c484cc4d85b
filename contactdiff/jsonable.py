"""One conversion of results to what ``json.dumps`` writes: the form of every ``--json``."""

from __future__ import annotations

import math
from enum import Enum

import numpy as np


def to_jsonable(x):
    """``x`` with numpy arrays and scalars turned into Python lists and numbers, tuples
    into lists, enums into their values, and non-finite floats into None (JSON has no
    NaN or infinity); dicts and lists are converted all the way down."""
    if isinstance(x, dict):
        return {(k.value if isinstance(k, Enum) else k): to_jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [to_jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return to_jsonable(x.tolist())
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    if isinstance(x, (float, np.floating)):
        return float(x) if math.isfinite(x) else None
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, Enum):
        return x.value
    return x
