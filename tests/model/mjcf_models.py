"""Small MJCF models with closed-form dynamics, shared by the MJCF tests.

Each ``*_XML`` string is a model; the functions give its mass matrix and bias
forces in Pinocchio's coordinates, derived by hand (derivations in the docstrings).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

G = 9.81  # m/s², MuJoCo's and Pinocchio's default gravity magnitude, along -z

SLIDER_MASS, SLIDER_ARMATURE = 2.0, 0.3
SLIDER_XML = f"""<mujoco model="slider">
  <worldbody>
    <body name="cart">
      <joint name="z" type="slide" axis="0 0 1" armature="{SLIDER_ARMATURE}"/>
      <inertial pos="0 0 0" mass="{SLIDER_MASS}" diaginertia="0.01 0.01 0.01"/>
    </body>
  </worldbody>
</mujoco>
"""
"""A mass sliding vertically, with armature: ``M = m + a`` (the armature adds to the
diagonal, as MuJoCo does), ``b = m g`` (the rotor has no weight)."""

# planar two-link leg about y: thigh (hip at the world's (0, 0, 1)), shank hinged L1 below the hip
M1, C1, I1 = 1.5, 0.2, 0.03  # kg, m (hip to thigh COM), kg m² about y at the COM
M2, C2, I2 = 0.8, 0.25, 0.015  # kg, m (knee to shank COM), kg m² about y at the COM
L1, FOOT_R, FOOT_L = 0.4, 0.03, 0.5  # m: hip to knee, foot sphere radius, knee to foot centre
LEG_XML = f"""<mujoco model="leg">
  <compiler angle="radian"/>
  <default>
    <joint type="hinge" axis="0 1 0"/>
    <default class="knee"><joint pos="0 0 -0.1"/></default>
    <default class="foot"><geom type="sphere" size="{FOOT_R}" pos="0 0 -{FOOT_L + 0.1}"/></default>
  </default>
  <worldbody>
    <body name="thigh" pos="0 0 1">
      <joint name="hip"/>
      <inertial pos="0 0 -{C1}" mass="{M1}" diaginertia="0.02 {I1} 0.02"/>
      <body name="shank" pos="0 0 -{L1 - 0.1}">
        <joint name="knee" class="knee"/>
        <inertial pos="0 0 -{C2 + 0.1}" mass="{M2}" diaginertia="0.01 {I2} 0.01"/>
        <geom name="foot" class="foot"/>
      </body>
    </body>
  </worldbody>
  <keyframe><key name="bent" qpos="0.3 -0.6"/></keyframe>
</mujoco>
"""
"""The shank's body sits 0.1 m above its knee: the knee's ``pos`` comes from the class
``knee`` (Pinocchio 4.1 ignores a class's joint ``pos``; the loader writes it inline),
and so does the foot sphere's ``pos``."""


def leg_mass_matrix(q: np.ndarray) -> np.ndarray:
    """Two-link pendulum about parallel axes (angles ``q1`` at the hip, ``q2`` at the knee):
    kinetic energy ``T = ½ (I1 + m1 c1²) q̇1² + ½ I2 (q̇1 + q̇2)² + ½ m2 |ṗ2|²`` with the shank
    COM ``p2 = l1 e(q1) + c2 e(q1 + q2)``, ``|e| = 1``, so
    ``M11 = I1 + m1 c1² + I2 + m2 (l1² + c2² + 2 l1 c2 cos q2)``,
    ``M12 = I2 + m2 (c2² + l1 c2 cos q2)``, ``M22 = I2 + m2 c2²``."""
    c = np.cos(q[1])
    m11 = I1 + M1 * C1**2 + I2 + M2 * (L1**2 + C2**2 + 2 * L1 * C2 * c)
    m12 = I2 + M2 * (C2**2 + L1 * C2 * c)
    return np.array([[m11, m12], [m12, I2 + M2 * C2**2]])


def leg_bias(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Coriolis and gravity of the leg. A rotation ``q`` about +y takes ``(0, 0, -L)`` to
    ``(-L sin q, 0, -L cos q)``, so the potential is ``V = -g (m1 c1 cos q1 + m2 (l1 cos q1
    + c2 cos(q1 + q2)))`` and ``∂V/∂q`` is the gravity term; with ``h = m2 l1 c2 sin q2``
    (from ``∂M/∂q2``) the Coriolis terms are ``(-h (2 q̇1 q̇2 + q̇2²), h q̇1²)``."""
    s1, s12, h = np.sin(q[0]), np.sin(q[0] + q[1]), M2 * L1 * C2 * np.sin(q[1])
    gravity = G * np.array([M1 * C1 * s1 + M2 * (L1 * s1 + C2 * s12), M2 * C2 * s12])
    coriolis = np.array([-h * (2 * v[0] * v[1] + v[1] ** 2), h * v[0] ** 2])
    return gravity + coriolis


FREE_MASS = 3.0
FREE_COM = np.array([0.1, -0.05, 0.02])  # m, body frame
FREE_INERTIA = np.array([[0.3, 0.02, -0.01], [0.02, 0.4, 0.03], [-0.01, 0.03, 0.5]])  # kg m² at the COM
FREE_XML = f"""<mujoco model="free">
  <worldbody>
    <body name="box" pos="0 0 1">
      <freejoint/>
      <inertial pos="{" ".join(map(str, FREE_COM))}" mass="{FREE_MASS}"
        fullinertia="0.3 0.4 0.5 0.02 -0.01 0.03"/>
    </body>
  </worldbody>
</mujoco>
"""
"""A free body whose inertia has off-diagonal terms (``fullinertia``: Ixx Iyy Izz Ixy Ixz Iyz)."""


def _skew(x: np.ndarray) -> np.ndarray:
    return np.array([[0, -x[2], x[1]], [x[2], 0, -x[0]], [-x[1], x[0], 0]])


def free_spatial_inertia() -> np.ndarray:
    """Spatial inertia about the body origin, (linear, angular) order: with ``ĉ`` the
    cross-product matrix of the COM ``c``, the momentum of a body moving with origin
    velocity ``v`` and angular velocity ``ω`` is ``p = m (v + ω × c)`` and its moment
    about the origin ``L = I_c ω + c × p``, so ``[[m 1, -m ĉ], [m ĉ, I_c - m ĉ ĉ]]``.
    It is the mass matrix of the free body in Pinocchio's (local) coordinates."""
    c = _skew(FREE_COM)
    return np.block([[FREE_MASS * np.eye(3), -FREE_MASS * c], [FREE_MASS * c, FREE_INERTIA - FREE_MASS * c @ c]])


def free_bias(rotation: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Newton-Euler in the body frame: ``b = V ×* (I V) - f_g``, the force cross product
    ``(v, ω) ×* (f, n) = (ω × f, ω × n + v × f)``, and the weight ``f_g = (m R^T g, c × m R^T g)``
    (``g = (0, 0, -9.81)``, ``R`` the body's orientation)."""
    inertia = free_spatial_inertia()
    f, n = np.split(inertia @ v, 2)
    lin, ang = v[:3], v[3:]
    weight = FREE_MASS * rotation.T @ np.array([0.0, 0.0, -G])
    return np.concatenate([np.cross(ang, f), np.cross(ang, n) + np.cross(lin, f)]) - np.concatenate(
        [weight, np.cross(FREE_COM, weight)]
    )


def write(folder: Path, name: str, text: str) -> Path:
    """Write ``text`` to ``folder / name`` and return the path."""
    path = folder / name
    path.write_text(text)
    return path


def write_stl(path: Path, triangles) -> Path:
    """A binary STL file of ``triangles`` (``m × 3 × 3``: face, vertex, xyz; counter-clockwise
    seen from outside), each vertex stored as a 32-bit float as the format has it."""
    import struct

    triangles = np.asarray(triangles, dtype=float)
    records = b"".join(struct.pack("<12fH", 0, 0, 0, *t.ravel(), 0) for t in triangles)
    path.write_bytes(b"\0" * 80 + struct.pack("<I", len(triangles)) + records)
    return path


BOX_CORNERS = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], dtype=float)
BOX_QUADS = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
"""The unit cube's corners (index ``4x + 2y + z``) and its faces, counter-clockwise from outside."""


def box_triangles(low, high) -> np.ndarray:
    """The twelve triangles of the box between corners ``low`` and ``high`` (outward order)."""
    corners = np.asarray(low) + BOX_CORNERS * (np.asarray(high) - np.asarray(low))
    return np.array([corners[[a, b, c]] for a, b, c, d in BOX_QUADS] + [corners[[a, c, d]] for a, b, c, d in BOX_QUADS])
