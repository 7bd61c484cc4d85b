"""Argument types and checks shared by the ``contactdiff`` subcommands (`contactdiff.cli`,
`contactdiff.sweeps.cli`): numbers in a range with messages that name the range, the
``--plot`` option and its early check, ``NAME=VALUE`` items, flushed printing, and
files written after the work (`write_output`)."""

from __future__ import annotations

import argparse

from .errors import (
    ContactDiffError,
    InvalidInputError,
    OutputFileError,
    check_output_file,
    require_extra,
    write_failed,
)


class Number:
    """An argparse type: a number (``int`` or ``float``) in a range, with a message
    that names the range rather than a Python function."""

    def __init__(self, kind: type, minimum: float | None = None, *, strict: bool = False, what: str | None = None):
        self.kind, self.minimum, self.strict = kind, minimum, strict
        self.what = what or ("an integer" if kind is int else "a finite number")

    def __call__(self, text: str):
        """``text`` as the number, or `argparse.ArgumentTypeError` naming the range."""
        try:
            value = self.kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be {self._range()}, got {text!r}") from None
        if (
            value != value
            or value in (float("inf"), float("-inf"))
            or (self.minimum is not None and (value <= self.minimum if self.strict else value < self.minimum))
        ):
            raise argparse.ArgumentTypeError(f"must be {self._range()}, got {text!r}")
        return value

    def _range(self) -> str:
        if self.minimum is None:
            return self.what
        return f"{self.what} {'>' if self.strict else '>='} {self.minimum:g}"


COUNT = Number(int, 0)
SEED = Number(int, 0, what="an integer seed")
NONNEGATIVE = Number(float, 0.0)
POSITIVE = Number(float, 0.0, strict=True)
FINITE = Number(float)


def add_plot(parser: argparse.ArgumentParser, help_text: str) -> None:
    """The ``--plot FILE`` option, its help ``help_text`` and the formats."""
    parser.add_argument(
        "--plot", metavar="FILE", help=help_text + " (any format matplotlib writes: png, pdf, svg, ...)"
    )


def check_plot_path(path: str) -> None:
    """Refuse a plot file that cannot be written, before any work is done: no
    matplotlib, a folder that does not exist, or a format matplotlib cannot write."""
    Figure = require_extra("matplotlib.figure", "plot", "--plot").Figure
    target = check_output_file("--plot", path, "plot.png")
    formats = Figure().canvas.get_supported_filetypes()
    suffix = target.suffix.lower().lstrip(".")
    if suffix and suffix not in formats:
        raise InvalidInputError(f"--plot {path!r}: unknown format {suffix!r}; valid: {', '.join(sorted(formats))}")


def write_output(option: str, path, write) -> OutputFileError | None:
    """Call ``write()``, which writes ``path`` (the file of ``option``) after the work is
    done; its failure is returned, not raised, so that the caller prints the results
    first and then raises it (`raise_failures`): a finished run is never lost to a
    folder that became unwritable or a full disk."""
    try:
        write()
    except OSError as exc:
        return write_failed(option, path, exc)
    except ContactDiffError as exc:  # the writer's own check (the folder went), or the content refused
        return OutputFileError(f"{option} {str(path)!r} not written: {exc}")
    return None


def raise_failures(failures) -> None:
    """Raise the failed writes of `write_output` (None for a write that succeeded) as one
    `OutputFileError`, once the results are printed."""
    failed = [f for f in failures if f is not None]
    if failed:
        raise OutputFileError("; ".join(map(str, failed)) + " (the results above are complete)")


def print_flushed(text: str) -> None:
    """Print ``text`` and flush, so that a closed pipe raises where the caller guards it."""
    print(text, flush=True)  # flushed here, so that a closed pipe raises inside main's guard


def assignment(item: str, flag: str, form: str) -> tuple[str, str]:
    """``NAME=TEXT`` as ``(name, text)``, else `InvalidInputError` showing the ``form``
    ``flag`` takes (``JOINT=VALUE``, ``NAME=VALUES``)."""
    name, sep, text = item.partition("=")
    if not sep or not name or not text:
        raise InvalidInputError(f"{flag} takes {form}, got {item!r}")
    return name, text
