"""Gait stability: stride map, its Jacobian, periodic gaits, Floquet multipliers.

References, never the code's own output:

* **Bouncing ball, closed form** (g, restitution e). Section ``z = 0``, ``v < 0``
  (just before impact). The impact gives ``v+ = -e v``, the flight lasts
  ``T = 2 v+/g = -2 e v / g`` and the ball comes back with ``v' = -v+ = e v``:
  the map on the section coordinate ``v`` is ``v -> e v``, multiplier ``e``,
  ``dT/dv = -2e/g``. Autonomy: starting further along the flow changes nothing
  but the start, so ``P F0 = 0``, ``dt'/dx0 · F0 = -1``, ``∂x'/∂t0 = 0``,
  ``∂t'/∂t0 = 1``.
* **Point mass in the x–z plane**, same law plus a constant horizontal speed u:
  on the section coordinates ``(x, u, w)`` (w the vertical speed) the map is
  ``x' = x + u T(w)``, ``u' = u``, ``w' = e w``, Jacobian
  ``[[1, T, u dT/dw], [0, 1, 0], [0, 0, e]]``: multipliers ``1, 1, e``; with
  the neutral translation x removed, ``1, e`` (the 1 left is the conserved u).
* **Ball on a clock-driven shaker** (the non-autonomous case with a closed
  form): force ``a cos(ωt)`` per unit mass, period ``P = 2π/ω``. In flight from
  ``t`` with upward speed ``w = -e v``,
  ``z(s) = w(s-t) - g(s-t)²/2 + (a/ω²)(cos ωt - cos ωs) - (a/ω) sin(ωt) (s-t)``.
  A period-1 orbit lands every P with speed V: ``z(t+P) = 0`` and
  ``z'(t+P) = -V`` give ``V = gP/(1+e)`` and ``sin ωt* = (ωgP/a)(e-1)/(2(1+e))``
  (two orbits per period). The map ``(v, t) -> (v', t')`` has, by the implicit
  function theorem on ``z(t') = 0``: ``dt'/dw = -(t'-t)/v'``,
  ``dt'/dt = -(-w + g(t'-t) - a cos(ωt)(t'-t))/v'``, and
  ``v' = w - g(t'-t) + (a/ω)(sin ωt' - sin ωt)`` differentiated along; with
  ``dw/dv = -e``. Its determinant is ``e²`` (checked), so complex multipliers
  have modulus exactly e. The touchdown time t' is found here by Brent's method
  on the closed-form z.
* **Central finite differences of the stride map** on the section: the start is
  moved along a section coordinate (tangent to the guard), put back onto the
  guard (`onto_section`, a second-order correction) and the stride simulated
  again. Step ε = 1e-5 at rtol = 1e-12, atol = 1e-13 (as tests/integration/test_sensitivity.py:
  truncation ~ε² ≈ 1e-10, step-sequence noise ~tol/ε ≈ 1e-8); measured on the
  soft trot: 2.7e-6, 2.7e-8, 2.6e-10 at ε = 1e-4, 1e-5, 1e-6 (shrinks as ε²).
  Asserted ≤ 1e-6 relative (docs/design.md §7). Models: planar_trot_soft (frictionless
  and sticking feet, through touchdowns and lift-offs), a bouncing solo12
  (free-flyer, quaternion base), the same with a clock-driven PD and the shaker
  (start-time column).
* **Neutral moves**, closed form: a translation along the ground maps to itself;
  a turn about the vertical through the start base point maps to the turn about
  the end base point plus the translation ``e_z × (p' - p0)``.
* **Symplectic return map** of a conservative system (planar_trot_soft with
  elastic feet): multipliers in pairs λ, 1/λ, product 1.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pinocchio as pin
import pytest
from helpers import assert_fd
from scipy.optimize import brentq

import contactdiff as cd
from contactdiff.analysis.gait import (
    StrideError,
    available_neutral,
    find_periodic_gait,
    first_touchdown,
    floquet_multipliers,
    neutral_directions,
    onto_section,
    period_map,
    section_basis,
    stride_map,
)
from contactdiff.cli import main as cli_main

TOL = dict(rtol=1e-12, atol=1e-13)
EPS = 1e-5
FD_RTOL = 1e-6


# ----------------------------------------------------------------------------------
# models
# ----------------------------------------------------------------------------------
def _ball(e: float) -> cd.Scene:
    return cd.Scene(cd.load_robot("ball"), [cd.Contact("ball", restitution=e)], gravity=[0, 0, -1.0], q0={"z": 1.0})


POINT_XZ = """<?xml version="1.0"?>
<robot name="point_xz">
  <link name="world"/>
  <link name="carriage"/>
  <link name="ball">
    <inertial><origin xyz="0 0 0"/><mass value="1"/>
      <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial>
  </link>
  <joint name="x" type="prismatic">
    <parent link="world"/><child link="carriage"/>
    <axis xyz="1 0 0"/><limit lower="-100" upper="100" effort="0" velocity="100"/>
  </joint>
  <joint name="z" type="prismatic">
    <parent link="carriage"/><child link="ball"/>
    <axis xyz="0 0 1"/><limit lower="-100" upper="100" effort="0" velocity="100"/>
  </joint>
</robot>
"""


class Shaker:
    """The ball (mass 1) with a clock-driven force ``a cos(ωt)``, restitution e, g = 1."""

    def __init__(self, e=0.5, period=2.0, a=1.2, g=1.0):
        self.e, self.P, self.a, self.g = e, period, a, g
        self.w = 2 * math.pi / period
        force = cd.UserEffort(
            lambda q, v, t: np.array([a * math.cos(self.w * t)]),
            lambda q, v, t: (np.zeros((1, 1)), np.zeros((1, 1))),
            name="shaker",
        )
        self.scene = cd.Scene(
            cd.load_robot("ball"),
            [cd.Contact("ball", restitution=e)],
            [force],
            gravity=[0, 0, -g],
            q0={"z": 0.0},
            v0={"z": -1.0},
        )
        self.V = g * period / (1 + e)
        s = (self.w * g * period / a) * (e - 1) / (2 * (1 + e))
        self.orbit_times = (math.asin(s) / self.w, (math.pi - math.asin(s)) / self.w)

    def touchdown(self, v: float, t: float) -> tuple[float, float, np.ndarray]:
        """Closed-form next touchdown ``(v', t')`` from ``(v, t)`` and the Jacobian d(v', t')/d(v, t)."""
        e, g, a, w = self.e, self.g, self.a, self.w
        up = -e * v

        def z(s):
            return (
                up * (s - t)
                - g * (s - t) ** 2 / 2
                + (a / w**2) * (math.cos(w * t) - math.cos(w * s))
                - (a / w) * math.sin(w * t) * (s - t)
            )

        t1 = brentq(z, t + 0.5 * self.P, t + 1.5 * self.P, xtol=1e-15, rtol=1e-15)
        T = t1 - t
        v1 = up - g * T + (a / w) * (math.sin(w * t1) - math.sin(w * t))
        dt1_dup, dt1_dt = -T / v1, -(-up + g * T - a * math.cos(w * t) * T) / v1
        dv1_dt1 = -g + a * math.cos(w * t1)
        dv1_dup = 1 + dv1_dt1 * dt1_dup
        dv1_dt = (g - a * math.cos(w * t)) + dv1_dt1 * dt1_dt
        return v1, t1, np.array([[-e * dv1_dup, dv1_dt], [-e * dt1_dup, dt1_dt]])


def _eig_sorted(A):
    lam = np.linalg.eigvals(A)
    return lam[np.lexsort((-lam.imag, -np.abs(lam)))]


# ----------------------------------------------------------------------------------
# closed forms
# ----------------------------------------------------------------------------------
@pytest.mark.parametrize("e", [0.8, 1.0])
def test_ball_stride_closed_form(e):
    scene = _ball(e)
    t, q, v = first_touchdown(scene, "ball")
    assert t == pytest.approx(math.sqrt(2), abs=1e-9) and v[0] == pytest.approx(-math.sqrt(2), abs=1e-9)
    s = stride_map(scene, "ball", q, v, t)
    assert s.stride_time == pytest.approx(2 * e * math.sqrt(2), abs=1e-9)
    assert s.v[0] == pytest.approx(-e * math.sqrt(2), abs=1e-9)
    # section coordinate v: multiplier e; dT/dv = -2e/g
    assert s.jacobian[1, 1] == pytest.approx(e, abs=1e-9)
    assert s.time_gradient[1] == pytest.approx(-2 * e, abs=1e-9)
    mult = floquet_multipliers(scene, s)
    assert mult.shape == (1,) and mult[0] == pytest.approx(e, abs=1e-9)
    # autonomy: the flow direction is the trivial one; the start time only shifts the run
    F0 = np.array([v[0], -1.0])
    np.testing.assert_allclose(s.jacobian @ F0, 0.0, atol=1e-9)
    assert s.time_gradient @ F0 == pytest.approx(-1.0, abs=1e-9)
    np.testing.assert_allclose(s.start_time_column, 0.0, atol=1e-9)
    assert s.start_time_derivative == pytest.approx(1.0, abs=1e-9)
    # the image lies on the section: Dh' P = 0 (Dh = [1, 0] for the ball)
    np.testing.assert_allclose(s.jacobian[0], 0.0, atol=1e-12)
    summary = json.loads(json.dumps(s.summary()))
    assert summary["stride_time"] == pytest.approx(2 * e * math.sqrt(2), abs=1e-9) and summary["period"] is None


def test_point_mass_plane_closed_form_and_neutral_translation(tmp_path):
    urdf = tmp_path / "point_xz.urdf"
    urdf.write_text(POINT_XZ)
    e, u, w = 0.6, 0.3, -1.0
    scene = cd.Scene(
        cd.load_robot(str(urdf)),
        [cd.Contact("ball", restitution=e)],
        gravity=[0, 0, -1.0],
        q0={"z": 0.0},
        v0={"x": u, "z": w},
    )
    assert available_neutral(scene) == ("x",)
    s = stride_map(scene, "ball", scene.q0, scene.v0)
    T, dT_dw = -2 * e * w, -2 * e
    assert s.stride_time == pytest.approx(T, abs=1e-9)
    # tangent order (x, z, ẋ, ż); section coordinates x, ẋ, ż (δz = 0)
    cols = [0, 2, 3]
    expected = np.zeros((4, 3))
    expected[0] = [1.0, T, u * dT_dw]
    expected[2] = [0.0, 1.0, 0.0]
    expected[3] = [0.0, 0.0, e]
    np.testing.assert_allclose(s.jacobian[:, cols], expected, atol=1e-9)
    np.testing.assert_allclose(floquet_multipliers(scene, s, ()), [1.0, 1.0, e], atol=1e-9)
    np.testing.assert_allclose(floquet_multipliers(scene, s), [1.0, e], atol=1e-9)
    n = neutral_directions(scene, s.q0, ("x",))[:, 0]
    np.testing.assert_allclose(n, [1.0, 0.0, 0.0, 0.0])
    np.testing.assert_allclose(s.jacobian @ n, n, atol=1e-12)


def test_shaker_multipliers_closed_form():
    sh = Shaker()
    for t_star in sh.orbit_times:
        v1, t1, J_ref = sh.touchdown(-sh.V, t_star)
        assert v1 == pytest.approx(-sh.V, abs=1e-12) and t1 - t_star == pytest.approx(sh.P, abs=1e-12)
        assert np.linalg.det(J_ref) == pytest.approx(sh.e**2, abs=1e-12)
        s = stride_map(sh.scene, "ball", [0.0], [-sh.V], t_star, period=sh.P, **TOL)
        assert s.period == sh.P
        assert s.stride_time == pytest.approx(sh.P, abs=1e-9)
        # extended state (z, v, τ); section coordinates (v, τ)
        J = s.extended_jacobian()
        np.testing.assert_allclose(J[1:, 1:], J_ref, rtol=1e-8, atol=1e-8)
        np.testing.assert_allclose(floquet_multipliers(sh.scene, s), _eig_sorted(J_ref), atol=1e-8)
    stable = floquet_multipliers(sh.scene, stride_map(sh.scene, "ball", [0.0], [-sh.V], sh.orbit_times[0], period=sh.P))
    np.testing.assert_allclose(np.abs(stable), [sh.e, sh.e], atol=1e-8)  # complex pair: |λ| = e


# ----------------------------------------------------------------------------------
# Newton towards a periodic gait
# ----------------------------------------------------------------------------------
@pytest.mark.parametrize("orbit", [0, 1])
def test_newton_finds_the_shaker_orbits(orbit):
    """Both period-1 orbits, the stable (complex multipliers of modulus e) and the
    saddle: Newton does not need stability; from 10% off in speed and 0.05 s off in phase."""
    sh = Shaker()
    t_star = sh.orbit_times[orbit]
    gait = find_periodic_gait(
        sh.scene, "ball", [0.0], [-1.1 * sh.V], t_star + 0.05, period=sh.P, iterations=10, tol=1e-10
    )
    assert gait.converged and gait.residuals[-1] <= 1e-10
    assert all(b < a for a, b in zip(gait.residuals, gait.residuals[1:]))
    assert gait.v[0] == pytest.approx(-sh.V, abs=1e-9)
    assert math.remainder(gait.t - t_star, sh.P) == pytest.approx(0.0, abs=1e-9)
    _, _, J_ref = sh.touchdown(-sh.V, t_star)
    np.testing.assert_allclose(gait.multipliers, _eig_sorted(J_ref), atol=1e-7)
    assert len(gait.steps) <= 8  # quadratic convergence: a handful of strides
    json.dumps(gait.to_dict())
    assert "Floquet multipliers" in gait.format()


@pytest.mark.parametrize("rtol", [1e-6, 1e-5])
@pytest.mark.parametrize("orbit", [0, 1])
def test_newton_stops_at_the_maps_resolution(orbit, rtol):
    """``tol = 0`` is below anything the map resolves at these loose tolerances
    (integration error 1e-8 to 1e-6); the search ends where the residual is within
    the map's resolution ρ and says so, instead of spending all its iterations on
    residuals the map cannot resolve. ρ is twice the change ``d`` of the residual
    when the stride is computed again at 10 times tighter tolerances: tightening
    tenfold at least halves the integration error e (DOP853: error ~ tol^(8/9), a
    factor 0.13), so ``|e| <= d + |e|/2``, ``|e| <= 2d = ρ``. The claim is checked
    against the closed-form orbit: near it ``r = A δx + e`` with ``A = J - I`` of
    the closed-form Jacobian, so the distance to the orbit is at most
    ``‖A⁻¹‖ (|r| + ρ)`` (to first order). Far from the orbit the map is resolved:
    every earlier iterate's residual is above its resolution."""
    sh = Shaker()
    t_star = sh.orbit_times[orbit]
    args = (sh.scene, "ball", [0.0], [-1.1 * sh.V], t_star + 0.05)
    opts = dict(period=sh.P, iterations=10, tol=0.0, rtol=rtol, atol=rtol * 1e-2)
    gait = find_periodic_gait(*args, **opts)
    assert gait.converged and gait.resolved and gait.residuals[-1] > 0.0
    assert len(gait.resolutions) == len(gait.residuals) and gait.resolution == gait.resolutions[-1]
    assert gait.residuals[-1] <= gait.resolution
    assert all(r > res for r, res in zip(gait.residuals[:-1], gait.resolutions[:-1]))
    _, _, J_ref = sh.touchdown(-sh.V, t_star)
    bound = np.linalg.norm(np.linalg.inv(J_ref - np.eye(2)), 2) * (gait.residuals[-1] + gait.resolution)
    assert math.hypot(gait.v[0] + sh.V, math.remainder(gait.t - t_star, sh.P)) <= bound
    assert "converged to the map's resolution" in gait.format()
    out = json.loads(json.dumps(gait.to_dict()))
    assert out["resolved"] and out["converged"] and out["resolutions"][-1] == gait.resolution
    # without the rule only tol ends the search: all iterations, not converged, nothing measured
    strict = find_periodic_gait(*args, **opts, resolution=False)
    assert len(strict.residuals) == 11 and strict.residuals[-1] > 0.0
    assert not strict.converged and not strict.resolved and strict.resolutions == [None] * 11
    assert "NOT converged" in strict.format()
    # a single stride measures nothing
    assert find_periodic_gait(*args, **opts | {"iterations": 0}).resolutions == [None]


def test_newton_elastic_soft_trot_multipliers_come_in_reciprocal_pairs():
    """planar_trot_soft with elastic feet (e = 1) is conservative: springs, gravity,
    frictionless elastic impacts. Its return map preserves the symplectic form on an
    energy level, so the multipliers come in pairs λ, 1/λ (plus the 1s of the energy
    and the horizontal momentum) and their product is 1. From the pitch-0.05
    touchdown Newton finds the orbit where both feet bounce together with the body
    at rest (a simultaneous start: the one-sided derivative of the rear-first
    branch, itself a symplectic map)."""
    base = cd.trot_touchdown("soft", 0.05)
    scene = cd.Scene(
        base.robot,
        [cd.Contact(c.frame, restitution=1.0) for c in base.contact_specs],
        base.effort_specs,
        None,
        base.q0,
        base.v0,
        name="soft_elastic",
    )
    gait = find_periodic_gait(scene, "rear_foot", iterations=10, tol=1e-9)
    assert gait.converged and gait.neutral == ("x",)
    assert gait.stride.simultaneous == ("front_foot",) and gait.stride.differentiable
    lam = gait.multipliers
    assert lam.shape == (12,)
    assert np.prod(lam) == pytest.approx(1.0, abs=1e-6)
    moduli = np.sort(np.abs(lam))
    np.testing.assert_allclose(moduli * moduli[::-1], 1.0, atol=1e-6)
    assert np.max(moduli) > 1.5  # a nontrivial, unstable orbit: not a degenerate all-ones case
    for m in lam:  # each λ has its reciprocal in the set
        assert np.min(np.abs(lam - 1.0 / m)) < 1e-6


def test_period_map_has_the_same_multipliers():
    """The stroboscopic map over one period from mid-flight of the stable orbit: its
    eigenvalues are the same Floquet multipliers as the touchdown map's."""
    sh = Shaker()
    t_star = sh.orbit_times[0]
    s = stride_map(sh.scene, "ball", [0.0], [-sh.V], t_star, period=sh.P, dense=True, **TOL)
    mid = t_star + 0.3 * sh.P
    q, v = s.trajectory.at(mid)
    pm = period_map(sh.scene, q, v, mid, period=sh.P, **TOL)
    assert pm.q[0] == pytest.approx(q[0], abs=1e-9) and pm.v[0] == pytest.approx(v[0], abs=1e-9)
    np.testing.assert_allclose(pm.multipliers, floquet_multipliers(sh.scene, s), atol=1e-7)


# ----------------------------------------------------------------------------------
# finite differences of the stride map
# ----------------------------------------------------------------------------------
def _fd_on_section(scene, foot, stride, basis_columns, clock=False, min_stride=None, min_flight=None, eps=EPS):
    """Central FD of (x', t') along section coordinates (and the start time if ``clock``)."""
    nv, model = scene.nv, scene.model
    kinds = [(e.kind, e.contacts) for e in stride.trajectory.events]

    def run(d, dt, eps):
        q = onto_section(scene, foot, pin.integrate(model, stride.q0, eps * d[:nv]))
        s = stride_map(
            scene,
            foot,
            q,
            stride.v0 + eps * d[nv : 2 * nv],
            stride.t0 + eps * dt,
            period=stride.period or False,
            min_stride=min_stride,
            min_flight=min_flight,
            jacobian=False,
            **TOL,
        )
        assert [(e.kind, e.contacts) for e in s.trajectory.events] == kinds  # same event sequence
        return s

    dx, dt = [], []
    directions = [(basis_columns[:, k], 0.0) for k in range(basis_columns.shape[1])]
    if clock:
        directions.append((np.zeros(2 * nv), 1.0))
    for d, tau in directions:
        p, m = run(d, tau, eps), run(d, tau, -eps)
        dx.append(np.concatenate([pin.difference(model, m.q, p.q), p.v - m.v]) / (2 * eps))
        dt.append((p.t - m.t) / (2 * eps))
    return np.array(dx).T, np.array(dt)


SOFT_STRIDES = {
    # rear touchdown, front touchdown, both lift-offs, front and rear touchdowns again
    "none": ["touchdown", "touchdown", "lift-off", "lift-off", "touchdown", "touchdown"],
    # sticking feet gliding forward at 0.3 (tangential velocity stopped at touchdown,
    # lift-offs with tangential force left): the rear lands again before the front
    "stick": ["touchdown", "touchdown", "lift-off", "lift-off", "touchdown"],
}


@pytest.mark.parametrize("friction", sorted(SOFT_STRIDES))
def test_stride_jacobian_fd_soft_trot(friction):
    """planar_trot_soft at pitch 0.05 from the rear touchdown: every section coordinate."""
    base = cd.trot_touchdown("soft", 0.05)
    scene = cd.Scene(
        base.robot,
        [cd.Contact(c.frame, friction=friction) for c in base.contact_specs],
        base.effort_specs,
        None,
        base.q0,
        base.v0,
        name=f"soft-{friction}",
    )
    if friction == "stick":
        scene = scene.with_state(None, {"body_x": 0.3, "rear_foot_x": 0.3, "front_foot_x": 0.3})
    t, q, v = first_touchdown(scene, "rear_foot", **TOL)
    s = stride_map(scene, "rear_foot", q, v, t, **TOL)
    assert [e.kind for e in s.trajectory.events] == SOFT_STRIDES[friction]
    B = section_basis(scene, "rear_foot", s.q0)
    assert B.shape == (14, 13)
    fd_x, fd_t = _fd_on_section(scene, "rear_foot", s, B)
    assert_fd(f"stride map dx'/dx0 (soft trot, {friction})", s.jacobian @ B, fd_x, rtol=FD_RTOL)
    assert_fd(f"stride map dt'/dx0 (soft trot, {friction})", s.time_gradient @ B, fd_t, rtol=FD_RTOL)
    # the neutral translation: every x moves together, the map commutes with it
    n = neutral_directions(scene, s.q0, ("x",))[:, 0]
    np.testing.assert_allclose(s.jacobian @ n, n, atol=1e-9)


def _solo12_bouncing() -> cd.Scene:
    """solo12 (free-flyer) on frictionless feet with restitution 0.7, holding its pose
    with undamped joint springs, tilted, raised 1 cm and moving (0.2, 0.1) m/s with
    yaw rate 0.3 rad/s: FR bounces at t ≈ 0.0956 and again 7.8 ms later, alone."""
    from scipy.spatial.transform import Rotation

    base = cd.load_scene("solo12_drop")
    contacts = [cd.Contact(c.frame, offset=c.offset, restitution=0.7) for c in base.contact_specs]
    springs = [cd.JointSpring(e.joint, stiffness=e.stiffness, rest=e.rest) for e in base.effort_specs]
    q = base.q0.copy()
    q[3:7] = Rotation.from_euler("xyz", [0.03, 0.05, 0.0]).as_quat()
    q[2] += 0.01
    v = np.r_[0.2, 0.1, 0.0, 0.0, 0.0, 0.3, np.zeros(12)]
    return cd.Scene(base.robot, contacts, springs, gravity=[0, 0, -9.81], q0=q, v0=v, name="solo12_bouncing")


def test_stride_jacobian_fd_free_flyer():
    """A free-flyer stride (quaternion base): every section coordinate by FD, and the
    neutral moves: translations map to the same translations at the end, the yaw about
    the start base point to the yaw about the end base point plus the translation
    ``e_z × (p' - p0)`` (closed form)."""
    scene = _solo12_bouncing()
    t, q, v = first_touchdown(scene, "FR_FOOT", **TOL)
    s = stride_map(scene, "FR_FOOT", q, v, t, **TOL)
    assert [(e.kind, e.contacts) for e in s.trajectory.events] == [("bounce", ("FR_FOOT",))] * 2
    assert available_neutral(scene, q, v, t) == ("x", "y", "yaw")
    B = section_basis(scene, "FR_FOOT", s.q0)
    assert B.shape == (36, 35)
    fd_x, fd_t = _fd_on_section(scene, "FR_FOOT", s, B)
    assert_fd("stride map dx'/dx0 (solo12 free-flyer)", s.jacobian @ B, fd_x, rtol=FD_RTOL)
    assert_fd("stride map dt'/dx0 (solo12 free-flyer)", s.time_gradient @ B, fd_t, rtol=FD_RTOL)
    N0 = neutral_directions(scene, s.q0, ("x", "y", "yaw"))
    N1 = neutral_directions(scene, s.q, ("x", "y", "yaw"))
    dx, dy = s.q[:2] - s.q0[:2]
    expected = N1 @ np.array([[1.0, 0.0, -dy], [0.0, 1.0, dx], [0.0, 0.0, 1.0]])
    np.testing.assert_allclose(s.jacobian @ N0, expected, atol=1e-8)


def test_stride_jacobian_fd_free_flyer_clock_driven():
    """The bouncing solo12 driven by a clock: PD torques (20 N m/rad, 0.3 N m s/rad) on
    every leg joint towards its standing angle plus 0.2 sin(2πt / 0.4 s) rad. Every
    section coordinate and the start time t0 (measured FD error 4e-9 and 5e-9 at
    ε = 1e-5, 3e-8 and 8e-9 at ε = 1e-6)."""
    bouncing = _solo12_bouncing()
    rest = bouncing.q0[7:].copy()
    kp, kd, period = 20.0, 0.3, 0.4

    def pd(q, v, t):
        tau = np.zeros(18)
        tau[6:] = kp * (rest + 0.2 * math.sin(2 * math.pi * t / period) - q[7:]) - kd * v[6:]
        return tau

    def pd_jacobian(q, v, t):
        dq, dv = np.zeros((18, 18)), np.zeros((18, 18))
        dq[6:, 6:], dv[6:, 6:] = -kp * np.eye(12), -kd * np.eye(12)
        return dq, dv

    scene = cd.Scene(
        bouncing.robot,
        bouncing.contact_specs,
        [cd.UserEffort(pd, pd_jacobian, name="clock PD")],
        gravity=[0, 0, -9.81],
        q0=bouncing.q0,
        v0=bouncing.v0,
        name="solo12_bouncing_clock",
    )
    t, q, v = first_touchdown(scene, "FR_FOOT", **TOL)
    s = stride_map(scene, "FR_FOOT", q, v, t, period=period, min_stride=0.0, min_flight=0.0, **TOL)
    assert [(e.kind, e.contacts) for e in s.trajectory.events] == [("bounce", ("FR_FOOT",))] * 2
    B = section_basis(scene, "FR_FOOT", s.q0)
    fd_x, fd_t = _fd_on_section(scene, "FR_FOOT", s, B, clock=True, min_stride=0.0, min_flight=0.0)
    analytic_x = np.column_stack([s.jacobian @ B, s.start_time_column])
    analytic_t = np.append(s.time_gradient @ B, s.start_time_derivative)
    assert_fd("stride map with clock, d(x', t')/d(x0, t0) (solo12)", analytic_x, fd_x, rtol=FD_RTOL)
    assert_fd("stride map with clock, dt' (solo12)", analytic_t, fd_t, rtol=FD_RTOL)
    assert abs(s.start_time_derivative - 1.0) > 1e-3  # the clock matters: not the autonomous value 1


def test_stride_jacobian_fd_clock_driven():
    """The shaker off its orbit: section coordinate v and the start time t0."""
    sh = Shaker()
    s = stride_map(sh.scene, "ball", [0.0], [-1.2 * sh.V], 0.1, period=sh.P, **TOL)
    B = section_basis(sh.scene, "ball", s.q0)
    fd_x, fd_t = _fd_on_section(sh.scene, "ball", s, B, clock=True)
    analytic_x = np.column_stack([s.jacobian @ B, s.start_time_column])
    analytic_t = np.append(s.time_gradient @ B, s.start_time_derivative)
    assert_fd("stride map with clock, d(x', t')/d(x0, t0)", analytic_x, fd_x, rtol=FD_RTOL)
    assert_fd("stride map with clock, dt'", analytic_t, fd_t, rtol=FD_RTOL)


def test_neutral_defaults():
    assert available_neutral(_ball(0.8)) == ()
    assert available_neutral(cd.trot_touchdown("soft", 0.0)) == ("x",)
    assert available_neutral(cd.load_scene("solo12_drop")) == ("x", "y", "yaw")


# ----------------------------------------------------------------------------------
# bad input
# ----------------------------------------------------------------------------------
def test_unknown_foot_lists_the_contacts():
    scene = cd.trot_touchdown("soft", 0.0)
    with pytest.raises(cd.UnknownNameError, match="front_foot, rear_foot"):
        stride_map(scene, "left_foot", scene.q0, scene.v0)
    with pytest.raises(cd.UnknownNameError, match="front_foot, rear_foot"):
        find_periodic_gait(scene, "left_foot")


def test_start_must_be_an_approaching_touchdown():
    scene = _ball(0.8)
    with pytest.raises(cd.InvalidInputError, match="gap 1"):
        stride_map(scene, "ball", [1.0], [0.0])
    with pytest.raises(cd.InvalidInputError, match="approaching"):
        stride_map(scene, "ball", [0.0], [0.5])


def test_no_return_within_t_max_is_a_stride_error():
    scene = _ball(0.8)
    with pytest.raises(StrideError, match="did not touch down again .* t_max"):
        stride_map(scene, "ball", [0.0], [-1.0], t_max=0.5)
    plastic = _ball(0.0)  # lands and stays
    with pytest.raises(StrideError, match="did not touch down again"):
        stride_map(plastic, "ball", [0.0], [-1.0], t_max=3.0)
    assert issubclass(StrideError, cd.ContactDiffError)


def test_bad_options():
    scene = cd.trot_touchdown("soft", 0.0)
    t, q, v = first_touchdown(scene, "rear_foot")
    with pytest.raises(cd.InvalidInputError, match="yaw.*valid here: x"):
        find_periodic_gait(scene, "rear_foot", q, v, t, neutral=("yaw",), iterations=0)
    with pytest.raises(cd.InvalidInputError, match="unknown neutral move 'z'; valid: x, y, yaw"):
        find_periodic_gait(scene, "rear_foot", q, v, t, neutral="z", iterations=0)
    with pytest.raises(cd.InvalidInputError, match="period must be > 0"):
        stride_map(scene, "rear_foot", q, v, t, period=0.0)
    with pytest.raises(cd.InvalidInputError, match="t_max must be > 0"):
        stride_map(scene, "rear_foot", q, v, t, t_max=0.0)
    with pytest.raises(cd.InvalidInputError, match="unknown simulation option"):
        stride_map(scene, "rear_foot", q, v, t, rtoll=1e-8)
    with pytest.raises(cd.InvalidInputError, match="no clock-driven effort"):
        period_map(scene)


def test_warmup_starts_at_the_touchdown_after_it():
    """Ball dropped from 1 m, g = 1, e = 0.8: touchdowns at sqrt(2) and
    sqrt(2) (1 + 2e) s (closed form as above). A warm-up of 1 s starts the search
    at the first, one of 2 s at the second (speed e sqrt(2))."""
    scene, e = _ball(0.8), 0.8
    for warmup, t_expected, v_expected in (
        (1.0, math.sqrt(2), -math.sqrt(2)),
        (2.0, math.sqrt(2) * (1 + 2 * e), -e * math.sqrt(2)),
    ):
        gait = find_periodic_gait(scene, "ball", iterations=0, warmup=warmup)
        assert gait.t == pytest.approx(t_expected, abs=1e-9)
        assert gait.v[0] == pytest.approx(v_expected, abs=1e-9)
    with pytest.raises(cd.InvalidInputError, match="warmup"):
        find_periodic_gait(scene, "ball", warmup=-1.0)


# ----------------------------------------------------------------------------------
# impact cascades: the section is the gait's touchdown, not a re-landing
# ----------------------------------------------------------------------------------
def _flight_before(events, foot, t):
    """Time (s) the foot was off the ground before its touchdown at ``t``, from the
    event list of a plain simulation starting with the foot on the ground."""
    last = 0.0
    for e in events:
        if e.t >= t:
            break
        if foot in e.contacts or foot in e.impulses or foot in e.mode_before or foot in e.mode_after:
            last = e.t
    return t - last


def test_min_flight_skips_cascade_relandings():
    """solo12's trot from rest: HR_FOOT stands at t = 0; the swing foot FR lands at
    about 0.06 s and its impact lifts HR, which lands again microseconds later (an
    impact cascade). The first touchdown with ``min_flight=0`` is that re-landing;
    with the default (5 % of the 0.4-s clock) it is HR's landing after its swing.
    Both are checked against the event list of a plain simulation."""
    scene = cd.load_scene("solo12_trot")
    opts = dict(rtol=1e-8, atol=1e-10, t_max=0.4)
    events = cd.simulate(scene, 0.4, **{k: opts[k] for k in ("rtol", "atol")}).events
    landings = [e.t for e in events if "HR_FOOT" in e.contacts and e.kind in ("touchdown", "bounce")]
    every, _, _ = first_touchdown(scene, "HR_FOOT", min_flight=0.0, **opts)
    gait, _, _ = first_touchdown(scene, "HR_FOOT", **opts)
    assert every == pytest.approx(landings[0], abs=1e-9)
    assert _flight_before(events, "HR_FOOT", landings[0]) < 1e-4  # s: a cascade re-landing
    main = next(t for t in landings if _flight_before(events, "HR_FOOT", t) >= 0.05 * 0.4)
    assert gait == pytest.approx(main, abs=1e-9)
    assert _flight_before(events, "HR_FOOT", main) > 0.1  # s: a swing
    with pytest.raises(cd.InvalidInputError, match="min_flight"):
        first_touchdown(scene, "HR_FOOT", min_flight=-1.0, **opts)


def test_trot_stride_skips_cascades_and_names_its_non_smooth_events():
    """From HR_FOOT's landing after its swing, the stride ends at its next such
    landing about one clock period later (0.4 s; the trot is not yet periodic),
    not at one of the cascade re-landings in between (gaps of microseconds to
    0.2 s). The cascades' simultaneous re-landings of coupled feet are not
    differentiable; `why_not_differentiable` names each of them."""
    scene = cd.load_scene("solo12_trot")
    opts = dict(rtol=1e-8, atol=1e-10, t_max=0.8)
    t, q, v = first_touchdown(scene, "HR_FOOT", **opts)
    gait = find_periodic_gait(scene, "HR_FOOT", q, v, t, iterations=0, **opts)
    stride = gait.stride
    assert abs(stride.stride_time - 0.4) < 0.05
    events = stride.trajectory.events
    relandings = [e for e in events[1:] if "HR_FOOT" in e.contacts and e.kind in ("touchdown", "bounce")]
    assert len(relandings) >= 2 and all(_flight_before(events, "HR_FOOT", e.t) < 1e-3 for e in relandings[:-1])
    assert relandings[-1].t == stride.t
    rough = [e for e in events if not e.differentiable]
    assert rough and not stride.differentiable
    why = gait.why_not_differentiable()
    assert why == [note for e in rough for note in e.nonsmooth.values()]  # every reason of every event
    for e in rough:
        assert all(f"{e.t:.12g}" in note for note in e.nonsmooth.values())
    assert gait.to_dict()["why_not_differentiable"] == why
    assert "not differentiable; the multipliers are those of the branch taken:" in gait.format()


# ----------------------------------------------------------------------------------
# command line
# ----------------------------------------------------------------------------------
def test_cli_stride_json(capsys):
    assert cli_main(["stride", "ball", "--foot", "ball", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["moduli"] == pytest.approx([0.8], abs=1e-9)
    assert out["stride_time"] == pytest.approx(1.6 * math.sqrt(2), abs=1e-9)
    assert out["neutral"] == [] and out["steps"] == ["start"]
    # a 2-s warm-up starts at the second touchdown, sqrt(2) (1 + 2e) s (closed form, e = 0.8)
    assert cli_main(["stride", "ball", "--foot", "ball", "--warmup", "2", "--min-flight", "0.1", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["t"] == pytest.approx(math.sqrt(2) * 2.6, abs=1e-9) and out["why_not_differentiable"] == []
    assert cli_main(["stride", "ball", "--foot", "ball", "--min-flight", "-1"]) == 2
    assert "min_flight must be >= 0" in capsys.readouterr().err


def test_cli_stride_neutral_option(capsys):
    args = ["stride", "planar_trot_soft", "--foot", "rear_foot", "--q", "body_pitch=0.05", "--json"]
    assert cli_main(args + ["--neutral", "none"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["neutral"] == [] and len(out["multipliers"]) == 13  # 2nv - 1
    assert cli_main(args + ["--neutral", "yaw"]) == 2
    assert "does not admit the neutral move(s) yaw" in capsys.readouterr().err


def test_cli_stride_text_and_errors(capsys):
    assert cli_main(["stride", "planar_trot_soft", "--foot", "rear_foot", "--q", "body_pitch=0.05"]) == 0
    text = capsys.readouterr().out
    assert "Floquet multipliers (12," in text and "neutral moves removed: x" in text
    assert cli_main(["stride", "ball", "--foot", "knee"]) == 2
    assert "unknown contact 'knee'; valid: ball" in capsys.readouterr().err
    assert cli_main(["stride", "ball", "--foot", "ball", "--t-max", "0.5"]) == 2
    assert "did not touch down" in capsys.readouterr().err


@pytest.mark.slow
def test_solo12_trot_is_periodic_and_both_maps_agree():
    """solo12's trot settles on its own (20 clock periods of warm-up) and Newton
    brings the stride-map residual below 1e-6 with a stride of one clock period.
    At a periodic gait the stride map (section: FL_FOOT's touchdown) and the
    stroboscopic map over one period from mid-stride have the same nonzero
    multipliers (two Poincare maps of one orbit); they agree to the residual's
    order, asserted at 1e-3 relative. All inside the unit circle: stable."""
    scene = cd.load_scene("solo12_trot")
    opts = dict(rtol=1e-10, atol=1e-12, t_max=1.6)
    gait = find_periodic_gait(scene, "FL_FOOT", warmup=8.0, iterations=2, **opts)
    assert gait.residuals[-1] < 1e-6
    assert gait.stride.stride_time == pytest.approx(0.4, abs=1e-8)
    stride_moduli = np.sort(np.abs(gait.multipliers))[::-1][:6]
    mid = gait.t + 0.2
    halfway = cd.simulate(scene, mid, gait.q, gait.v, t0=gait.t, rtol=1e-10, atol=1e-12)
    q, v = halfway.q, halfway.v
    pm = period_map(scene, q, v, mid, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(np.sort(np.abs(pm.multipliers))[::-1][:6], stride_moduli, rtol=1e-3)
    assert stride_moduli[0] < 1.0


def test_the_loops_public_hooks_a_stride_uses():
    """`HybridLoop.gaps_and_rates` of the ball (its contact point on the plane z = 0, as the
    closed forms above read it) at height z moving at w: gap z and rate w; `jacobian_after`
    of the ball's touchdown with saltation Ξ, from the start's ``[I]`` and from ``2 I``: Ξ and
    2 Ξ (products with a scaled identity are exact). And `StrideLoop` reads no private
    member of the loop: every ``self._name`` it uses is defined in its own class."""
    import ast
    import inspect

    from contactdiff.analysis.gait import StrideLoop

    loop = cd.HybridLoop(_ball(0.8), 0.0, 1.5, options=cd.SimulateOptions(jacobian=True))
    gaps, rates = loop.gaps_and_rates(np.array([0.25]), np.array([-0.5]))
    assert gaps.tolist() == [0.25] and rates.tolist() == [-0.5]
    loop.run()
    (event,) = loop.events
    assert event.saltation is not None and event.reference_jump is None
    np.testing.assert_array_equal(loop.jacobian_after(event), event.saltation)
    np.testing.assert_array_equal(loop.jacobian_after(event, 2.0 * np.eye(2)), 2.0 * event.saltation)
    tree = ast.parse(inspect.getsource(StrideLoop))
    used = {n.attr for n in ast.walk(tree) if isinstance(n, ast.Attribute) and n.attr.startswith("_")}
    used -= {n.attr for n in ast.walk(tree) if isinstance(n, ast.Attribute) and n.attr.startswith("__")}
    own = {n.name for n in ast.walk(tree) if isinstance(n, ast.FunctionDef)}
    assert used <= own, sorted(used - own)
