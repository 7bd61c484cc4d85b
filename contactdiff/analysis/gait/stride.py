"""Gait stability: the stride map, its Jacobian and the Floquet multipliers.

**Section.** The stride map of contact ``foot`` takes the state *just before*
a touchdown of that foot to the state just before its next touchdown. The
section is the foot's guard ``Σ = {x : a_foot(q) = 0}`` (approaching,
``A_foot v < 0``), a hypersurface of codimension 1 whose points are still
pre-impact states; the impact at the start of a stride is part of the map.
Working before the impact keeps the section a plain level set of the gap
(after a plastic impact the post-impact states would form a set of
codimension 2 or more).

**Jacobian.** With ``Φ`` the flow Jacobian from the start to just before the
next touchdown (through every event in between, saltation matrices included),
``F'`` the vector field just before that touchdown and ``Dh' = [A_foot, 0]``
the guard's gradient there, the touchdown time ``t'`` obeys
``dt'/dx0 = -Dh' Φ / (Dh' F')`` and the map's Jacobian is

    P = dx'/dx0 = (I - F' Dh' / (Dh' F')) Φ        (tangent space, 2nv × 2nv).

At the start, the impact enters ``Φ`` through the full saltation matrix
``Ξ0 = DR + (F0+ - DR F0-) Dh0 / (Dh0 F0-)`` of the foot's guard rather than
``DR`` alone: both agree on the section's tangent space (``Dh0 δx = 0``),
and with ``Ξ0`` the Jacobian also holds off the section for the flow
direction (``Ξ0 F0- = F0+``). So ``P F0- = 0`` for an autonomous scene, and
the start-time derivative of a clock-driven one follows from it (below).
``Dh' P = 0``: the image lies in the section's tangent space, so ``P`` has the
trivial eigenvalue 0 of the guard direction; the **multipliers** are the
eigenvalues of ``P`` restricted to the section, ``Bᵀ P B`` with ``B`` an
orthonormal basis of ``ker Dh0`` (section coordinates).

**Clock-driven scenes.** A controller on a clock of period ``T`` (an effort
with a ``period`` attribute, e.g. `contactdiff.control.trot_controller.TrotController`)
makes the scene T-periodic in time, not autonomous: the state of the map is
then ``(x, τ)`` with the phase ``τ = t mod T`` (s). Starting later by ``dt0``
from the same state shifts the whole run: ``∂x(t)/∂t0 = -Φ_flow F0+`` at fixed
``t``, which is ``-Φ F0-`` here because ``Ξ0 F0- = F0+``; with the event-time
correction,

    ∂x'/∂t0 = -(I - F' Dh' / (Dh' F')) Φ F0-,   ∂t'/∂t0 = Dh' Φ F0- / (Dh' F')

(``0`` and ``1`` for an autonomous scene), and the extended Jacobian is
``[[P, ∂x'/∂t0], [dt'/dx0, ∂t'/∂t0]]`` in ``(x, τ)``. `period_map` is the
alternative, stroboscopic map ``x(t0) -> x(t0 + T)``: its Jacobian is the flow
Jacobian itself, and its nonzero eigenvalues are the same multipliers.

**Symmetries.** On flat ground, moving the whole robot along the ground
(world ``x``, ``y``) or turning it about the vertical (``yaw``, free-flyer
bases) maps trajectories to trajectories, so a gait is periodic only up to
such a move and each of these *neutral* directions has multiplier 1. They are
removed: the state is aligned with the reference (centre of mass x–y and base
yaw) before it is compared, and the section coordinates ``B`` are taken
orthogonal to the neutral directions. The default set is every one of ``x``,
``y``, ``yaw`` that the model can realise by its joints and that leaves the
scene's gaps and free-flight dynamics unchanged (``x, y, yaw`` for a
free-flyer on flat ground, ``x`` for the planar trot models, none for the
ball). Tangent coordinates of a free-flyer are in the base frame (Pinocchio's
``q ⊕ δ = q · exp(δ)``), which these world moves leave unchanged, so the
Jacobians of the aligned and unaligned states are the same matrices.

**Simultaneous touchdowns.** When another contact lands at the same instant
as the foot (a perfect trot's diagonal pair), the pre-impact state is
discontinuous there: if the other foot lands first, its velocity has already
jumped. On the section the other foot can only be raised (land later), so the
Jacobian is the one-sided derivative of that branch: at the start, ``Ξ0`` is
the product of the single-contact saltation matrices with the foot first; at
the end, the state before both impacts. `Stride.simultaneous` names those
contacts. Events inside a stride are differentiable only where the limbs are
decoupled (`Event.differentiable`).

**Chattering.** A foot of a rigid robot may land again microseconds after its
touchdown, or after another foot's impact has jolted it off the ground while it
stood (an impact cascade); such a re-landing is not the gait's touchdown, and
a map through it would jump wherever the cascade appears or vanishes. A
touchdown therefore ends a stride only after the foot has been off the ground
for ``min_flight`` (default 5 % of the clock period of a clock-driven scene,
20 ms for a 0.4-s trot against cascade flights of microseconds) and at least
``min_stride`` after the start (default half the clock period).

The stride is run by `StrideLoop`, a subclass of the public hybrid loop
(`contactdiff.integration.hybrid.HybridLoop`) whose ``on_event`` hook makes the
foot's touchdown a terminal event and keeps the flow Jacobian just before it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ...dynamics.impacts import choose_mode
from ...errors import InvalidInputError, StrideError, check_number
from ...integration.hybrid import HybridLoop
from ...integration.options import SimulateOptions
from ...integration.parameter_jumps import ParameterJumps
from ...integration.sensitivity import gap_gradient, saltation, touchdown, vector_field
from ...integration.trajectory import Event, EventKind, Trajectory
from ...model.scene import Scene
from .section import (
    _IMPACT_KINDS,
    MIN_FLIGHT_SHARE,
    SECTION_TOL,
    _foot_index,
    _positive_duration,
    _resolve_period,
    onto_section,
    scene_period,
)

STRIDE_RTOL = 1e-10
"""Default relative tolerance of the runs of a stride (`stride_map`, `first_touchdown`,
`contactdiff.analysis.gait.periodic`); ``contactdiff stride --rtol``'s too."""
STRIDE_ATOL = 1e-12
"""Default absolute tolerance of those runs (m, rad, m/s)."""
STRIDE_METHOD = "DOP853"
"""Default stepper of those runs."""


# ----------------------------------------------------------------------------------
# results
# ----------------------------------------------------------------------------------
@dataclass(kw_only=True)
class Stride:
    """One stride: touchdown of ``foot`` to its next touchdown, both just before impact.

    Attributes:
        scene_name, foot: the scene and the contact whose touchdowns bound the stride.
        t0, q0, v0: start (s; q as Pinocchio, nq; v in the tangent space, nv).
        t, q, v: the next touchdown of the foot, just before its impact.
        jacobian: ``P = dx'/dx0`` (2nv × 2nv, tangent space) or None.
        time_gradient: ``dt'/dx0`` (2nv,) (s per tangent unit) or None.
        start_time_column: ``∂x'/∂t0`` (2nv,) or None.
        start_time_derivative: ``∂t'/∂t0`` (1 for an autonomous scene) or None.
        period: clock period (s) of a clock-driven scene, None if autonomous.
        trajectory: the simulated run (its events end with the foot's touchdown).
        simultaneous: other contacts landing at the same instant as the foot, at the
            start or at the end. There the pre-impact state is discontinuous (the other
            foot's velocity jumps if it lands first), and the Jacobian is the one-sided
            derivative for the other contacts landing at the same time or later.
        parameter_names: the scene parameters differentiated (``parameters=[...]``).
        parameter_jacobian: ``∂x'/∂p`` (2nv × p, tangent space, per unit of each) at a
            fixed start, or None: with the start's impact taken with the foot's guard
            (``Ξ0_p``, as ``Ξ0`` for the state) and the end's touchdown time moving with
            the parameters (``-F' (Dh' ∂x/∂p + ∂h/∂p) / (Dh' F')``).
        parameter_time_gradient: ``∂t'/∂p`` (p,) (s per unit of each), or None.
    """

    scene_name: str
    foot: str
    t0: float
    q0: np.ndarray
    v0: np.ndarray
    t: float
    q: np.ndarray
    v: np.ndarray
    jacobian: np.ndarray | None
    time_gradient: np.ndarray | None
    start_time_column: np.ndarray | None
    start_time_derivative: float | None
    period: float | None
    trajectory: Trajectory = field(repr=False)
    simultaneous: tuple[str, ...] = ()
    parameter_names: tuple[str, ...] = ()
    parameter_jacobian: np.ndarray | None = None
    parameter_time_gradient: np.ndarray | None = None

    @property
    def stride_time(self) -> float:
        """``t - t0`` (s)."""
        return self.t - self.t0

    @property
    def differentiable(self) -> bool:
        """False if any event of the stride has only a piecewise-linear derivative."""
        return self.trajectory.differentiable

    def extended_jacobian(self) -> np.ndarray:
        """The Jacobian in the map's state: ``P`` (autonomous), or in ``(x, τ)``
        ``[[P, ∂x'/∂t0], [dt'/dx0, ∂t'/∂t0]]`` ((2nv+1)², clock-driven)."""
        if self.jacobian is None:
            raise InvalidInputError("this stride was computed without its Jacobian (jacobian=False)")
        if self.period is None:
            return self.jacobian
        n = self.jacobian.shape[0]
        J = np.zeros((n + 1, n + 1))
        J[:n, :n] = self.jacobian
        J[:n, n] = self.start_time_column
        J[n, :n] = self.time_gradient
        J[n, n] = self.start_time_derivative
        return J

    def extended_parameter_jacobian(self) -> np.ndarray:
        """``∂x'/∂p`` in the map's state: (2nv × p), or in ``(x, τ)`` with the row ``∂t'/∂p``
        ((2nv+1) × p, clock-driven)."""
        if self.parameter_jacobian is None:
            raise InvalidInputError("this stride was computed without parameters (stride_map(..., parameters=[...]))")
        if self.period is None:
            return self.parameter_jacobian
        assert self.parameter_time_gradient is not None  # computed with the parameters' Jacobian
        return np.vstack([self.parameter_jacobian, self.parameter_time_gradient])

    def summary(self) -> dict:
        """The stride as JSON-ready data: ends, states, Jacobians where computed."""
        out = {
            "scene": self.scene_name,
            "foot": self.foot,
            "t0": self.t0,
            "t": self.t,
            "stride_time": self.stride_time,
            "q0": self.q0.tolist(),
            "v0": self.v0.tolist(),
            "q": self.q.tolist(),
            "v": self.v.tolist(),
            "period": self.period,
            "events": [f"{e.t:.12g} {e.kind} {'+'.join(e.contacts)}" for e in self.trajectory.events],
            "differentiable": self.differentiable,
            "simultaneous": list(self.simultaneous),
        }
        if self.jacobian is not None:
            assert self.time_gradient is not None and self.start_time_column is not None  # computed with it
            out |= {
                "jacobian": self.jacobian.tolist(),
                "time_gradient": self.time_gradient.tolist(),
                "start_time_column": self.start_time_column.tolist(),
                "start_time_derivative": self.start_time_derivative,
            }
        if self.parameter_jacobian is not None:
            assert self.parameter_time_gradient is not None  # computed with it
            out |= {
                "parameter_names": list(self.parameter_names),
                "parameter_jacobian": self.parameter_jacobian.tolist(),
                "parameter_time_gradient": self.parameter_time_gradient.tolist(),
            }
        return out


# ----------------------------------------------------------------------------------
# the stride map
# ----------------------------------------------------------------------------------
class StrideLoop(HybridLoop):
    """The hybrid loop, stopped at the first touchdown of one contact after ``t0``
    that follows at least ``min_stride`` and a flight of at least ``min_flight``
    (a terminal event, `HybridLoop.on_event`).

    Records the state and flow Jacobian just before that impact, and replaces the
    reset Jacobian of an impact at ``t0`` by the full saltation matrix of the
    foot's guard (see the module docstring)."""

    def __init__(
        self,
        scene,
        foot: int,
        t0,
        t_max,
        q0,
        v0,
        options: SimulateOptions,
        min_stride: float = 0.0,
        min_flight: float = 0.0,
    ):
        super().__init__(scene, t0, t_max, q0, v0, options)
        self.foot, self.t_earliest, self.min_flight = foot, t0 + min_stride, min_flight
        # last time the foot was on the ground (s); the start counts as such, so a
        # foot a few nanometres up after a restart does not "land" at once
        self.last_contact = t0
        # (event, mode before as keys, Φ just before)
        self.hit: tuple[Event, tuple[int, ...], np.ndarray | None] | None = None
        self.start = None  # (mode before, F- at the start, contacts landing with the foot)

    def initial_mode(self, q, v):
        """The loop's consistent start; an impact of the foot there takes the full
        saltation matrix of the foot's guard (module docstring)."""
        n = len(self.events)
        mode, v_plus = super().initial_mode(q, v)
        if not (self.options.jacobian and len(self.events) > n and self.names[self.foot] in self.events[-1].contacts):
            return mode, v_plus
        start = self.events[-1]
        closed = [i for i in range(len(self.contacts)) if self.names[i] in start.impulses]
        _, rates = self._gaps_and_rates(start.q, v)
        landing = [i for i in closed if i != self.foot and rates[i] < -self.options.grazing_speed]
        before = choose_mode(self.dyn, start.q, v, self.t0, [i for i in closed if i != self.foot and i not in landing])
        F_minus = vector_field(self.dyn, start.q, v, self.t0, before)
        if landing and self.jumps is not None:
            raise InvalidInputError(
                f"stride map: the start touchdown of {self.names[self.foot]} is simultaneous with "
                f"{', '.join(self.names[k] for k in landing)}; parameter derivatives of such a stride (a "
                "one-sided derivative) are not available: start the stride from another foot's touchdown"
            )
        if landing:
            # other contacts land at the same instant: on the section they can only be
            # raised (land later), so the one-sided derivative is the foot first, then
            # each of them (the product of single-contact saltation matrices)
            xi, vel, current = np.eye(2 * self.scene.nv), v, before
            for k in [self.foot] + landing:
                self.kin.update(start.q, vel)
                if self.contacts[k].rows(self.kin)[0] @ vel >= 0.0:
                    continue  # separating after the earlier impacts
                step = touchdown(self.dyn, self.t0, start.q, vel, current, [k], guard=k)
                xi, vel, current = step.saltation @ xi, step.v_plus, step.mode_after
            self.notes.append(
                f"the start touchdown of {self.names[self.foot]} is simultaneous with "
                f"{', '.join(self.names[k] for k in landing)}: one-sided derivative "
                "(those landing at the same time or later)"
            )
        else:
            Dh = gap_gradient(self.dyn, start.q, self.foot)
            F_plus = vector_field(self.dyn, start.q, v_plus, self.t0, mode)
            xi = saltation(start.saltation, Dh, F_minus, F_plus)
            if self.jumps is not None:  # the same guard term for the parameters (module doc)
                start.parameter_saltation = ParameterJumps.saltation(
                    start.parameter_saltation,
                    self.jumps.gap_guard(self.foot),
                    start.saltation,
                    F_minus,
                    F_plus,
                    float(Dh @ F_minus),
                )
        start.saltation = xi
        self.initial_saltation = self._jumped(self._identity_phi(), start)
        self.start = (before, F_minus, tuple(self.names[k] for k in landing))
        return mode, v_plus

    def on_event(self, event, mode_before, phi_before) -> bool:
        """The foot's touchdown that ends the stride is terminal; every event where the
        foot is on the ground moves the start of its flight."""
        stop = False
        if (
            self.names[self.foot] in event.contacts
            and event.kind not in (EventKind.LIFT_OFF, EventKind.SLIP)
            and event.t >= self.t_earliest
            and event.t - self.last_contact >= self.min_flight
            and self.hit is None
        ):
            self.hit = (event, tuple(mode_before), phi_before)
            stop = True
        if self._touches(event):
            self.last_contact = event.t
        return stop

    def _touches(self, event) -> bool:
        """Whether the foot is on the ground at ``event`` (before, in or after it)."""
        name = self.names[self.foot]
        return name in event.contacts or name in event.impulses or name in event.mode_before or name in event.mode_after


def stride_map(
    scene: Scene,
    foot: str,
    q: ArrayLike,
    v: ArrayLike,
    t: float = 0.0,
    *,
    t_max: float = 10.0,
    min_stride: float | None = None,
    min_flight: float | None = None,
    period: float | None = None,
    jacobian: bool = True,
    parameters: Sequence[str] = (),
    rtol: float = STRIDE_RTOL,
    atol: float = STRIDE_ATOL,
    method: str = STRIDE_METHOD,
    max_events: int = 1000,
    **options: Any,
) -> Stride:
    """The stride map of ``foot``: from just before one of its touchdowns to just before the next.

    Args:
        scene: the `Scene`.
        foot: name of the contact whose touchdowns bound the stride.
        q: start configuration on the section (nq,): the foot's gap within
            `SECTION_TOL` of 0 (it is closed exactly).
        v: start velocity (nv,), tangent space, approaching (``A_foot v < 0``).
        t: start time (s).
        t_max: longest stride (s); no touchdown of the foot within it raises `StrideError`.
        min_stride: shortest stride (s): touchdowns of the foot before ``t + min_stride``
            do not end the stride (a foot of a rigid robot may chatter, re-landing
            microseconds after its touchdown when another foot's impact jolts it).
            Default: half the clock period for a clock-driven scene, else 0. The map
            stays smooth as long as no touchdown of the foot comes near that time.
        min_flight: shortest flight (s) before a touchdown that ends the stride:
            re-landings after a shorter time off the ground (impact cascades) do
            not. Default `MIN_FLIGHT_SHARE` of the clock period for a clock-driven
            scene, else 0.
        period: clock period (s); default: the period of the scene's clock-driven
            efforts (`scene_period`), or an autonomous scene; False forces autonomous.
        jacobian: compute the Jacobian, the touchdown-time gradient and the
            start-time derivatives (module docstring).
        parameters: names of scene parameters (`Scene.parameter_names`): also
            ``Stride.parameter_jacobian`` and ``parameter_time_gradient`` (with ``jacobian``).
        rtol: relative tolerance of the simulation.
        atol: absolute tolerance (m, rad, m/s).
        method: the stepper (`contactdiff.integration.options.SIMULATE_METHODS`).
        max_events: event budget of the stride.
        **options: further fields of `SimulateOptions`.

    Returns:
        The `Stride`.

    Raises:
        UnknownNameError: ``foot`` is not a contact of the scene (lists the contacts).
        InvalidInputError: the start is not on the section or not approaching.
        StrideError: no touchdown of the foot within ``t_max``, or a grazing / Zeno one.
    """
    i = _foot_index(scene, foot)
    t = check_number("stride map", "t", t)
    t_max = _positive_duration("stride map", "t_max", t_max)
    clock = _resolve_period(scene, period)
    q, v = np.array(q, dtype=float), np.array(v, dtype=float)
    scene.check_state(q, v)
    kin = scene.kinematics
    kin.update(q, v)
    gap, rate = scene.contacts[i].gap(kin), float(scene.contacts[i].rows(kin)[0] @ v)
    if abs(gap) > SECTION_TOL:
        raise InvalidInputError(
            f"stride map: the start must be a touchdown of {foot!r} (gap 0), got gap {gap:.3e} m; "
            "start from first_touchdown(...) or move q with onto_section(...)"
        )
    if not rate < 0:
        raise InvalidInputError(
            f"stride map: {foot!r} must be approaching the ground at the start (normal speed < 0), got {rate:.3e} m/s"
        )
    q = onto_section(scene, foot, q)
    if parameters and not jacobian:
        raise InvalidInputError("stride map: parameters need jacobian=True")
    if parameters:
        options["parameters"] = parameters
    min_stride = (
        (0.5 * clock if clock else 0.0)
        if min_stride is None
        else check_number("stride map", "min_stride", min_stride, minimum=0.0)
    )
    if min_stride >= t_max:
        raise InvalidInputError(f"stride map: min_stride ({min_stride:g} s) must be below t_max ({t_max:g} s)")
    return _run_stride(
        scene,
        i,
        q,
        v,
        t,
        t + t_max,
        clock,
        jacobian,
        require_start=True,
        min_stride=min_stride,
        min_flight=_min_flight(min_flight, clock, "stride map"),
        rtol=rtol,
        atol=atol,
        method=method,
        max_events=max_events,
        **options,
    )


def _min_flight(value, clock: float | None, where: str) -> float:
    if value is None:
        return MIN_FLIGHT_SHARE * clock if clock else 0.0
    return check_number(where, "min_flight", value, minimum=0.0)


def first_touchdown(
    scene: Scene,
    foot: str,
    q=None,
    v=None,
    t: float = 0.0,
    *,
    t_max: float = 10.0,
    min_flight: float | None = None,
    rtol: float = STRIDE_RTOL,
    atol: float = STRIDE_ATOL,
    method: str = STRIDE_METHOD,
    max_events: int = 1000,
    **options,
) -> tuple[float, np.ndarray, np.ndarray]:
    """Simulate from ``(q, v, t)`` (default the scene's initial state) to the first
    touchdown of ``foot`` after ``t`` that follows a flight of at least ``min_flight``
    (s; default as in `stride_map`; the flight is counted from ``t`` at the
    earliest, so a landing sooner than that after ``t`` is skipped); return
    ``(t, q, v)`` just before its impact: a point of the section to start
    `stride_map` or `find_periodic_gait` from."""
    i = _foot_index(scene, foot)
    t = check_number("first touchdown", "t", t)
    q = scene.q0 if q is None else np.array(q, dtype=float)
    v = scene.v0 if v is None else np.array(v, dtype=float)
    s = _run_stride(
        scene,
        i,
        q,
        v,
        t,
        t + _positive_duration("first touchdown", "t_max", t_max),
        None,
        False,
        require_start=False,
        min_flight=_min_flight(min_flight, scene_period(scene), "first touchdown"),
        rtol=rtol,
        atol=atol,
        method=method,
        max_events=max_events,
        **options,
    )
    return s.t, s.q, s.v


def _run_stride(
    scene,
    i,
    q,
    v,
    t0,
    t_end,
    clock,
    jacobian,
    require_start,
    min_stride: float = 0.0,
    min_flight: float = 0.0,
    **options,
) -> Stride:
    foot = scene.contact_names[i]
    run = StrideLoop(
        scene,
        i,
        t0,
        t_end,
        q,
        v,
        SimulateOptions(jacobian=jacobian).replace(**options),
        min_stride=min_stride,
        min_flight=min_flight,
    )
    traj = run.run()
    if run.hit is None:
        seen = ", ".join(f"{e.kind} {'+'.join(e.contacts)} at {e.t:.6g}" for e in traj.events[-6:]) or "none"
        raise StrideError(
            f"{foot!r} did not touch down again between t = {t0:g} and t_max = {t_end:g} s "
            f"(last events: {seen}); raise t_max or check that the gait returns to the ground"
        )
    event, mode, phi = run.hit
    if event.kind not in _IMPACT_KINDS:
        raise StrideError(
            f"the touchdown of {foot!r} at t = {event.t:.12g} is a {event.kind} event "
            f"(normal speed {event.normal_speeds.get(foot, float('nan')):.3e} m/s): the section "
            "is not crossed transversally, so the stride map has no derivative there"
        )
    if require_start and (not traj.events or traj.events[0].t != t0 or foot not in traj.events[0].contacts):
        raise StrideError(f"no impact of {foot!r} at the start t = {t0:g}: the start is not a touchdown")
    t, q1, v1 = event.t, event.q.copy(), event.v_minus.copy()
    J = tg = col = dt = J_p = tg_p = None
    if jacobian:
        assert phi is not None  # a run with the Jacobian records it
        dyn = run.dyn
        Dh = gap_gradient(dyn, q1, i)
        F = vector_field(dyn, q1, v1, t, mode)
        rate = float(Dh @ F)
        project = np.eye(F.size) - np.outer(F, Dh) / rate
        phi, phi_p = phi[:, : run.n_state], phi[:, run.n_state :]
        J = project @ phi
        tg = -(Dh @ phi) / rate
        F0 = run.start[1] if run.start is not None else vector_field(dyn, q, v, t0, ())
        col = -(project @ (phi @ F0))
        dt = float(Dh @ (phi @ F0)) / rate
        if run.jumps is not None:  # the touchdown's guard moves with the parameters too (an offset)
            h_p = run.jumps.gap_guard(i)
            J_p = project @ phi_p - np.outer(F, h_p) / rate
            tg_p = -(Dh @ phi_p + h_p) / rate
        for x in (J, tg, col) + (() if J_p is None else (J_p, tg_p)):
            if not np.all(np.isfinite(x)):
                raise StrideError(f"the stride Jacobian of {foot!r} is not finite (touchdown rate {rate:.3e})")
    together = set(run.start[2] if run.start is not None else ()) | set(event.contacts)
    return Stride(
        scene_name=scene.name,
        foot=foot,
        t0=t0,
        q0=traj.q0.copy(),
        v0=traj.v0.copy(),
        t=t,
        q=q1,
        v=v1,
        jacobian=J,
        time_gradient=tg,
        start_time_column=col,
        start_time_derivative=dt,
        period=clock,
        trajectory=traj,
        simultaneous=tuple(sorted(together - {foot})),
        parameter_names=traj.parameter_names,
        parameter_jacobian=J_p,
        parameter_time_gradient=tg_p,
    )
