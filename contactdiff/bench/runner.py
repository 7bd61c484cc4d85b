"""Benchmarks: error against run time, per scene and method, in one process.

`run_bench` runs every method of a tolerance (or step) sweep on every scene and
measures, against a reference solution:

* the error of the final state, ``max(|q ⊖ q_ref|_inf, |v - v_ref|_inf)`` (the
  configuration difference taken on the manifold, `pinocchio.difference`);
* the error of the event times, matched by order (when the event counts differ
  this is reported and only the common prefix is compared);
* the run time (median of ``repeats`` runs; a run longer than ``LONG_RUN`` s is
  not repeated), dynamics evaluations and steps.

Methods: ``ours-DOP853`` and ``ours-Radau`` (`simulate`), ``solve_ivp-DOP853``
(`baselines.solve_ivp_baseline`, vector-space scenes only) and ``time-stepping``
(`baselines.time_stepping_baseline`, a sweep over the step ``dt``).

References: the ball has a closed form (bounce times and final state); every
other scene uses contactdiff's own DOP853 run at rtol 1e-13 / atol 1e-14, whose
difference from the run at rtol 1e-12 / atol 1e-13 is reported as its
convergence check.

Derivatives: on each scene the time of ``simulate(jacobian=True)`` over the plain
run, and of central finite differences (4 nv runs) over the Jacobian run, with
the largest difference between the two relative to the Jacobian's largest entry.

Ratios (all from the same run): a baseline's time over ours at equal error
(1e-6 and 1e-9 where reached), interpolated log-log along each method's curve;
"ours" is the faster of our methods at that error.
"""

from __future__ import annotations

import math
import statistics
import sys
import time
from collections.abc import Sequence
from typing import Any

import numpy as np
import pinocchio as pin

from ..errors import ContactDiffError, InvalidInputError, unknown_name
from ..integration.hybrid import simulate
from ..model.scene import Scene
from .baselines import solve_ivp_baseline, time_stepping_baseline
from .methods import METHODS
from .metrics import event_error, state_error, time_at_error
from .results import BenchResult, Reference
from .scene_table import FULL_DERIV_TOL, FULL_SWEEP, QUICK_DERIV_TOL, QUICK_SCENES, QUICK_SWEEP, SCENES

LONG_RUN = 2.0  # s: a run longer than this is timed once
TARGETS = (1e-6, 1e-9)
REF_TOL: dict[str, Any] = dict(rtol=1e-13, atol=1e-14)
CHECK_TOL: dict[str, Any] = dict(rtol=1e-12, atol=1e-13)
FD_EPS = 1e-5  # the sweet spot of tests/integration/test_sensitivity.py: truncation ~eps², step-sequence noise ~tol/eps


def ball_closed_form(scene: Scene, t_final: float) -> Reference:
    """Bounce times and final state of a ball dropped from rest (one frictionless contact)."""
    g = -float(scene.model.gravity.linear[2])
    e = scene.contacts[0].restitution
    z0 = float(scene.gaps(scene.q0)[0])
    u = math.sqrt(2 * g * z0)  # impact speed
    times, t = [], u / g
    while t <= t_final:  # bounce k (from 1) leaves at u e^k and lands 2 u e^k / g later
        times.append(t)
        t += 2 * u * e ** len(times) / g
    if times:
        s = t_final - times[-1]
        height, vz = u * e ** len(times) * s - 0.5 * g * s * s, u * e ** len(times) - g * s
    else:
        height, vz = z0 - 0.5 * g * t_final**2, -g * t_final
    q = scene.q0.copy()
    q[-1] += height - z0  # the ball's height coordinate (prismatic z)
    return Reference("closed-form", q, np.array([vz]), times)


def reference(name: str, scene: Scene, t_final: float) -> Reference:
    if name == "ball":
        return ball_closed_form(scene, t_final)
    ref = simulate(scene, t_final, **REF_TOL)
    chk = simulate(scene, t_final, **CHECK_TOL)
    times = [e.t for e in ref.events]
    return Reference(
        "DOP853 rtol=1e-13",
        ref.q.copy(),
        ref.v.copy(),
        times,
        state_error(scene, chk.q, chk.v, ref.q, ref.v),
        event_error([e.t for e in chk.events], times),
    )


# -- runs -----------------------------------------------------------------------------
def _timed(fn, repeats: int):
    times, out = [], None
    for k in range(max(1, repeats)):
        start = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - start)
        if times[0] > LONG_RUN:
            break
    return out, statistics.median(times)


def _run_one(name, scene, t_final, method, param, repeats):
    if method.startswith("ours-"):

        def fn():
            return simulate(scene, t_final, rtol=param, atol=param * 1e-2, method=method[5:])
    elif method == "solve_ivp-DOP853":

        def fn():
            return solve_ivp_baseline(scene, t_final, rtol=param, atol=param * 1e-2)
    elif method == "time-stepping":

        def fn():
            return time_stepping_baseline(scene, t_final, param)
    else:
        raise unknown_name("bench method", method, list(METHODS))
    out, elapsed = _timed(fn, repeats)
    if hasattr(out, "events"):  # Trajectory
        times = [e.t for e in out.events]
    else:
        times = list(out.event_times)
    return out, times, elapsed


def _curve(runs, scene, method):
    return sorted(
        (r["time"], r["error"])
        for r in runs
        if r["scene"] == scene and r["method"] == method and not r["failed"] and math.isfinite(r["error"])
    )


def _derivatives(name, scene, t_final, tol, repeats) -> dict:
    model, nv = scene.model, scene.nv
    plain, t_plain = _timed(lambda: simulate(scene, t_final, **tol), repeats)
    jac, t_jac = _timed(lambda: simulate(scene, t_final, jacobian=True, **tol), repeats)

    def fd():
        cols = []
        for k in range(2 * nv):
            e = np.zeros(nv)
            e[k % nv] = FD_EPS
            runs = []
            for sign in (1.0, -1.0):
                if k < nv:
                    q, v = pin.integrate(model, scene.q0, sign * e), scene.v0
                else:
                    q, v = scene.q0, scene.v0 + sign * e
                runs.append(simulate(scene.with_state(q, v), t_final, **tol))
            p, m = runs
            cols.append(np.concatenate([pin.difference(model, m.q, p.q), p.v - m.v]) / (2 * FD_EPS))
        return np.array(cols).T

    row = {
        "scene": name,
        "nv": nv,
        "tol": dict(tol),
        "time_plain": t_plain,
        "time_jacobian": t_jac,
        "steps_plain": int(plain.stats.steps),
        "steps_jacobian": int(jac.stats.steps),
        "derivative_evaluations": int(jac.stats.derivative_evaluations),
        "fd_runs": 4 * nv,
        "jacobian_over_plain": t_jac / t_plain,
        "differentiable": bool(jac.differentiable),
        "fd_skipped": None,
    }
    closed = [c.name for c, g in zip(scene.contacts, scene.gaps(scene.q0)) if g <= 2 * FD_EPS]
    if closed:  # perturbations q0 ⊕ ±ε e_k would push these through the ground
        row.update(
            time_fd=None,
            fd_over_jacobian=None,
            jacobian_vs_fd=None,
            fd_skipped=f"starts in contact ({', '.join(closed)}): FD perturbations are not admissible",
        )
        return row
    J_fd, t_fd = _timed(fd, 1)
    J = jac.jacobian
    row.update(
        time_fd=t_fd,
        fd_over_jacobian=t_fd / t_jac,
        jacobian_vs_fd=float(np.max(np.abs(J - J_fd)) / max(np.max(np.abs(J)), 1e-300)),
    )
    return row


class _Progress:
    """A one-line bar on stderr; ``enabled=None``: only when stderr is a terminal (a log
    file or a pipe gets no carriage-return redraws), True forces it, False hides it."""

    def __init__(self, total: int, enabled: bool | None):
        if enabled is None:
            isatty = getattr(sys.stderr, "isatty", None)
            enabled = bool(isatty and isatty())
        self.total, self.done, self.enabled = total, 0, enabled

    def step(self, label: str) -> None:
        self.done += 1
        if self.enabled:
            width = 30
            fill = int(width * self.done / max(self.total, 1))
            sys.stderr.write(f"\r[{'#' * fill}{'.' * (width - fill)}] {self.done}/{self.total} {label[:50]:<50}")
            if self.done == self.total:
                sys.stderr.write("\n")
            sys.stderr.flush()


def run_bench(
    scenes: Sequence[str] | None = None,
    methods: Sequence[str] | None = None,
    repeats: int = 3,
    progress: bool | None = None,
    quick: bool = False,
    derivatives: bool = True,
    studies: bool = False,
) -> BenchResult:
    """Measure error against run time for each scene and method (see the module doc).

    Args:
        scenes: names among `SCENES` (default all; ``quick``: ball and planar_trot_rigid).
        methods: names among `METHODS` (default all).
        repeats: timing repeats (the median is kept).
        progress: draw a progress bar on stderr (default None: only when stderr is a
            terminal; True forces it).
        quick: a tiny sweep (a few seconds), for tests and CI.
        derivatives: also measure the cost of flow Jacobians and finite differences.
        studies: also run the stiff and extreme-case studies (`contactdiff.bench.extreme_cases`) and
            the "only what a scene needs" measurements (`contactdiff.bench.footprint`);
            ``quick`` keeps them to seconds.
    """
    scenes = list(scenes) if scenes else list(QUICK_SCENES if quick else SCENES)
    methods = list(methods) if methods else list(METHODS)
    for s in scenes:
        if s not in SCENES:
            raise unknown_name("bench scene", s, list(SCENES))
    for m in methods:
        if m not in METHODS:
            raise unknown_name("bench method", m, list(METHODS))
    if int(repeats) < 1:
        raise InvalidInputError(f"repeats must be >= 1, got {repeats!r}")
    sweep = QUICK_SWEEP if quick else FULL_SWEEP
    deriv_tol = QUICK_DERIV_TOL if quick else FULL_DERIV_TOL
    result = BenchResult(repeats=int(repeats))
    built = {s: (SCENES[s][0](), SCENES[s][1]) for s in scenes}
    tasks = [
        (s, m, p)
        for s in scenes
        for m in methods
        for p in sweep[m]
        if not (m == "solve_ivp-DOP853" and built[s][0].robot.nq != built[s][0].nv)
    ]
    bar = _Progress(len(scenes) + len(tasks) + (len(scenes) if derivatives else 0), progress)
    for s in scenes:
        scene, t_final = built[s]
        result.references[s] = reference(s, scene, t_final)
        bar.step(f"{s}: reference")
    for s, m, p in tasks:
        scene, t_final = built[s]
        ref = result.references[s]
        row = {
            "scene": s,
            "method": m,
            "param": p,
            "param_name": "dt" if m == "time-stepping" else "rtol",
            "n_events_ref": len(ref.event_times),
        }
        try:
            out, times, elapsed = _run_one(s, scene, t_final, m, p, repeats)
            stats = out.stats
            row.update(
                error=state_error(scene, out.q, out.v, ref.q, ref.v),
                event_error=event_error(times, ref.event_times),
                n_events=len(times),
                time=elapsed,
                dynamics_evaluations=int(stats.dynamics_evaluations),
                steps=int(stats.steps),
                failed=None,
            )
        except ContactDiffError as exc:
            row.update(
                error=math.inf,
                event_error=None,
                n_events=0,
                time=math.nan,
                dynamics_evaluations=0,
                steps=0,
                failed=str(exc),
            )
        result.runs.append(row)
        bar.step(f"{s}: {m} {p:g}")
    if derivatives:
        for s in scenes:
            scene, t_final = built[s]
            result.derivatives.append(_derivatives(s, scene, t_final, deriv_tol, repeats))
            bar.step(f"{s}: derivatives")
    ours = [m for m in methods if m.startswith("ours-")]
    for s in scenes:
        for target in TARGETS:
            best, best_m = None, None
            for m in ours:
                t, _ = time_at_error(_curve(result.runs, s, m), target)
                if t is not None and (best is None or t < best):
                    best, best_m = t, m
            for b in (m for m in methods if not m.startswith("ours-")):
                pts = _curve(result.runs, s, b)
                if not pts and not any(r["scene"] == s and r["method"] == b for r in result.runs):
                    continue
                t_b, note = time_at_error(pts, target)
                if t_b is None and best is not None and "~" in note:
                    t_x = float(note.split("~")[1].split(" s")[0])
                    note += f", ~{t_x / best:.2g} x ours ({best_m} {1e3 * best:.2f} ms)"
                if best is None:
                    note = "ours does not reach it" + (f"; baseline: {note}" if note else "")
                ratio = t_b / best if (t_b is not None and best is not None) else None
                if ratio is not None and t_b is not None and best is not None and not note:
                    note = f"baseline {1e3 * t_b:.2f} ms vs {best_m} {1e3 * best:.2f} ms"
                elif ratio is not None and t_b is not None and best is not None:
                    note = f"baseline {1e3 * t_b:.2f} ms ({note}) vs {best_m} {1e3 * best:.2f} ms"
                result.ratios.append(
                    {
                        "scene": s,
                        "baseline": b,
                        "target": target,
                        "time_baseline": t_b,
                        "time_ours": best,
                        "ours_method": best_m,
                        "ratio": ratio,
                        "note": note,
                    }
                )
    if studies:
        from .extreme_cases import run_studies
        from .footprint import measure_footprint

        result.studies = run_studies(quick=quick)
        result.footprint = measure_footprint(quick=quick)
    return result


__all__ = [
    "BenchResult",
    "Reference",
    "run_bench",
    "time_at_error",
    "state_error",
    "event_error",
    "ball_closed_form",
    "SCENES",
    "METHODS",
]
