"""A clock-driven trot controller for quadrupeds: PD torques tracking a periodic
joint-space reference, with a scheduled feed-forward load.

`TrotController` is an effort spec like those of `contactdiff.model.efforts`
(``bind(robot)`` returns an evaluator with ``tau(kin, t)`` and
``derivatives(kin, t)``). On every joint of a leg it applies

    tau_j = g(t) [kp (q*_j(t) - q_j) + kd (q̇*_j(t) - v_j)] + tau_ff,j(t)       (N m)

and nothing on the base or on joints outside the legs.

**Clock.** The controller is driven by time only, never by contact state: the
gait phase is ``phi(t) = ((t - t_start) / period) mod 1``. Diagonal pair A is
front-left + hind-right, pair B front-right + hind-left. Each leg has its own
phase ``psi = (phi + o_leg) mod 1``, 0 at its scheduled touchdown; it is
scheduled in stance for ``psi < duty`` and in swing for ``psi >= duty``. The
hind foot of a pair follows its front foot by ``lag`` and pair B follows pair
A by half a period; with ``c = (duty + lag) / 2`` the offsets are

    o = c (A front),  c - lag (A hind),  c - 1/2 (B front),  c - 1/2 - lag (B hind),

so ``phi = 0`` is the middle of pair A's stance, pair B being in the air. In
phase, the scheduled events of one period are

    A front touchdown  -c           A hind touchdown  lag - c
    A front lift-off   duty - c     A hind lift-off   duty + lag - c
    pair B: the same plus 1/2.

With ``duty > 1/2`` a pair lands before the other lifts off (double support, a
walking trot). ``lag > 0`` keeps the two feet of a pair from landing or lifting
off at almost, but not exactly, the same instant (a diagonal pair of a
symmetric robot would otherwise do so within round-off, which no event
detection can order). The simulated touchdowns and lift-offs come from the
mechanics, near these scheduled times.

**Reference.** Each foot follows a path in the body frame relative to its
position in the stance pose (default: the robot's standing pose ``q_ref``).
With the quintic smooth step ``S(u) = 10u³ - 15u⁴ + 6u⁵`` (zero slope and
curvature at both ends) every piece is C² in time:

* forward: ``dx = step_length (1/2 - S(psi / duty))`` in stance,
  ``dx = step_length (S(s) - 1/2)`` in swing, ``s = (psi - duty) / (1 - duty)``
  (``step_length = 0`` trots in place);
* up, in swing only: up to ``step_height`` over the first `SWING_RISE` of the
  swing, down to ``approach_height`` by the phase ``1 - approach``, and down to
  the stance position over the last ``approach`` of the period.

The joint reference ``q*(phi)`` is the periodic cubic spline through the exact
inverse kinematics of those paths (base frame, Gauss–Newton on the leg's own
joints) at ``samples`` equally spaced phases, and ``q̇*`` its derivative over
the period: the feet follow the designed paths to interpolation accuracy.

**Feed-forward and contact transitions.** ``tau_ff,leg = g_leg - s w(psi)
J_leg^T (0, 0, c_leg m g)``, with ``g_leg`` the gravity torque of the leg's own
mass and ``J_leg`` its foot Jacobian (linear, world axes), both at the stance
pose, ``m g`` the robot's weight, ``c_leg`` the leg's share of it when its pair
stands alone (the two shares of a pair balance the weight's moment about the
line through its feet; 1/2 each for a robot whose centre of mass is centred)
and ``s`` the scale that makes the scheduled loads carry the weight on average
over a period. The load ``w`` (`TrotControllerEvaluator.load`, smooth steps
between levels) is 1 in stance and 0 in swing, with three transitions of
length ``transfer``:

* landing: in the last ``transfer`` of the swing ``w`` rises to
  ``touchdown_load``, pressing the foot down so that it meets the ground with
  a definite speed (not grazing) and is loaded at once; then it rises to 1
  over the first ``transfer`` of the stance;
* lift-off: over a window of ``2 transfer`` ``w`` falls from 1 through 0 at the
  scheduled lift-off to ``-liftoff_pull`` (a vertical pull), then returns to 0
  over the next ``transfer``;
* meanwhile the PD gains are scaled by ``g(psi)``, falling to ``release_gain``
  (default 0) at the scheduled lift-off and back to 1 over ``transfer`` on
  either side.

Why: with sticking contacts a foot is released when its normal force reaches
zero, and if its tangential force is not zero then, the released foot is
pushed into the ground (the sticking model has no friction cone to let it
slip first). Joint-space PD terms squeeze the two stance feet of a pair
against each other through the body; fading them out while a purely vertical
feed-forward pull takes the normal force through zero releases the foot with
almost no tangential force. What is left (the legs' own inertia) can still
hold a released foot a few nanometres below the ground for a fraction of a
millisecond, until the pull lifts it (the simulation may record tiny bounces
there).

**Breakpoints.** The schedule is C² in time but its third derivative jumps at
the spline's knots and at the ends of every smooth-step piece;
`TrotControllerEvaluator.next_breakpoint` lists those times, and the integrator
ends a step exactly on each (an 8th-order method stepping across them rejects
about as many steps as it accepts).

Because ``q*``, ``q̇*``, ``g`` and ``tau_ff`` depend on time only, the
derivatives are ``dtau/dq = -g(t) kp`` and ``dtau/dv = -g(t) kd`` on the leg
joints (tangent space), zero elsewhere.

Legs are found from the kinematic tree: the joints on the path from each foot
frame up to the free-flyer. Front/hind and left/right come from the foot
positions in the base frame at the stance pose (x forward, y left), so the
same code serves every quadruped whatever its naming.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import ClassVar

import numpy as np
import pinocchio as pin

from ..errors import InvalidInputError, check_number
from ..model.efforts import EffortParameters, central_time_difference
from ..model.kinematics import Kinematics
from ..model.robot import Robot
from .foot_paths import SWING_RISE, foot_offset, reference_spline, smooth_step
from .legs import PAIR_A, PAIR_B, Leg, base_at_origin, check_quadruped, find_legs
from .piecewise import PiecewisePolynomial
from .trot_parameters import TrotParameterDerivatives
from .trot_schedule import TrotSchedule, unload_window


@dataclass(frozen=True)
class TrotController:
    """PD trot: diagonal leg pairs alternate stance and swing on a clock.

    Args:
        period: gait period (s), > 0.
        duty: fraction of the period each foot is scheduled on the ground, in (0, 1).
        lag: phase by which the hind foot of a pair follows the front one, >= 0,
            below ``duty`` and ``1 - duty``.
        step_height: swing apex of each foot above its stance position (m, body frame), > 0.
        approach_height: height (m) from which the foot makes its final descent,
            in [0, step_height].
        approach: phase (fraction of the period) of that final descent, > 0.
        step_length: forward sweep of each foot over a stride (m, body frame);
            0 trots in place.
        transfer: phase over which a foot takes or gives up its load and its gains
            fade (see the module notes), > 0; the transitions must fit in the stance
            and the swing.
        touchdown_load: scheduled load pressing a landing foot down, in [0, 1].
        liftoff_pull: scheduled vertical pull on a leaving foot, in [0, 1].
        release_gain: scale of the PD gains at the scheduled lift-off, in [0, 1].
        kp: proportional gain (N m/rad), >= 0.
        kd: derivative gain (N m s/rad), >= 0.
        t_start: time (s) at which the phase is 0 (mid-stance of pair A).
        feedforward: add the leg gravity torques and the scheduled load.
        stance: joint angles (rad) of the stance pose by joint name, overriding the
            robot's reference pose; a mapping or a tuple of (name, value) pairs.
        samples: phases at which the inverse kinematics is solved (spline nodes), >= 16.
    """

    period: float = 0.4
    duty: float = 0.6
    lag: float = 0.03
    step_height: float = 0.04
    approach_height: float = 0.01
    approach: float = 0.15
    step_length: float = 0.0
    transfer: float = 0.05
    touchdown_load: float = 0.2
    liftoff_pull: float = 0.1
    release_gain: float = 0.0
    kp: float = 10.0
    kd: float = 0.2
    t_start: float = 0.0
    feedforward: bool = True
    stance: tuple = ()
    samples: int = 240
    KEYS: ClassVar[tuple[str, ...]]  # set below the class (module level: they list its fields)
    NUMBERS: ClassVar[tuple[str, ...]]

    def __post_init__(self) -> None:
        owner = "trot controller"
        set_ = object.__setattr__
        for name, minimum in (
            ("period", 0.0),
            ("duty", 0.0),
            ("lag", 0.0),
            ("step_height", 0.0),
            ("approach_height", 0.0),
            ("approach", 0.0),
            ("step_length", None),
            ("transfer", 0.0),
            ("touchdown_load", 0.0),
            ("liftoff_pull", 0.0),
            ("release_gain", 0.0),
            ("kp", 0.0),
            ("kd", 0.0),
            ("t_start", None),
        ):
            set_(self, name, check_number(owner, name, getattr(self, name), minimum=minimum))

        def bad(message: str):
            raise InvalidInputError(f"{owner}: {message}")

        if self.period == 0:
            bad(f"period must be > 0 s, got {self.period!r}")
        if not 0.0 < self.duty < 1.0:
            bad(f"duty must be in (0, 1), got {self.duty!r}")
        if not self.lag < min(self.duty, 1.0 - self.duty):
            bad(f"lag must be below duty and 1 - duty ({min(self.duty, 1.0 - self.duty)!r}), got {self.lag!r}")
        if self.step_height == 0:
            bad("step_height must be > 0 m, got 0")
        if self.approach_height > self.step_height:
            bad(f"approach_height must be in [0, step_height = {self.step_height!r}], got {self.approach_height!r}")
        longest = (1.0 - SWING_RISE) * (1.0 - self.duty)
        if not 0.0 < self.approach < longest:
            bad(f"approach must be in (0, {longest:.6g}) (after the swing apex), got {self.approach!r}")
        for name in ("touchdown_load", "liftoff_pull", "release_gain"):
            if getattr(self, name) > 1.0:
                bad(f"{name} must be in [0, 1], got {getattr(self, name)!r}")
        if self.transfer == 0:
            bad("transfer must be > 0, got 0")
        start, end = unload_window(self)
        if start < self.transfer or end + self.transfer > 1.0 - self.transfer:
            bad(
                f"transfer = {self.transfer!r} is too long for duty = {self.duty!r}: the load transitions "
                "(see TrotControllerEvaluator.load) must not overlap; shorten it"
            )
        if not isinstance(self.feedforward, bool):
            bad(f"feedforward must be true or false, got {self.feedforward!r}")
        if isinstance(self.samples, bool) or not isinstance(self.samples, (int, np.integer)) or self.samples < 16:
            bad(f"samples must be an integer >= 16, got {self.samples!r}")
        stance = self.stance.items() if isinstance(self.stance, Mapping) else self.stance
        try:
            pairs = tuple((str(name), value) for name, value in stance)
        except (TypeError, ValueError):
            bad(f"stance must map joint names to angles (rad), got {self.stance!r}")
        set_(
            self,
            "stance",
            tuple((name, check_number(owner, f"stance angle of {name!r}", value)) for name, value in pairs),
        )

    def named_parameters(self) -> EffortParameters:
        """``trot:<field>`` for each of `NUMBERS`."""
        return EffortParameters("trot", "", self.NUMBERS)

    def bind(self, robot: Robot) -> TrotControllerEvaluator:
        """The evaluator of this controller on ``robot`` (its legs found, the schedule precomputed)."""
        return TrotControllerEvaluator(self, robot)


TrotController.KEYS = tuple(f.name for f in fields(TrotController))
"""Argument names of `TrotController` (the keys of a scene file's ``[trot]`` table)."""

TrotController.NUMBERS = tuple(f.name for f in fields(TrotController) if type(f.default) is float)
"""The controller's real numbers (not ``feedforward``, ``stance``, ``samples``): the scene
parameters ``trot:<field>`` (`contactdiff.model.parameters`)."""


class TrotControllerEvaluator(TrotSchedule, TrotParameterDerivatives):
    """`TrotController` bound to a robot.

    Attributes:
        spec: the controller.
        legs: the `Leg` list (order of ``robot.feet``).
        q_stance: stance pose (nq,), base at the origin.
        iq, iv: configuration and tangent indices of all leg joints (legs in order).
        shares: fraction of the weight each leg carries when its pair stands alone.
        load_scale: the scale ``s`` of the scheduled loads (see the module notes).
    """

    spec: TrotController

    def __init__(self, spec: TrotController, robot: Robot):
        self.spec, self.robot, self.nv = spec, robot, robot.nv
        check_quadruped(robot)
        q_stance = base_at_origin(robot.q_ref)
        for name, value in spec.stance:
            q_stance[robot.scalar_joint(name)[0]] = value
        self.q_stance = q_stance
        self.legs = find_legs(robot, q_stance)
        self.iq = np.array([i for leg in self.legs for i in leg.iq])
        self.iv = np.array([i for leg in self.legs for i in leg.iv])
        self._sizes = [len(leg.iv) for leg in self.legs]
        TrotSchedule.__init__(self, spec, self.legs)
        self._spline = reference_spline(spec, robot, self.legs, self.offsets, q_stance, self.iq.size)
        # the spline's pieces, evaluated by hand in `reference` (Horner, as SciPy does, to the
        # same bits): a CubicSpline call costs ~20 µs of Python for a dozen numbers
        self._knots, self._coef = self._spline.x, self._spline.c
        self._gravity, self._carry, self.shares = self._static_terms()
        grid = np.linspace(0.0, 1.0, 4001)
        # both legs of each pair share the weight (c_front + c_hind = 1): two pairs
        self.load_scale = 1.0 / (2.0 * np.trapezoid([self.load(p % 1.0) for p in grid], grid))
        # the torques' time-only terms, one polynomial between breakpoints: a table
        self._schedule = PiecewisePolynomial(self._breakpoint_phases(), self._schedule_terms_at_phases, self._DEGREE)
        # tau reads q on the tangent indices: each leg joint's configuration entry
        # (the base's entries have zero gains; any index will do)
        self._q_of_v = np.zeros(self.nv, dtype=int)
        self._q_of_v[self.iv] = self.iq

    def _breakpoint_phases(self) -> np.ndarray:
        """Gait phases in [0, 1) where the schedule is not smooth: the reference spline's
        knots (its third derivative jumps there) and, per leg, the ends of the smooth-step
        pieces of the load and of the gain scale (``S'''`` jumps there), sorted, with
        phases closer than 1e-12 merged."""
        knots = list(self._knots[:-1]) + self.leg_breakpoint_phases()
        phases = np.sort(np.mod(knots, 1.0))
        keep = np.concatenate(([True], np.diff(phases) > 1e-12))
        return phases[keep]

    def next_breakpoint(self, t: float) -> float:
        """The first time (s) after ``t`` at which the schedule is not smooth (see
        `_breakpoint_phases`): a stepper that ends a step there exactly never steps across
        a jump of a derivative of the torques."""
        s = self.spec
        x = (t - s.t_start) / s.period
        n = math.floor(x)
        breaks = self._schedule.starts  # the pieces start at the breakpoint phases
        i = bisect.bisect_right(breaks, x - n)
        while True:
            if i == len(breaks):
                n, i = n + 1, 0
            t_break = s.t_start + s.period * (n + breaks[i])
            if t_break > t:
                return t_break
            i += 1

    # -- reference ------------------------------------------------------------------
    def foot_offset(self, psi):
        """Foot displacement ``(dx, dz)`` (m, base frame) from the stance pose at leg phase ``psi``."""
        return foot_offset(self.spec, psi)

    def _static_terms(self, model: pin.Model | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Leg gravity torques at the stance pose, and per leg (rows) the torques that
        press its foot on the ground with its share of the robot's weight when its
        pair carries the robot alone: the shares of a pair balance the moment of the
        weight about the line through its feet (centre of mass projected on that line,
        horizontal plane). Also the shares. On ``model`` (default the robot's): a
        copy with other masses or gravity gives the terms that a scene with those
        would bind (see `model_parameter_derivatives`)."""
        model = self.robot.model if model is None else model
        data = model.createData()
        q = self.q_stance
        gravity = pin.computeGeneralizedGravity(model, data, q)[self.iv].copy()
        com = pin.centerOfMass(model, data, q)
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        weight = pin.computeTotalMass(model) * np.linalg.norm(model.gravity.linear)
        up = -np.asarray(model.gravity.linear) / max(np.linalg.norm(model.gravity.linear), 1e-300)
        feet = [self.robot.frame_id(leg.foot) for leg in self.legs]
        carry = np.zeros((4, self.iv.size))
        shares = np.zeros(4)
        for k, leg in enumerate(self.legs):
            partner = next(j for j, other in enumerate(self.legs) if other.pair == leg.pair and j != k)
            p_k, p_j = data.oMf[feet[k]].translation[:2], data.oMf[feet[partner]].translation[:2]
            shares[k] = np.clip((com[:2] - p_j) @ (p_k - p_j) / ((p_k - p_j) @ (p_k - p_j)), 0.0, 1.0)
            J = pin.getFrameJacobian(model, data, feet[k], pin.LOCAL_WORLD_ALIGNED)[:3]
            carry[k] = -(J.T @ (shares[k] * weight * up))[self.iv]
        return gravity, carry, shares

    def reference(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Joint reference ``q*`` (rad) and ``q̇*`` (rad/s) of the leg joints at time ``t`` (s)."""
        phi = self.phase(t)
        i = min(max(bisect.bisect_right(self._knots, phi) - 1, 0), self._coef.shape[1] - 1)
        c, dx = self._coef[:, i], phi - self._knots[i]
        value = ((c[0] * dx + c[1]) * dx + c[2]) * dx + c[3]
        rate = ((3.0 * c[0]) * dx + 2.0 * c[1]) * dx + c[2]
        return value, rate / self.spec.period

    def gains(self, t: float) -> np.ndarray:
        """Gain scale ``g`` of every leg joint at time ``t``."""
        phi = self.phase(t)
        return np.repeat([self.gain(self.leg_phase(k, phi)) for k in range(4)], self._sizes)

    def feedforward(self, t: float) -> np.ndarray:
        """Feed-forward torques (N m) of the leg joints at time ``t``."""
        if not self.spec.feedforward:
            return np.zeros(self.iv.size)
        phi = self.phase(t)
        loads = np.array([self.load(self.leg_phase(k, phi)) for k in range(4)])
        return self._gravity + self.load_scale * (loads @ self._carry)

    # -- the schedule as one table of polynomial pieces --------------------------------
    _DEGREE = 8
    """Degree in time of the torques' time-only terms on a piece between breakpoints: the
    gain scale (a quintic smooth step) times the reference (a cubic spline piece)."""

    def _phase_terms(self, phis: np.ndarray):
        """At many gait phases: the reference ``q*``, ``q̇*`` and the gain scale ``g`` of the
        leg joints (rows: phases), and the legs' loads ``w`` (rows: phases; zero without
        feed-forward); the spline evaluated by SciPy, the gains and loads leg by leg."""
        s = self.spec
        q_ref = self._spline(phis)
        v_ref = self._spline(phis, 1) / s.period
        psis = [(phis + offset) % 1.0 for offset in self.offsets]
        g = np.repeat(np.array([[self.gain(p) for p in psi] for psi in psis]).T, self._sizes, axis=1)
        loads = np.array([[self.load(p) for p in psi] for psi in psis]).T if s.feedforward else np.zeros((len(phis), 4))
        return q_ref, v_ref, g, loads

    def _schedule_terms_at_phases(self, phis: np.ndarray) -> np.ndarray:
        """``(b, kp g, kd g)`` stacked (rows of 3 nv) at many gait phases in [0, 1): the
        torques are ``b - (kp g) q - (kd g) v`` on the leg joints, with
        ``b = g (kp q* + kd q̇*) + tau_ff`` (zero on the base)."""
        s, nv, iv = self.spec, self.nv, self.iv
        q_ref, v_ref, g, loads = self._phase_terms(phis)
        out = np.zeros((len(phis), 3 * nv))
        ff = np.zeros((len(phis), iv.size))
        if s.feedforward:
            ff = self._gravity + self.load_scale * (loads @ self._carry)
        out[:, iv] = g * (s.kp * q_ref + s.kd * v_ref) + ff
        out[:, nv + iv] = s.kp * g
        out[:, 2 * nv + iv] = s.kd * g
        return out

    def _terms(self, t: float) -> np.ndarray:
        """`_schedule_terms_at_phases` at time ``t`` (s), from the table."""
        return self._schedule(self.phase(t))

    # -- effort protocol --------------------------------------------------------------
    def tau(self, kin: Kinematics, t: float) -> np.ndarray:
        """Generalised force (nv,) at the state of ``kin`` and time ``t`` (s): the PD and
        feed-forward torques on the leg joints (N m), zero elsewhere (from the table of
        `PiecewisePolynomial`; `tau_by_formula` evaluates the formulas themselves)."""
        nv = self.nv
        terms = self._terms(t)
        return terms[:nv] - terms[nv : 2 * nv] * kin.q[self._q_of_v] - terms[2 * nv :] * kin.v

    def tau_by_formula(self, kin: Kinematics, t: float) -> np.ndarray:
        """`tau` from the schedule's formulas (reference, gains, feed-forward), the oracle
        that the table is tested against."""
        s = self.spec
        q_ref, v_ref = self.reference(t)
        out = np.zeros(self.nv)
        out[self.iv] = self.gains(t) * (
            s.kp * (q_ref - kin.q[self.iq]) + s.kd * (v_ref - kin.v[self.iv])
        ) + self.feedforward(t)
        return out

    def time_derivative(self, kin: Kinematics, t: float) -> np.ndarray:
        """``d tau/dt`` at fixed state: a central difference in ``t`` with a step of 1e-6
        period (the schedule is smooth on that scale: relative error ~1e-10)."""
        return central_time_difference(self, kin, t, 1e-6 * self.spec.period)

    def derivatives(self, kin: Kinematics, t: float) -> tuple[np.ndarray, np.ndarray]:
        """``(d tau/dq, d tau/dv)``, each (nv × nv), tangent space: ``-g kp`` and ``-g kd`` on
        the diagonal of the leg joints, zero elsewhere."""
        nv = self.nv
        terms = self._terms(t)
        return np.diag(-terms[nv : 2 * nv]), np.diag(-terms[2 * nv :])


__all__ = [
    "TrotController",
    "TrotControllerEvaluator",
    "Leg",
    "find_legs",
    "smooth_step",
    "PAIR_A",
    "PAIR_B",
    "SWING_RISE",
]
