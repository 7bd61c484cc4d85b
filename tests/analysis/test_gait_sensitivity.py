"""Derivatives of strides and periodic gaits with respect to parameters.

References, never the code's own output:

* **The clock-driven shaker's closed forms** (test_stride.py's `Shaker`: the ball,
  restitution e, a force ``a cos(ωt)``, period P, g = 1). Its period-1 orbits land
  with speed ``V = gP/(1+e)`` at ``sin(ωt*) = S(e) = (ωgP/a)(e-1)/(2(1+e))``, so
  ``dV/de = -gP/(1+e)²`` and ``dt*/de = ± S'(e) / (ω sqrt(1 - S²))`` with
  ``S'(e) = (ωgP/a)/(1+e)²`` (+ on the orbit ``asin S``, - on ``π - asin S``); the
  stride time is P whatever e (derivative 0); the stable orbit's complex multipliers
  have modulus exactly e (their product is det J = e²), so ``d|λ|/de = 1``.
* **Central differences of re-converged gaits**: the multipliers of the gaits found
  anew (Newton from the nominal orbit) with the parameter at ``p ± h``, h = 1e-4 |p|;
  the multiplier is a simple real one there (the saddle orbit).
* **Central differences of the stride map** at a fixed start through
  `Scene.with_parameters` (h = 1e-5 |p|, as the state's stride tests).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_stride import POINT_XZ, TOL, Shaker

import contactdiff as cd
from contactdiff.analysis.gait import find_periodic_gait, gait_sensitivity, stride_map
from contactdiff.errors import InvalidInputError

GAIT = dict(rtol=1e-12, atol=1e-13)


def _gait(sh: Shaker, orbit: int):
    return find_periodic_gait(
        sh.scene,
        "ball",
        [0.0],
        [-1.05 * sh.V],
        sh.orbit_times[orbit] + 0.02,
        period=sh.P,
        iterations=10,
        tol=1e-12,
        **GAIT,
    )


def test_stride_parameter_jacobian_matches_finite_differences():
    sh = Shaker()
    names = ["contact:ball:restitution", "scene:gravity_z", "body:ball:mass"]
    start = ([0.0], [-1.05 * sh.V], sh.orbit_times[0])
    s = stride_map(sh.scene, "ball", *start, period=sh.P, parameters=names, **TOL)
    Jp = s.extended_parameter_jacobian()
    assert Jp.shape == (3, 3) and s.parameter_names == tuple(names)
    for k, (name, value) in enumerate(zip(names, sh.scene.parameter_values(names))):
        h = 1e-5 * abs(value)
        ends = []
        for sign in (1, -1):
            moved = stride_map(
                sh.scene.with_parameters({name: value + sign * h}), "ball", *start, period=sh.P, jacobian=False, **TOL
            )
            ends.append(np.array([moved.q[0], moved.v[0], moved.t]))
        fd = (ends[0] - ends[1]) / (2 * h)
        # truncation ~h² (1e-10), integration noise ~1e-12 / 2h (5e-8 relative at most)
        assert np.abs(Jp[:, k] - fd).max() <= 1e-6 * max(1.0, np.abs(fd).max()), (name, Jp[:, k], fd)


@pytest.mark.parametrize("orbit", [0, 1])
def test_shaker_fixed_point_and_stride_time_closed_form(orbit):
    sh = Shaker()
    g = gait_sensitivity(sh.scene, _gait(sh, orbit), ["contact:ball:restitution"], which=(), **GAIT)
    e, gP, a, w = sh.e, sh.g * sh.P, sh.a, sh.w
    S = (w * gP / a) * (e - 1) / (2 * (1 + e))
    dS = (w * gP / a) / (1 + e) ** 2
    dt = (1 if orbit == 0 else -1) * dS / (w * math.sqrt(1 - S * S))
    # (z, v, τ) at the touchdown: z stays 0, v = -V
    expected = [0.0, gP / (1 + e) ** 2, dt]
    # the fixed point is converged to 1e-12 and the stride Jacobians are exact to ~1e-10
    assert g.fixed_point[:, 0] == pytest.approx(expected, abs=1e-8)
    assert g.stride_time == pytest.approx([0.0], abs=1e-9)


def test_shaker_stable_multipliers_modulus_moves_one_for_one_with_restitution():
    """|λ| = e on the stable orbit: d|λ|/de = 1 (central differences of the
    re-converged Jacobians at h = 1e-4 e: truncation 84 h² ≈ 2e-7 here)."""
    sh = Shaker()
    gait = _gait(sh, 0)
    assert abs(gait.multipliers[0]) == pytest.approx(sh.e, abs=1e-9)
    g = gait_sensitivity(sh.scene, gait, ["contact:ball:restitution"], which=(0, 1), **GAIT)
    assert g.modulus_gradient(0) == pytest.approx([1.0], abs=1e-5)
    assert g.modulus_gradient(1) == pytest.approx([1.0], abs=1e-5)  # the conjugate
    assert g.multiplier_derivatives[1, 0] == pytest.approx(np.conj(g.multiplier_derivatives[0, 0]), abs=1e-8)


def test_saddle_multiplier_derivatives_match_reconverged_gaits():
    sh = Shaker()
    gait = _gait(sh, 1)
    names = ["contact:ball:restitution", "scene:gravity_z"]
    g = gait_sensitivity(sh.scene, gait, names, which=(0,), **GAIT)
    assert abs(g.multipliers[0].imag) == 0.0 and abs(g.multipliers[0]) > 1  # a simple, real, unstable one
    for j, (name, value) in enumerate(zip(names, sh.scene.parameter_values(names))):
        h = 1e-4 * abs(value)
        lam = []
        for sign in (1, -1):
            moved = sh.scene.with_parameters({name: value + sign * h})
            again = find_periodic_gait(
                moved, "ball", [0.0], [-sh.V], gait.t, period=sh.P, iterations=10, tol=1e-12, **GAIT
            )
            lam.append(again.multipliers[0].real)
        fd = (lam[0] - lam[1]) / (2 * h)
        # two central differences of the same smooth function with the same step: their
        # truncations (~h² |λ'''|) are of the same size, 1e-6 relative here
        assert g.multiplier_derivatives[0, j].real == pytest.approx(fd, rel=1e-5), name
        assert g.multiplier_derivatives[0, j].imag == pytest.approx(0.0, abs=1e-9)


def test_a_repeated_multiplier_has_no_derivative(tmp_path):
    """The point mass bouncing elastically in the x-z plane is periodic from any start; its
    conserved horizontal speed gives a multiplier 1, the same eigenvalue as the neutral
    translation's (and the bounce speed's, e = 1)."""
    path = tmp_path / "point_xz.urdf"
    path.write_text(POINT_XZ)
    scene = cd.Scene(
        cd.load_robot(str(path)),
        [cd.Contact("ball", restitution=1.0)],
        gravity=[0, 0, -1.0],
        q0={"z": 0.0},
        v0={"x": 0.3, "z": -1.0},
    )
    gait = find_periodic_gait(scene, "ball", iterations=0, **GAIT)
    lam = gait.multipliers
    one = int(np.argmin(np.abs(lam - 1.0)))
    with pytest.raises(InvalidInputError, match="repeated"):
        gait_sensitivity(scene, gait, ["contact:ball:restitution"], which=(one,), **GAIT)


def test_bad_requests_are_named():
    sh = Shaker()
    gait = _gait(sh, 0)
    with pytest.raises(InvalidInputError, match="multiplier index"):
        gait_sensitivity(sh.scene, gait, ["contact:ball:restitution"], which=(7,), **GAIT)
    with pytest.raises(InvalidInputError, match="contact:ball:restitution"):
        gait_sensitivity(sh.scene, gait, ["contact:ball:bounciness"], which=(), **GAIT)
    with pytest.raises(InvalidInputError, match="jacobian"):
        stride_map(sh.scene, "ball", [0.0], [-sh.V], 0.1, period=sh.P, jacobian=False, parameters=["scene:gravity_z"])


def _planar_shaker(sh: Shaker, tmp_path) -> cd.Scene:
    """The shaker's force on the point mass of the x-z plane (test_stride.py's POINT_XZ)."""
    path = tmp_path / "point_xz.urdf"
    path.write_text(POINT_XZ)
    force = cd.UserEffort(
        lambda q, v, t: np.array([0.0, sh.a * math.cos(sh.w * t)]),
        lambda q, v, t: (np.zeros((2, 2)), np.zeros((2, 2))),
        name="shaker",
    )
    return cd.Scene(
        cd.load_robot(str(path)),
        [cd.Contact("ball", restitution=sh.e)],
        [force],
        gravity=[0, 0, -sh.g],
        q0={"z": 0.0},
        v0={"x": 0.3, "z": -1.0},
    )


def _planar_gait(scene, sh: Shaker, orbit: int):
    return find_periodic_gait(
        scene,
        "ball",
        [0.0, 0.0],
        [0.3, -1.05 * sh.V],
        sh.orbit_times[orbit] + 0.02,
        period=sh.P,
        iterations=10,
        tol=1e-12,
        **GAIT,
    )


def test_planar_saddle_multiplier_derivatives_match_reconverged_gaits(tmp_path):
    """The x-z model's saddle orbit: its unstable multiplier against central differences of
    the multipliers of gaits found anew at p ± h (as on the line above)."""
    sh = Shaker()
    scene = _planar_shaker(sh, tmp_path)
    gait = _planar_gait(scene, sh, 1)
    assert gait.converged and abs(gait.multipliers[0]) > 1
    names = ["contact:ball:restitution", "scene:gravity_z", "body:ball:mass"]
    g = gait_sensitivity(scene, gait, names, which=(0,), **GAIT)
    for j, (name, value) in enumerate(zip(names, scene.parameter_values(names))):
        h = 1e-4 * abs(value)
        lam = [
            _planar_gait(scene.with_parameters({name: value + sign * h}), sh, 1).multipliers[0].real for sign in (1, -1)
        ]
        fd = (lam[0] - lam[1]) / (2 * h)
        assert g.multiplier_derivatives[0, j].real == pytest.approx(fd, rel=1e-5, abs=1e-9), name


def test_planar_shaker_multipliers_move_as_the_vertical_ones(tmp_path):
    """The shaker's force on a point mass in the x-z plane, gliding at a constant
    horizontal speed: the vertical motion is the shaker's, so on its stable orbit the
    complex pair keeps |λ| = e (d|λ|/de = 1), while the glide adds the multiplier 1
    of the conserved horizontal speed (the neutral translation x removed)."""
    sh = Shaker()
    scene = _planar_shaker(sh, tmp_path)
    gait = _planar_gait(scene, sh, 0)
    assert gait.converged and gait.neutral == ("x",)
    pair = [k for k, m in enumerate(gait.multipliers) if abs(m.imag) > 0.1]
    assert len(pair) == 2 and abs(gait.multipliers[pair[0]]) == pytest.approx(sh.e, abs=1e-9)
    g = gait_sensitivity(scene, gait, ["contact:ball:restitution"], which=pair, **GAIT)
    # truncation of the central differences: 84 h² ≈ 2e-7 at h = 1e-4 e (as on the line)
    assert g.modulus_gradient(0) == pytest.approx([1.0], abs=1e-5)
    assert g.modulus_gradient(1) == pytest.approx([1.0], abs=1e-5)
    # the horizontal speed and the landing speed do not depend on e through the glide
    nv = scene.nv
    assert g.fixed_point[nv, 0] == pytest.approx(0.0, abs=1e-9)  # dv_x/de
    assert g.fixed_point[nv + 1, 0] == pytest.approx(sh.g * sh.P / (1 + sh.e) ** 2, abs=1e-8)  # d(-V)/de
