"""Coulomb slip in the mode dynamics: force rows, derivatives, Painlevé.

References: central finite differences on the manifold (`helpers`), Newton's
law written out with Pinocchio's own ABA and frame Jacobians, and closed forms
derived here (a block sliding on a plane; the end-sliding rod of Painlevé).
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
from helpers import assert_fd, fd_dq, fd_dv, random_state, rod_urdf, sphere_urdf

import contactdiff as cd
from contactdiff.dynamics.mode import ModeDynamics
from contactdiff.dynamics.slip import SLIP_SPEED_EPS, reference_turn, slip_direction
from contactdiff.errors import InvalidInputError, PainleveError
from contactdiff.model.contacts import Contact

MU = 0.6
TILTED = tuple(np.array([0.6, -0.3, 1.0]) / np.linalg.norm([0.6, -0.3, 1.0]))

BALL_URDF = sphere_urdf(2.0, 0.008)  # a solid sphere of radius 0.1 m: I = 2/5 m r²


@pytest.fixture(scope="module")
def ball(tmp_path_factory):
    path = tmp_path_factory.mktemp("slip") / "ball3d.urdf"
    path.write_text(BALL_URDF)
    return cd.load_robot(str(path), floating_base=True)


# -- the friction coefficient of a contact ---------------------------------------------------
def test_friction_coefficient_spec():
    assert Contact("f", friction=0.8).friction == 0.8 and Contact("f", friction=0.8).mu == 0.8
    assert Contact("f", friction=0.8).coulomb and Contact("f", friction=0.8).sticking
    assert Contact("f", friction=0).friction == "none" and Contact("f", friction=0.0).mu == 0.0
    assert Contact("f", friction=math.inf).friction == "stick" and Contact("f", friction="stick").mu == math.inf
    assert not Contact("f", friction="stick").coulomb and not Contact("f").coulomb
    for bad in (-0.1, math.nan, "sticky", True, None):
        with pytest.raises(InvalidInputError, match="friction must be one of none, stick or a Coulomb"):
            Contact("f", friction=bad)


def test_friction_coefficient_from_toml(tmp_path):
    (tmp_path / "ball.toml").write_text(
        'robot = "ball"\n[[contact]]\nframe = "ball"\nfriction = 0.35\n[initial]\nq = { z = 1.0 }\n'
    )
    scene = cd.load_scene(tmp_path / "ball.toml")
    assert scene.contacts[0].spec.mu == 0.35
    # the ball moves along z only: no tangential row, so no friction acts
    assert scene.contacts[0].n_rows == 1 and scene.contacts[0].mu == 0.0


# -- the slip direction ----------------------------------------------------------------------
def test_slip_direction_rules():
    s, D = slip_direction(np.array([3.0, 4.0]), None)
    np.testing.assert_allclose(s, [0.6, 0.8], rtol=1e-15)
    np.testing.assert_allclose(D, (np.eye(2) - np.outer(s, s)) / 5.0, rtol=1e-15)
    # continued through the stop: against the reference the direction is the reference itself, so a
    # slip velocity past the stop does not turn it (D = 0: no transverse feedback, slip.py)
    for u in ([-3.0, -4.0], [-4.0, -3.0], [0.8, -0.6 - 1e-9]):
        s, D = slip_direction(np.array(u), np.array([0.6, 0.8]))
        assert D is None and s.tolist() == [0.6, 0.8]
    # at rest: the reference; a planar contact: its reference sign, else its own sign
    s, D = slip_direction(np.array([0.1 * SLIP_SPEED_EPS, 0.0]), np.array([0.0, -1.0]))
    assert D is None and s.tolist() == [0.0, -1.0]
    assert slip_direction(np.array([-2.0]), None)[0].tolist() == [-1.0]
    assert slip_direction(np.array([-2.0]), np.array([1.0]))[0].tolist() == [1.0]


# -- Newton's law in a slipping mode, and its derivatives ------------------------------------
CASES = [  # (robot, contact)
    ("ball", Contact("ball", radius=0.1, friction=MU)),
    ("ball", Contact("ball", normal=TILTED, offset=0.2, radius=0.1, friction=MU)),
    ("solo12", Contact("FR_FOOT", normal=TILTED, friction=MU)),
    ("planar_trot_rigid", Contact("front_foot", radius=0.05, friction=MU)),
    ("planar_trot_rigid", Contact("front_foot", normal=(-0.4, 0.0, 1.0), friction=MU)),
]
IDS = [f"{r}-{c.frame}-{i}" for i, (r, c) in enumerate(CASES)]


def _case(ball, i, seed):
    name, spec = CASES[i]
    robot = ball if name == "ball" else cd.load_robot(name)
    rng = np.random.default_rng(seed)
    if robot.model.nq == robot.model.nv:
        q = robot.q_ref + rng.uniform(-0.6, 0.6, robot.nq)
        v = rng.standard_normal(robot.nv)
    else:
        q, v = random_state(robot.model, robot.q_ref, rng, 0.3, 1.0)
    q0 = robot.q_ref.copy()  # a valid start for the scene; the states tested are q, v
    if robot.model.nq != robot.model.nv:
        q0[2] += 1.0
    else:
        q0 = cd.load_scene(name).q0
    scene = cd.Scene(robot, [spec], gravity=[0, 0, -9.81], q0=q0)
    return scene, q, v


@pytest.mark.parametrize("i", range(len(CASES)), ids=IDS)
def test_slip_mode_is_newtons_law(ball, i):
    """ddq and λ_N satisfy M ddq + nle = (A_n - μ s^T A_T)^T λ_N and A_n ddq + drift_n = 0,
    with s the slip velocity's direction, written out with Pinocchio's own calls."""
    scene, q, v = _case(ball, i, 1)
    dyn = ModeDynamics(scene)
    contact = scene.contacts[0]
    sol = dyn.solve(q, v, 0.0, (dyn.sliding_key(0),))
    kin = scene.kinematics
    kin.update(q, v)
    A = contact.rows(kin)
    u_T = A[1:] @ v
    s = u_T / np.linalg.norm(u_T) if len(u_T) == 2 else np.sign(u_T)
    data = scene.model.createData()
    M = pin.crba(scene.model, data, q)
    M = np.triu(M) + np.triu(M, 1).T
    nle = pin.nonLinearEffects(scene.model, data, q, v)
    lam = sol.forces[0]
    residual = M @ sol.ddq + nle - scene.tau(kin, 0.0) - (A[0] - MU * s @ A[1:]) * lam
    assert np.max(np.abs(residual)) < 1e-10 * max(1.0, np.max(np.abs(nle)))  # N: round-off of M ddq
    assert abs(A[0] @ sol.ddq + contact.drift(kin)[0]) < 1e-10 * max(1.0, np.max(np.abs(sol.ddq)))


@pytest.mark.parametrize("i", range(len(CASES)), ids=IDS)
@pytest.mark.parametrize("seed", [2, 3])
def test_slip_mode_derivatives_match_fd(ball, i, seed):
    scene, q, v = _case(ball, i, seed)
    dyn = ModeDynamics(scene)
    mode = (dyn.sliding_key(0),)
    sol, der = dyn.solve(q, v, 0.0, mode, derivatives=True)
    name = f"slip-{CASES[i][0]}"
    assert_fd(f"{name} ddq/dq", der.ddq_dq, fd_dq(lambda x: dyn.solve(x, v, 0.0, mode).ddq, scene.model, q), sol.ddq)
    assert_fd(f"{name} ddq/dv", der.ddq_dv, fd_dv(lambda x: dyn.solve(q, x, 0.0, mode).ddq, v), sol.ddq)
    assert_fd(
        f"{name} lam/dq", der.forces_dq, fd_dq(lambda x: dyn.solve(x, v, 0.0, mode).forces, scene.model, q), sol.forces
    )
    assert_fd(f"{name} lam/dv", der.forces_dv, fd_dv(lambda x: dyn.solve(q, x, 0.0, mode).forces, v), sol.forces)
    # a generalised force d moves ddq by ddq_dtau d (the efforts' response)
    d = np.random.default_rng(seed).standard_normal(scene.nv)
    tau = scene.tau(scene.kinematics, 0.0)
    step = 1e-6
    fd = dyn.solve(q, v, 0.0, mode, tau=tau + step * d).ddq - dyn.solve(q, v, 0.0, mode, tau=tau - step * d).ddq
    assert_fd(f"{name} ddq/dtau", der.ddq_dtau @ d, fd / (2 * step), sol.ddq)


# -- Painlevé's paradox ----------------------------------------------------------------------
ROD_HALF, ROD_MASS = 0.5, 1.0


@pytest.fixture(scope="module")
def rod(tmp_path_factory):
    path = tmp_path_factory.mktemp("rod") / "rod.urdf"
    path.write_text(rod_urdf(ROD_HALF, ROD_MASS))
    return cd.load_robot(path)


def rod_g(theta: float, mu: float, slip_sign: float) -> float:
    """Closed form ``g = A_n M^-1 F^T`` of the rod's lower end sliding (1/kg).

    The rod (mass m, half length l, inertia m l²/3 about its centre) is pitched by
    θ about +y (tip at ``(l cos θ, -l sin θ)`` from the centre, so θ > 0 puts it
    below). The tip's velocity ``(ẋ - l sin θ θ̇, ż - l cos θ θ̇)``: ``A_n = (0, 1,
    -l cos θ)``, ``A_T = (1, 0, -l sin θ)`` and ``M^-1 = diag(1/m, 1/m, 3/(m l²))``;
    with ``F = A_n - μ s A_T``:

        g = [1 + 3 cos²θ - 3 μ s sin θ cos θ] / m.
    """
    c, s = math.cos(theta), math.sin(theta)
    return (1.0 + 3.0 * c * c - 3.0 * mu * slip_sign * s * c) / ROD_MASS


@pytest.mark.parametrize("theta", [0.3, 0.6, 1.0])
@pytest.mark.parametrize("mu", [0.5, 1.4, 2.0, 4.0])
@pytest.mark.parametrize("slip_sign", [1.0, -1.0])
def test_painleve_rod(rod, theta, mu, slip_sign):
    """Sliding with the tip on the ground: a solution exists (and is unique) exactly
    where the closed-form ``g > 0``; elsewhere `PainleveError`."""
    scene = cd.Scene(rod, [Contact("tip", friction=mu)], gravity=[0, 0, -9.81], q0=np.array([0.0, 1.0, theta]))
    dyn = ModeDynamics(scene)
    q = np.array([0.0, ROD_HALF * math.sin(theta), theta])  # tip on the ground
    v = np.array([slip_sign * 1.0, 0.0, 0.0])  # the tip slides along x with the body
    g = rod_g(theta, mu, slip_sign)
    if g > 0.0:
        sol = dyn.solve(q, v, 0.0, (dyn.sliding_key(0),))
        # λ_N = -b/g with b the tip's free normal acceleration: -9.81 plus the centripetal term (θ̇ = 0)
        assert sol.forces[0] == pytest.approx(9.81 / g, rel=1e-12)
    else:
        with pytest.raises(PainleveError, match="Painlevé"):
            dyn.solve(q, v, 0.0, (dyn.sliding_key(0),))


@pytest.mark.parametrize("theta", [0.6, 1.0])
@pytest.mark.parametrize("mu", [0.5, 1.4, 4.0])
@pytest.mark.parametrize("slip_sign", [1.0, -1.0])
@pytest.mark.parametrize("spin", [0.0, 8.0])
def test_painleve_rod_in_simulate(rod, theta, mu, slip_sign, spin):
    """A run that starts with the tip sliding on the ground raises `PainleveError` exactly
    where ``g <= 0``. The tip's free normal acceleration is ``b = -9.81 + l sin θ θ̇²``
    (the centripetal term of the tip at ``(x + l cos θ, z - l sin θ)``): with ``θ̇ = 0``
    (``b < 0``) the Painlevé region has no solution, with ``θ̇ = 8`` (``b > 0``) two
    (separate, or slide on pushed). Outside it the rod slides (``b < 0``) or lifts (``b > 0``)."""
    q0 = np.array([0.0, ROD_HALF * math.sin(theta), theta])  # tip on the ground
    # the tip slides along slip_sign at 1 m/s with zero normal speed: ẋ - l sin θ θ̇ = ±1, ż - l cos θ θ̇ = 0
    v0 = np.array([slip_sign + ROD_HALF * math.sin(theta) * spin, ROD_HALF * math.cos(theta) * spin, spin])
    scene = cd.Scene(rod, [Contact("tip", friction=mu)], gravity=[0, 0, -9.81], q0=q0, v0=v0)
    b = -9.81 + ROD_HALF * math.sin(theta) * spin**2
    if rod_g(theta, mu, slip_sign) <= 0.0:
        with pytest.raises(PainleveError, match="Painlevé"):
            cd.simulate(scene, 0.02)
    else:
        traj = cd.simulate(scene, 0.02)
        assert traj.segments[0].sliding == (("tip",) if b < 0.0 else ())


def test_slip_direction_turns_smoothly_through_the_noise_floor():
    """Between the floor ε and 2ε the direction turns from the reference to the slip's own
    (slip.py): continuous at both ends, exact above 2ε, and ``D = ds/du_T`` matches central
    differences inside the band (steps 1e-6 ε: the band's curvature scale is ε)."""
    eps, r = 1e-6, np.array([0.0, 1.0])
    own = np.array([0.8, 0.6])  # the slip's own direction, 53° from the reference
    below, _ = slip_direction(own * eps * (1 - 1e-12), r, eps)
    entering, _ = slip_direction(own * eps * (1 + 1e-12), r, eps)
    leaving, _ = slip_direction(own * 2 * eps * (1 - 1e-12), r, eps)
    above, _ = slip_direction(own * 2 * eps * (1 + 1e-12), r, eps)
    np.testing.assert_allclose(below, r, atol=0)
    np.testing.assert_allclose(entering, r, atol=1e-11)  # the smooth step's value ~ 3 (1e-12)²
    np.testing.assert_allclose(leaving, own, atol=1e-11)
    np.testing.assert_allclose(above, own, rtol=1e-15)
    h = 1e-6 * eps
    for speed in (1.1 * eps, 1.5 * eps, 1.9 * eps, 2.5 * eps):
        # against r (past a stop) the direction is r, in the band and above it
        s, D = slip_direction(-own * speed, r, eps)
        assert D is None and s.tolist() == r.tolist()
        if speed < 2 * eps:
            u = own * speed
            s, D = slip_direction(u, r, eps)
            assert s @ r > 0.0  # it keeps the reference's side
            assert abs(np.linalg.norm(s) - 1.0) < 1e-15
            fd = np.column_stack(
                [
                    (slip_direction(u + h * e, r, eps)[0] - slip_direction(u - h * e, r, eps)[0]) / (2 * h)
                    for e in np.eye(2)
                ]
            )
            # truncation ~ (h / ε)² |D|, round-off ~ 1e-16 / h: both below 1e-6 |D|
            np.testing.assert_allclose(D, fd, rtol=0, atol=1e-6 * np.abs(D).max())


def test_reference_turn_matches_central_differences_in_the_angle():
    """``∂s/∂θ`` (`reference_turn`) against central differences of `slip_direction` in the
    reference's angle, ``r(θ) = (cos θ, sin θ)``, at fixed slip velocity: below the floor and
    past a stop ``s = r`` (``∂s/∂θ = r⊥``), in the band the blend's share ``1 - a``, above
    ``2ε`` nothing (None, and the differences are zero). Step 1e-6 rad: truncation
    ~ (1e-6)² times the third derivative in θ (``s`` turns with ``θ`` at rates of order 1),
    round-off ~ 1e-16 / 1e-6 = 1e-10: both below the 1e-8 asserted."""
    eps, theta = 1e-6, 1.2
    own = np.array([0.8, 0.6])  # the slip's own direction, 32° from the reference

    def direction(u, angle):
        return slip_direction(u, np.array([math.cos(angle), math.sin(angle)]), eps)[0]

    h = 1e-6
    r = np.array([math.cos(theta), math.sin(theta)])
    for u in (own * 0.5 * eps, -own * 1.5 * eps, own * 1.1 * eps, own * 1.5 * eps, own * 1.9 * eps, own * 3 * eps):
        fd = (direction(u, theta + h) - direction(u, theta - h)) / (2 * h)
        turn = reference_turn(u, r, eps)
        if np.linalg.norm(u) >= 2 * eps:
            assert turn is None and np.abs(fd).max() == 0.0
            continue
        np.testing.assert_allclose(turn, fd, rtol=0, atol=1e-8)
    assert np.abs(reference_turn(own * 1.5 * eps, r, eps)).max() > 1e-3  # the band's term is there
