"""The named parameters of contacts and of groups of contacts (part of
`contactdiff.model.parameters`).

**Contacts** (``contact:NAME:field``): every contact has ``restitution`` (1) and
``offset`` (m); a contact with a Coulomb coefficient (a number ``μ > 0``, not
``"none"`` or ``"stick"``) also has ``friction`` (1).

**Groups** (``group:GROUP:field``): contacts that name one ``group``
(`Contact.group`, ``group = "cube"`` in a scene file) share a parameter per
field: ``restitution`` and ``offset`` always, ``friction`` when every member has
a Coulomb coefficient. Its value is the members' common value (reading it while
they differ raises `GroupMismatchError`, listing them); setting it sets every
member; its derivative is the sum of the members' (each member's coefficient
moves by the same amount). Groups are listed after the contacts, in the order of
their first member.

**Friction's range.** ``with_parameters`` takes ``μ >= 0``. ``μ = 0`` makes the
contact frictionless (``"none"``: its tangential rows are dropped, it neither
sticks nor slips), so the scene it gives has no ``friction`` parameter for that
contact (nor for its group): derivatives in ``μ`` exist only where ``μ > 0``.
"""

from __future__ import annotations

import math

from ..errors import GroupMismatchError, InvalidInputError
from .contacts import Contact
from .parameter_types import Parameter, ParameterKind, ParametrisedScene

CONTACT_FIELDS = ("restitution", "offset", "friction")
"""Fields of a contact (and of a group): Newton's coefficient (1), the offset (m), Coulomb's μ (1)."""


def contact_fields(spec: Contact) -> tuple[str, ...]:
    """The parameter fields of one contact spec: ``friction`` only with a Coulomb coefficient."""
    return CONTACT_FIELDS if spec.coulomb else CONTACT_FIELDS[:2]


def groups(scene: ParametrisedScene) -> dict[str, tuple[int, ...]]:
    """Each group name -> the scene indices of its contacts (groups in the order of their
    first member)."""
    out: dict[str, list[int]] = {}
    for i, spec in enumerate(scene.contact_specs):
        if spec.group is not None:
            out.setdefault(spec.group, []).append(i)
    return {name: tuple(members) for name, members in out.items()}


def contact_parameters(scene: ParametrisedScene) -> list[Parameter]:
    """The ``contact`` then ``group`` parameters of ``scene`` (module doc)."""
    specs = scene.contact_specs
    out = [
        Parameter(ParameterKind.CONTACT, c.name, f, index=i, members=(i,))
        for i, c in enumerate(specs)
        for f in contact_fields(c)
    ]
    for name, members in groups(scene).items():
        fields = CONTACT_FIELDS if all(specs[i].coulomb for i in members) else CONTACT_FIELDS[:2]
        out += [Parameter(ParameterKind.GROUP, name, f, members=members) for f in fields]
    return out


def contact_value(scene: ParametrisedScene, p: Parameter) -> float:
    """The value of a ``contact`` or ``group`` parameter (a group's: its members' common one).

    Raises:
        GroupMismatchError: the group's members hold different values.
    """
    values = [float(getattr(scene.contact_specs[i], p.field)) for i in p.members]
    if any(x != values[0] for x in values[1:]):
        listed = ", ".join(f"{scene.contact_specs[i].name} = {x!r}" for i, x in zip(p.members, values))
        raise GroupMismatchError(
            f"parameter {p.name!r}: the group's contacts differ ({listed}); it has a value "
            f"only when they agree (setting it gives them all one)"
        )
    return values[0]


def stage_contact_change(scene: ParametrisedScene, specs: dict, p: Parameter, x: float) -> None:
    """Note setting ``p`` (a ``contact`` or ``group`` parameter) to ``x`` on each member in
    ``specs`` (``("contact", index) -> (changes, names, values)``, as `with_parameters`
    collects them before building the new contacts).

    Raises:
        InvalidInputError: a negative or non-finite friction coefficient (restitution's
            range is the contact's own check), or two parameters that give one contact's
            field different values (a contact's own and its group's).
    """
    if p.field == "friction" and not (x >= 0.0 and math.isfinite(x)):
        raise InvalidInputError(
            f"parameter {p.name!r} (Coulomb's friction coefficient) must be >= 0, got {x!r} "
            "(0 makes the contact frictionless)"
        )
    for i in p.members:
        changes, names, values = specs.setdefault(("contact", i), ({}, [], []))
        if p.field in changes and changes[p.field] != x:
            raise InvalidInputError(
                f"parameters {names[-1]!r} = {values[-1]!r} and {p.name!r} = {x!r} set the "
                f"{p.field} of contact {scene.contact_specs[i].name!r} to different values"
            )
        changes[p.field] = x
        names.append(p.name)
        values.append(x)


__all__ = ["CONTACT_FIELDS", "contact_fields", "contact_parameters", "contact_value", "groups", "stage_contact_change"]
