"""Figures (matplotlib, an optional extra imported only here and only when plotting)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .errors import require_extra
from .integration.trajectory import EventKind, Trajectory

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from .model.scene import Scene


def _pyplot():
    matplotlib = require_extra("matplotlib", "plot", "plotting")
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


_EVENT_STYLE = {
    EventKind.TOUCHDOWN: ("tab:red", "-"),
    EventKind.LIFT_OFF: ("tab:green", "--"),
    EventKind.SLIP: ("tab:olive", "--"),
    EventKind.BOUNCE: ("tab:orange", ":"),
    EventKind.GRAZING: ("tab:purple", "-."),
    EventKind.ZENO: ("black", "-"),
    EventKind.BEAR: ("tab:brown", ":"),
}


def plot_gaps(traj: Trajectory, scene: Scene, path: str | Path, n_samples: int = 800) -> Path:
    """Contact gaps (m) against time with every event marked; saved as PNG.

    Args:
        traj: the trajectory.
        scene: the scene it was computed on (for the contact gaps).
        path: output file.
        n_samples: points per curve (event times are added so jumps are sharp).
    """
    plt = _pyplot()
    times = np.linspace(traj.t0, traj.t, n_samples)
    times = np.unique(np.concatenate([times, [e.t for e in traj.events]]))
    gaps = np.array([scene.gaps(traj.at(float(t))[0]) for t in times])
    fig, ax = plt.subplots(figsize=(8, 4.2), constrained_layout=True)
    for k, name in enumerate(scene.contact_names):
        ax.plot(times, gaps[:, k], label=name, lw=1.4)
    seen = set()
    for e in traj.events:
        color, style = _EVENT_STYLE.get(e.kind, ("gray", "-"))
        ax.axvline(e.t, color=color, ls=style, lw=0.8, alpha=0.7, label=e.kind if e.kind not in seen else None)
        seen.add(e.kind)
    ax.axhline(0.0, color="k", lw=0.6)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("contact gap (m)")
    ax.set_title(f"{traj.scene_name}: contact gaps and events")
    ax.legend(loc="best", fontsize=8)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return Path(path)


def plot_gait(traj: Trajectory, scene: Scene, path: str | Path, n_samples: int = 1500) -> Path:
    """Save `gait_figure` to ``path`` (any format matplotlib writes)."""
    plt = _pyplot()
    fig = gait_figure(traj, scene, n_samples)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return Path(path)


def gait_figure(traj: Trajectory, scene: Scene, n_samples: int = 1500) -> Figure:
    """Gait figure of a floating-base scene: a contact timeline (one row per contact, a
    bar wherever it is active, touchdowns marked red and lift-offs green, with a
    legend), and the base height (m) and its roll and pitch (rad, Pinocchio's
    roll-pitch-yaw of the base orientation) against time (s).

    Args:
        traj: the trajectory.
        scene: the scene it was computed on (a free-flyer robot).
        n_samples: points per curve.

    Returns:
        The matplotlib ``Figure``.
    """
    import pinocchio as pin

    plt = _pyplot()
    times = np.linspace(traj.t0, traj.t, n_samples)
    qs, _ = traj.sample(times)
    rpy = np.array([pin.rpy.matrixToRpy(pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix()) for q in qs])
    fig, (ax_c, ax_z, ax_a) = plt.subplots(
        3, 1, figsize=(9, 7), sharex=True, constrained_layout=True, gridspec_kw={"height_ratios": [1.1, 1, 1]}
    )
    names = scene.contact_names
    for row, name in enumerate(names):
        spans = [(s.t0, s.t1 - s.t0) for s in traj.segments if name in s.mode and s.t1 > s.t0]
        ax_c.broken_barh(spans, (row - 0.35, 0.7), color=f"C{row}")
    ax_c.set_yticks(range(len(names)), names)
    ax_c.set_ylim(len(names) - 0.5, -0.5)
    ax_c.set_title(f"{traj.scene_name}: feet on the ground, base height and attitude")
    for kind, color in ((EventKind.TOUCHDOWN, "tab:red"), (EventKind.LIFT_OFF, "tab:green")):
        marks = [(e.t, names.index(c)) for e in traj.events if e.kind == kind for c in e.contacts]
        if marks:
            ax_c.plot(*zip(*marks), "|", color=color, ms=9, label=kind)
    if ax_c.get_legend_handles_labels()[0]:
        ax_c.legend(loc="upper right", fontsize=8, ncols=2, framealpha=0.9)
    ax_z.plot(times, qs[:, 2], color="k", lw=1.2)
    ax_z.set_ylabel("base height (m)")
    ax_a.plot(times, rpy[:, 0], label="roll", lw=1.2)
    ax_a.plot(times, rpy[:, 1], label="pitch", lw=1.2)
    ax_a.axhline(0.0, color="k", lw=0.5)
    ax_a.set_ylabel("base attitude (rad)")
    ax_a.set_xlabel("time (s)")
    ax_a.legend(loc="best", fontsize=8)
    return fig


def readable_log_ticks(axis) -> None:
    """Tick labels of a log ``axis`` that do not run into each other: no labels on the
    minor ticks (matplotlib labels them on an axis spanning under about two decades,
    where they crowd as ``2×10⁻³3×10⁻³``), and major ticks at 1, 2 and 5 times the
    powers of ten over spans under two decades (1 to 9 times under half a decade) so
    that such an axis still carries at least two labels. Call after the data are drawn."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    low, high = sorted(axis.get_view_interval())
    if not (low > 0 and np.isfinite(high)):
        return
    decades = np.log10(high / low)
    if decades < 2:
        subs = (1.0, 2.0, 5.0) if decades >= 0.5 else tuple(float(k) for k in range(1, 10))
        axis.set_major_locator(LogLocator(base=10.0, subs=subs))
        axis.set_major_formatter(FuncFormatter(_power_label))
    axis.set_minor_formatter(NullFormatter())


def _power_label(value: float, _position=None) -> str:
    """``10^e`` or ``m×10^e`` (mathtext) for a tick at ``m`` times a power of ten."""
    if not value > 0:
        return ""
    exponent = int(np.floor(np.log10(value) + 1e-9))
    mantissa = round(value / 10.0**exponent)
    return f"$10^{{{exponent}}}$" if mantissa == 1 else f"${mantissa}\\times10^{{{exponent}}}$"


def plot_bench(result, path: str | Path) -> Path:
    """Save `bench_figure` of ``result`` to ``path``."""
    plt = _pyplot()
    fig = bench_figure(result)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return Path(path)


def bench_figure(result):
    """A `BenchResult`'s error against run time: log-log, one panel per scene, one
    line per method (colours of ``contactdiff.bench.methods.COLORS``); the matplotlib ``Figure``."""
    import math

    from .bench.methods import COLORS, METHODS

    plt = _pyplot()
    scenes = list(result.references)
    cols = min(3, len(scenes))
    rows = math.ceil(len(scenes) / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(4.5 * cols, 3.8 * rows), squeeze=False)
    for ax, scene in zip(axes.flat, scenes):
        for method in METHODS:
            pts = sorted(
                (r["time"], max(r["error"], 1e-17))
                for r in result.runs
                if r["scene"] == scene and r["method"] == method and not r["failed"] and math.isfinite(r["error"])
            )
            if pts:
                ax.loglog([p[0] for p in pts], [p[1] for p in pts], "o-", label=method, ms=4, color=COLORS[method])
        ax.set_title(scene)
        ax.set_xlabel("run time (s)")
        ax.set_ylabel("final-state error")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
        readable_log_ticks(ax.xaxis)
        readable_log_ticks(ax.yaxis)
    for ax in list(axes.flat)[len(scenes) :]:
        ax.set_visible(False)
    fig.tight_layout()
    return fig
