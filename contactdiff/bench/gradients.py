"""Gradients through contact: the tasks, their exact gradients, and contactdiff's.

Five tasks on which differentiable simulators are known to return wrong, zero
or NaN gradients (docs/results/gradients.md). Each has a closed-form outcome
from which the exact gradient follows by hand (tasks 1, 3, 4) or by the
complex step of the closed form (task 2, exact to round-off: ``Im f(x + i h) / h``
with ``h = 1e-30`` has no difference to cancel); task 5 has no closed form and
is compared with a converged central difference of contactdiff's own runs.

Balls are solid spheres (``I = 2/5 m r²``) of radius ``r`` (m), in the x-z plane,
world frame, z up; the ground is ``z = 0``, a wall the plane ``x = W`` facing -x.
Impacts follow Newton's law on the normal (restitution ``e``) and Coulomb's law
for the tangential impulse: the contact point's slip ``u`` stops (stick) when the
impulse needed, ``m 2|u|/7``, lies in the cone ``μ P_n``; else the impulse is
``μ P_n`` against ``u`` (slide). For a ball with spin ``ω_y`` the slip at the
ground is ``u = v_x - r ω_y`` and at the wall ``w = v_z - r ω_y``; a tangential
impulse ``P`` against the slip changes the centre's velocity by ``-P/m`` and the
spin by ``+5 P/(2 m r)``, hence the slip by ``-7 P/(2 m)``.

Task 1 (one bounce, frictionless): from ``(x0, z0)`` at ``(vx, vz)`` the ball
lands at ``t1 = (vz + s)/g``, ``s = sqrt(vz² + 2 g h)``, ``h = z0 - r``, leaves at
``e s`` and at ``T`` (``τ = T - t1`` after it) is at ``x = x0 + vx T``,
``z = r + e s τ - g τ²/2``. With ``dt1/dvz = t1/s`` and ``ds/dvz = vz/s``:
``dx/dvx = T``, ``dx/dvz = dz/dvx = 0``,
``dz/dvz = e τ vz/s - (e s - g τ) t1/s`` (`bounce_gradient`).

Task 2 (ground, then a wall, to a target): the closed form is an event-driven
ballistic flight with the impact maps above (`ball_outcome`), differentiated
by the complex step (`ball_gradient`). Frictionless, x and z separate: after the
wall ``x(T) = W - r - e_w (vx T - (W - r - x0))``, so ``dx/dvx = -e_w T``.

Task 3 (two equal balls, elastic, no gravity, Nimble's case): ball 2 at rest
``d = 2r`` ahead of the gap; ball 1 reaches it at ``tc = (x2 - x1 - d)/(v1 - v2)``
and the balls swap velocities, so ``x2(T) = x2 + v2 tc + v1 (T - tc) = x1 + d + v1 T``
and ``x1(T) = x2 - d + v2 T``: ``d x2(T)/d(x1, x2, v1, v2) = (1, 0, T, 0)``,
``d x1(T)/d(...) = (0, 1, 0, T)`` (`two_ball_gradient`).

Task 4 (Brax's case, elastic, no gravity): a ball falling at speed ``c`` from
``z0``: ``z(T) = r + |z0 - r - c T|``, ``dz(T)/dz0 = sign(z0 - r - c T)``: +1 when
it has not landed by ``T``, -1 when it has; at ``z0 = r + c T`` (the landing at
``T`` exactly) the one-sided derivatives differ and there is no gradient
(`brax_outcome`).

Task 5 (a cube toss): `cube_reference` (central differences of tight runs).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace

import numpy as np

from ..errors import InvalidInputError
from ..integration.hybrid import simulate
from ..model.contacts import Contact
from ..model.objects import SceneObject, add_objects, empty_robot
from ..model.scene import Scene

COMPLEX_STEP = 1e-30
"""Step of the complex-step derivative (no cancellation: any tiny step is exact)."""


@dataclass(frozen=True)
class BallTask:
    """A ball in the x-z plane (tasks 1 and 2; SI units, world frame).

    Attributes:
        radius: m; mass: kg; gravity: m/s² (downward); horizon: T (s).
        position: initial centre (x0, z0), m; velocity: initial (vx, vz), m/s.
        restitution, friction: the ground's e and μ (0: frictionless).
        wall: the wall's x (m), or None for no wall; wall_restitution, wall_friction: its e, μ.
        target: the centre's target (x, z) at T for task 2 (m), or None.
    """

    radius: float = 0.1
    mass: float = 1.0
    gravity: float = 9.81
    horizon: float = 1.0
    position: tuple[float, float] = (0.0, 1.0)
    velocity: tuple[float, float] = (1.0, 0.5)
    restitution: float = 0.8
    friction: float = 0.0
    wall: float | None = None
    wall_restitution: float = 0.8
    wall_friction: float = 0.0
    target: tuple[float, float] | None = None


BOUNCE = BallTask()
"""Task 1: one bounce by T = 1 s (lands at t1 ≈ 0.482 s), no wall."""

WALL = BallTask(velocity=(2.0, 0.5), wall=1.5, target=(0.9, 0.6))
"""Task 2 without friction: from x = 0 the ball lands (t1 ≈ 0.48 s), reaches the wall
(x = 1.5) at ≈ 0.7 s and flies back."""

WALL_FRICTION = replace(WALL, friction=0.3, wall_friction=0.1)
"""Task 2 with μ = 0.3 on the ground and 0.1 on the wall: the ground's impact sticks
(the slip stops: the ball leaves rolling), the wall's slides (it would stick from
μ ≈ 0.15 on)."""


def _flight(state, dt, g):
    """Ballistic flight of ``state = [x, z, vx, vz, wy]`` for ``dt`` seconds."""
    x, z, vx, vz, wy = state
    return [x + vx * dt, z + vz * dt - 0.5 * g * dt * dt, vx, vz - g * dt, wy]


def _tangential(slip, normal_impulse, mu):
    """Tangential impulse per unit mass (along the slip) of a ball's impact (module doc)."""
    stick = 2.0 * slip / 7.0
    if abs(stick.real) <= mu * normal_impulse.real:
        return stick
    return mu * normal_impulse * math.copysign(1.0, slip.real)


def ball_outcome(task: BallTask, velocity=None, max_impacts: int = 20) -> np.ndarray:
    """The ball's state ``[x, z, vx, vz, ω_y]`` at T in closed form (task 1 and 2).

    Works on complex velocities (for `ball_gradient`): branches on real parts.

    Args:
        task: the `BallTask`.
        velocity: initial (vx, vz) (m/s), default the task's.
        max_impacts: impacts allowed before T.

    Raises:
        InvalidInputError: more impacts than ``max_impacts``.
    """
    vx, vz = task.velocity if velocity is None else velocity
    x0, z0 = task.position
    r, g, t_left = task.radius, task.gravity, task.horizon + 0j
    state = [x0 + 0j, z0 + 0j, vx + 0j, vz + 0j, 0j]
    for _ in range(max_impacts + 1):
        x, z, vx, vz, wy = state
        s = np.sqrt(vz * vz + 2.0 * g * (z - r))
        t_ground = (vz + s) / g
        t_wall = (task.wall - r - x) / vx if task.wall is not None and vx.real > 0.0 else math.inf + 0j
        t_hit = t_ground if t_ground.real <= t_wall.real else t_wall
        if t_hit.real >= t_left.real:
            return np.array(_flight(state, t_left, g))
        t_left -= t_hit
        x, z, vx, vz, wy = _flight(state, t_hit, g)
        if t_hit is t_ground:
            pn = (1.0 + task.restitution) * -vz
            pt = _tangential(vx - r * wy, pn, task.friction) if task.friction > 0 else 0j
            state = [x, z, vx - pt, -task.restitution * vz, wy + 2.5 * pt / r]
        else:
            pn = (1.0 + task.wall_restitution) * vx
            pt = _tangential(vz - r * wy, pn, task.wall_friction) if task.wall_friction > 0 else 0j
            state = [x, z, -task.wall_restitution * vx, vz - pt, wy + 2.5 * pt / r]
    raise InvalidInputError(f"ball_outcome: more than max_impacts = {max_impacts} impacts before T")


def ball_gradient(task: BallTask, velocity=None) -> np.ndarray:
    """``d(x, z)(T) / d(vx, vz)`` (2 × 2) of `ball_outcome` by the complex step (exact to round-off)."""
    v = np.asarray(task.velocity if velocity is None else velocity, dtype=float)
    columns = []
    for k in range(2):
        dv = np.zeros(2, dtype=complex)
        dv[k] = 1j * COMPLEX_STEP
        columns.append(ball_outcome(task, v + dv)[:2].imag / COMPLEX_STEP)
    return np.array(columns).T


def bounce_gradient(task: BallTask = BOUNCE) -> np.ndarray:
    """Task 1's ``d(x, z)(T) / d(vx, vz)`` by the formulas of the module doc (frictionless, no
    wall, one bounce before T)."""
    vx, vz = task.velocity
    g, r, e, big_t = task.gravity, task.radius, task.restitution, task.horizon
    s = math.sqrt(vz * vz + 2.0 * g * (task.position[1] - r))
    t1 = (vz + s) / g
    tau = big_t - t1
    if not 0.0 < tau < 2.0 * e * s / g:
        raise InvalidInputError(f"bounce_gradient: the task needs one bounce before T: t1 = {t1:.6g} s, T = {big_t} s")
    return np.array([[big_t, 0.0], [0.0, e * tau * vz / s - (e * s - g * tau) * t1 / s]])


@dataclass(frozen=True)
class TwoBalls:
    """Task 3: ball 1 at ``x1`` moving at ``v1`` towards ball 2 at ``x2`` (m, m/s, along x),
    equal radii ``radius`` and masses ``mass``, elastic, no gravity, horizon T (s)."""

    x1: float = 0.0
    x2: float = 0.5
    v1: float = 1.0
    v2: float = 0.0
    radius: float = 0.1
    mass: float = 1.0
    horizon: float = 1.0


NIMBLE = TwoBalls()
"""Nimble's set-up: T = 1, so the gradient of ball 2's final x is (1, 0, 1, 0)."""


def two_ball_gradient(task: TwoBalls = NIMBLE) -> np.ndarray:
    """``d(x1, x2)(T) / d(x1, x2, v1, v2)`` (2 × 4) of an elastic collision of equal balls
    (module doc); the collision must happen before T."""
    tc = (task.x2 - task.x1 - 2.0 * task.radius) / (task.v1 - task.v2)
    if not 0.0 < tc < task.horizon:
        raise InvalidInputError(f"two_ball_gradient: the balls must collide before T: tc = {tc:.6g} s")
    big_t = task.horizon
    return np.array([[0.0, 1.0, 0.0, big_t], [1.0, 0.0, big_t, 0.0]])


@dataclass(frozen=True)
class FallingBall:
    """Task 4 (Brax's case): a ball of radius ``radius`` (m) falling at ``speed`` (m/s) from
    height z0 onto the ground, elastic, no gravity, horizon T (s)."""

    radius: float = 0.1
    speed: float = 1.0
    horizon: float = 1.0
    mass: float = 1.0

    @property
    def kink(self) -> float:
        """The initial height (m) at which it lands at T exactly: no gradient there."""
        return self.radius + self.speed * self.horizon


BRAX = FallingBall()
"""Lands at T = 1 s when dropped from 1.1 m."""


def brax_outcome(task: FallingBall, z0: float) -> tuple[float, float | None]:
    """``(z(T), dz(T)/dz0)`` (m, 1) at initial height ``z0``; the derivative is None at the kink."""
    d = z0 - task.kink
    return task.radius + abs(d), (None if d == 0.0 else math.copysign(1.0, d))


# -- contactdiff's gradients ----------------------------------------------------------------


def _sphere(name: str, radius: float, mass: float, x: float, z: float) -> SceneObject:
    return SceneObject(name, shape="sphere", radius=radius, mass=mass, position=(x, 0.0, z))


def _friction(mu: float):
    return mu if mu > 0.0 else "none"


def ball_scene(task: BallTask) -> Scene:
    """Task 1 or 2 as a `Scene`: object ``ball``, contacts ``ground`` and (with a wall) ``wall``."""
    x0, z0 = task.position
    contacts = [Contact("ball", restitution=task.restitution, friction=_friction(task.friction), name="ground")]
    if task.wall is not None:
        contacts.append(
            Contact(
                "ball",
                normal=(-1.0, 0.0, 0.0),
                offset=-task.wall,
                radius=task.radius,
                restitution=task.wall_restitution,
                friction=_friction(task.wall_friction),
                name="wall",
            )
        )
    robot = add_objects(empty_robot(), [_sphere("ball", task.radius, task.mass, x0, z0)])
    return Scene(robot, contacts, gravity=(0.0, 0.0, -task.gravity), name="ball_task")


def _rotation(q: np.ndarray) -> np.ndarray:
    """World rotation of a free-flyer configuration ``[x y z qx qy qz qw]``."""
    x, y, z, w = q[3:7] / np.linalg.norm(q[3:7])
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


@dataclass(frozen=True)
class Cost:
    """Wall-clock and CPU time of one computation (s). On a shared machine the wall time
    also counts the time the process waited for a core (whole scheduler slices, ~4 ms
    each, on a run of a few ms); the CPU time (`time.process_time`: every thread of
    the process) counts its own work only."""

    wall: float
    cpu: float


class Stopwatch:
    """Started on creation; `read` gives the `Cost` since."""

    def __init__(self):
        self._wall, self._cpu = time.perf_counter(), time.process_time()

    def read(self) -> Cost:
        """The wall and CPU time since the start (s)."""
        return Cost(time.perf_counter() - self._wall, time.process_time() - self._cpu)


def median_cost(costs) -> Cost:
    """The median wall and the median CPU time of several `Cost`s."""
    costs = list(costs)
    return Cost(float(np.median([c.wall for c in costs])), float(np.median([c.cpu for c in costs])))


@dataclass
class Run:
    """contactdiff's gradient of a task: ``gradient`` (the task's block), ``cost`` (of the one
    run, `Cost`), ``differentiable`` (its verdict), ``outcome`` (the task's outputs)."""

    gradient: np.ndarray
    cost: Cost
    differentiable: bool
    outcome: np.ndarray
    notes: list[str] = field(default_factory=list)

    @property
    def seconds(self) -> float:
        """Wall time of the run (s)."""
        return self.cost.wall


def contactdiff_ball(task: BallTask, velocity=None, rtol: float = 1e-12, atol: float = 1e-13) -> Run:
    """``d(x, z)(T)/d(vx, vz)`` (world frame) from one run with the flow Jacobian.

    The free flyer's tangent displacement at T is in the ball's frame, so the world
    position's rows are ``R(T) J[0:3]``; at t0 the ball is unrotated, so its velocity
    columns ``J[:, 6:9]`` are world ones.
    """
    vx, vz = task.velocity if velocity is None else velocity
    scene = ball_scene(task)
    watch = Stopwatch()
    traj = simulate(scene, task.horizon, v0=np.array([vx, 0.0, vz, 0.0, 0.0, 0.0]), jacobian=True, rtol=rtol, atol=atol)
    cost = watch.read()
    assert traj.jacobian is not None  # asked for
    world = _rotation(traj.q) @ traj.jacobian[0:3, 6:9]
    return Run(
        world[np.ix_([0, 2], [0, 2])], cost, traj.differentiable, traj.q[[0, 2]].copy(), traj.why_not_differentiable()
    )


def two_ball_scene(task: TwoBalls = NIMBLE) -> Scene:
    """Task 3 as a `Scene`: objects ``ball1``, ``ball2`` and their contact ``balls``."""
    robot = add_objects(
        empty_robot(),
        [
            _sphere("ball1", task.radius, task.mass, task.x1, 0.0),
            _sphere("ball2", task.radius, task.mass, task.x2, 0.0),
        ],
    )
    contacts = [
        Contact(
            "ball2", against="ball1", normal=(1.0, 0.0, 0.0), offset=2.0 * task.radius, restitution=1.0, name="balls"
        )
    ]
    return Scene(robot, contacts, gravity=(0.0, 0.0, 0.0), name="two_balls")


def contactdiff_two_balls(task: TwoBalls = NIMBLE, rtol: float = 1e-12, atol: float = 1e-13) -> Run:
    """``d(x1, x2)(T)/d(x1, x2, v1, v2)`` from one run (tangent indices 0, 6 and 12, 18)."""
    scene = two_ball_scene(task)
    v0 = np.zeros(12)
    v0[0], v0[6] = task.v1, task.v2
    watch = Stopwatch()
    traj = simulate(scene, task.horizon, v0=v0, jacobian=True, rtol=rtol, atol=atol)
    cost = watch.read()
    assert traj.jacobian is not None  # asked for
    return Run(
        traj.jacobian[np.ix_([0, 6], [0, 6, 12, 18])],
        cost,
        traj.differentiable,
        traj.q[[0, 7]].copy(),
        traj.why_not_differentiable(),
    )


def falling_scene(task: FallingBall = BRAX) -> Scene:
    """Task 4 as a `Scene`: object ``ball`` (starting at 1 m; `contactdiff_brax` sets z0)."""
    robot = add_objects(empty_robot(), [_sphere("ball", task.radius, task.mass, 0.0, 1.0)])
    return Scene(robot, [Contact("ball", restitution=1.0, name="ground")], gravity=(0.0, 0.0, 0.0), name="falling_ball")


def contactdiff_brax(task: FallingBall, z0: float, rtol: float = 1e-12, atol: float = 1e-13) -> Run:
    """``dz(T)/dz0`` (1 × 1) at initial height ``z0`` from one run; ``differentiable`` is the
    run's verdict (a landing at T itself is `NonSmooth.FINAL_TIME`)."""
    scene = falling_scene(task)
    q0 = scene.q0.copy()
    q0[2] = z0
    watch = Stopwatch()
    traj = simulate(
        scene,
        task.horizon,
        q0=q0,
        v0=np.array([0.0, 0.0, -task.speed, 0.0, 0.0, 0.0]),
        jacobian=True,
        rtol=rtol,
        atol=atol,
    )
    cost = watch.read()
    assert traj.jacobian is not None  # asked for
    return Run(
        traj.jacobian[2:3, 2:3].copy(), cost, traj.differentiable, traj.q[2:3].copy(), traj.why_not_differentiable()
    )
