"""Points of a sweep: grid order, ranges, zipped and explicit lists, seeded random samples."""

from __future__ import annotations

import numpy as np
import pytest

from contactdiff.errors import InvalidInputError
from contactdiff.sweeps.points import (
    Normal,
    Uniform,
    grid,
    parse_distribution,
    parse_values,
    point_list,
    random_points,
)


def test_a_range_holds_both_ends_evenly_spaced():
    values = parse_values("x", "-1:2:4")
    assert values == [-1.0, 0.0, 1.0, 2.0]
    assert parse_values("x", "0.5:0.5:1") == [0.5]
    assert parse_values("x", "3,1.5,solo12,none") == [3, 1.5, "solo12", None]


@pytest.mark.parametrize("spec", ["0:1:0", "0:1:-2", "0:1:2.5"])
def test_an_empty_or_fractional_range_is_refused(spec):
    with pytest.raises(InvalidInputError, match="lo:hi:n"):
        parse_values("x", spec)


def test_an_empty_value_or_list_is_refused():
    with pytest.raises(InvalidInputError, match="empty value"):
        parse_values("x", "1,,2")
    with pytest.raises(InvalidInputError, match="no values"):
        grid({"x": []})
    with pytest.raises(InvalidInputError, match="at least one"):
        grid({})


def test_grid_is_the_product_with_the_last_name_fastest():
    points = grid({"a": [1, 2], "b": "10:30:3"})
    assert points.names == ("a", "b")
    assert [tuple(p.values()) for p in points] == [(1, 10.0), (1, 20.0), (1, 30.0), (2, 10.0), (2, 20.0), (2, 30.0)]
    assert points.axes == ((1, 2), (10.0, 20.0, 30.0))


def test_fixed_columns_come_first_and_cannot_repeat_a_swept_one():
    points = grid({"a": [1, 2]}).with_fixed({"t_final": 0.5})
    assert list(points) == [{"t_final": 0.5, "a": 1}, {"t_final": 0.5, "a": 2}]
    with pytest.raises(InvalidInputError, match="both fixed and swept"):
        grid({"a": [1, 2]}).with_fixed({"a": 3})


def test_point_lists_zip_or_take_mappings():
    zipped = point_list({"a": "1,2,3", "b": [4.0, 5.0, 6.0]})
    assert [tuple(p.values()) for p in zipped] == [(1, 4.0), (2, 5.0), (3, 6.0)]
    with pytest.raises(InvalidInputError, match="one length"):
        point_list({"a": [1, 2], "b": [1]})
    explicit = point_list([{"a": 1, "b": 2}, {"b": 4, "a": 3}])
    assert [tuple(p.values()) for p in explicit] == [(1, 2), (3, 4)]
    with pytest.raises(InvalidInputError, match="same quantities"):
        point_list([{"a": 1}, {"b": 2}])
    with pytest.raises(InvalidInputError, match="empty"):
        point_list([])


def test_values_are_plain_python_and_finite():
    points = grid({"a": np.array([1.5, 2.5]), "b": [np.int64(3)]})
    for value in points.values[0]:
        assert type(value) in (float, int)
    with pytest.raises(InvalidInputError, match="finite"):
        grid({"a": [float("nan")]})
    with pytest.raises(InvalidInputError, match="number, a string"):
        grid({"a": [[1, 2]]})


def test_random_samples_are_reproducible_from_their_seed():
    spec = {"a": "uniform:-1:1", "b": Normal(2.0, 0.5)}
    first, again, other = (random_points(spec, 200, seed) for seed in (7, 7, 8))
    assert first.values == again.values
    assert first.values != other.values
    a = np.array([p["a"] for p in first])
    b = np.array([p["b"] for p in first])
    assert a.min() >= -1 and a.max() < 1
    # 200 normal samples: the mean is within 4 standard errors (0.5 / sqrt(200)) of 2
    assert abs(b.mean() - 2.0) < 4 * 0.5 / np.sqrt(200)


@pytest.mark.parametrize("spec", ["uniform:1:1", "normal:0:0", "gauss:0:1", "uniform:0", "uniform:a:b"])
def test_bad_distributions_are_refused(spec):
    with pytest.raises(InvalidInputError):
        parse_distribution("x", spec)


def test_bad_sample_counts_and_seeds_are_refused():
    with pytest.raises(InvalidInputError, match="samples"):
        random_points({"a": Uniform(0, 1)}, 0)
    with pytest.raises(InvalidInputError, match="seed"):
        random_points({"a": Uniform(0, 1)}, 3, seed=-1)
