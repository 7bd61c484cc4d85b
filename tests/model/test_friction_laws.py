"""A contact's friction law is an enum (`FrictionLaw`) that compares as its strings."""

import math

import pytest

import contactdiff as cd
from contactdiff.errors import InvalidInputError
from contactdiff.model.contacts import FRICTION_MODES, FrictionLaw


@pytest.mark.parametrize(
    "given, law, mu",
    [
        ("none", FrictionLaw.NONE, 0.0),
        (0.0, FrictionLaw.NONE, 0.0),
        ("stick", FrictionLaw.STICK, math.inf),
        (math.inf, FrictionLaw.STICK, math.inf),
        (0.8, FrictionLaw.COULOMB, 0.8),
    ],
)
def test_each_friction_given_is_its_law(given, law, mu):
    """A name is its law, 0 frictionless and inf sticking (the limits of Coulomb's cone
    ||λ_T|| <= μ λ_N), a finite μ > 0 Coulomb's law with that coefficient."""
    contact = cd.Contact("foot", friction=given)
    assert contact.law is law and contact.mu == mu
    assert contact.coulomb == (law is FrictionLaw.COULOMB) and contact.sticking == (law is not FrictionLaw.NONE)
    if law is not FrictionLaw.COULOMB:  # the named laws stay equal to the strings of before
        assert contact.friction is law and contact.friction == str(law) and f"{contact.friction}" == law.value


def test_the_named_laws_and_a_bad_friction_listed():
    assert [str(m) for m in FRICTION_MODES] == ["none", "stick"]
    with pytest.raises(InvalidInputError, match=r"friction must be one of none, stick or a Coulomb.*'coulomb'"):
        cd.Contact("foot", friction="coulomb")  # the law of a coefficient, not a name a contact is given
