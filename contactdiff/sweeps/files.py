"""Results files: rows written as runs finish, read back to resume a sweep.

Two formats, chosen by the file's suffix (`FORMATS`):

* JSON Lines (``.jsonl``): one JSON object per row, in the order the runs finished;
* CSV (``.csv``): a header of the columns and one line per row. Numbers are
  written with all their digits, true/false in lower case, None as an empty
  cell, lists as JSON, and text that would read back as something else quoted
  as JSON. When a row brings columns the header lacks (the first successful
  run after failed ones), the file is written again with them.

Both read back to the same values they were written from. A line cut short by
an interrupted write is dropped. `ResultsFile.read` returns the flat rows in
file order; a later row for the same point replaces an earlier one.
"""

from __future__ import annotations

import csv
import json
from enum import StrEnum
from pathlib import Path

from ..errors import InvalidInputError, ModelLoadError, check_output_file


class FileFormat(StrEnum):
    """Results file formats, by suffix."""

    JSONL = ".jsonl"
    CSV = ".csv"


FORMATS = tuple(FileFormat)
"""Valid suffixes of a results file."""


class ResultsFile:
    """A results file (JSON Lines or CSV, by suffix) that rows are appended to.

    Args:
        path: the file; its folder must exist.

    Raises:
        InvalidInputError: an unknown suffix (the valid ones are listed), a missing
            folder, or a folder given as the file.
    """

    def __init__(self, path: str | Path):
        self.path = Path(path)
        suffix = self.path.suffix.lower()
        if suffix not in FORMATS:
            raise InvalidInputError(f"--out {str(path)!r}: unknown format {suffix or '(no suffix)'!r}; valid: "
                                    + ", ".join(FORMATS))
        check_output_file("--out", path, "results" + suffix)
        self.format = FileFormat(suffix)
        self._header: list[str] | None = None

    def read(self) -> list[dict]:
        """The rows already in the file (flat form), in file order; [] without a file.

        Raises:
            ModelLoadError: the file cannot be read, or a line (other than a last one
                cut short) is not a row.
        """
        if not self.path.exists():
            return []
        try:
            text = self.path.read_text()
        except (OSError, UnicodeDecodeError) as exc:
            raise ModelLoadError(f"cannot read results file {str(self.path)!r}: {exc}") from None
        text = _complete_lines(text)
        if self.format is FileFormat.JSONL:
            rows = []
            for n, line in enumerate(text.splitlines(), 1):
                if line.strip():
                    try:
                        rows.append(json.loads(line))
                    except json.JSONDecodeError as exc:
                        raise ModelLoadError(f"results file {str(self.path)!r} line {n} is not JSON: {exc}") from None
            return rows
        reader = csv.DictReader(text.splitlines())
        self._header = list(reader.fieldnames or [])
        return [{k: _from_cell(v) for k, v in line.items()} for line in reader]

    def start(self) -> None:
        """Prepare to append: drop a last line cut short by an interrupted write."""
        if self.path.exists():
            text = self.path.read_text()
            complete = _complete_lines(text)
            if complete != text:
                self.path.write_text(complete)
            if self.format is FileFormat.CSV and self._header is None:
                self.read()

    def append(self, row: dict) -> None:
        """Write one row (flat form) at the end of the file, flushed."""
        if self.format is FileFormat.JSONL:
            with self.path.open("a") as f:
                f.write(json.dumps(row, allow_nan=False) + "\n")
            return
        header = self._header or []
        missing = [k for k in row if k not in header]
        if missing or not self.path.exists() or not header:
            rows = self.read() if self.path.exists() and header else []
            self._header = header + missing
            with self.path.open("w", newline="") as f:
                writer = csv.DictWriter(f, self._header)
                writer.writeheader()
                for old in rows + [row]:
                    writer.writerow({k: _to_cell(old.get(k)) for k in self._header})
            return
        with self.path.open("a", newline="") as f:
            csv.DictWriter(f, self._header).writerow({k: _to_cell(row.get(k)) for k in self._header})


def _complete_lines(text: str) -> str:
    """``text`` up to its last newline (a last line without one was cut short)."""
    return text if not text or text.endswith("\n") else text[:text.rfind("\n") + 1]


def _to_cell(value) -> str:
    if value is None:
        return ""
    if isinstance(value, str):
        try:
            json.loads(value)
        except ValueError:
            return value  # plain text: written as it is
        return json.dumps(value)  # text that reads as a number, true, null, ...: quoted
    return json.dumps(value, allow_nan=False)


def _from_cell(text: str | None):
    if text is None or text == "":
        return None
    try:
        return json.loads(text)
    except ValueError:
        return text


__all__ = ["ResultsFile", "FileFormat", "FORMATS"]
