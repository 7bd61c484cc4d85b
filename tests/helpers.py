"""Shared test helpers: central finite differences on the configuration manifold.

Column ``k`` of a derivative with respect to ``q`` is the perturbation
``q ⊕ ε e_k = pin.integrate(model, q, ε e_k)`` (Pinocchio's tangent space);
with respect to ``v`` it is ``v + ε e_k``.

Step and tolerance. Central differences have truncation error ~ ε² |f'''| and
round-off ~ u |f| / ε (u = 2.2e-16). With ε = 1e-6 both are ~1e-10 relative to
the size of the function and its derivatives for the O(1)-scaled models here,
so derivatives are compared with ``rtol = 1e-6`` relative to the larger of the
derivative's max-abs entry and the function's own max-abs value (the scale of
the round-off). That leaves four orders of margin for noise while any wrong
term (a missing sign, transposition, wrong frame) shows up at O(1e-2..1).

Set ``CONTACTDIFF_FD_REPORT=1`` to print the largest relative error seen per
category at exit (``pytest -s``).
"""

from __future__ import annotations

import atexit
import importlib.util
import os
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pinocchio as pin

from contactdiff.model.kinematics import Kinematics

EPS = 1e-6
RTOL = 1e-6

# A planar leg: a body free in x and z (1 kg) with a rigid leg (0.2 kg, 0.5 m) on a hip
# hinge about y; its foot is the frame ``foot`` at the leg's end.
LEG_URDF = """<?xml version="1.0"?>
<robot name="leg">
  <link name="world"/>
  <link name="slider"><inertial><origin xyz="0 0 0"/><mass value="0.5"/>
    <inertia ixx="0.001" iyy="0.001" izz="0.001" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="body_x" type="prismatic"><parent link="world"/><child link="slider"/>
    <axis xyz="1 0 0"/><limit lower="-100" upper="100" effort="0" velocity="100"/></joint>
  <link name="body"><inertial><origin xyz="0 0 0"/><mass value="0.5"/>
    <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="body_z" type="prismatic"><parent link="slider"/><child link="body"/>
    <axis xyz="0 0 1"/><limit lower="-100" upper="100" effort="0" velocity="100"/></joint>
  <link name="leg"><inertial><origin xyz="0 0 -0.25"/><mass value="0.2"/>
    <inertia ixx="0.005" iyy="0.005" izz="0.005" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="hip" type="revolute"><parent link="body"/><child link="leg"/>
    <axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="0" velocity="100"/></joint>
  <link name="foot"/>
  <joint name="foot_joint" type="fixed"><parent link="leg"/><child link="foot"/>
    <origin xyz="0 0 -0.5"/></joint>
</robot>
"""
LEG_RAMP, LEG_RAMP_START = 30.0, 0.1  # N/s, s: the upward force on the leg's body ramps from t = 0.1 s


def leg_lift(q, v, t):
    """The leg's unloading effort: an upward force on the body ramping at ``LEG_RAMP``."""
    return np.array([0.0, LEG_RAMP * max(0.0, t - LEG_RAMP_START), 0.0])


def leg_lift_jacobian(q, v, t):
    return np.zeros((3, 3)), np.zeros((3, 3))


def leg_lift_rate(q, v, t):
    return np.array([0.0, LEG_RAMP if t > LEG_RAMP_START else 0.0, 0.0])


FD_ERRORS: dict[str, float] = {}


def _report() -> None:  # pragma: no cover - diagnostics only
    if os.environ.get("CONTACTDIFF_FD_REPORT") and FD_ERRORS:
        print("\nlargest relative FD error per category:")
        for key in sorted(FD_ERRORS):
            print(f"  {key:45s} {FD_ERRORS[key]:.2e}")


atexit.register(_report)


def fd_dq(f: Callable[[np.ndarray], np.ndarray], model: pin.Model, q: np.ndarray, eps: float = EPS) -> np.ndarray:
    """Central FD of ``f(q)`` on the manifold; result has shape ``f.shape + (nv,)``."""
    cols = []
    for k in range(model.nv):
        e = np.zeros(model.nv)
        e[k] = eps
        plus = np.asarray(f(pin.integrate(model, q, e)), dtype=float)
        minus = np.asarray(f(pin.integrate(model, q, -e)), dtype=float)
        cols.append((plus - minus) / (2 * eps))
    return np.stack(cols, axis=-1)


def fd_dv(f: Callable[[np.ndarray], np.ndarray], v: np.ndarray, eps: float = EPS) -> np.ndarray:
    """Central FD of ``f(v)`` in the vector space R^nv; shape ``f.shape + (nv,)``."""
    cols = []
    for k in range(v.size):
        e = np.zeros(v.size)
        e[k] = eps
        cols.append((np.asarray(f(v + e), dtype=float) - np.asarray(f(v - e), dtype=float)) / (2 * eps))
    return np.stack(cols, axis=-1)


def assert_fd(category: str, analytic, reference, value=None, rtol: float = RTOL) -> float:
    """Assert ``analytic ≈ reference`` (a finite-difference matrix).

    The error is ``max|analytic - reference|`` divided by the largest of
    ``max|reference|``, ``max|analytic|`` and ``max|value|`` (the function's own
    magnitude, which sets the FD round-off). Records the error under ``category``.
    """
    analytic = np.asarray(analytic, dtype=float)
    reference = np.asarray(reference, dtype=float)
    assert analytic.shape == reference.shape, (category, analytic.shape, reference.shape)
    scale = max(
        np.abs(reference).max(initial=0.0),
        np.abs(analytic).max(initial=0.0),
        0.0 if value is None else np.abs(np.asarray(value, dtype=float)).max(initial=0.0),
        1e-300,
    )
    err = float(np.abs(analytic - reference).max(initial=0.0) / scale)
    FD_ERRORS[category] = max(FD_ERRORS.get(category, 0.0), err)
    assert err < rtol, (
        f"{category}: relative FD error {err:.3e} >= {rtol:g} (scale {scale:.3e})\n"
        f"analytic=\n{analytic}\nreference=\n{reference}"
    )
    return err


def random_state(
    model: pin.Model, q_ref: np.ndarray, rng: np.random.Generator, q_scale: float = 0.3, v_scale: float = 1.0
) -> tuple[np.ndarray, np.ndarray]:
    """``q = q_ref ⊕ q_scale·N(0, I)``, ``v = v_scale·N(0, I)``."""
    q = pin.integrate(model, q_ref, q_scale * rng.standard_normal(model.nv))
    return q, v_scale * rng.standard_normal(model.nv)


def second_derivative_along(
    f: Callable[[np.ndarray], float],
    model: pin.Model,
    q: np.ndarray,
    v: np.ndarray,
    ddq: np.ndarray | None = None,
    h: float = 1e-4,
) -> float:
    """``d²/dt² f(q(t))`` at t = 0 for the curve with ``q(0) = q``, velocity ``v`` and
    acceleration ``ddq`` (0 if None), by the central second difference of
    ``f(q ⊕ (t v + t²/2 ddq))``.

    For Pinocchio's ⊕ (``q · exp(ξ)`` on a free-flyer), ``ξ(t) = t v + t²/2 ddq`` has
    tangent velocity ``v + t ddq + O(t²)`` (the first correction is ``ad_ξ ξ̇ / 2``,
    of order t² because ``ad_v v = 0``), so the curve is right to O(t³); the odd
    O(t³) terms cancel in the central difference, leaving O(h²) truncation and
    O(u/h²) round-off: about 1e-8 at h = 1e-4.
    """
    a = np.zeros_like(v) if ddq is None else ddq
    fp = f(pin.integrate(model, q, h * v + 0.5 * h * h * a))
    fm = f(pin.integrate(model, q, -h * v + 0.5 * h * h * a))
    return (np.asarray(fp) - 2 * np.asarray(f(q)) + np.asarray(fm)) / (h * h)


class ContactEvaluator:
    """A bound contact's functions at any state, on its own `Kinematics` (for finite
    differences of gaps, rows and drifts)."""

    def __init__(self, robot, contact):
        self.robot, self.c = robot, contact
        self.kin = Kinematics(robot.model)

    def at(self, q, v=None, derivatives=False):
        self.kin.update(q, np.zeros(self.robot.nv) if v is None else v, derivatives=derivatives)
        return self.kin

    def gap(self, q):
        return self.c.gap(self.at(q))

    def rows(self, q):
        return self.c.rows(self.at(q)).copy()

    def drift(self, q, v):
        return self.c.drift(self.at(q, v)).copy()

    def assert_derivatives(self, prefix: str, q, v, x, lam) -> dict[str, np.ndarray]:
        """Assert the contact's derivatives at ``(q, v)`` against central differences:
        ``d(A v)/dq``, ``d drift/d(q, v)``, ``d(A x)/dq`` and ``d(A^T lam)/dq``, with FD
        categories ``"{prefix} <name>"``. Returns the analytic matrices by name, and
        ``rows_times_v_dq`` (``d(A x)/dq`` at ``x = v``), all taken before the FD moves
        the kinematics."""
        c, model = self.c, self.robot.model
        kin = self.at(q, v, derivatives=True)
        drift_dq, drift_dv = c.drift_derivatives(kin)
        d = dict(
            rows_velocity_dq=c.rows_velocity_dq(kin).copy(),
            drift_dq=drift_dq.copy(),
            drift_dv=drift_dv.copy(),
            rows_times_dq=c.rows_times_dq(kin, x).copy(),
            rows_transpose_dq=c.rows_transpose_dq(kin, lam).copy(),
            rows_times_v_dq=c.rows_times_dq(kin, v).copy(),
        )
        assert_fd(
            f"{prefix} rows_velocity_dq",
            d["rows_velocity_dq"],
            fd_dq(lambda qq: self.rows(qq) @ v, model, q),
            value=self.rows(q) @ v,
        )
        assert_fd(
            f"{prefix} drift_dq", d["drift_dq"], fd_dq(lambda qq: self.drift(qq, v), model, q), value=self.drift(q, v)
        )
        assert_fd(f"{prefix} drift_dv", d["drift_dv"], fd_dv(lambda vv: self.drift(q, vv), v), value=self.drift(q, v))
        assert_fd(
            f"{prefix} rows_times_dq",
            d["rows_times_dq"],
            fd_dq(lambda qq: self.rows(qq) @ x, model, q),
            value=self.rows(q) @ x,
        )
        assert_fd(
            f"{prefix} rows_transpose_dq",
            d["rows_transpose_dq"],
            fd_dq(lambda qq: self.rows(qq).T @ lam, model, q),
            value=self.rows(q).T @ lam,
        )
        return d


def sphere_urdf(mass: float, inertia: float) -> str:
    """URDF of one free body ``ball`` (its frame at the centre of mass) of ``mass`` (kg) with
    the isotropic rotational inertia ``inertia`` (kg m²); load it with ``floating_base=True``."""
    return f"""<?xml version="1.0"?>
<robot name="ball3d">
  <link name="ball">
    <inertial><origin xyz="0 0 0"/><mass value="{mass}"/>
      <inertia ixx="{inertia}" ixy="0" ixz="0" iyy="{inertia}" iyz="0" izz="{inertia}"/></inertial>
  </link>
</robot>
"""


def spy_salted(monkeypatch):
    """Count, per event (by ``id``), the reads of ``Ξ φ`` (`EventJacobians.salted`) and how
    many of them formed it anew: ``(reads, formed)``, two `collections.Counter`."""
    from collections import Counter

    from contactdiff.integration.event_jacobians import EventJacobians

    reads, formed = Counter(), Counter()
    salted = EventJacobians.salted

    def spy(self, phi, event):
        before = self._last
        out = salted(self, phi, event)
        reads[id(event)] += 1
        formed[id(event)] += self._last is not before
        return out

    monkeypatch.setattr(EventJacobians, "salted", spy)
    return reads, formed


def rod_urdf(half_length: float, mass: float) -> str:
    """URDF of a uniform rod (inertia ``m (2l)² / 12`` about its centre) moving in the x-z
    plane: joints ``x``, ``z`` (prismatic) and ``theta`` (about +y), and a frame ``tip`` at
    ``half_length`` along the rod (Painlevé's rod: the tip slides on the ground)."""
    inertia = mass * (2 * half_length) ** 2 / 12.0
    return f"""<?xml version="1.0"?>
<robot name="rod">
  <link name="world"/>
  <link name="sx"/>
  <link name="sz"/>
  <link name="rod"><inertial><mass value="{mass}"/>
    <inertia ixx="{inertia}" iyy="{inertia}" izz="{inertia}" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="x" type="prismatic"><parent link="world"/><child link="sx"/><axis xyz="1 0 0"/>
    <limit lower="-100" upper="100" effort="0" velocity="100"/></joint>
  <joint name="z" type="prismatic"><parent link="sx"/><child link="sz"/><axis xyz="0 0 1"/>
    <limit lower="-100" upper="100" effort="0" velocity="100"/></joint>
  <joint name="theta" type="revolute"><parent link="sz"/><child link="rod"/><axis xyz="0 1 0"/>
    <limit lower="-10" upper="10" effort="0" velocity="100"/></joint>
  <link name="tip"/>
  <joint name="tip_joint" type="fixed"><parent link="rod"/><child link="tip"/>
    <origin xyz="{half_length} 0 0"/></joint>
</robot>
"""


MENAGERIE = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "menagerie"
"""MuJoCo Menagerie models (XML only) kept beside the repository, in ``../shared/data/menagerie``."""


def menagerie_file(relative: str) -> Path:
    """``MENAGERIE / relative``, or skip the test (with the path) when it is absent."""
    import pytest

    path = MENAGERIE / relative
    if not path.is_file():
        pytest.skip(f"Menagerie model {relative} is not in {MENAGERIE} (../shared/data/menagerie)")
    return path


def load_script(name: str):
    """The module of ``scripts/NAME.py`` (the scripts are not a package), executed once per call."""
    path = Path(__file__).resolve().parents[1] / "scripts" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(name, path)
    assert spec is not None and spec.loader is not None, path
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
