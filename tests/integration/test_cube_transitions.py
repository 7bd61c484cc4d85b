"""The measured cube (`contactdiff.cube_scene`: eight Coulomb corners) through the
transitions between its face, an edge and a corner: tipping and falling back, rolling
over an edge, rocking to rest, pivoting on a corner, a push that lifts the back edge,
and a slide that pitches onto the front edge. Runs against closed forms.

Cube of half edge b, mass m, moment I_c about every axis through its centre (the
scene's inertia is isotropic), gravity g; ground z = 0.

**Fixed-axis pivot.** A cube turning about a horizontal axis through a pivot on the
ground (an edge, or a corner with the axis perpendicular to the vertical plane through
that corner and the centre) whose contacts stick is a pendulum: with s the centre's
horizontal distance from the axis (b for an edge, b√2 for a corner), L = √(s² + b²)
and φ0 = atan2(b, s), the centre's height after turning by θ is
h(θ) = s sin θ + b cos θ = L sin(φ0 + θ), the moment about the axis is
I = I_c + m L², and energy gives ω(θ)² = ω0² - (2 m g / I) (h(θ) - b). The cube
passes over the top (θ = π/2 - φ0, h = L) when ω0 exceeds ω_c = √(2 m g (L - b) / I),
and otherwise stops at θ_max with sin(φ0 + θ_max) = (b + I ω0² / (2 m g)) / L and
falls back, reaching θ = 0 again at 2 t(θ_max), t(θ) = ∫0^θ dθ' / ω(θ'), with the
speed ω0 it started with (the motion is reversible). A corner's pivot stays in its
plane of symmetry (a cube's plane x = y through the corner): the axis normal to a
symmetry plane is a principal axis at every point of it, so the turn keeps its axis.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from scipy.integrate import quad

import contactdiff as cd

P = cd.CubeParameters()
B, MASS, I_C, G = P.edge / 2, P.mass, P.moment, P.gravity
MU = 1.0  # the pivots below need at most 0.6 (`pivot_loads` checks each run's arc)
CORNERS = ["cube/" + "".join(s + a for s, a in zip(signs, "xyz"))
           for signs in [(sx, sy, sz) for sx in "+-" for sy in "+-" for sz in "+-"]]
# events are located to ~(atol + rtol |x|) / |guard rate| with rates O(1), and the states
# carry the integration error ~rtol over O(1) s: at rtol 1e-10 both are ~1e-10; the
# quadratures of the references are good to ~1e-12
TIGHT = dict(rtol=1e-10, atol=1e-12)
EVENT_ATOL = 1e-8  # s
STATE_ATOL = 1e-8  # m, m/s, rad, rad/s


def corners(**signs) -> set[str]:
    """The corners with the given signs, e.g. ``corners(x="-", z="-")``."""
    return {n for n in CORNERS if all(f"{s}{axis}" in n for axis, s in signs.items())}


class Pivot:
    """The cube turning about a horizontal axis ``u`` (world, unit) through ``point`` on
    the ground (module doc); ``s`` is the centre's horizontal distance from the axis."""

    def __init__(self, point, u, s):
        self.point, self.u, self.s = np.asarray(point, float), np.asarray(u, float), s
        self.L = np.hypot(s, B)
        self.phi0 = np.arctan2(B, s)
        self.inertia = I_C + MASS * self.L**2
        self.critical = np.sqrt(2 * MASS * G * (self.L - B) / self.inertia)

    def omega2(self, theta, omega0):
        return omega0**2 - 2 * MASS * G / self.inertia * (self.s * np.sin(theta) + B * np.cos(theta) - B)

    def theta_max(self, omega0):
        return np.arcsin((B + self.inertia * omega0**2 / (2 * MASS * G)) / self.L) - self.phi0

    def time_to_peak(self, omega0):
        """t(θ_max): ∫ dθ/ω with ω² = (2 m g L / I) (sin(φ0+θ_max) - sin(φ0+θ)), written
        as 2 cos((2φ0+θ_max+θ)/2) sin((θ_max-θ)/2) (no cancellation near the peak), and
        its (θ_max - θ)^(-1/2) singularity taken by the quadrature's weight."""
        top = self.theta_max(omega0)
        k = 2 * MASS * G * self.L / self.inertia

        def smooth(theta):
            d = top - theta
            w2 = k * 2 * np.cos(self.phi0 + (top + theta) / 2) * np.sin(d / 2)
            return np.sqrt(d / w2) if d > 0 else np.sqrt(1.0 / (k * np.cos(self.phi0 + top)))
        value, _ = quad(smooth, 0.0, top, weight="alg", wvar=(0.0, -0.5), epsabs=1e-14, epsrel=1e-13)
        return value

    def time_to(self, theta, omega0):
        """t(θ) for a θ the turn reaches with ω > 0 all the way."""
        value, _ = quad(lambda x: 1.0 / np.sqrt(self.omega2(x, omega0)), 0.0, theta, epsabs=1e-14, epsrel=1e-13)
        return value

    def pose(self, theta):
        """(q) of the cube turned by θ about the axis from flat on its face."""
        rotation = pin.exp3(self.u * theta)
        centre = self.point + rotation @ (np.array([0.0, 0.0, B]) - self.point)
        return np.r_[centre, pin.Quaternion(rotation).coeffs()]

    def state(self, theta, omega):
        """(q, v) turned by θ and turning at ω about the axis (v in the cube's frame)."""
        q = self.pose(theta)
        rotation = pin.Quaternion(q[3:7]).matrix()
        w = omega * self.u
        return q, np.r_[rotation.T @ np.cross(w, q[:3] - self.point), rotation.T @ w]

    def pivot_loads(self, omega0, theta_end):
        """The smallest normal force over m g and the largest |friction| / normal force
        the pivot needs on [0, θ_end]: m a_c = R + m g with the centre at L (cos φ, sin φ)
        in the vertical plane of the turn, φ = φ0 + θ, and I θ'' = -m g L cos φ."""
        theta = np.linspace(0.0, theta_end, 4001)
        phi = self.phi0 + theta
        w2 = np.maximum(self.omega2(theta, omega0), 0.0)
        alpha = -MASS * G * self.L * np.cos(phi) / self.inertia
        ax = self.L * (-alpha * np.sin(phi) - w2 * np.cos(phi))
        az = self.L * (alpha * np.cos(phi) - w2 * np.sin(phi))
        normal = MASS * (az + G)
        return normal.min() / (MASS * G), np.abs(MASS * ax / normal).max()


# the bottom edge x = -b (the ``-x..-z`` corners), turning about -y lifts the +x side
EDGE = Pivot((-B, 0.0, 0.0), (0.0, -1.0, 0.0), B)
# the corner -x-y-z, about the horizontal axis normal to the diagonal plane x = y
CORNER = Pivot((-B, -B, 0.0), np.array([1.0, -1.0, 0.0]) / np.sqrt(2), B * np.sqrt(2))
RHO = I_C / EDGE.inertia
"""Housner's ratio of a plastic landing on the opposite edge of the face (angular
momentum about the new edge: I_c ω before, I_edge ω after; tests/integration/
test_face_friction.py derives it)."""


def cube(mu=MU, restitution=0.0):
    return cd.cube_scene(friction=mu, restitution=restitution)


def level(q) -> float:
    """|1 - cos(tilt)| of the cube's z axis against the vertical."""
    return abs(1.0 - pin.Quaternion(q[3:7]).matrix()[2, 2])


@pytest.mark.parametrize("share", [0.9, 1.1])
def test_a_cube_tipped_onto_an_edge_falls_back_or_rolls_over(share):
    """Flat on its face, turning at ω0 = share × ω_c about its bottom edge x = -b: the
    far corners (x = +b) rise at once, so the run starts on the edge alone (sticking).
    Below ω_c it stops at θ_max and falls back onto its face at 2 t(θ_max), at speed ω0,
    the x = +b corners landing together; above, it passes the top and lands at
    t(π/2) on the next face (the ``-x..+z`` corners, whose height is b again, so again
    at speed ω0). Either landing is Housner's: plastic, the new edge sticking, the
    angular velocity drops by ρ = I_c / I_edge and the old edge lifts.
    Precondition from the closed form: the edge's normal force stays positive and its
    friction within μ on the arc (μ = 1)."""
    omega0 = share * EDGE.critical
    falls_back = share < 1
    end = EDGE.theta_max(omega0) if falls_back else np.pi / 2
    n_min, ratio = EDGE.pivot_loads(omega0, end)
    assert n_min > 0.1 and ratio < 0.5 * MU
    t_peak = EDGE.time_to_peak(omega0) if falls_back else None
    t_land = 2 * t_peak if falls_back else EDGE.time_to(np.pi / 2, omega0)
    q, v = EDGE.state(0.0, omega0)
    traj = cd.simulate(cube().with_state(q, v), t_land + 0.01, dense=True, **TIGHT)
    assert set(traj.segments[0].mode) == corners(x="-", z="-") and not traj.segments[0].sliding
    landing = traj.events[0]
    new_edge = corners(x="+", z="-") if falls_back else corners(x="-", z="+")
    assert landing.kind == "touchdown" and set(landing.contacts) == new_edge
    assert landing.t == pytest.approx(t_land, abs=EVENT_ATOL)
    # the turn is about ∓y in the world; about the same axis in the cube's frame, which
    # it leaves fixed: falling back it turns the other way
    sign = 1.0 if falls_back else -1.0
    np.testing.assert_allclose(landing.v_minus[3:], [0.0, sign * omega0, 0.0], atol=1e-7)
    np.testing.assert_allclose(landing.v_plus[3:], RHO * landing.v_minus[3:], atol=1e-7)
    assert set(landing.mode_after) == new_edge
    if falls_back:
        q_peak, v_peak = traj.at(t_peak)
        np.testing.assert_allclose(pin.difference(cube().model, q_peak, EDGE.pose(EDGE.theta_max(omega0))), 0.0,
                                   atol=STATE_ATOL)
        np.testing.assert_allclose(v_peak, 0.0, atol=1e-6)  # the velocity's time error: ω' t_err


def test_a_rocking_cube_decays_to_rest_rock_by_rock():
    """Started as in the fall-back case (ω0 = 0.9 ω_c about the edge x = -b), plastic: each
    landing keeps ρ = I_c / I_edge of the angular velocity and the cube rocks about the
    edge it landed on, which by symmetry is the same pendulum, so the k-th rock lasts
    2 t(θ_max) at ω_k = ρ^k ω0 and lands on the edge opposite the last. The landing
    times are the partial sums; the rocks shrink geometrically (each lasts about
    2 I_edge ω_k / (m g b) once small), so the sequence ends after a finite time and the
    Zeno rule leaves the cube flat where it started (the edges stick: it never moves
    along the ground): centre (0, 0, b), level, still."""
    omega0 = 0.9 * EDGE.critical
    q, v = EDGE.state(0.0, omega0)
    traj = cd.simulate(cube().with_state(q, v), 1.0, **TIGHT)
    landings = [e for e in traj.events if e.kind == "touchdown"]
    t, omega = 0.0, omega0
    for k in range(4):
        t += 2 * EDGE.time_to_peak(omega)
        edge = corners(x="+" if k % 2 == 0 else "-", z="-")
        assert set(landings[k].contacts) == edge and landings[k].t == pytest.approx(t, abs=k * 1e-8 + EVENT_ATOL)
        assert abs(landings[k].v_minus[4]) == pytest.approx(omega, rel=1e-6)
        assert landings[k].v_plus[4] / landings[k].v_minus[4] == pytest.approx(RHO, rel=1e-7)
        omega *= RHO
    assert traj.t == 1.0 and len(traj.events) < 100
    np.testing.assert_allclose(traj.q[:3], [0.0, 0.0, B], atol=1e-8)
    assert level(traj.q) < 1e-12
    np.testing.assert_allclose(traj.v, 0.0, atol=1e-6)


def test_a_cube_tipped_onto_a_corner_falls_back_onto_its_face_and_stops():
    """Flat, turning at ω0 = 0.7 ω_c about the horizontal axis through its corner
    (-b, -b, 0) normal to the diagonal plane x = y: the other three bottom corners rise
    at once and it pivots on that corner (sticking) as a pendulum with s = b√2, stops at
    θ_max and falls back, the three corners landing together at 2 t(θ_max).
    The plastic landing stops it dead. Rocking onto the opposite corner (b, b, 0) alone
    would keep the angular momentum about the axis through it parallel to the turn's:
    the centre's velocity is ω × r0 (r0 = c - c_pivot), so H = I_c ω + m r2 · r0 ω
    with r2 = c - c_opposite, r2 · r0 = (-b, -b, b) · (b, b, b) = -b², against
    (I_c + 3 m b²) ω' after: ω'/ω = (I_c - m b²)/(I_c + 3 m b²) < 0 for this cube
    (I_c < m b²), a turn that would drive the pivot corner into the ground. An edge
    rocking breaks the x = y symmetry the landing has, so the plastic face takes it
    all: v+ = 0, the normal impulses summing to the centre's vertical momentum
    m ω0 b√2 (its speed ω0 b√3 normal to r0, whose horizontal part is b√2)."""
    assert I_C < MASS * B**2
    omega0 = 0.7 * CORNER.critical
    top = CORNER.theta_max(omega0)
    n_min, ratio = CORNER.pivot_loads(omega0, top)
    assert n_min > 0.1 and ratio < 0.7 * MU
    t_peak = CORNER.time_to_peak(omega0)
    q, v = CORNER.state(0.0, omega0)
    traj = cd.simulate(cube().with_state(q, v), 2 * t_peak + 0.05, dense=True, **TIGHT)
    assert set(traj.segments[0].mode) == {"cube/-x-y-z"} and not traj.segments[0].sliding
    q_peak, v_peak = traj.at(t_peak)
    np.testing.assert_allclose(pin.difference(cube().model, q_peak, CORNER.pose(top)), 0.0, atol=STATE_ATOL)
    np.testing.assert_allclose(v_peak, 0.0, atol=1e-6)
    landing = traj.events[0]
    assert landing.kind == "touchdown" and set(landing.contacts) == corners(z="-") - {"cube/-x-y-z"}
    assert landing.t == pytest.approx(2 * t_peak, abs=EVENT_ATOL)
    np.testing.assert_allclose(landing.v_minus[3:], -omega0 * CORNER.u, atol=1e-7)  # flat: cube frame = world
    np.testing.assert_allclose(landing.v_plus, 0.0, atol=1e-9)
    normal = [landing.impulses[n] for n in corners(z="-")]
    assert min(normal) >= -1e-12 and sum(normal) == pytest.approx(MASS * omega0 * B * np.sqrt(2), rel=1e-7)
    assert set(landing.mode_after) == corners(z="-")
    assert len(traj.events) == 1
    np.testing.assert_allclose(traj.q[:3], [0.0, 0.0, B], atol=1e-8)
    np.testing.assert_allclose(traj.v, 0.0, atol=1e-9)
