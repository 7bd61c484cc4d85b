"""Forces of redundant rows: a box on one face, the rigid limit of equal supports.

The four bottom corners of a box on the ground hold three motions (height, roll,
pitch) with four normal rows: the loads are fixed up to the pattern (+, -, +, -)
over the corners. The principle (`contactdiff.dynamics.redundant`) takes the
loads of a compatible (planar) deflection of equal supports: loads linear in the
corners' positions.
"""

from __future__ import annotations

import itertools

import numpy as np
import pinocchio as pin
import pytest
from helpers import assert_fd, fd_dq, fd_dv

import contactdiff as cd
from contactdiff.dynamics.mode import ModeDynamics
from contactdiff.dynamics.redundant import range_basis, solve_in_range
from contactdiff.model.objects import SceneObject, add_objects, empty_robot

A_HALF, B_HALF, C_HALF = 0.15, 0.10, 0.05  # m: the box's half edges along x, y, z
MASS, G, MU = 2.0, 9.81, 0.3
CORNERS = [f"box/{sx}x{sy}y-z" for sx, sy in itertools.product("+-", repeat=2)]


def box_scene(mu=MU, gravity=(0.0, 0.0, -G)):
    box = SceneObject(
        "box", shape="box", size=(2 * A_HALF, 2 * B_HALF, 2 * C_HALF), mass=MASS, position=(0.0, 0.0, C_HALF)
    )
    robot = add_objects(empty_robot(), [box])
    return cd.Scene(robot, [cd.Contact(name, friction=mu) for name in CORNERS], gravity=gravity)


def corner_xy(name):
    """The corner's position (m) in the box frame, horizontal part."""
    sx, sy = name[4], name[6]
    return np.array([A_HALF if sx == "+" else -A_HALF, B_HALF if sy == "+" else -B_HALF])


def state(yaw, velocity_world, omega_z=0.0):
    """The box flat on the ground at yaw ``yaw`` (rad), its centre moving at
    ``velocity_world`` (m/s, horizontal) and turning at ``omega_z`` (rad/s)."""
    rotation = pin.rpy.rpyToMatrix(0.0, 0.0, yaw)
    quat = pin.Quaternion(rotation).coeffs()
    q = np.r_[0.0, 0.0, C_HALF, quat]
    v = np.r_[rotation.T @ np.r_[velocity_world, 0.0], 0.0, 0.0, omega_z]
    return q, v


def sliding_mode(dyn):
    return tuple(sorted(dyn.sliding_key(i) for i in range(4)))


def test_range_solution_is_least_norm_when_symmetric_and_the_compliant_limit_otherwise():
    """For ``G = A Aᵀ`` (symmetric) the compatible load is the pseudo-inverse's
    least-norm solution; for a non-symmetric ``G = A Fᵀ`` it is the limit of the
    regularised ``(G + ε I)⁻¹ b`` as ε → 0 (the compliant limit), which differs from
    the least-norm one. The limit is approached as O(ε): at ε = 1e-7 the two agree
    to ~1e-7 of the forces' size (the problem's numbers are O(1))."""
    rng = np.random.default_rng(3)
    base = rng.standard_normal((3, 5))
    A = np.vstack([base, base[0] - base[1] + base[2]])  # four rows of rank 3
    U = range_basis(A)
    assert U is not None and U.shape == (4, 3)
    b = A @ rng.standard_normal(5)  # consistent right-hand side, in range(A)
    G_sym = A @ A.T
    np.testing.assert_allclose(solve_in_range(G_sym, b, U), np.linalg.pinv(G_sym) @ b, atol=1e-12)
    F = A + 0.3 * rng.standard_normal((4, 5))  # force rows differ from constraint rows
    G = A @ F.T
    lam = solve_in_range(G, b, U)
    np.testing.assert_allclose(G @ lam, b, atol=1e-12)
    eps = 1e-7
    regularised = np.linalg.solve(G + eps * np.eye(4), b)
    np.testing.assert_allclose(regularised, lam, atol=1e-5 * np.abs(lam).max())
    assert np.abs(np.linalg.pinv(G) @ b - lam).max() > 1e-3 * np.abs(lam).max()  # not least-norm


def test_independent_rows_are_not_redundant():
    assert range_basis(np.eye(3)[:2]) is None
    assert range_basis(np.zeros((0, 4))) is None


@pytest.mark.parametrize("yaw, direction", [(0.0, 0.0), (0.4, 1.1), (-1.2, 2.5)])
def test_sliding_face_loads_and_deceleration(yaw, direction):
    """A box sliding flat on its bottom face, all four corners slipping along ``d``.

    Derivation: the normal loads ``λ_i`` carry the weight, ``Σ λ_i = m g``, and each
    corner's friction is ``-μ λ_i d``, so the centre decelerates at ``μ g`` along
    ``-d`` and does not turn. The moments about the centre of the loads and of the
    friction acting ``c`` below it (corner positions ``(x_i, y_i, -c)`` in the
    box's yawed frame) vanish only if the centre of pressure moves forward:
    ``Σ λ_i x_i = μ c m g d_x``, ``Σ λ_i y_i = μ c m g d_y`` (``d`` in the box frame).
    That is the determined part. The principle's part: the loads are linear in the
    corners' positions, ``λ_i = m g / 4 (1 + μ c d_x x_i / a² + μ c d_y y_i / b²)``.
    """
    scene = box_scene()
    dyn = ModeDynamics(scene)
    d_world = np.array([np.cos(direction), np.sin(direction)])
    q, v = state(yaw, 0.7 * d_world)
    sol = dyn.solve(q, v, 0.0, sliding_mode(dyn))
    rotation = pin.rpy.rpyToMatrix(0.0, 0.0, yaw)
    accel_world = rotation @ sol.ddq[:3]  # body-frame classical = spatial here (ω = 0)
    scale = G  # m/s²: round-off of the solve is ~1e-15 of the accelerations
    np.testing.assert_allclose(accel_world, np.r_[-MU * G * d_world, 0.0], atol=1e-12 * scale)
    np.testing.assert_allclose(sol.ddq[3:], 0.0, atol=1e-12 * scale / A_HALF)
    loads = sol.normal_forces()
    d_box = (rotation.T @ np.r_[d_world, 0.0])[:2]
    xy = np.array([corner_xy(name) for name in CORNERS])
    weight = MASS * G
    np.testing.assert_allclose(loads.sum(), weight, rtol=1e-12)
    np.testing.assert_allclose(loads @ xy, MU * C_HALF * weight * d_box, atol=1e-12 * weight)
    expected = weight / 4 * (1 + MU * C_HALF * (d_box[0] * xy[:, 0] / A_HALF**2 + d_box[1] * xy[:, 1] / B_HALF**2))
    np.testing.assert_allclose(loads, expected, rtol=1e-12)


def test_spinning_face_friction_torque():
    """A box spinning about the vertical on its face, the centre at rest: each corner
    slips at ``ω r`` along its circle (``r = √(a² + b²)`` for all four), so the
    friction torque is ``μ r Σ λ_i = μ m g r`` whatever the split, and
    ``I_z ω' = -μ m g r`` with ``I_z = m (a² + b²) / 3`` (edges 2a, 2b). By symmetry
    of the slip pattern the loads are equal (the linear load with no moment)."""
    dyn = ModeDynamics(box_scene())
    q, v = state(0.3, np.zeros(2), omega_z=2.0)
    sol = dyn.solve(q, v, 0.0, sliding_mode(dyn))
    r = np.hypot(A_HALF, B_HALF)
    inertia = MASS * (A_HALF**2 + B_HALF**2) / 3
    assert sol.ddq[5] == pytest.approx(-MU * MASS * G * r / inertia, rel=1e-12)
    np.testing.assert_allclose(sol.ddq[:5], 0.0, atol=1e-12 * G)
    np.testing.assert_allclose(sol.normal_forces(), MASS * G / 4, rtol=1e-12)


@pytest.mark.parametrize("case", ["sliding", "one_sticking"])
def test_redundant_mode_derivatives_match_finite_differences(case):
    """``ddq`` and the forces of a redundant mode, differentiated, against central
    differences on the manifold (ε = 1e-6: truncation ~ε² of O(1) third derivatives,
    round-off ~1e-16/ε of O(10) forces; tolerance 1e-6 relative)."""
    scene = box_scene()
    dyn = ModeDynamics(scene)
    if case == "sliding":
        mode = sliding_mode(dyn)
        q, v = state(0.3, np.array([0.5, -0.2]), omega_z=1.5)
    else:
        # corner 0 sticks (the box turns about it), the other three slip around it
        mode = tuple(sorted([0] + [dyn.sliding_key(i) for i in range(1, 4)]))
        q, v0 = state(0.3, np.zeros(2), omega_z=1.5)
        pivot = pin.rpy.rpyToMatrix(0.0, 0.0, 0.3) @ np.r_[corner_xy(CORNERS[0]), 0.0]
        # the centre turns about the pivot: v_centre = ω × (centre - pivot)
        v_world = np.cross([0.0, 0.0, 1.5], -pivot)
        _, v = state(0.3, v_world[:2], omega_z=1.5)
    sol, der = dyn.solve(q, v, 0.0, mode, derivatives=True)
    assert dyn.redundant(mode)

    def ddq_at(qq, vv):
        return dyn.solve(qq, vv, 0.0, mode).ddq

    def forces_at(qq, vv):
        return dyn.solve(qq, vv, 0.0, mode).forces

    eps = 1e-6
    assert_fd("redundant ddq/dq", der.ddq_dq, fd_dq(lambda qq: ddq_at(qq, v), scene.model, q, eps), sol.ddq, 1e-6)
    assert_fd("redundant ddq/dv", der.ddq_dv, fd_dv(lambda vv: ddq_at(q, vv), v, eps), sol.ddq, 1e-6)
    assert_fd(
        "redundant forces/dq", der.forces_dq, fd_dq(lambda qq: forces_at(qq, v), scene.model, q, eps), sol.forces, 1e-6
    )
    assert_fd("redundant forces/dv", der.forces_dv, fd_dv(lambda vv: forces_at(q, vv), v, eps), sol.forces, 1e-6)


def test_sticking_face_takes_the_python_path_with_least_norm_loads():
    """Four sticking corners (12 rows of rank 6) at rest: the loads are equal (the
    least-norm split of the weight, by symmetry) and the tangential forces zero;
    Pinocchio's constraint dynamics, which needs independent rows, is not used."""
    scene = box_scene(mu="stick")
    dyn = ModeDynamics(scene)
    q, v = state(0.7, np.zeros(2))
    mode = (0, 1, 2, 3)
    assert dyn.redundant(mode)
    assert dyn.accelerator(mode).rigid is None
    sol = dyn.solve(q, v, 0.0, mode)
    np.testing.assert_allclose(sol.normal_forces(), MASS * G / 4, rtol=1e-12)
    np.testing.assert_allclose(sol.ddq, 0.0, atol=1e-12 * G)
    tangential = np.concatenate([f[1:] for f in sol.row_forces()])
    np.testing.assert_allclose(tangential, 0.0, atol=1e-12 * MASS * G)
