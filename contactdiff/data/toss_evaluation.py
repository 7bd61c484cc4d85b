"""The cube's parameters on held-out tosses: the published metrics over tosses, and their luck.

`evaluate_start` runs held-out tosses from one `Start` at given parameter values
and summarises the published metrics (time-averaged position error in % of the
edge, rotation error in degrees; `error_summary`: mean, std and median over
tosses), with the failed runs and the worst tosses. `start_noise` reruns them
from starts perturbed by the data's own noise (`START_NOISE`, measured by
`contactdiff.data.toss_checks.length_check`): how much of the error is luck.
scripts/cube_tosses.py reports both.
"""

from __future__ import annotations

import statistics
from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from typing import Any

import numpy as np
import pinocchio as pin

from ..fit.rollouts import rollouts
from .cube_recordings import Start, toss_errors, toss_recording
from .cube_tosses import Toss, cube_scene


def error_summary(errors: Sequence[tuple[float, float]]) -> dict:
    """The published metrics over tosses from each toss's ``(position %, rotation deg)``
    (`toss_errors`): count, mean, population standard deviation and median of each;
    ``{"tosses": 0}`` for none."""
    pos = [e[0] for e in errors]
    rot = [e[1] for e in errors]
    if not pos:
        return {"tosses": 0}
    return {
        "tosses": len(pos),
        "position_mean": statistics.fmean(pos),
        "position_std": statistics.pstdev(pos),
        "position_median": statistics.median(pos),
        "rotation_mean": statistics.fmean(rot),
        "rotation_std": statistics.pstdev(rot),
        "rotation_median": statistics.median(rot),
    }


def evaluate_start(
    tosses: Mapping[str, Toss],
    names: Sequence[str],
    values: Mapping | None,
    start: Start,
    jobs: int,
    options: Mapping,
    source: Callable = cube_scene,
) -> dict:
    """The held-out ``names``' rollouts from ``start`` at ``values`` (None: the scene's
    own; ``source`` builds the scene, as `contactdiff.fit.rollouts` takes it): their
    `error_summary`, the failed runs (``"name: error"``), the eight worst tosses by
    position error (with wall time in s, events and non-smooth events), how many are not
    differentiable, the median wall time (s) and every toss's ``[name, position %,
    rotation deg]``, worst first."""
    recs = [toss_recording(tosses[n], start) for n in names]
    runs = rollouts(source, recs, values, jobs=jobs, options=options, progress=None)
    errors: list[tuple[float, float]] = []
    failed: list[str] = []
    rows: list[dict[str, Any]] = []
    for rec, run in zip(recs, runs):
        if not run.complete:
            failed.append(f"{rec.name}: {run.error}")
            continue
        e = toss_errors(rec, run.q)
        errors.append(e)
        rows.append(
            {
                "toss": rec.name,
                "position": e[0],
                "rotation": e[1],
                "wall": run.wall,
                "events": run.events,
                "nonsmooth": run.nonsmooth,
            }
        )
    rows.sort(key=lambda r: -r["position"])
    return error_summary(errors) | {
        "failed": failed,
        "worst": rows[:8],
        "not_differentiable": sum(bool(r["nonsmooth"]) for r in rows),
        "wall_median": statistics.median([r["wall"] for r in rows]) if rows else None,
        "per_toss": [[r["toss"], r["position"], r["rotation"]] for r in rows],
    }


START_NOISE = (2.3e-5, 3.2e-4)
"""The data's noise in free flight (m per axis of position, rad per axis of orientation), medians
over the tosses' first flights (`length_check`): the start's perturbations of `start_noise`."""


def start_noise(
    tosses: Mapping[str, Toss],
    names: Sequence[str],
    values: Mapping | None,
    jobs: int,
    options: Mapping,
    source: Callable,
    draws: int,
    seed: int = 0,
) -> dict:
    """How much of the held-out error is luck: each held-out toss's rollout from before touch at
    ``values``, ``draws`` times from a start perturbed by the data's own noise (`START_NOISE`:
    Gaussian per axis on the centre, a rotation ``R0 exp(δ)`` with Gaussian ``δ``; the velocity as
    fitted). Per draw the mean over tosses; per toss the spread (largest less smallest error)."""
    rng = np.random.default_rng(seed)
    base = [toss_recording(tosses[n], Start.BEFORE_TOUCH) for n in names]
    recs = []
    for _ in range(draws):
        for rec in base:
            q0 = rec.q0.copy()
            q0[:3] += START_NOISE[0] * rng.standard_normal(3)
            rotation = pin.Quaternion(q0[6], q0[3], q0[4], q0[5]).normalized().matrix()
            q0[3:7] = pin.Quaternion(rotation @ pin.exp3(START_NOISE[1] * rng.standard_normal(3))).coeffs()
            recs.append(replace(rec, q0=q0))
    runs = rollouts(source, recs, values, jobs=jobs, options=options, progress=None)
    errors = np.full((draws, len(base)), np.nan)
    for i, (rec, run) in enumerate(zip(recs, runs)):
        if run.complete:
            errors[i // len(base), i % len(base)] = toss_errors(rec, run.q)[0]
    means = np.nanmean(errors, axis=1)
    spread = np.nanmax(errors, axis=0) - np.nanmin(errors, axis=0)
    return {
        "draws": draws,
        "noise": list(START_NOISE),
        "failed": int(np.isnan(errors).sum()),
        "draw_means": means.tolist(),
        "draw_mean_std": float(np.std(means)),
        "best_of_draws_mean": float(np.mean(np.nanmin(errors, axis=0))),
        "worst_of_draws_mean": float(np.mean(np.nanmax(errors, axis=0))),
        "spread_median": float(np.median(spread)),
        "tosses_spread_over_10": int(np.sum(spread > 10.0)),
        "per_toss": {n: errors[:, j].tolist() for j, n in enumerate(names)},
    }
