"""`check_member`: the one check of an enum option (a member or its value, else a
named error listing the valid values), used by the simulate options, the fit and
the cube recordings' start."""

from __future__ import annotations

from enum import StrEnum

import numpy as np
import pytest

from contactdiff.errors import InvalidInputError, check_member


class Colour(StrEnum):
    RED = "red"
    DARK_BLUE = "dark blue"


def test_a_member_or_its_value_gives_the_member():
    """A member is returned as itself; its string value (also an equal plain str)
    gives the member, of the enum's type, not the string."""
    assert check_member("colour", Colour.RED, Colour) is Colour.RED
    got = check_member("colour", "dark blue", Colour)
    assert got is Colour.DARK_BLUE and type(got) is Colour


@pytest.mark.parametrize("bad", [True, False, None, 0, "Red", "RED", "", ["red"], np.array(["red"])])
def test_anything_else_is_refused_by_name_with_the_valid_values(bad):
    """Bools, None, numbers, a member's name (not its value), a wrong case and a
    container holding a valid value are refused; the one-line message names the
    option, lists every valid value and shows the bad value's repr."""
    with pytest.raises(InvalidInputError) as err:
        check_member("colour", bad, Colour)
    message = str(err.value)
    assert message == f"colour must be one of red, dark blue; got {bad!r}"


def test_the_callers_refuse_through_it():
    """The simulate options and the cube recordings' start give its wording with their
    own option names (the fit's options: tests/fit/test_loss.py, test_fit.py)."""
    from contactdiff.data.cube_recordings import toss_recording
    from contactdiff.integration.options import SimulateOptions

    with pytest.raises(InvalidInputError, match=r"^on_grazing must be one of .*; got True$"):
        SimulateOptions(on_grazing=True)
    with pytest.raises(InvalidInputError, match=r"^toss start must be one of first, .*; got 'last'$"):
        toss_recording(None, "last")  # the start is checked before the toss is read
