"""The frictional impact map's derivative in its parameters at a fixed pre-impact state
(`impact_parameter_jacobian` through `ParameterJumps.impact`): Coulomb's μ (a contact's own
and a group's), the restitution and the inertia, for the sliding and sticking patterns,
one point, a sphere with spin, a cube corner and a cube face (four dependent normal rows:
the impulses in the range of the held rows, `contactdiff.dynamics.redundant`).

Reference: central differences of `resolve_impact`'s v+ on `Scene.with_parameters`, the
same contacts' states on both sides. The map is smooth in the parameters within one
pattern: the differences' truncation is h² |v+'''| / 6 and their round-off ~1e-16 |v+| / h
(the slip-angle solve is polished to 1e-13 rad, `contactdiff.dynamics.friction_slip`:
noise ~1e-13 |v+| / h). With h = 1e-6 |p| (p ~ 0.2 .. 0.6 here) the round-off is ≤ 1e-6
|v+| and the truncation ~1e-12 |v+'''|: compared at 1e-5 of max(|v+|, the column's
size), while a missing friction column, a wrong load share or a sticking row kept on a
sliding contact errs at O(1e-2 .. 1) of the column.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import contactdiff as cd
from contactdiff.dynamics.frictional_impact import ContactState
from contactdiff.dynamics.impacts import resolve_impact
from contactdiff.dynamics.mode import ModeDynamics
from contactdiff.integration.parameter_jumps import ParameterJumps
from contactdiff.integration.sensitivity import impact_reset_jacobian
from contactdiff.model.objects import SceneObject, add_objects, empty_robot
from contactdiff.model.parameters import resolve

REL_STEP = 1e-6
RTOL = 1e-5
EDGE = 0.1048  # m, `cd.cube_scene`'s edge


def _cube_state(rpy, velocity, omega):
    """The cube with orientation ``rpy`` and its lowest corner (or face) on the board z = 0;
    ``velocity`` (world, m/s) and ``omega`` (rad/s, world) turned into the free-flyer's frame."""
    rotation = pin.rpy.rpyToMatrix(*rpy)
    corners = np.array([[sx, sy, sz] for sx in (1, -1) for sy in (1, -1) for sz in (1, -1)]) * EDGE / 2
    low = float(-(corners @ rotation.T)[:, 2].min())
    q = np.r_[0.0, 0.0, low, pin.Quaternion(rotation).coeffs()]
    return q, np.r_[rotation.T @ np.asarray(velocity, float), rotation.T @ np.asarray(omega, float)]


def _closed(scene, q):
    """Scene indices of the contacts closed at ``q`` (gap within 1e-12 m)."""
    return [i for i, g in enumerate(scene.gaps(q)) if abs(g) <= 1e-12]


def _ball():
    """A free sphere (R = 0.1 m, 2 kg) touching the board, landing with spin: its slip's
    direction is one of the impact's unknowns (3-D)."""
    ball = SceneObject("ball", shape="sphere", radius=0.1, mass=2.0, position=(0.0, 0.0, 0.1))
    scene = cd.Scene(
        add_objects(empty_robot(), [ball]),
        [cd.Contact("ball", friction=0.15, restitution=0.4)],
        gravity=(0.0, 0.0, -9.81),
    )
    q = np.r_[0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 1.0]
    return scene, q, np.r_[1.5, -0.5, -2.0, -20.0, 30.0, -3.0]


CASES = {
    # name: (scene, q, v-, the parameters, the expected states)
    "cube-corner-slides": lambda: (
        cd.cube_scene(),
        *_cube_state((0.5, 0.4, 0.0), (0.9, 0.3, -0.5), (1.0, -2.0, 0.5)),
        ["group:cube:friction", "group:cube:restitution", "body:cube:mass"],
        "slide",
    ),
    "cube-corner-sticks": lambda: (
        cd.cube_scene(friction=0.9),
        *_cube_state((0.5, 0.4, 0.0), (0.05, 0.02, -0.8), (0.0, 0.0, 0.0)),
        ["group:cube:friction", "group:cube:restitution", "body:cube:mass"],
        "stick",
    ),
    "cube-face-spins": lambda: (
        cd.cube_scene(restitution=0.0),
        *_cube_state((0.0, 0.0, 0.3), (0.7, -0.2, -0.9), (0.0, 0.0, 6.0)),
        ["group:cube:friction", "contact:cube/+x+y-z:friction", "body:cube:mass"],
        "slide",
    ),
    "sphere-spins": lambda: (
        *_ball(),
        ["contact:ball:friction", "contact:ball:restitution", "body:ball:mass"],
        "slide",
    ),
}


@pytest.mark.parametrize("case", list(CASES))
def test_impact_parameter_columns_match_finite_differences(case):
    """Each column of ``∂v+/∂p`` against central differences (module doc); the sliding cases
    must slide (a μ column that is not zero), the sticking one stick (its μ column exactly 0:
    a sticking impulse does not depend on μ)."""
    scene, q, v, names, pattern = CASES[case]()
    dyn = ModeDynamics(scene)
    closed = _closed(scene, q)
    impact = resolve_impact(dyn, q, v, closed)
    states = {impact.states[k] for k in impact.active}
    expected = ContactState.SLIDE if pattern == "slide" else ContactState.STICK
    assert states == {expected}, (case, impact.states)
    J = ParameterJumps(dyn, resolve(scene, names)).impact(q, v, impact, impact.contacts)
    nv = scene.nv
    assert not np.any(J[:nv])
    for k, name in enumerate(names):
        value = float(scene.parameter_values([name])[0])
        h = REL_STEP * abs(value)
        sides = []
        for sign in (1.0, -1.0):
            moved = scene.with_parameters({name: value + sign * h})
            other = resolve_impact(ModeDynamics(moved), q, v, closed)
            assert other.states == impact.states, (name, sign)
            sides.append(other.v_plus)
        fd = (sides[0] - sides[1]) / (2 * h)
        scale = max(np.abs(impact.v_plus).max(), np.abs(fd).max())
        err = np.abs(J[nv:, k] - fd).max()
        assert err <= RTOL * scale, f"{case} {name}: {err:.3g} > {RTOL * scale:.3g}\n{J[nv:, k]}\n{fd}"
        if name.endswith(":friction"):
            if pattern == "stick":
                assert not np.any(J[:, k]), name
            elif "cube/+x+y-z" not in name:  # a single face corner's share can be small, not zero
                assert np.abs(fd).max() > 1e-3, f"{name} does not move v+ in {case}: an empty check"


def test_spinning_face_reset_jacobian_keeps_the_range_principle():
    """The state's reset Jacobian ``DR`` (`impact_reset_jacobian`) at the spinning face landing:
    its corners slide in different directions, so v+ depends on their load shares, and the
    derivative must keep the impulses in the range of the held rows as the law does (least
    squares errs by O(1) here). Against central differences of `resolve_impact` in every
    velocity direction and in the configuration directions that keep the face on the board
    (x, y, yaw); tolerance as the module doc's (h = 1e-6 on unit-scale states)."""
    scene, q, v, _, _ = CASES["cube-face-spins"]()
    dyn = ModeDynamics(scene)
    closed = _closed(scene, q)
    impact = resolve_impact(dyn, q, v, closed)
    DR = impact_reset_jacobian(dyn, q, v, impact)
    nv, h = scene.nv, 1e-6
    scale = np.abs(impact.v_plus).max()
    # (the column of DR, δq, δv)
    directions = [(nv + k, np.zeros(nv), np.eye(nv)[k]) for k in range(nv)]
    directions += [(k, np.eye(nv)[k], np.zeros(nv)) for k in (0, 1, 5)]
    for column, dq, dv in directions:
        sides = []
        for sign in (1.0, -1.0):
            other = resolve_impact(
                ModeDynamics(scene), pin.integrate(scene.model, q, sign * h * dq), v + sign * h * dv, closed
            )
            assert other.states == impact.states
            sides.append(other.v_plus)
        fd = (sides[0] - sides[1]) / (2 * h)
        exact = DR[nv:, column]
        assert np.abs(exact - fd).max() <= RTOL * max(scale, np.abs(fd).max()), (column, exact, fd)
