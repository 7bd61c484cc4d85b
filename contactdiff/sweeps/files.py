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
file order; a later row for the same point replaces an earlier one. A damaged
line elsewhere (not JSON, not an object, a CSV line whose cells do not match the
header, a row without its index or sweep) is not a row: `ResultsFile.damaged`
names it (`Damage`: line number, what is wrong), and `ResultsFile.start` can
leave it out when the file is written again.
"""

from __future__ import annotations

import csv
import json
from collections.abc import Iterable
from dataclasses import dataclass
from enum import StrEnum
from pathlib import Path

from ..errors import InvalidInputError, ModelLoadError, check_output_file


class FileFormat(StrEnum):
    """Results file formats, by suffix."""

    JSONL = ".jsonl"
    CSV = ".csv"


FORMATS = tuple(FileFormat)
"""Valid suffixes of a results file."""


@dataclass(frozen=True)
class Damage:
    """A line of a results file that is not a row.

    Attributes:
        line: its number in the file (1 is the first; for a CSV row over several lines, its last).
        reason: what is wrong with it.
    """

    line: int
    reason: str

    def __str__(self) -> str:
        return f"line {self.line}: {self.reason}"


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
            raise InvalidInputError(
                f"--out {str(path)!r}: unknown format {suffix or '(no suffix)'!r}; valid: " + ", ".join(FORMATS)
            )
        check_output_file("--out", path, "results" + suffix)
        self.format = FileFormat(suffix)
        self._header: list[str] | None = None
        self.damaged: list[Damage] = []

    def read(self) -> list[dict]:
        """The rows already in the file (flat form), in file order; [] without a file.
        Damaged lines are left out and listed in `damaged`.

        Raises:
            ModelLoadError: the file cannot be read.
        """
        return [row for _, row in self.lines()]

    def lines(self) -> list[tuple[int, dict]]:
        """The rows already in the file with their line numbers, in file order; [] without
        a file. Sets `damaged`: the lines that are not rows (`Damage`).

        Raises:
            ModelLoadError: the file cannot be read.
        """
        self.damaged = []
        if not self.path.exists():
            return []
        try:
            text = self.path.read_text()
        except (OSError, UnicodeDecodeError) as exc:
            raise ModelLoadError(f"cannot read results file {str(self.path)!r}: {exc}") from None
        text = _complete_lines(text)
        rows = []
        for n, row in self._parse(text):
            reason = row if isinstance(row, str) else _not_a_row(row)
            if reason:
                self.damaged.append(Damage(n, reason))
            else:
                rows.append((n, row))
        return rows

    def _parse(self, text: str):
        """``(line number, flat row or what is wrong with the line)`` for each line of ``text``."""
        if self.format is FileFormat.JSONL:
            for n, line in enumerate(text.splitlines(), 1):
                if line.strip():
                    try:
                        yield n, json.loads(line)
                    except json.JSONDecodeError as exc:
                        yield n, f"not JSON ({exc})"
            return
        reader = csv.reader(text.splitlines(keepends=True))
        self._header = None
        while True:
            try:
                cells = next(reader)
            except StopIteration:
                return
            except csv.Error as exc:
                yield reader.line_num, f"not CSV ({exc})"
                continue
            if not cells:
                continue  # a blank line
            if self._header is None:
                self._header = cells
            elif len(cells) != len(self._header):
                yield reader.line_num, f"{len(cells)} cells, the header has {len(self._header)}"
            else:
                yield reader.line_num, {k: _from_cell(v) for k, v in zip(self._header, cells)}

    def start(self, drop: Iterable[int] = ()) -> None:
        """Prepare to append: drop a last line cut short by an interrupted write, and the
        lines numbered ``drop`` (damaged ones)."""
        drop = set(drop)
        if self.path.exists():
            text = self.path.read_text()
            complete = _complete_lines(text)
            if drop and self.format is FileFormat.CSV:
                kept = [row for n, row in self.lines() if n not in drop]
                self._write_csv(self._header or [], kept)
                return
            if drop:
                complete = "".join(
                    line for n, line in enumerate(complete.splitlines(keepends=True), 1) if n not in drop
                )
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
            self._write_csv(header + missing, rows + [row])
            return
        with self.path.open("a", newline="") as f:
            csv.DictWriter(f, header).writerow({k: _to_cell(row.get(k)) for k in header})

    def _write_csv(self, header: list[str], rows: list[dict]) -> None:
        """Write the file anew: ``header`` and ``rows``."""
        self._header = header
        with self.path.open("w", newline="") as f:
            writer = csv.DictWriter(f, header)
            writer.writeheader()
            for row in rows:
                writer.writerow({k: _to_cell(row.get(k)) for k in header})


def _not_a_row(row) -> str:
    """What keeps ``row`` (a line read back) from being a row; "" if nothing does."""
    if not isinstance(row, dict):
        return f"not an object but {type(row).__name__}"
    index = row.get("index")
    if isinstance(index, bool) or not isinstance(index, int) or index < 0:
        return f"its index is {index!r}, not a count"
    if not isinstance(row.get("sweep"), str) or not row["sweep"]:
        return f"its sweep is {row.get('sweep')!r}, not an identity"
    return ""


def _complete_lines(text: str) -> str:
    """``text`` up to its last newline (a last line without one was cut short)."""
    return text if not text or text.endswith("\n") else text[: text.rfind("\n") + 1]


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


__all__ = ["ResultsFile", "FileFormat", "FORMATS", "Damage"]
