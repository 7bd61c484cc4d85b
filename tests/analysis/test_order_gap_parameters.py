"""The order gap's derivatives with respect to parameters.

Reference: central differences of `order_gap(...).outcome` through
`Scene.with_parameters` at the same event state (the planar rigid trot landing on
both feet, test_order_gap.py's closed-form case, with some armature and restitution
so that every kind of term acts). The outcome is a ratio of M-norms of impact
velocities, each a smooth function of the parameters while the impacts' active sets
stay; with h = 1e-6 max(|p|, 0.01) the truncation is ~h² (1e-12) and the round-off
~1e-16 / h (1e-10 relative), so the two agree to 1e-7 of the largest derivative.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_order_gap import planar_touchdown

from contactdiff.analysis.order_gap import order_gap
from contactdiff.analysis.order_gap_parameters import order_gap_gradient
from contactdiff.errors import InvalidInputError

PAIR = ("rear_foot", "front_foot")
NAMES = [
    "body:body:mass",
    "body:body:iyy",
    "body:body:com_x",
    "joint:body_pitch:armature",
    "contact:rear_foot:restitution",
    "contact:front_foot:restitution",
    "scene:gravity_z",
]


def test_outcome_gradient_matches_finite_differences():
    scene, q, v = planar_touchdown("planar_trot_rigid")
    scene = scene.with_parameters(
        {"joint:body_pitch:armature": 0.1, "contact:rear_foot:restitution": 0.3, "contact:front_foot:restitution": 0.2}
    )
    g = order_gap_gradient(scene, q, v, PAIR, NAMES, t=1.0)
    assert g.gap.outcome > 0.1  # coupled: the orders differ by a finite amount
    fd = []
    for name, value in zip(NAMES, scene.parameter_values(NAMES)):
        h = 1e-6 * max(abs(value), 1e-2)
        plus, minus = (order_gap(scene.with_parameters({name: value + s * h}), q, v, PAIR, t=1.0) for s in (1, -1))
        fd.append((plus.outcome - minus.outcome) / (2 * h))
    fd = np.array(fd)
    assert np.abs(g.outcome - fd).max() <= 1e-7 * np.abs(fd).max(), (g.outcome, fd)
    # an impact does not feel gravity: that derivative is exactly 0
    assert g.outcome[NAMES.index("scene:gravity_z")] == 0.0
    assert np.abs(fd[NAMES.index("scene:gravity_z")]) <= 1e-9


def test_friction_and_group_columns_match_finite_differences():
    """The same landing, 0.8 m/s forward, with Coulomb feet (μ = 0.3, both in group ``feet``:
    the forward speed makes the impacts slide, so μ acts): the feet's own μ,
    the group's μ and the group's restitution against the same central differences (the
    outcome is smooth in them while each impact's sticking/sliding states stay; the
    perturbed runs must keep them, else the difference straddles a pattern change). The
    group's columns equal the sums of the members' (the restitution's: the two contacts'
    in NAMES)."""
    import dataclasses

    import contactdiff as cd

    base, q, v = planar_touchdown("planar_trot_rigid")
    v = v + np.array([0.8, 0.0, 0.0])  # m/s along the body's x coordinate
    contacts = [dataclasses.replace(c, friction=0.3, restitution=0.2, group="feet") for c in base.contact_specs]
    scene = cd.Scene(base.robot, contacts, list(base.effort_specs), None, base.q0, base.v0, base.name)
    names = [
        "contact:rear_foot:friction",
        "contact:front_foot:friction",
        "group:feet:friction",
        "group:feet:restitution",
        "contact:rear_foot:restitution",
        "contact:front_foot:restitution",
    ]
    g = order_gap_gradient(scene, q, v, PAIR, names, t=1.0)
    assert g.gap.outcome > 0.1
    fd = []
    for name, value in zip(names, scene.parameter_values(names)):
        h = 1e-6 * max(abs(value), 1e-2)
        plus, minus = (order_gap(scene.with_parameters({name: value + s * h}), q, v, PAIR, t=1.0) for s in (1, -1))
        fd.append((plus.outcome - minus.outcome) / (2 * h))
    fd = np.array(fd)
    assert np.abs(g.outcome - fd).max() <= 1e-7 * np.abs(fd).max(), (g.outcome, fd)
    assert np.abs(fd[:3]).max() > 1e-3, "μ does not move the outcome: an empty check"
    assert g.outcome[2] == pytest.approx(g.outcome[0] + g.outcome[1], abs=1e-12 * np.abs(g.outcome).max())
    assert g.outcome[3] == pytest.approx(g.outcome[4] + g.outcome[5], abs=1e-12 * np.abs(g.outcome).max())


def test_a_decoupled_pair_has_no_outcome_gradient():
    scene, q, v = planar_touchdown("two_limb")
    with pytest.raises(InvalidInputError, match="no derivative"):
        order_gap_gradient(scene, q, v, scene.contact_names, ["body:body:mass"])


def test_unknown_parameters_are_listed():
    scene, q, v = planar_touchdown("planar_trot_rigid")
    with pytest.raises(InvalidInputError, match="body:body:mass"):
        order_gap_gradient(scene, q, v, PAIR, ["body:body:weight"], t=1.0)
