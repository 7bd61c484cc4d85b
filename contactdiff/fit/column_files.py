"""Named columns of numbers written as a CSV or ``.npz`` file (docs/observations.md).

What the columns mean is `contactdiff.fit.observations`'; reading them back, with
the checks of a measured table, is `contactdiff.fit.observation_files`'.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from ..errors import ObservationFileError, OutputFileError

FORMATS = (".csv", ".npz")
"""The suffixes of observation files."""


def write_columns(columns: dict[str, np.ndarray], path: str | Path) -> Path:
    """Write ``columns`` (name -> 1-D array, all of one length) as CSV (17 significant
    digits: a float read back is the float written) or ``.npz``, by the suffix of ``path``.

    Raises:
        ObservationFileError: an unknown suffix; OutputFileError: the file cannot be written.
    """
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix not in FORMATS:
        raise ObservationFileError(
            f"{path}: unknown kind of observation file {p.suffix!r}; valid: {', '.join(FORMATS)}"
        )
    try:
        if suffix == ".npz":
            np.savez(p, **columns)  # type: ignore[arg-type]  # mypy matches the ** dict against the bool allow_pickle too
        else:
            table = np.column_stack(list(columns.values()))
            with p.open("w", newline="", encoding="utf-8") as handle:
                writer = csv.writer(handle)
                writer.writerow(list(columns))
                writer.writerows([[f"{x:.17g}" for x in row] for row in table])
    except OSError as exc:
        raise OutputFileError(f"{path}: cannot write the observations ({exc})") from None
    return p


__all__ = ["FORMATS", "write_columns"]
