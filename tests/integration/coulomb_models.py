"""Models, constants and finite differences shared by the tests of Coulomb friction in `simulate`
(``test_coulomb_slides.py``: slides and stops; ``test_coulomb_impacts.py``: impacts, the rolling
sphere, properties, the unchanged ``"stick"`` and ``"none"``), which check them against closed
forms derived in their docstrings and central finite differences.

Models (URDFs in strings below; a test module loads the ones it needs with ``load``):

* ``block3``: a point mass m = 2 kg on three prismatic joints x, y, z (q = position, v = velocity);
* ``block2``: the same mass on x and z only (a planar model: one tangent row);
* ``ball``: a free-flying solid sphere, m = 2 kg, radius R = 0.1 m, I = 2/5 m R² about every axis;
  its contact has ``radius=R`` on the centre frame, so its tangent rows hold the lowest material point.

Closed forms (each test's docstring derives its own). The recurring one: a point mass sliding on a
plane with normal force N = m g cos α (α the tilt) feels the friction force ``-μ N ŝ``, ŝ the unit
slip velocity; on flat ground, with no other horizontal force, ``v(t) = v0 - μ g t v̂0`` (ŝ is
constant because the deceleration is along the velocity).

Conventions checked on the way: the Jacobian is in the tangent space, columns (q0, v0) and rows
(q, v) at t_final; directions off the contact manifold (the normal position and velocity of a
closed contact) are those of the index-reduced mode flow: a closed contact's normal velocity is
conserved by ``A ddq + drift = 0`` (flat ground: drift = 0) and the ``stick`` reset, which holds the
contact's rows, zeroes it (so d q_z / d v_z0 = t_stop). Finite differences only perturb along the
manifold (a perturbation off it starts open or penetrating).

Tolerances. Runs use rtol = atol = 1e-12 (`TOL`). A run's error is then at most ~1e-12 per unit of
the state over its O(10²) steps, so closed-form values of O(1) are compared at 1e-10 relative (a
100x margin over ~1e-12 per step, while any wrong term in a closed form is O(1)); Jacobians
propagated by the variational equation carry the same relative error and are compared at 1e-8
(their own step error is controlled with the state's, the default ``jacobian_error``). Central
differences (ε = 1e-6): the
truncation ε² |x'''| / 6 ~ 1e-13 for the O(1)..O(10) third derivatives here, and the noise of two
runs each within ~rtol |x| + atol ≈ 2e-12 is ≤ 2 · 2e-12 / (2 ε) = 2e-6 absolute at worst; the
Jacobians here have max-abs entry ≥ 1 (d q / d q0 = I), so `FD_RTOL` = 1e-5 relative to that scale
keeps a 5x margin over that worst case while an O(1e-2..1) error in a saltation term cannot pass.
"""

from __future__ import annotations

import numpy as np

import contactdiff as cd

G = 9.81  # m/s²
MASS = 2.0  # kg (block and ball)
MU = 0.5
RADIUS = 0.1  # m (ball)
INERTIA = 0.4 * MASS * RADIUS**2  # solid sphere, kg m²
TOL = dict(rtol=1e-12, atol=1e-12)
EPS = 1e-6  # central-difference step (module doc)
FD_RTOL = 1e-5  # module doc: worst-case FD noise 2e-6 relative to a Jacobian of scale >= 1, 5x margin
REL = 1e-10  # closed-form values of O(1) (module doc)
JAC_REL = 1e-8  # closed-form Jacobians and event time gradients (module doc)

_JOINT = (
    '<joint name="{n}" type="prismatic"><parent link="{p}"/><child link="{c}"/><axis xyz="{a}"/>'
    '<limit lower="-100" upper="100" effort="0" velocity="100"/></joint>'
)
_MASS_LINK = (
    '<link name="block"><inertial><mass value="{m}"/>'
    '<inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>'
)
BLOCK3_URDF = (
    f'<?xml version="1.0"?><robot name="block3"><link name="world"/><link name="sx"/><link name="sy"/>'
    f"{_MASS_LINK.format(m=MASS)}"
    f"{_JOINT.format(n='x', p='world', c='sx', a='1 0 0')}"
    f"{_JOINT.format(n='y', p='sx', c='sy', a='0 1 0')}"
    f"{_JOINT.format(n='z', p='sy', c='block', a='0 0 1')}</robot>"
)
BLOCK2_URDF = (
    f'<?xml version="1.0"?><robot name="block2"><link name="world"/><link name="sx"/>'
    f"{_MASS_LINK.format(m=MASS)}"
    f"{_JOINT.format(n='x', p='world', c='sx', a='1 0 0')}"
    f"{_JOINT.format(n='z', p='sx', c='block', a='0 0 1')}</robot>"
)
BALL_URDF = (
    f'<?xml version="1.0"?><robot name="ball"><link name="ball"><inertial><origin xyz="0 0 0"/>'
    f'<mass value="{MASS}"/><inertia ixx="{INERTIA}" iyy="{INERTIA}" izz="{INERTIA}" ixy="0" ixz="0" '
    f'iyz="0"/></inertial></link></robot>'
)


def load(tmp_path_factory, name, text, **kwargs):
    path = tmp_path_factory.mktemp("coulomb") / f"{name}.urdf"
    path.write_text(text)
    return cd.load_robot(str(path), **kwargs)


def constant_force(force):
    """A constant generalised force (N on the prismatic joints) with its exact (zero) derivatives."""
    force = np.asarray(force, dtype=float)
    n = force.size
    return cd.UserEffort(
        lambda q, v, t: force,
        lambda q, v, t: (np.zeros((n, n)), np.zeros((n, n))),
        name="push",
        time_derivative=lambda q, v, t: np.zeros(n),
    )


def event_kinds(traj):
    return [(e.kind, e.contacts) for e in traj.events]


def central_differences(scene, t_final, directions, kinds):
    """Central differences of the final state (tangent space) and of every event time, along the
    initial-state tangent directions ``directions`` (each 2nv: dq then dv). Every perturbed run must
    have the nominal event sequence ``kinds`` (else the difference straddles a mode change)."""
    robot, nv = scene.robot, scene.nv
    cols, times = [], []
    for d in directions:
        d = np.asarray(d, dtype=float)
        runs = []
        for sign in (1.0, -1.0):
            q0 = robot.integrate(scene.q0, sign * EPS * d[:nv])
            run = cd.simulate(scene.with_state(q0, scene.v0 + sign * EPS * d[nv:]), t_final, **TOL)
            assert event_kinds(run) == kinds, (d, event_kinds(run))
            runs.append(run)
        plus, minus = runs
        cols.append(np.concatenate([robot.difference(minus.q, plus.q), plus.v - minus.v]) / (2 * EPS))
        times.append([(a.t - b.t) / (2 * EPS) for a, b in zip(plus.events, minus.events)])
    return np.array(cols).T, np.array(times).T


def unit(k, n):
    e = np.zeros(n)
    e[k] = 1.0
    return e
