"""The measured cube (`contactdiff.cube_scene`: eight Coulomb corners) through the
transitions between its face, an edge and a corner: tipping and falling back, rolling
over an edge, rocking to rest, pivoting on a corner, a push that lifts the back edge,
a slide that pitches onto the front edge, and a diagonal slide whose trailing corner
the compatible loads release and which bears again (at the stop, or, under a couple,
where its compatible load turns positive). Runs against closed forms.

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
CORNERS = [
    "cube/" + "".join(s + a for s, a in zip(signs, "xyz"))
    for signs in [(sx, sy, sz) for sx in "+-" for sy in "+-" for sz in "+-"]
]
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
        np.testing.assert_allclose(
            pin.difference(cube().model, q_peak, EDGE.pose(EDGE.theta_max(omega0))), 0.0, atol=STATE_ATOL
        )
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


def push_at_the_top(rate):
    """A horizontal force ``rate`` × t (N) along world x at the centre of the cube's top
    face (its frame's (0, 0, b)), as the free flyer's generalised force: the force and its
    moment about the centre, both in the cube's frame."""
    arm = np.array([0.0, 0.0, B])

    def wrench(q, v, t, scale):
        force = pin.Quaternion(q[3:7]).matrix().T @ np.array([scale, 0.0, 0.0])
        return np.r_[force, np.cross(arm, force)]

    return cd.UserEffort(
        lambda q, v, t: wrench(q, v, t, rate * t), name="push", time_derivative=lambda q, v, t: wrench(q, v, t, rate)
    )


@pytest.mark.parametrize("u0, mu", [(0.0, 0.8), (1.0, 0.3)])
def test_a_push_at_the_top_lifts_the_back_edge(u0, mu):
    """Flat on its face, sliding along x at u0 (or at rest), pushed along x at the top
    face's centre (2b above the ground) by F = k t. Moments about the front bottom edge
    while all four corners hold: the push tips with F 2b, the centre's deceleration a
    (d'Alembert's force m a forward at height b) with m a b, gravity restores with
    m g b. At rest the corners stick (F <= μ m g) and a = 0; sliding, friction is
    μ m g backwards and a = μ g - F/m, so the tipping moment is F b + μ m g b. The back
    corners' normal force (the back edge's total is determined by the pitch balance;
    left = right by symmetry) reaches zero together when F = m g / 2 at rest, or
    F = m g (1 - μ) sliding: a lift-off of the two back corners at t = F / k, the front
    edge holding (still sliding at u0 - μ g t + k t² / (2 m) > 0 in the sliding case).
    At rest the friction's split is the principle's (`contactdiff.dynamics.redundant`):
    the compatible deflection of a push along x is a translation (the pitch moves every
    bottom corner along x by the same amount too), so each corner carries F/4 of it,
    while a back corner's load is (m g - 2F)/4: the back corners reach their cones
    first, F/4 = μ (m g - 2F)/4 at F = μ m g / (1 + 2μ), and slip (on the spot: the
    front corners stick) before they lift."""
    F_lift = MASS * G / 2 if u0 == 0.0 else MASS * G * (1 - mu)
    if u0 == 0.0:
        assert F_lift <= mu * MASS * G
    t_lift = 0.1
    rate = F_lift / t_lift
    speed = u0 - mu * G * t_lift + rate * t_lift**2 / (2 * MASS)
    scene = cube(mu)
    scene = cd.Scene(scene.robot, scene.contact_specs, efforts=[push_at_the_top(rate)])  # the model's gravity
    q = np.r_[0.0, 0.0, B, 0.0, 0.0, 0.0, 1.0]
    traj = cd.simulate(scene.with_state(q, np.r_[u0, 0.0, 0.0, 0.0, 0.0, 0.0]), t_lift + 1e-3, **TIGHT)
    if u0 == 0.0:
        slip, lift = traj.events
        assert slip.kind == "slip" and set(slip.contacts) == corners(x="-", z="-")
        assert slip.t == pytest.approx(mu * MASS * G / (1 + 2 * mu) / rate, abs=EVENT_ATOL)
        assert set(slip.sliding) == corners(x="-", z="-") and set(slip.mode_after) == corners(z="-")
    else:
        (lift,) = traj.events
    assert lift.kind == "lift-off" and set(lift.contacts) == corners(x="-", z="-") and lift.simultaneous
    assert lift.t == pytest.approx(t_lift, abs=EVENT_ATOL)
    assert set(lift.mode_after) == corners(x="+", z="-")
    front_slides = set(lift.sliding) == corners(x="+", z="-")
    assert front_slides == (u0 > 0.0)
    if u0 > 0.0:
        assert lift.v_minus[0] == pytest.approx(speed, abs=STATE_ATOL) and speed > 0.0
    else:
        np.testing.assert_allclose(lift.v_minus, 0.0, atol=STATE_ATOL)


@pytest.mark.parametrize("mu", [0.9, 1.2])
def test_a_slide_pitches_the_cube_onto_its_front_edge_when_friction_exceeds_one(mu):
    """Flat, sliding along x at u0 = 1 m/s. On four corners friction μ m g acts b below the
    centre; the pitch balance puts the front edge's load at m g (1 + μ)/2 and the back
    edge's at m g (1 - μ)/2 (b from the centre each): below μ = 1 (a cube's half edge over
    its half height) it slides flat to a stop at u0 / (μ g), all four corners sticking
    together; above, the back corners would pull, so they lift at once (t = 0) and the
    cube slides on its front edge at r = (b, -b) from the centre. There, with normal force
    N and friction -μ N along x: the pitch (about +y, front down) α = b N (μ - 1) / I_c,
    the centre's accelerations a_x = -μ N / m and a_z = N / m - g, and the edge keeps its
    height, a_z - b α = 0 (ω = 0): N = m g / (1 - m b² (μ - 1) / I_c), positive below
    Painlevé's bound μ < 1 + I_c / (m b²) (1.80 for this cube). Checked on the run's
    velocity (world frame) after t_s = 1e-4 s: the accelerations depend on the pitch θ
    and on ω² only, so their rate vanishes at t = 0 and the difference quotient's error
    is ä t_s² / 6, ä ~ α² a (a relative 1e-5 here), plus the run's ~1e-10 / t_s."""
    u0 = 1.0
    q = np.r_[0.0, 0.0, B, 0.0, 0.0, 0.0, 1.0]
    T = u0 / (mu * G) + 0.01 if mu < 1 else 0.01
    traj = cd.simulate(cube(mu).with_state(q, np.r_[u0, 0.0, 0.0, 0.0, 0.0, 0.0]), T, dense=True, **TIGHT)
    first = traj.events[0]
    assert set(traj.segments[0].sliding) == corners(z="-")
    if mu < 1:
        assert [e.kind for e in traj.events] == ["stick"] and set(first.contacts) == corners(z="-")
        assert first.t == pytest.approx(u0 / (mu * G), abs=EVENT_ATOL)
        assert traj.q[0] == pytest.approx(u0**2 / (2 * mu * G), abs=STATE_ATOL)
        assert traj.q[2] == pytest.approx(B, abs=STATE_ATOL) and level(traj.q) < 1e-14
        return
    assert I_C / (MASS * B**2) + 1 > mu
    assert first.kind == "lift-off" and first.t == 0.0 and set(first.contacts) == corners(x="-", z="-")
    assert set(first.mode_after) == set(first.sliding) == corners(x="+", z="-")
    normal = MASS * G / (1 - MASS * B**2 * (mu - 1) / I_C)
    expected = np.array([-mu * normal / MASS, 0.0, normal / MASS - G, 0.0, B * normal * (mu - 1) / I_C, 0.0])
    t_s = 1e-4
    q_s, v_s = traj.at(t_s)
    rotation = pin.Quaternion(q_s[3:7]).matrix()
    measured = (np.r_[rotation @ v_s[:3], rotation @ v_s[3:]] - traj.v0) / t_s
    np.testing.assert_allclose(measured, expected, rtol=1e-4, atol=1e-6)


def test_a_corner_released_in_a_diagonal_slide_bears_again_when_the_cube_stops():
    """Sliding at u0 along the diagonal d = (1, 1)/√2: friction μ m g acts b below the
    centre along -d. The compatible loads are linear in the corners' positions p_i
    (`contactdiff.dynamics.redundant`): λ_i = α + β · p_i, with Σ λ_i = m g and the
    moment balance Σ λ_i p_i = b μ m g d (four corners: Σ p_i p_iᵀ = 4 b² I), so
    λ_i = (m g / 4) (1 + μ d · p_i / b); the trailing corner (-b, -b) gets
    (m g / 4) (1 - μ √2), which would pull for μ > 1/√2: it lifts at once (μ = 0.85).
    The other three then carry the determined loads λ_(+,+) = μ' m g and
    λ_(+,-) = λ_(-,+) = m g (1 - μ')/2, μ' = μ/√2 (< 1: none pulls), all sliding
    along d with no yaw moment (the two side corners' moments cancel): the cube stops
    at u0 / (μ g) after u0² / (2 μ g), the three corners sticking together. At rest the
    principle's loads on the whole face are m g / 4 each (no friction): the released
    corner, held at zero gap by the others all along, bears again at the stop, and
    the cube rests on four sticking corners (on three, the centre would sit on the line
    of the two side corners, with the third unloaded: a balance on a diagonal that any
    round-off tips)."""
    mu, u0 = 0.85, 0.5
    d = np.array([1.0, 1.0, 0.0]) / np.sqrt(2)
    q = np.r_[0.0, 0.0, B, 0.0, 0.0, 0.0, 1.0]
    t_stop = u0 / (mu * G)
    traj = cd.simulate(cube(mu).with_state(q, np.r_[u0 * d, 0.0, 0.0, 0.0]), t_stop + 0.3, **TIGHT)
    lift, stop = traj.events
    assert lift.kind == "lift-off" and lift.t == 0.0 and lift.contacts == ("cube/-x-y-z",)
    assert set(lift.mode_after) == set(lift.sliding) == corners(z="-") - {"cube/-x-y-z"}
    assert stop.kind == "stick" and stop.t == pytest.approx(t_stop, abs=EVENT_ATOL)
    assert set(stop.contacts) == corners(z="-") - {"cube/-x-y-z"}
    assert set(stop.mode_after) == corners(z="-") and not stop.sliding
    np.testing.assert_allclose(traj.q[:3], np.r_[u0**2 / (2 * mu * G) * d[:2], B], atol=STATE_ATOL)
    assert level(traj.q) < 1e-14
    np.testing.assert_allclose(traj.v, 0.0, atol=STATE_ATOL)


def test_flow_jacobian_through_the_diagonal_stop_matches_finite_differences():
    """The flow Jacobian of the diagonal slide of the test above through the trailing
    corner's lift-off at t = 0 and the stop on three corners (where the released one
    bears again), along the perturbations that keep the slide diagonal (horizontal
    position, speed along d), against central differences on the manifold. The speed's
    column is (d u0 / (μ g), 0) at rest: stop distance u0² / (2 μ g). ε = 1e-6 with
    rtol 1e-12: the differences' error is ~1e-12/ε plus ε² terms, so 1e-5 relative to
    the columns' size."""
    mu, u0 = 0.85, 0.5
    d = np.array([1.0, 1.0, 0.0]) / np.sqrt(2)
    q = np.r_[0.0, 0.0, B, 0.0, 0.0, 0.0, 1.0]
    scene = cube(mu)
    T = u0 / (mu * G) + 0.05
    opts = dict(rtol=1e-12, atol=1e-14)
    traj = cd.simulate(scene.with_state(q, np.r_[u0 * d, 0.0, 0.0, 0.0]), T, jacobian=True, **opts)
    assert [e.kind for e in traj.events] == ["lift-off", "stick"]
    model, v = scene.model, np.r_[u0 * d, 0.0, 0.0, 0.0]
    directions = [(np.eye(6)[0], np.zeros(6)), (np.eye(6)[1], np.zeros(6)), (np.zeros(6), np.r_[d, 0.0, 0.0, 0.0])]
    eps = 1e-6
    for dq, dv in directions:
        runs = [
            cd.simulate(scene.with_state(pin.integrate(model, q, s * eps * dq), v + s * eps * dv), T, **opts)
            for s in (1.0, -1.0)
        ]
        fd = np.r_[pin.difference(model, runs[1].q, runs[0].q), runs[0].v - runs[1].v] / (2 * eps)
        exact = traj.jacobian @ np.r_[dq, dv]
        assert np.abs(exact - fd).max() <= 1e-5 * max(1.0, np.abs(fd).max()), (exact, fd)
    speed_column = traj.jacobian @ np.r_[np.zeros(6), d, 0.0, 0.0, 0.0]
    np.testing.assert_allclose(speed_column[:3], u0 / (mu * G) * d, atol=1e-7)


MU_COUPLE = 0.85
"""μ of the couple on the diagonal slide (tests below): above 1/√2, the trailing corner pulls at t = 0."""


def couple_slide(mu, rate):
    """The cube sliding along the diagonal with the couple ``rate`` × t (N m) about
    u = (1, -1, 0)/√2 (test below)."""
    u = np.array([1.0, -1.0, 0.0]) / np.sqrt(2)

    def couple(q, scale):
        return np.r_[np.zeros(3), pin.Quaternion(q[3:7]).matrix().T @ (scale * u)]

    effort = cd.UserEffort(
        lambda q, v, t: couple(q, rate * t), name="couple", time_derivative=lambda q, v, t: couple(q, rate)
    )
    scene = cube(mu)
    return cd.Scene(scene.robot, scene.contact_specs, efforts=[effort])


COUPLE_RATE = MU_COUPLE * B * MASS * G / 0.1
"""k (N m/s) of the couple below: T = k t, so that T = μ b m g at t = 0.1 s."""


def couple_times(mu=MU_COUPLE, k=COUPLE_RATE, mass=MASS):
    """The couple's closed form (test below): the trailing corner bears at t1, the
    leading corner lifts at t2, a side corner would lift at t3."""
    t1 = B * mass * G * (mu - 1 / np.sqrt(2)) / k
    t2 = B * mass * G * (mu + 1 / np.sqrt(2)) / k
    t3 = B * mass * G * (mu + np.sqrt(2)) / k
    return t1, t2, t3


def test_a_held_corner_bears_when_its_compatible_load_turns_positive():
    """The diagonal slide of the tests above (μ = 0.85, u0 = 2 m/s along d), with a couple
    T = k t about the horizontal axis u = (1, -1, 0)/√2 = -ẑ × d, which presses the
    trailing corner (-b, -b) down and lifts the leading one (b, b); k = μ b m g / 0.1 s.
    The face stays level and slides at μ g along d as long as three corners hold it.

    Moment balance about the centre (horizontal part), corners at p_i = (x_i, y_i, -b),
    friction -μ λ_i d: Σ λ_i (y_i, -x_i) = -(b μ m g - T)(ẑ × d). On four corners the
    compatible loads are linear, λ_i = m g / 4 + β · p_i (`contactdiff.dynamics.redundant`),
    Σ λ_i p_i = 4 b² β: β = (b μ m g - T) d / (4 b²), so
    λ_trailing = (m g / 4)(1 - μ √2) + T / (2 √2 b) and
    λ_leading = (m g / 4)(1 + μ √2) - T / (2 √2 b), the side corners m g / 4.
    At t = 0 the trailing corner would pull (μ > 1/√2): it lifts, held at zero gap by the
    other three. Its compatible load on the whole face turns positive at
    T = b m g (μ - 1/√2), t1 = 0.1 (1 - 1/(μ √2)) = 0.0168 s: it bears there (event
    ``bear``, no impulse), the face on four corners. The leading corner's load reaches
    zero at T = b m g (μ + 1/√2), t2 = 0.1 (1 + 1/(μ √2)) = 0.183 s: it lifts, and the
    trailing and side corners carry λ_trailing = (T - b μ m g) / (√2 b),
    λ_side = (m g - λ_trailing) / 2 (unique on three), positive until
    T = b m g (μ + √2), t3 = 0.1 (1 + √2/μ) = 0.266 s, after the run's end at 0.2 s
    (the slide stops at u0 / (μ g) = 0.24 s). Throughout every corner slides at the centre's
    velocity (no turn: the side corners' yaw moments cancel), so the velocity and position
    are those of a slide decelerating at μ g along d."""
    mu, u0, T = MU_COUPLE, 2.0, 0.2
    t1, t2, t3 = couple_times()
    assert 0.0 < t1 < t2 < T < min(t3, u0 / (mu * G))
    d = np.array([1.0, 1.0, 0.0]) / np.sqrt(2)
    q = np.r_[0.0, 0.0, B, 0.0, 0.0, 0.0, 1.0]
    traj = cd.simulate(couple_slide(mu, COUPLE_RATE).with_state(q, np.r_[u0 * d, 0.0, 0.0, 0.0]), T, **TIGHT)
    release, bear, lift = traj.events
    assert release.kind == "lift-off" and release.t == 0.0 and release.contacts == ("cube/-x-y-z",)
    assert bear.kind == "bear" and bear.contacts == ("cube/-x-y-z",)
    assert bear.t == pytest.approx(t1, abs=EVENT_ATOL)
    assert set(bear.mode_after) == set(bear.sliding) == corners(z="-") and not bear.impulses
    np.testing.assert_array_equal(bear.v_plus, bear.v_minus)
    assert lift.kind == "lift-off" and lift.contacts == ("cube/+x+y-z",)
    assert lift.t == pytest.approx(t2, abs=EVENT_ATOL)
    assert set(lift.mode_after) == set(lift.sliding) == corners(z="-") - {"cube/+x+y-z"}
    np.testing.assert_allclose(traj.v[:3], (u0 - mu * G * T) * d, atol=STATE_ATOL)
    np.testing.assert_allclose(traj.v[3:], 0.0, atol=STATE_ATOL)
    np.testing.assert_allclose(traj.q[:3], np.r_[(u0 * T - mu * G * T**2 / 2) * d[:2], B], atol=STATE_ATOL)
    assert level(traj.q) < 1e-14


def test_the_held_corners_slide_ends_where_the_closed_form_puts_it_at_default_tolerances():
    """The run of the test above at the default tolerances (rtol 1e-8, atol 1e-10): the
    held trailing corner's gap is the others' drift, and it has no gap guard while they
    hold it (a crossing of the grazing band by that drift closed it as a grazing landing
    before its load was watched): the events are the closed form's, release, bearing
    and the leading corner's lift-off, at their times to the run's error (~1e-8 relative
    of the guards' scale over the slide), and the face slides on at μ g along d to the
    closed form's velocity and position at T = 0.2 s (to 1e-6: the run's error and the
    drift the projection allows). (After a grazing landing, corners that slid on at
    1.3 m/s with sticking keys took as slip direction the force they resisted, against
    their slip: their slips looked stopped and the stop held the whole face still.)"""
    mu, u0, T = MU_COUPLE, 2.0, 0.2
    t1, t2, _ = couple_times()
    d = np.array([1.0, 1.0, 0.0]) / np.sqrt(2)
    q = np.r_[0.0, 0.0, B, 0.0, 0.0, 0.0, 1.0]
    traj = cd.simulate(couple_slide(mu, COUPLE_RATE).with_state(q, np.r_[u0 * d, 0.0, 0.0, 0.0]), T)
    assert [e.kind for e in traj.events] == ["lift-off", "bear", "lift-off"]
    np.testing.assert_allclose([e.t for e in traj.events], [0.0, t1, t2], atol=1e-6)
    np.testing.assert_allclose(traj.v[:3], (u0 - mu * G * T) * d, atol=1e-6)
    np.testing.assert_allclose(traj.q[:3], np.r_[(u0 * T - mu * G * T**2 / 2) * d[:2], B], atol=1e-6)


def test_an_impacts_open_neighbour_slides_on_along_its_own_slip():
    """After a frictional impact, a closed contact the law leaves open (no impulse, zero
    normal speed after) that still slips keeps sliding along its own slip velocity,
    whatever slip direction an earlier mode left for it: here the cube slides along +x
    at 1 m/s on its face, the corner (+x, -y)'s stored direction points back along -x
    (stale), and the impact's outcome is read as the four corners sliding along +x (the
    cube's own velocity, each corner's slip) with no creeping contact. The outcome names
    its contacts by scene index, as the frictional law returns them (checked on a real
    impact of the same face): the corner's key before the impact says it slid. Read by
    its index alone it kept a sticking key while slipping at 0.66 m/s (a measured toss,
    whose face then slid 0.11 s with that corner "sticking" at constant slip, until a
    cone crossing and a stop at one instant removed the slip without an impulse)."""
    from types import SimpleNamespace

    from contactdiff.dynamics.frictional_impact import ContactState
    from contactdiff.dynamics.impacts import resolve_impact

    q = np.r_[0.0, 0.0, B, 0.0, 0.0, 0.0, 1.0]
    v = np.r_[1.0, 0.0, 0.0, 0.0, 0.0, 0.0]
    scene = cube(0.18).with_state(q, v)
    loop = cd.HybridLoop(scene, 0.0, 1.0)
    dyn, names = loop.dyn, scene.contact_names
    bottom = [names.index(n) for n in sorted(corners(z="-"))]
    stale = names.index("cube/+x-y-z")
    dyn.slip_reference[stale] = np.array([-1.0, 0.0])
    keys_before = [dyn.sliding_key(i) if i == stale else i for i in bottom]
    slide = ContactState.SLIDE
    real = resolve_impact(dyn, q, v, keys_before)
    assert real.contacts == tuple(bottom)  # scene indices, whatever the keys before
    impact = SimpleNamespace(
        contacts=tuple(bottom),
        v_plus=v,
        normal_speeds_before=np.zeros(4),
        normal_speeds_after=np.zeros(4),
        states=tuple(ContactState.OPEN if i == stale else slide for i in bottom),
        slide_directions=tuple(np.zeros(2) if i == stale else np.array([1.0, 0.0]) for i in bottom),
    )
    keys, creeping = loop._friction_keys(q, impact, keys_before)
    assert keys == [dyn.sliding_key(i) for i in bottom] and creeping == []
    dyn.kin.update(q, v)
    slip = dyn.contact(stale).rows(dyn.kin)[1:] @ v
    np.testing.assert_allclose(dyn.slip_reference[stale], slip / np.linalg.norm(slip), atol=1e-15)
    assert slip @ np.array([-1.0, 0.0]) < 0.0  # the stale direction was the other way


def test_flow_jacobian_through_a_held_corners_bearing_matches_finite_differences():
    """The flow Jacobian of the couple on the diagonal slide (test above), the cube turned
    by 0.1 rad about the vertical (the slide still along d), to T = 0.2 s: through the
    trailing corner's release at t = 0, its bearing and the leading corner's lift-off,
    along horizontal position, yaw, and the speed along and across d, against central
    differences on the manifold; and the bearing's event-time gradient
    (``-Dh Φ / (Dh F + h_t)``, ``h`` minus the corner's load on the whole face) against
    central differences of the bearing times. (Turned: on the exact diagonal the loads
    are even in yaw and in the speed across d, so no state direction would move the
    bearing at first order.) ε = 1e-6 with rtol 1e-12: the differences' error is
    ~1e-12/ε plus ε² terms, so 1e-5 relative to the columns' size. Every perturbed run
    has the same events: the held corner has no gap guard (round-off of its gap closed
    it as a grazing landing on one of them, under one BLAS kernel, before its load was
    watched)."""
    mu, u0, T, yaw = MU_COUPLE, 2.0, 0.2, 0.1
    scene = couple_slide(mu, COUPLE_RATE)
    turn = pin.rpy.rpyToMatrix(0.0, 0.0, yaw)
    d, across = np.array([1.0, 1.0, 0.0]) / np.sqrt(2), np.array([-1.0, 1.0, 0.0]) / np.sqrt(2)
    q = np.r_[0.0, 0.0, B, pin.Quaternion(turn).coeffs()]
    v = np.r_[turn.T @ (u0 * d), 0.0, 0.0, 0.0]  # the free flyer's velocity in the cube's frame
    opts = dict(rtol=1e-12, atol=1e-14)
    traj = cd.simulate(scene.with_state(q, v), T, jacobian=True, **opts)
    kinds = [e.kind for e in traj.events]
    assert kinds == ["lift-off", "bear", "lift-off"] and traj.differentiable
    model, eps = scene.model, 1e-6
    directions = [(np.r_[turn.T @ np.eye(3)[k], 0.0, 0.0, 0.0], np.zeros(6)) for k in (0, 1)] + [
        (np.eye(6)[5], np.zeros(6)),
        (np.zeros(6), np.r_[turn.T @ d, 0.0, 0.0, 0.0]),
        (np.zeros(6), np.r_[turn.T @ across, 0.0, 0.0, 0.0]),
    ]
    bear = traj.events[1]
    moved = 0.0
    for dq, dv in directions:
        runs = [
            cd.simulate(scene.with_state(pin.integrate(model, q, s * eps * dq), v + s * eps * dv), T, **opts)
            for s in (1.0, -1.0)
        ]
        assert [e.kind for e in runs[0].events] == [e.kind for e in runs[1].events] == kinds
        fd = np.r_[pin.difference(model, runs[1].q, runs[0].q), runs[0].v - runs[1].v] / (2 * eps)
        exact = traj.jacobian @ np.r_[dq, dv]
        assert np.abs(exact - fd).max() <= 1e-5 * max(1.0, np.abs(fd).max()), (dq, dv, exact, fd)
        fd_time = (runs[0].events[1].t - runs[1].events[1].t) / (2 * eps)
        # the bearing is located to ~1e-14 s (Brent to full precision on a dense output good
        # to rtol 1e-12): over 2ε, 1e-8 s per unit of perturbation
        assert bear.time_gradient @ np.r_[dq, dv] == pytest.approx(fd_time, abs=1e-8)
        moved = max(moved, abs(fd_time))
    assert moved > 1e-3  # s per unit: some direction moves the bearing (the gradient is tested)


def test_the_bearing_time_moves_with_the_mass_as_the_closed_form():
    """With the cube's mass as a parameter (the couple's rate k held): t1 = b m g
    (μ - 1/√2) / k and t2 = b m g (μ + 1/√2) / k (test above) are proportional to m, so
    ∂t1/∂m = t1 / m and ∂t2/∂m = t2 / m: the bearing's and the lift-off's parameter
    time gradients, ``-(Dh Φ_p + h_p) / rate`` with ``h_p`` the loads' mass derivative.
    The loads of a level, sliding face balance forces and moments and do not involve
    the inertia. To 1e-6 relative: the flow Jacobian's integration error at rtol 1e-10."""
    mu, u0 = MU_COUPLE, 2.0
    d = np.array([1.0, 1.0, 0.0]) / np.sqrt(2)
    q = np.r_[0.0, 0.0, B, 0.0, 0.0, 0.0, 1.0]
    scene = couple_slide(mu, COUPLE_RATE).with_state(q, np.r_[u0 * d, 0.0, 0.0, 0.0])
    traj = cd.simulate(scene, 0.2, jacobian=True, parameters=["body:cube:mass"], **TIGHT)
    _, bear, lift = traj.events
    assert bear.kind == "bear" and lift.kind == "lift-off"
    t1, t2, _ = couple_times()
    assert bear.parameter_time_gradient[0] == pytest.approx(t1 / MASS, rel=1e-6)
    assert lift.parameter_time_gradient[0] == pytest.approx(t2 / MASS, rel=1e-6)
