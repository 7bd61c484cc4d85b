"""A figure of one output over a sweep: a line over one quantity, a heatmap over two.

The quantities drawn are those whose value changes between the rows (fixed
ones are left out). Over two quantities whose points form a full grid, a
heatmap; over two that do not (random samples), a scatter coloured by the
output. Failed runs and missing values are gaps: a line breaks there, every point
with a value has its marker, each point without one is marked on the x axis, and
the title says how many there are. Text values (a factory's
``arg:robot``) are placed in their order of appearance. matplotlib is imported
only here, only when drawing.
"""

from __future__ import annotations

import numbers
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

import numpy as np

from ..errors import InvalidInputError, unknown_name

if TYPE_CHECKING:
    from matplotlib.figure import Figure


class SweepRows(Protocol):
    """What a sweep's figure reads of its rows (`contactdiff.sweeps.rows.SweepResult`)."""

    names: tuple[str, ...]
    default_output: str | None

    @property
    def failed(self) -> list: ...
    def __len__(self) -> int: ...
    def column(self, name: str) -> list: ...
    def numeric_outputs(self) -> list[str]: ...


def numeric_outputs(result: SweepRows) -> list[str]:
    """Output columns holding numbers (or true/false) in some row, in column order
    (`SweepResult.numeric_outputs`)."""
    return result.numeric_outputs()


def plot_sweep(result: SweepRows, path: str | Path, output: str | None = None) -> Path:
    """Draw ``output`` (default: the job's, e.g. ``events`` for a plain simulation, else
    the first numeric output) over the swept quantities and save it to ``path``
    (`sweep_figure`).

    Raises:
        UnknownNameError: ``output`` is not a numeric output of the rows (they are listed).
        InvalidInputError: not 1 or 2 varying quantities, or no row has a value.
    """
    from ..plotting import _pyplot

    plt = _pyplot()
    fig = sweep_figure(result, output)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return Path(path)


def sweep_figure(result: SweepRows, output: str | None = None) -> Figure:
    """The matplotlib ``Figure`` of `plot_sweep` (same arguments and errors)."""
    from ..plotting import _pyplot

    valid = numeric_outputs(result)
    if output is None:
        output = result.default_output if result.default_output in valid else (valid[0] if valid else None)
    if output not in valid:
        raise unknown_name("numeric output to plot", output, valid)
    varying = [n for n in result.names if len({repr(v) for v in result.column(n)}) > 1]
    if len(varying) not in (1, 2):
        raise InvalidInputError(
            f"a sweep plot draws over 1 or 2 quantities; {len(varying)} vary here"
            + (f": {', '.join(varying)}" if varying else "")
        )
    z = np.array([np.nan if v is None else float(v) for v in result.column(output)])
    if not np.isfinite(z).any():
        raise InvalidInputError(f"no row has a value of {output!r} to plot (every run failed?)")
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7, 4.5), constrained_layout=True)
    if len(varying) == 1:
        x, labels = _axis(result.column(varying[0]))
        order = np.argsort(x, kind="stable")
        x, zs = x[order], z[order]
        ax.plot(x, zs, "o-", ms=4, color="C0", label=output)  # a NaN breaks the line: a gap
        gaps = ~np.isfinite(zs)
        if gaps.any():  # on the x axis (axes coordinates in y), where the line has no value
            ax.plot(
                x[gaps],
                np.full(gaps.sum(), 0.02),
                "x",
                ms=8,
                mew=2,
                color="tab:red",
                clip_on=False,
                transform=ax.get_xaxis_transform(),
                label=f"no value ({gaps.sum()})",
            )
            ax.legend(fontsize=8, loc="best")
        _label(ax.set_xticks, ax.set_xticklabels, labels)
        ax.set_xlabel(varying[0])
        ax.set_ylabel(output)
    else:
        (x, xlabels), (y, ylabels) = (_axis(result.column(n)) for n in varying)
        xs, ys = np.unique(x), np.unique(y)
        if len(xs) * len(ys) == len(z) and len({(a, b) for a, b in zip(x, y)}) == len(z):
            grid = np.full((len(ys), len(xs)), np.nan)
            grid[np.searchsorted(ys, y), np.searchsorted(xs, x)] = z
            image = ax.pcolormesh(_edges(xs), _edges(ys), np.ma.masked_invalid(grid), shading="flat")
        else:
            image = ax.scatter(x, y, c=z, s=30)
        fig.colorbar(image, ax=ax, label=output)
        _label(ax.set_xticks, ax.set_xticklabels, xlabels)
        _label(ax.set_yticks, ax.set_yticklabels, ylabels)
        ax.set_xlabel(varying[0])
        ax.set_ylabel(varying[1])
    ax.set_title(f"{output} over {len(result)} points" + _gaps_note(len(result.failed), int((~np.isfinite(z)).sum())))
    return fig


def _gaps_note(failed: int, without: int) -> str:
    """`` (k without a value: f failed, m missing)`` for a title, or nothing."""
    if not without:
        return ""
    parts = [f"{failed} failed"] * bool(failed) + [f"{without - failed} missing"] * bool(without - failed)
    return f" ({without} without a value: {', '.join(parts)})"


def _axis(values: list) -> tuple[np.ndarray, list[str] | None]:
    """Positions of a column's values, and tick labels where they are text."""
    if all(isinstance(v, numbers.Real) for v in values):
        return np.array(values, dtype=float), None
    labels = list(dict.fromkeys(str(v) for v in values))
    return np.array([labels.index(str(v)) for v in values], dtype=float), labels


def _label(set_ticks, set_labels, labels: list[str] | None) -> None:
    if labels is not None:
        set_ticks(range(len(labels)))
        set_labels(labels)


def _edges(centres: np.ndarray) -> np.ndarray:
    """Cell edges around sorted centres (a single centre gets a unit cell)."""
    if len(centres) == 1:
        return np.array([centres[0] - 0.5, centres[0] + 0.5])
    mid = (centres[1:] + centres[:-1]) / 2
    return np.concatenate([[2 * centres[0] - mid[0]], mid, [2 * centres[-1] - mid[-1]]])


__all__ = ["plot_sweep", "sweep_figure", "numeric_outputs"]
