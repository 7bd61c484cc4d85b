"""Stiff and extreme cases: each a check of correctness and a row of cost.

Every study returns `StudyRow` objects: the case, its parameter, the method,
the error against a closed form or a converged tight-tolerance run (and which),
the run time (one run, s), the steps, the dynamics evaluations and the outcome
(a named error counts as an outcome, not a failure). `run_studies` collects
them in a `StudyResult` with ``format()`` and ``to_dict()``; `contactdiff bench
--studies` prints them and ``scripts/stiff_study.py`` draws the stiffness sweep.

Units follow the scenes (g = 1 in the paper's models): m, s, m/s.

The studies:

* `stiffness_sweep`: both leg springs of planar_trot_soft scaled by 1 … 1e7,
  undamped (as shipped: the touchdown rings the legs, which every accurate
  method must resolve) or with a leg damping ratio (the fast motion decays:
  a stiff problem); DOP853, Radau and ``method="auto"``.
* `tiny_mass_study`: two_limb with limb masses down to 1e-6 of the body's,
  against its closed form.
* `grazing_study`: touchdown speeds 1e-3 … 1e-12 of a slow drop (transversal),
  and a tangential approach whose dip below the ground shrinks to nothing.
* `simultaneous_study`: the soft (decoupled) and rigid trot landing Δt apart,
  Δt = 1e-2 … 1e-14 and 0.
* `zeno_study`: balls with e = 0.5, 0.9, 0.99 against the limit time.
* `elastic_study`: a ball with e = 1 over many impacts: energy and constraint drift.
* `bad_input_study`: non-finite numbers in the state and the parameters.
"""

from __future__ import annotations

from .edge_cases import (
    bad_input_study,
    elastic_study,
    grazing_study,
    pitch_for_gap_time,
    simultaneous_study,
    slow_drop,
    tangent_approach,
    touchdown_gap_time,
    zeno_study,
)
from .stiff_cases import (
    settled_stance,
    stiff_trot,
    stiffness_sweep,
    tiny_mass_study,
    two_limb_closed_form,
    two_limb_with_mass,
)
from .study_rows import StudyResult, StudyRow, state_error


# -- all ------------------------------------------------------------------------------------
def _skip_radau_ringing(scale, method):
    return "ringing: ~10x DOP853 cost" if method == "Radau" and scale > 1e4 else None


def run_studies(quick: bool = True) -> StudyResult:
    """Every study; ``quick`` keeps each short (seconds in all), the full run takes minutes.

    Full: stiffness 1 … 1e7 with damped legs (all methods) and 1 … 1e5 undamped
    (Radau up to 1e4), tiny masses down to 1e-6, all grazing cases, Δt down to
    1e-14, Zeno e = 0.5, 0.9, 0.99 and 10,000 elastic impacts.
    """
    result = StudyResult()
    if quick:
        result.rows += stiffness_sweep(scales=(1, 1e2, 1e4), damping_ratio=1.0)
        result.rows += stiffness_sweep(scales=(1, 1e2), damping_ratio=0.0, methods=("auto", "DOP853"))
        result.rows += tiny_mass_study(masses=(1e-3,), methods=("auto", "DOP853"), t_final=1.85)
        result.rows += grazing_study(speeds=(1e-3, 1e-9, 1e-12), dips=(1e-4, 1e-12, 0.0))
        result.rows += simultaneous_study(gaps=(1e-4, 1e-8, 1e-12), rigid=True)
        result.rows += zeno_study(restitutions=(0.5, 0.9))
        result.rows += elastic_study(impacts=200)
    else:
        result.rows += stiffness_sweep(damping_ratio=1.0)
        result.rows += stiffness_sweep(scales=(1, 10, 1e2, 1e3, 1e4, 1e5), damping_ratio=0.0, skip=_skip_radau_ringing)
        result.rows += tiny_mass_study()
        result.rows += grazing_study()
        result.rows += simultaneous_study()
        result.rows += zeno_study()
        result.rows += elastic_study(impacts=10_000)
    result.rows += bad_input_study()
    return result


__all__ = [
    "StudyRow",
    "StudyResult",
    "run_studies",
    "stiffness_sweep",
    "tiny_mass_study",
    "grazing_study",
    "simultaneous_study",
    "zeno_study",
    "elastic_study",
    "bad_input_study",
    "stiff_trot",
    "settled_stance",
    "two_limb_with_mass",
    "two_limb_closed_form",
    "slow_drop",
    "tangent_approach",
    "touchdown_gap_time",
    "pitch_for_gap_time",
    "state_error",
]
