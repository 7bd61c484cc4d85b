"""The benchmark's results (`contactdiff.bench.runner`): each scene's reference
and its convergence check, the rows of every method's sweep, the ratios at equal
error, and their text, JSON and plot."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ..jsonable import to_jsonable

if TYPE_CHECKING:
    from .footprint import Footprint
    from .study_rows import StudyResult


@dataclass
class Reference:
    """Reference solution of a scene: final state and event times."""

    kind: str  # "closed-form" or "DOP853 rtol=1e-13"
    q: np.ndarray
    v: np.ndarray
    event_times: list[float]
    convergence: float | None = None  # |ref - run at rtol 1e-12| (state), None for closed form
    convergence_events: float | None = None

    def to_dict(self) -> dict:
        """JSON-ready form: ``q`` and ``v`` as lists, event times in s."""
        return {
            "kind": self.kind,
            "q": self.q.tolist(),
            "v": self.v.tolist(),
            "event_times": list(self.event_times),
            "convergence": self.convergence,
            "convergence_events": self.convergence_events,
        }


@dataclass
class BenchResult:
    """What `run_bench` measured.

    Attributes:
        runs: one dict per (scene, method, parameter): ``scene, method, param``
            (``rtol`` or ``dt``), ``param_name``, ``error`` (final state),
            ``event_error``, ``n_events``, ``n_events_ref``, ``time`` (s, median),
            ``dynamics_evaluations``, ``steps``, ``failed`` (message or None).
        references: scene -> `Reference`.
        derivatives: one dict per scene: ``nv``, ``tol``, ``time_plain``,
            ``time_jacobian``, ``time_fd``, ``jacobian_over_plain``, ``fd_over_jacobian``,
            ``jacobian_vs_fd`` (relative difference), ``fd_runs``, ``fd_skipped`` (why the
            FD columns are None: a scene starting in contact admits no perturbation
            pushing a foot through the ground).
        ratios: one dict per (scene, baseline, target): ``time_baseline``,
            ``time_ours``, ``ours_method``, ``ratio`` (None where a method does not reach
            the target), ``note``.
        repeats: timing repeats.
    """

    runs: list[dict] = field(default_factory=list)
    references: dict[str, Reference] = field(default_factory=dict)
    derivatives: list[dict] = field(default_factory=list)
    ratios: list[dict] = field(default_factory=list)
    repeats: int = 3
    studies: StudyResult | None = None  # the stiff and extreme cases, with --studies
    footprint: Footprint | None = None  # only what a scene needs, with --studies

    def to_dict(self) -> dict:
        """JSON-ready form: every measurement, with the studies and footprint when run."""
        extra = {}
        if self.studies is not None:
            extra["studies"] = self.studies.to_dict()
        if self.footprint is not None:
            extra["footprint"] = dict(self.footprint)
        return {
            "repeats": self.repeats,
            "runs": [to_jsonable(r) for r in self.runs],
            "references": {k: to_jsonable(r.to_dict()) for k, r in self.references.items()},
            "derivatives": [to_jsonable(d) for d in self.derivatives],
            "ratios": [to_jsonable(r) for r in self.ratios],
        } | extra

    def format(self) -> str:
        """The tables as text."""
        out = []
        for scene, ref in self.references.items():
            conv = (
                ""
                if ref.convergence is None
                else f"; vs rtol 1e-12: state {ref.convergence:.1e}, events {_num(ref.convergence_events)}"
            )
            out.append(f"== {scene}  (reference: {ref.kind}, {len(ref.event_times)} events{conv})")
            out.append(
                f"  {'method':<17} {'param':>9} {'state err':>10} {'event err':>10} "
                f"{'events':>7} {'time (ms)':>10} {'dyn evals':>10} {'steps':>7}"
            )
            for r in self.runs:
                if r["scene"] != scene:
                    continue
                if r["failed"]:
                    out.append(f"  {r['method']:<17} {r['param']:>9.0e}  failed: {r['failed']}")
                    continue
                ev = f"{r['n_events']}/{r['n_events_ref']}"
                out.append(
                    f"  {r['method']:<17} {r['param']:>9.0e} {r['error']:>10.2e} "
                    f"{_num(r['event_error']):>10} {ev:>7} {1e3 * r['time']:>10.2f} "
                    f"{r['dynamics_evaluations']:>10d} {r['steps']:>7d}"
                )
            out.append("")
        if self.derivatives:
            out.append("== derivatives: flow Jacobian vs plain run vs central FD (4 nv runs)")
            out.append(
                f"  {'scene':<18} {'nv':>3} {'plain (ms)':>11} {'jac (ms)':>10} {'FD (ms)':>10} "
                f"{'jac/plain':>10} {'FD/jac':>8} {'|J-FD|/|J|':>11} {'steps plain/jac':>16}"
            )
            for d in self.derivatives:
                steps = f"{d['steps_plain']}/{d['steps_jacobian']}"
                fd = d["time_fd"] is not None
                t_fd = f"{1e3 * d['time_fd']:.1f}" if fd else "-"
                fd_ratio = f"{d['fd_over_jacobian']:.1f}" if fd else "-"
                fd_err = f"{d['jacobian_vs_fd']:.1e}" if fd else "-"
                out.append(
                    f"  {d['scene']:<18} {d['nv']:>3} {1e3 * d['time_plain']:>11.2f} "
                    f"{1e3 * d['time_jacobian']:>10.2f} {t_fd:>10} "
                    f"{d['jacobian_over_plain']:>10.2f} {fd_ratio:>8} {fd_err:>11} {steps:>16}"
                    + ("" if fd else f"  (FD skipped: {d['fd_skipped']})")
                    + (
                        ""
                        if d["differentiable"]
                        else "  (not differentiable: simultaneous event whose landing orders differ; FD meaningless)"
                    )
                )
            out.append("")
        if self.ratios:
            out.append("== time of a baseline / ours at equal final-state error (log-log interpolation)")
            for r in self.ratios:
                ratio = "n/a" if r["ratio"] is None else f"{r['ratio']:.3g}"
                out.append(f"  {r['scene']:<18} {r['baseline']:<17} err {r['target']:.0e}: {ratio:>8}  {r['note']}")
        if self.studies is not None:
            out += ["", self.studies.format()]
        if self.footprint is not None:
            out += ["", self.footprint.format()]
        return "\n".join(out)

    def plot(self, path: str) -> None:
        """Log-log error vs run time, one panel per scene, one line per method
        (`contactdiff.plotting.plot_bench`)."""
        from ..plotting import plot_bench

        plot_bench(self, path)


def _num(x) -> str:
    return "-" if x is None else f"{x:.2e}"
