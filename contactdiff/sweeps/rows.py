"""A sweep's rows: one per point, and the list of them a sweep returns.

A `Row` holds the point's values, the job's outputs, the run time and, for a
failed run, its `RunError` (the class name of the exception and its message).
Its flat form (`Row.to_dict`), one column per name, is what the results files
hold and what `SweepResult.to_pandas` tabulates:

    index, <point values...>, <outputs...>, error, error_message, run_time, sweep

``sweep`` identifies the sweep the row belongs to (scene, job, run settings and
swept names; `contactdiff.sweeps.runner`), so that a results file is resumed
only by the same sweep. Everything but ``run_time`` is the same, to the bit,
whatever the backend and the number of workers.
"""

from __future__ import annotations

import numbers
from collections.abc import Sequence
from dataclasses import dataclass, field

from ..errors import ContactDiffError, require_extra

RESERVED = ("index", "error", "error_message", "run_time", "sweep")
"""Columns of every row besides the point's values and the outputs."""


@dataclass(frozen=True)
class RunError:
    """Why a point's run failed.

    Attributes:
        kind: the exception's class name (``TooManyStepsError``, ``InconsistentStateError``, ...).
        message: its message.
    """

    kind: str
    message: str

    @classmethod
    def of(cls, exc: BaseException) -> RunError:
        """The error of an exception."""
        return cls(type(exc).__name__, str(exc))


@dataclass(frozen=True)
class Row:
    """One point's result.

    Attributes:
        index: the point's position in the sweep's points.
        point: its values by quantity name.
        outputs: the job's outputs by name (empty for a failed run).
        run_time: wall time (s) of the point in its worker: the scene's variant
            (and, for its first point, the worker's build of the scene) and the job.
        error: the `RunError` of a failed run, else None.
        sweep: the identity of the sweep (see the module docstring).
    """

    index: int
    point: dict
    outputs: dict = field(default_factory=dict)
    run_time: float = 0.0
    error: RunError | None = None
    sweep: str = ""

    @property
    def ok(self) -> bool:
        """Whether the run finished without error."""
        return self.error is None

    def to_dict(self, run_time: bool = True) -> dict:
        """The flat form (module docstring); ``run_time=False`` leaves out the one
        column that differs between two runs of the same sweep."""
        out = {
            "index": self.index,
            **self.point,
            **self.outputs,
            "error": None if self.error is None else self.error.kind,
            "error_message": None if self.error is None else self.error.message,
        }
        if run_time:
            out["run_time"] = self.run_time
        out["sweep"] = self.sweep
        return out

    def __getitem__(self, name: str):
        return self.to_dict()[name]

    @classmethod
    def from_dict(cls, flat: dict, names: Sequence[str]) -> Row:
        """A row from its flat form, the point being the columns ``names``."""
        point = {n: flat.get(n) for n in names}
        outputs = {k: v for k, v in flat.items() if k not in RESERVED and k not in point}
        error = None if flat.get("error") is None else RunError(str(flat["error"]), str(flat.get("error_message")))
        return cls(
            int(flat["index"]), point, outputs, float(flat.get("run_time") or 0.0), error, str(flat.get("sweep") or "")
        )


class SweepResult(list):
    """The rows of a sweep, in the order of its points (a list of `Row`).

    Attributes:
        names: the swept quantities.
        skipped: how many rows were read back from the results file instead of run.
        wall_time: wall time of the sweep (s).
    """

    def __init__(
        self,
        rows: Sequence[Row],
        names: Sequence[str],
        skipped: int = 0,
        wall_time: float = 0.0,
        default_output: str | None = None,
    ):
        super().__init__(rows)
        self.names = tuple(names)
        self.skipped = skipped
        self.wall_time = wall_time
        self.default_output = default_output

    @property
    def failed(self) -> list[Row]:
        """The rows whose run failed."""
        return [r for r in self if not r.ok]

    def raise_failure(self) -> SweepResult:
        """These rows if every run succeeded; else the first failed point's error, raised
        as a `ContactDiffError` naming the point (for studies that need every row)."""
        for r in self.failed[:1]:
            assert r.error is not None  # a failed row has its error
            raise ContactDiffError(f"{r.error.kind} at {r.point}: {r.error.message}")
        return self

    def to_dicts(self, run_time: bool = True) -> list[dict]:
        """Every row's flat form (`Row.to_dict`)."""
        return [r.to_dict(run_time) for r in self]

    def column(self, name: str) -> list:
        """One column over the rows (None where a row has no such value, e.g. a failed run)."""
        return [r.to_dict().get(name) for r in self]

    def numeric_outputs(self) -> list[str]:
        """Output columns holding numbers (or true/false) in some row, in column order."""
        names: dict[str, None] = {}
        for row in self:
            for name, value in row.outputs.items():
                if isinstance(value, (numbers.Real, bool)) and name not in RESERVED:
                    names.setdefault(name)
        return list(names)

    def to_pandas(self):
        """The rows as a `pandas.DataFrame`, one column per name (needs pandas).

        Raises:
            MissingExtraError: pandas is not installed.
        """
        return require_extra("pandas", "pandas", "to_pandas").DataFrame(self.to_dicts())

    def plot(self, path, output: str | None = None):
        """Draw ``output`` over the sweep (`contactdiff.sweeps.plot.plot_sweep`)."""
        from .plot import plot_sweep

        return plot_sweep(self, path, output)


__all__ = ["Row", "RunError", "SweepResult", "RESERVED"]
