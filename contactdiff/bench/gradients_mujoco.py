"""MuJoCo baselines of the gradient benchmark (the ``mujoco`` extra; imported lazily).

The tasks of `contactdiff.bench.gradients` written as MJCF: spheres and a box with
free joints, the ground a plane ``z = 0``, the wall a plane ``x = W`` facing -x.
MuJoCo's contacts are soft; a contact's ``solref`` in MuJoCo's direct form
``(-k, -b)`` makes the gap a unit-mass spring-damper of stiffness ``k = 1/τ²``
(1/s², ``τ`` the contact's time constant) and damping ``b = 2 ζ / τ`` (1/s), whose
bounce has Newton's restitution ``e = exp(-π ζ / sqrt(1 - ζ²))``: so
``ζ = -ln e / sqrt(π² + ln² e)`` (``e = 1``: ``b = 0``). ``solimp`` 0.99 keeps the
impedance's softening small. Frictionless contacts have ``condim`` 1, Coulomb ones
3 with ``friction = μ``. Integrator: MuJoCo's default (semi-implicit Euler).

Two gradients of a rollout of ``T/dt`` steps:

`fd_gradient`
    central differences of whole rollouts, step ``h`` in each input;
`transition_gradient`
    the product of the one-step Jacobians ``mjd_transitionFD`` (centred, ``eps``)
    along the rollout: ``d x_N / d x_0 = A_N ... A_1`` on MuJoCo's state
    ``(dqpos, qvel)`` (a free joint's position tangent: world displacement, then
    rotation in the body frame; its velocity: world linear, body angular).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from ..errors import InvalidInputError, require_extra
from .gradients import BallTask, Cost, FallingBall, Stopwatch, TwoBalls

SOLIMP = "0.99 0.99 0.001"
"""MuJoCo's impedance (``solimp``) of every contact: near 1, so the force follows the spring."""


def mujoco():
    """The ``mujoco`` module, or a `MissingExtraError` saying how to install it."""
    return require_extra("mujoco", "mujoco", "the MuJoCo baselines")


@dataclass(frozen=True)
class Variant:
    """A MuJoCo set-up: ``timestep`` (s) and the contacts' time constant ``timeconst`` (s)."""

    timestep: float
    timeconst: float

    @property
    def label(self) -> str:
        """The variant as text (the tables' column)."""
        return f"dt {self.timestep:g} s, tau {self.timeconst:g} s"


def solref(timeconst: float, restitution: float) -> str:
    """MJCF ``solref`` in direct form for a contact of time constant ``timeconst`` (s) and
    restitution ``restitution`` (module doc)."""
    if not 0.0 < restitution <= 1.0:
        raise InvalidInputError(f"solref: restitution must be in (0, 1], got {restitution!r}")
    log_e = math.log(restitution)
    zeta = -log_e / math.sqrt(math.pi**2 + log_e**2)
    return f"{-1.0 / timeconst**2:.17g} {-2.0 * zeta / timeconst:.17g}"


def _contact(timeconst: float, restitution: float, friction: float) -> str:
    condim = 3 if friction > 0 else 1
    return (
        f'condim="{condim}" friction="{max(friction, 0.0):.17g} 0 0" solref="{solref(timeconst, restitution)}" '
        f'solimp="{SOLIMP}"'
    )


def _model(variant: Variant, gravity: float, world: str):
    xml = (
        f'<mujoco><option timestep="{variant.timestep:.17g}" gravity="0 0 {-gravity:.17g}"/>'
        f"<worldbody>{world}</worldbody></mujoco>"
    )
    return mujoco().MjModel.from_xml_string(xml)


def _ball(name: str, radius: float, mass: float, x: float, z: float, contact: str) -> str:
    return (
        f'<body name="{name}" pos="{x:.17g} 0 {z:.17g}"><freejoint/>'
        f'<geom type="sphere" size="{radius:.17g}" mass="{mass:.17g}" {contact}/></body>'
    )


def ball_model(task: BallTask, variant: Variant):
    """Task 1 or 2 as a MuJoCo model (the wall's contact: its own e and μ)."""
    ground = _contact(variant.timeconst, task.restitution, task.friction)
    world = f'<geom type="plane" size="0 0 1" {ground}/>'
    if task.wall is not None:
        wall = _contact(variant.timeconst, task.wall_restitution, task.wall_friction)
        world += f'<geom type="plane" pos="{task.wall:.17g} 0 0" zaxis="-1 0 0" size="0 0 1" {wall}/>'
    # MuJoCo mixes two geoms' parameters: the ball takes the ground's, and a wall with other
    # values would mix; the tasks give both the same.
    world += _ball("ball", task.radius, task.mass, *task.position, ground)
    return _model(variant, task.gravity, world)


def two_ball_model(task: TwoBalls, variant: Variant):
    """Task 3: two balls, elastic, frictionless, no gravity."""
    contact = _contact(variant.timeconst, 1.0, 0.0)
    world = _ball("ball1", task.radius, task.mass, task.x1, 0.0, contact) + _ball(
        "ball2", task.radius, task.mass, task.x2, 0.0, contact
    )
    return _model(variant, 0.0, world)


def falling_model(task: FallingBall, variant: Variant):
    """Task 4: the falling ball, elastic, no gravity (z0 set through ``qpos[2]``)."""
    contact = _contact(variant.timeconst, 1.0, 0.0)
    world = f'<geom type="plane" size="0 0 1" {contact}/>' + _ball("ball", task.radius, task.mass, 0.0, 1.0, contact)
    return _model(variant, 0.0, world)


def steps_of(horizon: float, timestep: float) -> int:
    """Steps of ``timestep`` making ``horizon`` (s); they must divide it (to 1e-9 relative)."""
    steps = round(horizon / timestep)
    if steps < 1 or abs(steps * timestep - horizon) > 1e-9 * horizon:
        raise InvalidInputError(f"timestep {timestep!r} s does not divide the horizon {horizon!r} s")
    return steps


def rollout(model, qpos: np.ndarray, qvel: np.ndarray, steps: int) -> np.ndarray:
    """Final ``qpos`` after ``steps`` steps from ``(qpos, qvel)``."""
    mj = mujoco()
    data = mj.MjData(model)
    data.qpos[:] = qpos
    data.qvel[:] = qvel
    mj.mj_step(model, data, nstep=steps)
    return data.qpos.copy()


def fd_gradient(model, qpos, qvel, steps: int, rows, columns, h: float) -> tuple[np.ndarray, Cost]:
    """Central differences of rollouts: ``d qpos_N[rows] / d x0[columns]`` and their `Cost`.

    ``columns`` index MuJoCo's state ``(qpos, qvel)`` as ``k < nq`` (a position
    coordinate) or ``nq + j`` (velocity ``j``); ``rows`` index ``qpos`` (translation
    coordinates only: they are their own tangent).
    """
    watch = Stopwatch()
    base = np.concatenate([qpos, qvel])
    out = []
    for k in columns:
        ends = []
        for sign in (1.0, -1.0):
            x = base.copy()
            x[k] += sign * h
            ends.append(rollout(model, x[: model.nq], x[model.nq :], steps)[list(rows)])
        out.append((ends[0] - ends[1]) / (2.0 * h))
    return np.array(out).T, watch.read()


def transition_gradient(model, qpos, qvel, steps: int, rows, columns, eps: float = 1e-6) -> tuple[np.ndarray, Cost]:
    """The product of ``mjd_transitionFD``'s centred one-step Jacobians along the rollout:
    ``d x_N[rows] / d x_0[columns]`` on MuJoCo's tangent state ``(dqpos, qvel)`` (indices
    ``< nv`` positions, ``nv + j`` velocities), and its `Cost`."""
    mj = mujoco()
    watch = Stopwatch()
    data = mj.MjData(model)
    data.qpos[:] = qpos
    data.qvel[:] = qvel
    n = 2 * model.nv + model.na
    a = np.zeros((n, n))
    product = np.eye(n)
    for _ in range(steps):
        mj.mjd_transitionFD(model, data, eps, True, a, None, None, None)
        product = a @ product
        mj.mj_step(model, data)
    return product[np.ix_(list(rows), list(columns))], watch.read()


FD_STEP = 1e-5
"""Step of the rollouts' central differences (m/s or m): the inputs are O(1)."""


def _method(model, qpos, qvel, steps, method: str, fd: tuple, tangent: tuple, h: float):
    if method == "fd":
        rows, columns = fd
        return fd_gradient(model, qpos, qvel, steps, rows, columns, h)
    if method == "transition":
        return transition_gradient(model, qpos, qvel, steps, *tangent)
    raise InvalidInputError(f"method must be 'fd' or 'transition', got {method!r}")


def mujoco_ball(
    task: BallTask, variant: Variant, method: str, velocity=None, h: float = FD_STEP
) -> tuple[np.ndarray, Cost]:
    """MuJoCo's ``d(x, z)(T)/d(vx, vz)`` (2 × 2) by ``method`` (``"fd"`` or ``"transition"``)
    and its `Cost`."""
    vx, vz = task.velocity if velocity is None else velocity
    model = ball_model(task, variant)
    qpos = np.array([task.position[0], 0.0, task.position[1], 1.0, 0.0, 0.0, 0.0])
    qvel = np.array([vx, 0.0, vz, 0.0, 0.0, 0.0])
    steps = steps_of(task.horizon, variant.timestep)
    return _method(model, qpos, qvel, steps, method, ((0, 2), (7, 9)), ((0, 2), (6, 8)), h)


def mujoco_ball_position(task: BallTask, variant: Variant, velocity) -> np.ndarray:
    """MuJoCo's final (x, z) (m) from initial velocity ``velocity`` (vx, vz)."""
    model = ball_model(task, variant)
    qpos = np.array([task.position[0], 0.0, task.position[1], 1.0, 0.0, 0.0, 0.0])
    qvel = np.array([velocity[0], 0.0, velocity[1], 0.0, 0.0, 0.0])
    return rollout(model, qpos, qvel, steps_of(task.horizon, variant.timestep))[[0, 2]]


def mujoco_two_balls(task: TwoBalls, variant: Variant, method: str, h: float = FD_STEP) -> tuple[np.ndarray, Cost]:
    """MuJoCo's ``d(x1, x2)(T)/d(x1, x2, v1, v2)`` (2 × 4) and its `Cost`."""
    model = two_ball_model(task, variant)
    unit = [1.0, 0.0, 0.0, 0.0]
    qpos = np.array([task.x1, 0.0, 0.0, *unit, task.x2, 0.0, 0.0, *unit])
    qvel = np.zeros(12)
    qvel[0], qvel[6] = task.v1, task.v2
    steps = steps_of(task.horizon, variant.timestep)
    return _method(model, qpos, qvel, steps, method, ((0, 7), (0, 7, 14, 20)), ((0, 6), (0, 6, 12, 18)), h)


def mujoco_brax(
    task: FallingBall, variant: Variant, z0: float, method: str, h: float = FD_STEP
) -> tuple[np.ndarray, Cost, float]:
    """MuJoCo's ``dz(T)/dz0`` (1 × 1), its `Cost` and ``z(T)`` (m) at initial height ``z0``."""
    model = falling_model(task, variant)
    qpos = np.array([0.0, 0.0, z0, 1.0, 0.0, 0.0, 0.0])
    qvel = np.array([0.0, 0.0, -task.speed, 0.0, 0.0, 0.0])
    steps = steps_of(task.horizon, variant.timestep)
    gradient, cost = _method(model, qpos, qvel, steps, method, ((2,), (2,)), ((2,), (2,)), h)
    return gradient, cost, float(rollout(model, qpos, qvel, steps)[2])


def cube_model(variant: Variant, friction: float, restitution: float):
    """Task 5: `contactdiff.cube_scene`'s cube (edge, mass, moment of `CubeParameters`) on
    a board at ``z = 0`` with friction ``friction`` and restitution ``restitution``."""
    from ..data.cube_tosses import NOMINAL

    p = NOMINAL
    contact = _contact(variant.timeconst, restitution, friction)
    inertia = f"{p.moment:.17g} " * 3
    world = (
        f'<geom type="plane" size="0 0 1" {contact}/><body name="cube"><freejoint/>'
        f'<inertial pos="0 0 0" mass="{p.mass:.17g}" diaginertia="{inertia.strip()}"/>'
        f'<geom type="box" size="{p.edge / 2:.17g} {p.edge / 2:.17g} {p.edge / 2:.17g}" {contact}/></body>'
    )
    return _model(variant, p.gravity, world)


def _quaternion_matrix(w, x, y, z) -> np.ndarray:
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def mujoco_cube(variant: Variant, h: float = 1e-4) -> tuple[np.ndarray, Cost]:
    """MuJoCo's ``d pose(T) / d(μ, e)`` (6 × 2, the pose's tangent at T as contactdiff's, from
    central differences of rollouts with models at ``μ ± h``, ``e ± h``) and its `Cost`."""
    from ..data.cube_tosses import NOMINAL
    from .gradients_cube import HORIZON, pose_difference, toss_scene

    scene = toss_scene()
    q, v = scene.q0, scene.v0  # Pinocchio: [x y z qx qy qz qw], body-frame v
    qpos = np.concatenate([q[:3], [q[6]], q[3:6]])
    qvel = np.concatenate([_quaternion_matrix(q[6], *q[3:6]) @ v[:3], v[3:6]])
    steps = steps_of(HORIZON, variant.timestep)

    settings = [
        (NOMINAL.friction, NOMINAL.restitution),
        (NOMINAL.friction + h, NOMINAL.restitution),
        (NOMINAL.friction - h, NOMINAL.restitution),
        (NOMINAL.friction, NOMINAL.restitution + h),
        (NOMINAL.friction, NOMINAL.restitution - h),
    ]
    models = {setting: cube_model(variant, *setting) for setting in settings}  # compiled outside the timer

    def final(mu, e):
        end = rollout(models[(mu, e)], qpos, qvel, steps)
        return np.concatenate([end[:3], end[4:7], [end[3]]])

    watch = Stopwatch()  # the rollouts alone, as contactdiff's runs (its scene is built before its timer)
    nominal = final(*settings[0])
    columns = [
        pose_difference(scene, nominal, final(*settings[1]), final(*settings[2]), h),
        pose_difference(scene, nominal, final(*settings[3]), final(*settings[4]), h),
    ]
    return np.array(columns).T, watch.read()


def mjx_gradient(model, qpos, qvel, steps: int, rows, columns) -> tuple[np.ndarray, float, Cost]:
    """MJX (JAX, CPU, float64) forward-mode derivative ``d qpos_N[rows] / d x0[columns]`` of the
    rollout (indices as `fd_gradient`'s), the first call's wall time (s, with JAX's compilation)
    and a second call's `Cost` (the run alone).

    Raises:
        MissingExtraError: ``jax`` or ``mujoco.mjx`` is not installed (the ``mjx`` extra).
    """
    jax = require_extra("jax", "mjx", "the MJX baseline")
    jnp = require_extra("jax.numpy", "mjx", "the MJX baseline")
    mjx = require_extra("mujoco.mjx", "mjx", "the MJX baseline")
    jax.config.update("jax_enable_x64", True)
    start = time.perf_counter()
    mx = mjx.put_model(model)
    x0 = jnp.asarray(np.concatenate([qpos, qvel]))
    rows, columns, nq = jnp.asarray(rows), jnp.asarray(columns), model.nq

    def final(sub):
        x = x0.at[columns].set(sub)
        data = mjx.make_data(mx).replace(qpos=x[:nq], qvel=x[nq:])
        data = jax.lax.fori_loop(0, steps, lambda i, d: mjx.step(mx, d), data)
        return data.qpos[rows]

    jacobian = jax.jit(jax.jacfwd(final))
    gradient = np.asarray(jacobian(x0[columns]).block_until_ready())
    first = time.perf_counter() - start
    watch = Stopwatch()
    jacobian(x0[columns]).block_until_ready()
    return gradient, first, watch.read()
