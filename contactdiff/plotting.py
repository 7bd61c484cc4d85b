"""Figures (matplotlib, an optional extra imported only here and only when plotting)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .errors import ContactDiffError
from .trajectory import Trajectory


def _pyplot():
    try:
        import matplotlib
    except ImportError:
        raise ContactDiffError("plotting needs matplotlib: pip install 'contactdiff[plot]'") from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


_EVENT_STYLE = {"touchdown": ("tab:red", "-"), "lift-off": ("tab:green", "--"), "bounce": ("tab:orange", ":"),
                "grazing": ("tab:purple", "-."), "zeno": ("black", "-")}


def plot_gaps(traj: Trajectory, scene, path: str | Path, n_samples: int = 800) -> Path:
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
        ax.axvline(e.t, color=color, ls=style, lw=0.8, alpha=0.7,
                   label=e.kind if e.kind not in seen else None)
        seen.add(e.kind)
    ax.axhline(0.0, color="k", lw=0.6)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("contact gap (m)")
    ax.set_title(f"{traj.scene_name}: contact gaps and events")
    ax.legend(loc="best", fontsize=8)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return Path(path)
