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
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ...errors import InvalidInputError, StrideError, check_number
from ...integration.options import SimulateOptions
from ...integration.sensitivity import gap_gradient, vector_field
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
from .stride_loop import StrideLoop
from .stride_result import Stride

STRIDE_RTOL = 1e-10
"""Default relative tolerance of the runs of a stride (`stride_map`, `first_touchdown`,
`contactdiff.analysis.gait.periodic`); ``contactdiff stride --rtol``'s too."""
STRIDE_ATOL = 1e-12
"""Default absolute tolerance of those runs (m, rad, m/s)."""
STRIDE_METHOD = "DOP853"
"""Default stepper of those runs."""


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
