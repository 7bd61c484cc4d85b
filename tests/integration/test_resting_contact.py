"""An impact against a resting contact: flagged not differentiable, with both outcomes.

Model: two unit masses on vertical prismatic joints, no gravity (M = I). The lower
one, ``a``, rests on the ground (contact ``ground``: gap z_a, closed with zero
force); the upper one, ``b``, starts 0.5 m above contact with ``a`` (contact ``ab``,
``b`` against ``a``: gap z_b - z_a - 1) and lands on it at speed u = 1 m/s at
t = 0.5 s, elastic (e_ab = 1); the ground's restitution is e_g.

Rows (ab, ground) = ((-1, 1), (1, 0)), so G = A M^-1 A^T = [[2, -1], [-1, 1]]: the two
are coupled, G_12 / sqrt(G_11 G_22) = -1/sqrt(2).

* Together (the run: the ground is closed at the impact): u- = (-u, 0); the ground
  does not approach, so its restitution is 0; the impulses (2u, 2u) give
  v+ = (v_a, v_b) = (0, u) with u+ = (u, 0), as Newton's law asks.
* As a cascade (a gap of any size opens the ground): ``ab`` alone exchanges the equal
  masses' velocities, (v_a, v_b) = (-u, 0); ``a`` hits the ground, v_a = e_g u; if
  e_g > 0 it meets ``b`` at rest and they exchange again: (0, e_g u).

The outcomes differ by (1 - e_g) u: flagged for e_g < 1, not for e_g = 1. A run with
the ground 1e-9 m below ``a`` is the cascade itself, and ends where the flagged
event's ``outcomes["cascade"]`` says.
"""

from __future__ import annotations

import numpy as np
import pytest

import contactdiff as cd

U = 1.0  # m/s
_JOINT = (
    '<joint name="z{c}" type="prismatic"><parent link="world"/><child link="{c}"/><axis xyz="0 0 1"/>'
    '<limit lower="-100" upper="100" effort="0" velocity="100"/></joint>'
)
_LINK = (
    '<link name="{c}"><inertial><mass value="1"/>'
    '<inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>'
)
STACK_URDF = (
    '<?xml version="1.0"?><robot name="stack"><link name="world"/>'
    + "".join(_LINK.format(c=c) + _JOINT.format(c=c) for c in "ab")
    + "</robot>"
)
# the impact law's velocities are sums of a few O(1) terms: round-off ~1e-16
VEL_ATOL = 1e-12  # m/s


@pytest.fixture(scope="module")
def stack(tmp_path_factory):
    path = tmp_path_factory.mktemp("stack") / "stack.urdf"
    path.write_text(STACK_URDF)
    return cd.load_robot(str(path))


def _scene(robot, e_ground, gap=0.0, b_lands_on="a"):
    if b_lands_on == "a":
        upper = cd.Contact("b", against="a", offset=1.0, restitution=1.0, name="ab")
    else:  # b has its own floor, 1 m down: it does not push on a
        upper = cd.Contact("b", offset=1.0, restitution=1.0, name="floor_b")
    return cd.Scene(
        robot,
        [cd.Contact("a", restitution=e_ground, name="ground"), upper],
        gravity=[0, 0, 0],
        q0=np.array([gap, 1.5 + gap]),
        v0=np.array([0.0, -U]),
    )


@pytest.mark.parametrize("e_ground", [0.0, 0.5])
def test_landing_on_a_resting_contact_is_flagged_with_both_outcomes(stack, e_ground):
    traj = cd.simulate(_scene(stack, e_ground), 1.0)
    (impact,) = traj.events
    assert impact.contacts == ("ab",) and impact.t == pytest.approx(0.5, abs=1e-12)
    assert set(impact.nonsmooth) == {cd.NonSmooth.RESTING_CONTACT} and not traj.differentiable
    assert "ground" in impact.nonsmooth[cd.NonSmooth.RESTING_CONTACT]
    np.testing.assert_allclose(impact.outcomes["simultaneous"], [0.0, U], atol=VEL_ATOL)
    np.testing.assert_allclose(impact.outcomes["cascade"], [0.0, e_ground * U], atol=VEL_ATOL)
    np.testing.assert_allclose(traj.v, [0.0, U], atol=VEL_ATOL)  # the run takes the simultaneous one
    assert impact.to_dict()["outcomes"]["cascade"] == pytest.approx([0.0, e_ground * U], abs=VEL_ATOL)
    # a gap of 1e-9 m under a: the run is the cascade, and ends where the flag said
    opened = cd.simulate(_scene(stack, e_ground, gap=1e-9), 1.0)
    assert [e.contacts for e in opened.events][:2] == [("ab",), ("ground",)]
    np.testing.assert_allclose(opened.v, impact.outcomes["cascade"], atol=VEL_ATOL)


def test_elastic_ground_gives_one_outcome_and_no_flag(stack):
    traj = cd.simulate(_scene(stack, 1.0), 1.0)
    (impact,) = traj.events
    assert impact.differentiable and impact.outcomes is None
    np.testing.assert_allclose(traj.v, [0.0, U], atol=VEL_ATOL)
    opened = cd.simulate(_scene(stack, 1.0, gap=1e-9), 1.0)
    np.testing.assert_allclose(opened.v, [0.0, U], atol=VEL_ATOL)


def test_a_landing_decoupled_from_the_resting_contact_is_not_flagged(stack):
    """b lands on its own floor: its row (0, 1) and the ground's (1, 0) have G_12 = 0."""
    traj = cd.simulate(_scene(stack, 0.0, b_lands_on="floor"), 1.0)
    (impact,) = traj.events
    assert impact.contacts == ("floor_b",) and impact.differentiable and impact.outcomes is None
    np.testing.assert_allclose(traj.v, [0.0, U], atol=VEL_ATOL)
