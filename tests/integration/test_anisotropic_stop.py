"""A slip that stops with a turning direction: a point mass whose tangential inverse inertia is
anisotropic, against the closed form derived here and central finite differences (models,
conventions and tolerances: `coulomb_models`).

**Model.** The mass m = 2 kg on prismatic joints x, y, z as ``block3``, with 1 kg more on the
x slider: the generalised inertia is ``M = diag(m_x, m_y, m) = diag(3, 2, 2)`` kg, so the
contact's tangential inverse inertia (its Delassus block ``A_T M⁻¹ A_Tᵀ``) is ``diag(1/m_x, 1/m_y)``,
not a multiple of the identity. The normal row is z alone and the ground is flat, so the normal
force is ``N = m g`` whatever the slip direction (``A_n M⁻¹ Fᵀ = 1/m``), and the slip velocity
``u = (v_x, v_y)`` obeys

    u̇ = -c W u / |u|,   c = μ m g,   W = diag(1/m_x, 1/m_y).

**Closed form.** In the time ``τ`` with ``dt = |u| dτ`` the law is linear, ``du/dτ = -c W u``:
``u_x = x0 e^{-α τ}``, ``u_y = y0 e^{-β τ}`` with ``α = c / m_x``, ``β = c / m_y``. Here
``β / α = m_x / m_y = 3/2``. With ``z = e^{-α τ}`` (1 at the start, 0 at the stop)
``u = (x0 z, y0 z^{3/2})``, ``|u| = z √(A + B z)`` (``A = x0²``, ``B = y0²``) and
``dt = |u| dτ = √(A + B z) dz / α`` (z decreasing), so

    t(z) = [(A + B)^{3/2} - (A + B z)^{3/2}] · 2 / (3 B α),   t_s = t(0) = 2 [(A + B)^{3/2} - A^{3/2}] / (3 B α),

which inverts to ``z(t) = ([(A + B)^{3/2} - 3 B α t / 2]^{2/3} - A) / B``. The displacements
``Δp = ∫ u dt = ∫_0^1 u √(A + B z) dz / α`` are

    Δp_x = (x0 / α) ∫_0^1 z √(A + B z) dz = (x0 / α) [2 w^{5/2} / 5 - 2 A w^{3/2} / 3]_{w=A}^{A+B} / B²,
    Δp_y = (y0 / α) ∫_0^1 z R dz,   R = √(B z² + A z),   ∫ z R dz = R³ / (3B) - (A / 2B) ∫ R dz

(from ``d(R³)/dz = 3 B z R + 3 A R / 2``), and with ``k = A / (2B)``,
``∫_0^1 R dz = √B [(1 + k) √(1 + 2k) / 2 - k² ln((1 + k + √(1 + 2k)) / k) / 2]``
(``R = √B √((z + k)² - k²)``). The stop time's gradient, differentiating ``t_s = ∫_0^1 √(A + Bz) dz / α``
under the integral: ``∂t_s/∂x0 = (x0 / α) ∫_0^1 dz / √(A + Bz) = 2 x0 (√(A + B) - √A) / (α B)`` and
``∂t_s/∂y0 = (y0 / α) ∫_0^1 z dz / √(A + Bz) = (y0 / α) [2 w^{3/2} / 3 - 2 A w^{1/2}]_{w=A}^{A+B} / B²``;
a shift of the start changes nothing (``∂t_s/∂q0 = 0``). After the stop the mass sticks (no
force but gravity, which the normal force carries).

**The approach is a fractional power.** Near the stop ``t_s - t ≈ |x0| z / α``, so the slip's
angle to its final direction (the x axis, the heavier one) is ``atan(y0 z^{1/2} / x0)``
``∝ (t_s - t)^{1/2}``: its rate diverges like ``(t_s - t)^{-1/2}``, and so does the second derivative
of ``u_y ∝ (t_s - t)^{3/2}``. No step-size controller gets past such a point with steps longer than
the time left (``scripts/friction_trots.py --profile`` counts them in the trots).

Tolerances: as `coulomb_models` (runs at rtol = atol = 1e-12, closed-form values at 1e-10
relative, Jacobians by central differences at `FD_RTOL`); the closed-form time gradient is compared
at `JAC_REL` (the variational equation's error is controlled with the state's, the default
``jacobian_error``: the same relative error as the state's).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from coulomb_models import (
    FD_RTOL,
    JAC_REL,
    MASS,
    MU,
    REL,
    TOL,
    G,
    central_differences,
    event_kinds,
    load,
    unit,
)
from helpers import assert_fd

import contactdiff as cd

EXTRA_X = 1.0  # kg on the x slider: m_x = 3 kg, m_y = 2 kg (module doc)
_INERTIAL = (
    '<inertial><mass value="{m}"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>'
)
_JOINT = (
    '<joint name="{n}" type="prismatic"><parent link="{p}"/><child link="{c}"/><axis xyz="{a}"/>'
    '<limit lower="-100" upper="100" effort="0" velocity="100"/></joint>'
)
ANISO_URDF = (
    f'<?xml version="1.0"?><robot name="aniso"><link name="world"/>'
    f'<link name="sx">{_INERTIAL.format(m=EXTRA_X)}</link><link name="sy"/>'
    f'<link name="block">{_INERTIAL.format(m=MASS)}</link>'
    f"{_JOINT.format(n='x', p='world', c='sx', a='1 0 0')}"
    f"{_JOINT.format(n='y', p='sx', c='sy', a='0 1 0')}"
    f"{_JOINT.format(n='z', p='sy', c='block', a='0 0 1')}</robot>"
)

# initial slip velocities (m/s): mostly along the heavy axis, mostly along the light one (the
# slip turns by almost 90 deg), and a small transverse part
STARTS = {"oblique": (1.2, -0.9), "light-axis": (-0.4, 1.5), "nearly-heavy": (0.9, 0.05)}


@pytest.fixture(scope="module")
def aniso(tmp_path_factory):
    return load(tmp_path_factory, "aniso", ANISO_URDF)


class Stop:
    """The closed form of the module doc for the start ``(x0, y0)``."""

    def __init__(self, x0: float, y0: float):
        self.x0, self.y0 = x0, y0
        self.alpha = MU * MASS * G / (MASS + EXTRA_X)
        A, B, al = x0 * x0, y0 * y0, self.alpha
        self.A, self.B = A, B
        w0, w1 = A, A + B
        self.t_s = 2.0 * (w1**1.5 - A**1.5) / (3.0 * B * al)
        px = lambda w: 0.4 * w**2.5 - 2.0 * A * w**1.5 / 3.0  # noqa: E731
        k = A / (2.0 * B)
        root = math.sqrt(1.0 + 2.0 * k)
        int_r = math.sqrt(B) * ((1.0 + k) * root / 2.0 - k * k * math.log((1.0 + k + root) / k) / 2.0)
        self.dp = np.array(
            [x0 / al * (px(w1) - px(w0)) / B**2, y0 / al * (w1**1.5 / (3.0 * B) - A / (2.0 * B) * int_r)]
        )
        ty = lambda w: 2.0 * w**1.5 / 3.0 - 2.0 * A * math.sqrt(w)  # noqa: E731
        self.dt_dv0 = np.array(
            [2.0 * x0 * (math.sqrt(w1) - math.sqrt(w0)) / (al * B), y0 / al * (ty(w1) - ty(w0)) / B**2]
        )

    def slip(self, t: float) -> np.ndarray:
        """``u(t)`` (m/s) for ``0 <= t <= t_s``."""
        A, B = self.A, self.B
        z = (((A + B) ** 1.5 - 1.5 * B * self.alpha * t) ** (2.0 / 3.0) - A) / B
        return np.array([self.x0 * z, self.y0 * z**1.5])


def _scene(robot, start):
    return cd.Scene(
        robot, [cd.Contact("block", friction=MU)], [], gravity=[0, 0, -G], q0=np.zeros(3), v0=np.array([*start, 0.0])
    )


def test_closed_form_is_consistent():
    """The closed form against itself: ``z(t)`` inverts ``t(z)`` (``u(0) = u0``, ``u(t_s) = 0``), and
    its stop time and displacements match a plain trapezoid sum of ``∫ √(A + Bz) dz / α`` and
    ``∫ u √(A + Bz) dz / α`` over 2e5 intervals (error ~ h² |f''| / 12 ~ 1e-11 for these O(1)
    integrands away from z = 0, where ``z^{1/2}`` in Δp_y limits it to ~h^{3/2} ~ 1e-8)."""
    for start in STARTS.values():
        stop = Stop(*start)
        np.testing.assert_allclose(stop.slip(0.0), start, rtol=1e-13)
        np.testing.assert_allclose(stop.slip(stop.t_s), 0.0, atol=1e-7 * np.linalg.norm(start))
        z = np.linspace(0.0, 1.0, 200_001)
        root = np.sqrt(stop.A + stop.B * z)
        trap = lambda f: float(np.sum((f[1:] + f[:-1]) * np.diff(z)) / 2.0)  # noqa: E731
        assert trap(root) / stop.alpha == pytest.approx(stop.t_s, rel=1e-9)
        np.testing.assert_allclose(
            [trap(start[0] * z * root) / stop.alpha, trap(start[1] * z**1.5 * root) / stop.alpha], stop.dp, rtol=1e-7
        )


@pytest.mark.parametrize("case", STARTS, ids=list(STARTS))
def test_anisotropic_slip_stops_on_time(aniso, case):
    """The stop time, the state at the stop and after it, and the stop time's gradient against
    the closed form (module doc); the flow Jacobian and the time gradient against central
    differences along the ground (q_x, q_y, v_x, v_y)."""
    stop = Stop(*STARTS[case])
    speed = float(np.hypot(*STARTS[case]))
    scene = _scene(aniso, STARTS[case])
    t_final = stop.t_s + 0.1
    traj = cd.simulate(scene, t_final, jacobian=True, **TOL)

    assert event_kinds(traj) == [("stick", ("block",))]
    (event,) = traj.events
    assert event.mode_after == ("block",) and event.sliding == () and event.differentiable
    assert event.t == pytest.approx(stop.t_s, rel=REL)
    np.testing.assert_allclose(event.q, [*stop.dp, 0.0], rtol=0, atol=REL * speed * stop.t_s)
    np.testing.assert_allclose(traj.q, [*stop.dp, 0.0], rtol=0, atol=REL * speed * stop.t_s)
    np.testing.assert_allclose(traj.v, 0.0, rtol=0, atol=REL * speed)

    grad = np.zeros(6)
    grad[3:5] = stop.dt_dv0
    np.testing.assert_allclose(event.time_gradient, grad, rtol=0, atol=JAC_REL * stop.t_s / speed)

    directions = [unit(k, 6) for k in (0, 1, 3, 4)]
    fd, fd_times = central_differences(scene, t_final, directions, event_kinds(traj))
    assert_fd(f"anisotropic stop {case}", traj.jacobian[:, [0, 1, 3, 4]], fd, traj.q, rtol=FD_RTOL)
    assert_fd(f"anisotropic stop time {case}", event.time_gradient[[0, 1, 3, 4]], fd_times[0], stop.t_s, rtol=FD_RTOL)


def test_direction_settles_like_the_square_root_of_the_time_left(aniso):
    """The dense output's slip velocity at 1e-2 .. 1e-6 s before the stop against ``u(t)`` of the
    closed form, to REL of the initial speed (the interpolant's error is of the order of the steps'
    1e-12), and the angle to the final direction (x) shrinking by √10 per decade of time left
    (module doc: ``θ ∝ (t_s - t)^{1/2}`` up to relative terms O(z) and O(θ²) of the closed form,
    6.3e-3 at most, for the first decade; an exponent 1 or 1/3 would give ratios 10 or 2.2)."""
    start = STARTS["oblique"]
    stop = Stop(*start)
    speed = float(np.hypot(*start))
    traj = cd.simulate(_scene(aniso, start), stop.t_s + 0.01, dense=True, **TOL)
    lefts = 10.0 ** -np.arange(2, 7)
    angles = []
    for left in lefts:
        _, v = traj.at(stop.t_s - left)
        np.testing.assert_allclose(v[:2], stop.slip(stop.t_s - left), rtol=0, atol=REL * speed)
        angles.append(math.atan2(-v[1], v[0]))  # y0 < 0: the angle below the x axis
    ratios = np.array(angles[:-1]) / np.array(angles[1:])
    np.testing.assert_allclose(ratios, math.sqrt(10.0), rtol=1e-2)
