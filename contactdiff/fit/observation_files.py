"""Observation files: CSV and ``.npz`` tables of a measured trajectory (docs/observations.md).

CSV: UTF-8 text, a header row of column names (`contactdiff.fit.observations` lists
them: ``t``, ``weight``, and each joint's), then one row of numbers per sample; blank
lines and lines starting with ``#`` are skipped; spaces around names and numbers are
ignored. ``.npz``: one 1-D array per column, by the same names. Every fault is one
`ObservationFileError` naming the file and what is wrong.
"""

from __future__ import annotations

import csv
import zipfile
from pathlib import Path

import numpy as np

from ..errors import ObservationFileError
from .column_files import FORMATS, write_columns
from .observations import Observations, from_columns


def load_observations(path: str | Path, scene) -> Observations:
    """Read a measured trajectory of ``scene`` from a CSV or ``.npz`` file.

    Args:
        path: the file (``.csv`` or ``.npz``, by its suffix).
        scene: the `Scene` observed (its joints name the columns).

    Returns:
        The `Observations` (its ``source`` is ``path``).

    Raises:
        ObservationFileError: a missing, unreadable or unknown kind of file, or a bad
            table (`contactdiff.fit.observations.from_columns`), in one line naming the file.
    """
    source = str(path)
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix not in FORMATS:
        raise ObservationFileError(
            f"{source}: unknown kind of observation file {p.suffix!r}; valid: {', '.join(FORMATS)}"
        )
    if not p.is_file():
        raise ObservationFileError(f"{source}: no such file")
    if suffix == ".csv":
        columns, lines = _read_csv(p, source)
    else:
        columns, lines = _read_npz(p, source), None
    return from_columns(columns, scene, source, lines)


def _read_csv(path: Path, source: str) -> tuple[dict, list[int]]:
    """Columns by name (file order) and each data row's line number."""
    try:
        with path.open(newline="", encoding="utf-8") as handle:
            rows = [
                (n, row)
                for n, row in enumerate(csv.reader(handle), start=1)
                if row and any(c.strip() for c in row) and not row[0].lstrip().startswith("#")
            ]
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise ObservationFileError(f"{source}: not a readable CSV file ({exc})") from None
    if not rows:
        raise ObservationFileError(f"{source}: empty (a CSV observation file starts with a header row of column names)")
    _, header = rows[0]
    names = [c.strip() for c in header]
    if "" in names:
        raise ObservationFileError(f"{source}: header column {names.index('') + 1} has no name")
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise ObservationFileError(f"{source}: column(s) named twice: {', '.join(twice)}")
    data, lines = [], []
    for k, (line, row) in enumerate(rows[1:]):
        if len(row) != len(names):
            raise ObservationFileError(
                f"{source}: row {k} (line {line}) has {len(row)} values for {len(names)} columns"
            )
        values = []
        for name, cell in zip(names, row):
            try:
                values.append(float(cell))
            except ValueError:
                raise ObservationFileError(
                    f"{source}: row {k} (line {line}), column {name!r}: {cell.strip()!r} is not a number"
                ) from None
        data.append(values)
        lines.append(line)
    table = np.array(data, dtype=float).reshape(len(data), len(names))
    return {name: table[:, i] for i, name in enumerate(names)}, lines


def _read_npz(path: Path, source: str) -> dict:
    try:
        with np.load(path, allow_pickle=False) as archive:
            return {name: archive[name] for name in archive.files}
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
        raise ObservationFileError(f"{source}: not a readable .npz file ({exc})") from None


def save_observations(observations: Observations, path: str | Path, scene) -> Path:
    """Write ``observations`` of ``scene`` as CSV (17 significant digits: a float read back
    is the float written) or ``.npz``, by the suffix of ``path``.

    Raises:
        ObservationFileError: an unknown suffix; OutputFileError: the file cannot be written.
    """
    return write_columns(observations.columns(scene), path)
