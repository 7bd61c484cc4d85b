"""Figures that must stay readable: log axes whose tick labels do not run into each other
(`contactdiff.plotting.readable_log_ticks`) and sweep lines that show their gaps."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

pytest.importorskip("matplotlib")

from contactdiff.bench.methods import METHODS  # noqa: E402
from contactdiff.plotting import bench_figure  # noqa: E402
from contactdiff.sweeps.plot import sweep_figure  # noqa: E402
from contactdiff.sweeps.rows import Row, RunError, SweepResult  # noqa: E402


def _labels(fig, axis):
    """The visible, non-empty tick labels of ``axis`` and their boxes in the drawn figure (pixels)."""
    renderer = fig.canvas.get_renderer()
    fig.draw(renderer)
    low, high = sorted(axis.get_view_interval())
    out = []
    for tick in axis.get_major_ticks() + axis.get_minor_ticks():
        label = tick.label1
        if label.get_visible() and label.get_text() and low <= tick.get_loc() <= high:
            out.append((label.get_text(), label.get_window_extent(renderer)))
    return out


@pytest.mark.parametrize("times", [(1.5e-3, 2.5e-2), (2.1e-3, 4.0e-3), (1e-4, 30.0)])
def test_bench_tick_labels_do_not_overlap(times):
    """Run times spanning 1.2 decades (the bench --quick panel whose minor labels read
    2×10⁻³3×10⁻³...), 0.28 decades and 5.5 decades: at least two labels on the x axis, and no
    two labels' boxes intersect."""
    runs = [
        {"scene": "ball", "method": m, "time": t, "error": e, "failed": False}
        for m in METHODS[:2]
        for t, e in zip(np.geomspace(*times, 5), np.geomspace(1e-3, 1e-12, 5))
    ]
    fig = bench_figure(SimpleNamespace(references={"ball": None}, runs=runs))
    ax = fig.axes[0]
    for axis in (ax.xaxis, ax.yaxis):
        labels = _labels(fig, axis)
        assert len(labels) >= 2, labels
        boxes = sorted((b for _, b in labels), key=lambda b: b.x0 if axis is ax.xaxis else b.y0)
        for a, b in zip(boxes, boxes[1:]):
            assert not a.overlaps(b), [t for t, _ in labels]


def _line_sweep(values) -> SweepResult:
    rows = []
    for k, v in enumerate(values):
        error = RunError("IntegrationError", "stopped") if v == "failed" else None
        outputs = {} if error else {"events": v}
        rows.append(Row(k, {"q:z": 1.0 + 0.1 * k}, outputs, error=error))
    return SweepResult(rows, ["q:z"], default_output="events")


def test_a_sweep_line_shows_its_gaps():
    """Six points, one value None and two failed runs: every point with a value has a marker,
    the three without one are marked on the x axis, and the title counts them."""
    result = _line_sweep([3, None, 5, "failed", 4, "failed"])
    fig = sweep_figure(result)
    ax = fig.axes[0]
    line, gaps = ax.get_lines()
    assert line.get_marker() == "o"
    shown = np.asarray(line.get_ydata(), dtype=float)
    assert np.isfinite(shown).sum() == 3
    assert np.asarray(gaps.get_xdata(), dtype=float).tolist() == pytest.approx([1.1, 1.3, 1.5])
    assert "3 without a value: 2 failed, 1 missing" in ax.get_title()
    assert any("no value (3)" in t.get_text() for t in ax.get_legend().get_texts())


def test_a_sweep_line_without_gaps_has_no_note():
    fig = sweep_figure(_line_sweep([3, 4, 5]))
    ax = fig.axes[0]
    assert len(ax.get_lines()) == 1 and "without" not in ax.get_title()
