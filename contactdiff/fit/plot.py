"""A fit's trajectories drawn: measured positions (dots) against the fitted rollout (lines)."""

from __future__ import annotations

import numpy as np

MAX_PANELS = 6
"""Trajectories drawn at most (the first ones)."""


def plot_fit(result, recordings, path) -> None:
    """Write a figure to ``path``: one panel per trajectory (at most `MAX_PANELS`), the free
    bodies' position coordinates (m) over time (s), measured as dots, fitted as lines; a
    configuration of fewer than 7 coordinates (no free body) shows its first three instead."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    shown = list(zip(recordings, result.recordings))[:MAX_PANELS]
    fig, axes = plt.subplots(len(shown), 1, figsize=(7, 2.4 * len(shown)), squeeze=False, sharex=False)
    for ax, (rec, fitted) in zip(axes[:, 0], shown):
        k = rec.compared
        coordinates = (
            list(zip(range(3), "xyz"))
            if rec.q.shape[1] >= 7
            else [(j, f"q[{j}]") for j in range(min(3, rec.q.shape[1]))]
        )
        for j, label in coordinates:
            color = f"C{j}"
            ax.plot(rec.t[k], rec.q[k, j], ".", color=color, markersize=3, label=f"{label} measured")
            ax.plot(rec.t[k], fitted.q[:, j], "-", color=color, linewidth=1.2, label=f"{label} fitted")
        verdict = "" if fitted.differentiable else " (not differentiable)"
        ax.set_title(f"{fitted.name}: rms residual {fitted.rms:.3g}{verdict}", fontsize=9)
        ax.set_ylabel("m" if rec.q.shape[1] >= 7 else "q")
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("t (s)")
    axes[0, 0].legend(fontsize=7, ncol=3, loc="best")
    values = ", ".join(
        f"{n} = {v:.4g} ± {e:.2g}" for n, v, e in zip(result.names, result.values, np.asarray(result.standard_errors))
    )
    fig.suptitle(values, fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


__all__ = ["plot_fit", "MAX_PANELS"]
