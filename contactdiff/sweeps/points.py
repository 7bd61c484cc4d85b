"""The points of a sweep: a grid, an explicit list, or seeded random samples.

A `PointSet` is a table: the names of the swept quantities
(`contactdiff.sweeps.quantities`) and one tuple of values per point, in the
order the sweep runs them and returns its rows. Build one with

* `grid` (every combination of value lists, the last name varying fastest;
  a list is given as values or as a range ``"lo:hi:n"``, see `parse_values`),
* `point_list` (mappings, or equal-length value lists zipped together),
* `random_points` (``n`` samples of `Uniform` or `Normal` distributions from
  one seed: the same seed gives the same points, to the bit),

and add constant columns with `PointSet.with_fixed`. Values are Python
numbers, strings (a scene factory's categorical arguments) or None; numpy
scalars are turned into Python ones so that every row writes and reads back
exactly.
"""

from __future__ import annotations

import itertools
import json
import math
import numbers
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import InvalidInputError, check_count, check_number

Value = float | int | str | bool | None

MAX_POINTS = 100_000
"""The most points a sweep takes; more are refused, with their count, before they are
made. A sweep keeps its points and its rows in memory (the rows follow the points, and
a results file is matched against them): 1e5 runs of the simulate job on the ball
peaked at 0.37 GB in all (docs/sweep.md), and a 1e8-point grid would take many
gigabytes before the first run. A larger study is several sweeps, which may share
one results file."""


def check_size(what: str, count: float) -> None:
    """Refuse ``count`` points (of ``what``: a range, a grid, samples) past `MAX_POINTS`,
    before they are made."""
    if count > MAX_POINTS:
        raise InvalidInputError(
            f"sweep: {what} has {count:,.0f} points; a sweep takes at most {MAX_POINTS:,} "
            "(MAX_POINTS): split it into several sweeps (they can share one results file)"
        )


def clean_value(name: str, value) -> Value:
    """``value`` as a plain Python scalar (numpy scalars converted), else `InvalidInputError`.

    Numbers must be finite: a row is written as JSON, which has no NaN.
    """
    if value is None or isinstance(value, (str, bool)):
        return value
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, numbers.Integral):
        return int(value)
    if isinstance(value, numbers.Real):
        return check_number("sweep", f"value of {name!r}", value)
    raise InvalidInputError(f"sweep: value of {name!r} must be a number, a string or None, got {value!r}")


@dataclass(frozen=True)
class PointSet:
    """The points of a sweep, in order.

    Attributes:
        names: the swept quantities, one per column.
        values: one tuple of values per point (same order as ``names``).
        axes: for a grid, each name's list of values (the heatmap's axes); empty otherwise.
    """

    names: tuple[str, ...]
    values: tuple[tuple[Value, ...], ...]
    axes: tuple[tuple[Value, ...], ...] = ()

    def __post_init__(self) -> None:
        if not self.values:
            raise InvalidInputError("sweep: no points to run (an empty list or a range of 0 values)")
        check_size("the point list", len(self.values))
        if len(set(self.names)) != len(self.names):
            repeated = sorted({n for n in self.names if self.names.count(n) > 1})
            raise InvalidInputError(f"sweep: a quantity is swept twice: {', '.join(repeated)}")

    def __len__(self) -> int:
        return len(self.values)

    def __iter__(self):
        return (dict(zip(self.names, row)) for row in self.values)

    def __getitem__(self, index: int) -> dict:
        return dict(zip(self.names, self.values[index]))

    def with_fixed(self, fixed: Mapping) -> PointSet:
        """These points with constant columns added (``{name: value}``, before the swept ones)."""
        if not fixed:
            return self
        extra = tuple(fixed)
        clash = sorted(set(extra) & set(self.names))
        if clash:
            raise InvalidInputError(f"sweep: {', '.join(clash)} is both fixed and swept")
        constants = tuple(clean_value(n, v) for n, v in fixed.items())
        axes = tuple((v,) for v in constants) + self.axes if self.axes else ()
        return PointSet(extra + self.names, tuple(constants + row for row in self.values), axes)


def key(values: Sequence[Value]) -> str:
    """A point's identity in a results file: its values as canonical JSON."""
    return json.dumps(list(values), separators=(",", ":"))


# -- building point sets ------------------------------------------------------------------
def grid(axes: Mapping[str, Sequence | str]) -> PointSet:
    """Every combination of the value lists of ``axes`` (``{name: values or "lo:hi:n"}``),
    in `itertools.product` order: the last name varies fastest.

    Raises:
        InvalidInputError: no axes, an empty list or range, a bad value, more than
            `MAX_POINTS` points (refused before they are made).
    """
    if not isinstance(axes, Mapping) or not axes:
        raise InvalidInputError(f"sweep: a grid needs at least one quantity and its values, got {axes!r}")
    names = tuple(axes)
    lists = tuple(tuple(parse_values(name, spec)) for name, spec in axes.items())
    check_size("the grid " + " × ".join(f"{n} ({len(v)})" for n, v in zip(names, lists)), math.prod(map(len, lists)))
    return PointSet(names, tuple(itertools.product(*lists)), lists)


def point_list(points: Sequence[Mapping] | Mapping[str, Sequence]) -> PointSet:
    """Explicit points: a sequence of mappings with the same names, or a mapping of
    equal-length value lists zipped together (``{"a": [1, 2], "b": [3, 4]}`` is two points).

    Raises:
        InvalidInputError: no points, mappings naming different quantities, lists of
            different lengths.
    """
    if isinstance(points, Mapping):
        lists = {name: parse_values(name, spec) for name, spec in points.items()}
        lengths = {name: len(v) for name, v in lists.items()}
        if len(set(lengths.values())) > 1:
            raise InvalidInputError(
                "sweep: the lists of a point list must have one length; got "
                + ", ".join(f"{n}: {k}" for n, k in lengths.items())
            )
        return PointSet(tuple(lists), tuple(zip(*lists.values())))
    if isinstance(points, (str, bytes)) or not isinstance(points, Sequence):
        raise InvalidInputError(f"sweep: points must be a list of mappings, got {points!r}")
    if not points:
        raise InvalidInputError("sweep: the point list is empty")
    names = tuple(points[0]) if isinstance(points[0], Mapping) else ()
    rows = []
    for i, point in enumerate(points):
        if not isinstance(point, Mapping) or set(point) != set(names):
            raise InvalidInputError(
                f"sweep: point #{i} {point!r} does not name the same quantities as point #0 ({', '.join(names)})"
            )
        rows.append(tuple(clean_value(n, point[n]) for n in names))
    return PointSet(names, tuple(rows))


@dataclass(frozen=True)
class Uniform:
    """Uniform samples in ``[low, high)`` (the quantity's unit)."""

    low: float
    high: float

    def __post_init__(self) -> None:
        low, high = (check_number("sweep", f"uniform {n}", v) for n, v in (("low", self.low), ("high", self.high)))
        if not low < high:
            raise InvalidInputError(f"sweep: a uniform distribution needs low < high, got {low!r}:{high!r}")

    def draw(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """``n`` samples from ``rng``."""
        return rng.uniform(self.low, self.high, n)


@dataclass(frozen=True)
class Normal:
    """Normal samples of mean ``mean`` and standard deviation ``std`` > 0 (the quantity's unit)."""

    mean: float
    std: float

    def __post_init__(self) -> None:
        check_number("sweep", "normal mean", self.mean)
        if not check_number("sweep", "normal std", self.std) > 0:
            raise InvalidInputError(f"sweep: a normal distribution needs std > 0, got {self.std!r}")

    def draw(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """``n`` samples from ``rng``."""
        return rng.normal(self.mean, self.std, n)


DISTRIBUTIONS: dict[str, type[Uniform] | type[Normal]] = {"uniform": Uniform, "normal": Normal}
"""Distribution names of `parse_distribution`: ``uniform:LOW:HIGH``, ``normal:MEAN:STD``."""


def random_points(distributions: Mapping[str, Uniform | Normal | str], n: int, seed: int = 0) -> PointSet:
    """``n`` random points: each quantity drawn from its distribution (a `Uniform`,
    a `Normal`, or their text ``"uniform:lo:hi"`` / ``"normal:mean:std"``), all from one
    `numpy.random.default_rng` seeded with ``seed``, quantity by quantity in the given
    order. The same arguments give the same points.

    Raises:
        InvalidInputError: no quantity, a bad distribution, ``n`` < 1 or a bad seed.
    """
    n = check_count("sweep", "samples", n, minimum=1)
    check_size("the random sample", n)
    seed = check_count("sweep", "seed", seed)
    if not isinstance(distributions, Mapping) or not distributions:
        raise InvalidInputError(f"sweep: random points need a distribution per quantity, got {distributions!r}")
    rng = np.random.default_rng(seed)
    columns = [parse_distribution(name, d).draw(rng, n) for name, d in distributions.items()]
    return PointSet(tuple(distributions), tuple(zip(*(c.tolist() for c in columns))))


# -- text forms (the command line) --------------------------------------------------------
def parse_values(name: str, spec) -> list[Value]:
    """Values of one quantity: a sequence of values, or text: a range ``"lo:hi:n"``
    (``n`` evenly spaced numbers from ``lo`` to ``hi``, both included), or
    comma-separated values (numbers where they parse, else strings: ``"solo12,a1"``).

    Raises:
        InvalidInputError: an empty list, a range whose count is not a positive integer or
            is past `MAX_POINTS`, a malformed range.
    """
    if isinstance(spec, str):
        parts = spec.split(":")
        if len(parts) == 3 and all(_number_or_none(p) is not None for p in parts):
            lo, hi, count = (float(p) for p in parts)  # numbers: checked just above
            if count != int(count) or count < 1:
                raise InvalidInputError(
                    f"sweep: range {name}={spec!r}: the count n of lo:hi:n must be a positive integer, got {parts[2]!r}"
                )
            check_size(f"range {name}={spec!r}", count)  # before the values are made
            values = np.linspace(lo, hi, int(count)).tolist()
        else:
            values = [_text_value(x.strip()) for x in spec.split(",")]
            if any(v == "" for v in values):
                raise InvalidInputError(
                    f"sweep: {name}={spec!r} holds an empty value; give values 'a,b,c' or a range 'lo:hi:n'"
                )
    elif isinstance(spec, Sequence) or isinstance(spec, np.ndarray):
        values = list(spec)
    else:
        values = [spec]
    if not values:
        raise InvalidInputError(f"sweep: {name} has no values (an empty list)")
    return [clean_value(name, v) for v in values]


def parse_value(name: str, text: str) -> Value:
    """One value from text (``--set NAME=VALUE``): an integer, a number, ``none``, else
    the text itself (a name such as a method or a factory's categorical argument)."""
    return clean_value(name, _text_value(text.strip()))


def parse_distribution(name: str, spec) -> Uniform | Normal:
    """A distribution, or its text ``uniform:LOW:HIGH`` / ``normal:MEAN:STD``."""
    if isinstance(spec, (Uniform, Normal)):
        return spec
    kind, _, rest = str(spec).partition(":")
    numbers_ = [_number_or_none(x) for x in rest.split(":")]
    if kind not in DISTRIBUTIONS or len(numbers_) != 2 or None in numbers_:
        raise InvalidInputError(
            f"sweep: distribution of {name} must be uniform:LOW:HIGH or normal:MEAN:STD, got {spec!r}"
        )
    low_or_mean, high_or_std = (float(x) for x in rest.split(":"))  # numbers: checked just above
    return DISTRIBUTIONS[kind](low_or_mean, high_or_std)


def _number_or_none(text: str) -> float | None:
    try:
        x = float(text)
    except ValueError:
        return None
    return x if math.isfinite(x) else None


def _text_value(text: str) -> Value:
    if text.lower() in ("none", "null"):
        return None
    try:
        return int(text)
    except ValueError:
        pass
    x = _number_or_none(text)
    return text if x is None else x


def as_points(points: PointSet | Mapping[str, Sequence | str] | Sequence[Mapping]) -> PointSet:
    """A `PointSet` from what `sweep` accepts: a `PointSet`, a mapping (a `grid`) or a
    sequence of mappings (a `point_list`)."""
    if isinstance(points, PointSet):
        return points
    if isinstance(points, Mapping):
        return grid(points)
    return point_list(points)


__all__ = [
    "PointSet",
    "grid",
    "point_list",
    "random_points",
    "Uniform",
    "Normal",
    "parse_values",
    "parse_value",
    "parse_distribution",
    "as_points",
    "key",
    "DISTRIBUTIONS",
    "clean_value",
    "MAX_POINTS",
    "check_size",
]
