"""Rows of the stiff and extreme-case studies, and what every study shares."""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, field

import numpy as np

from ..errors import ContactDiffError
from ..integration.hybrid import simulate
from ..jsonable import to_jsonable
from ..model.scene import Scene
from .metrics import state_error as bench_state_error

SQ2 = math.sqrt(2.0)
DEFAULT_TOL = dict(rtol=1e-8, atol=1e-10)
TIGHT_TOL = dict(rtol=1e-12, atol=1e-14)


@dataclass
class StudyRow:
    """One run of a study.

    Attributes:
        study: the study (``stiffness``, ``tiny-mass``, ...).
        case: the scene or variant.
        parameter: the swept value, as text (``k x 1e5``, ``u = 1e-9 m/s``, ...).
        method: ``simulate``'s method (``auto``, ``DOP853``, ``Radau``) or ``-``.
        error: error against ``reference`` (None where there is none).
        reference: what the error is measured against.
        time: run time of one run (s).
        steps, evaluations: accepted steps and dynamics evaluations.
        outcome: what happened (``ok``, an event kind, a named error, ``refused``...).
        ok: whether the outcome is the right one (correct within the stated bound,
            or a named error where one is due).
        details: further numbers of the row.
    """

    study: str
    case: str
    parameter: str
    method: str
    error: float | None
    reference: str
    time: float
    steps: int
    evaluations: int
    outcome: str
    ok: bool
    details: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        """JSON-ready form: every field (times in s)."""
        return to_jsonable(asdict(self))


@dataclass
class StudyResult:
    """The rows of several studies."""

    rows: list[StudyRow] = field(default_factory=list)

    def to_dict(self) -> dict:
        """JSON-ready form: the rows and ``all_ok`` (every row's outcome the right one)."""
        return {"rows": [r.to_dict() for r in self.rows], "all_ok": all(r.ok for r in self.rows)}

    def format(self) -> str:
        """One table per study (run times in ms), each with what its errors are measured against."""
        out = []
        for study in dict.fromkeys(r.study for r in self.rows):
            rows = [r for r in self.rows if r.study == study]
            out.append(f"== study: {study}")
            out.append(
                f"  {'case':<30} {'parameter':<24} {'method':<7} {'error':>9} {'time (ms)':>10} "
                f"{'steps':>7} {'evals':>8}  outcome"
            )
            for r in rows:
                err = "-" if r.error is None else f"{r.error:.2e}"
                mark = "" if r.ok else "  <-- NOT OK"
                out.append(
                    f"  {r.case[:30]:<30} {r.parameter[:24]:<24} {r.method:<7} {err:>9} "
                    f"{1e3 * r.time:>10.1f} {r.steps:>7d} {r.evaluations:>8d}  {r.outcome}{mark}"
                )
            refs = sorted({r.reference for r in rows if r.reference})
            out.append("  error against: " + "; ".join(refs))
            out.append("")
        return "\n".join(out)


def _run(scene, t_final, **options):
    """simulate() timed once; returns (trajectory or the named error, seconds)."""
    start = time.perf_counter()
    try:
        out = simulate(scene, t_final, **options)
    except ContactDiffError as exc:
        out = exc
    return out, time.perf_counter() - start


def _failed(base: dict, error: ContactDiffError, elapsed: float) -> StudyRow:
    """The row of a run that ended in a named error."""
    return StudyRow(
        **base, error=None, time=elapsed, steps=0, evaluations=0, outcome=f"{type(error).__name__}: {error}", ok=False
    )


def _skipped(base: dict, reason: str, details: dict) -> StudyRow:
    """The row of a case not run for ``reason`` (no error, no time, counted as ok)."""
    return StudyRow(
        **base,
        error=None,
        time=math.nan,
        steps=0,
        evaluations=0,
        outcome=f"skipped: {reason}",
        ok=True,
        details=details,
    )


def _error_name(out) -> str:
    """Name of the error a `_run` returned, or ``"no error"``."""
    return type(out).__name__ if isinstance(out, Exception) else "no error"


def _counts(traj) -> tuple[int, int]:
    return int(traj.stats.steps), int(traj.stats.dynamics_evaluations)


def state_error(scene: Scene, traj, q_ref, v_ref) -> float:
    """``max(|q ⊖ q_ref|_inf, |v - v_ref|_inf)`` of a trajectory's final state (`bench.state_error`)."""
    return bench_state_error(scene, traj.q, traj.v, np.asarray(q_ref, dtype=float), np.asarray(v_ref))
