"""Periodic gaits: Newton's method on the stride map and the map's resolution (the
stroboscopic map ``x(t0) -> x(t0 + period)`` that cross-checks the multipliers is
`contactdiff.analysis.gait.period_map`).

The mathematics is in `contactdiff.analysis.gait.stride`'s module docstring.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike

from ...errors import InconsistentStateError, InvalidInputError, StrideError, check_number
from ...integration.hybrid import simulate
from ...integration.options import RTOL_MIN
from ...model.scene import Scene
from .section import (
    RESOLUTION_TIGHTENING,
    SECTION_TOL,
    _check_neutral,
    _foot_index,
    _resolve_period,
    _sorted_eigenvalues,
    align,
    onto_section,
    section_basis,
)
from .stride import STRIDE_ATOL, STRIDE_METHOD, STRIDE_RTOL, _min_flight, first_touchdown, stride_map
from .stride_result import Stride


@dataclass(kw_only=True)
class PeriodicGait:
    """Result of `find_periodic_gait`.

    Attributes:
        foot: the contact whose touchdowns define the section.
        t, q, v: the last iterate on the section (just before the foot's touchdown).
        stride: the stride from there (its Jacobian gives the multipliers).
        residuals: size of the reduced residual ``Bᵀ(x'' ⊖ x)`` at each iterate (mixed
            units: m, rad, m/s and, clock-driven, s), the last one at ``(q, v, t)``.
        resolutions: the map's resolution at each iterate, in the residual's units:
            twice the change of the residual vector when that stride is computed
            again at tolerances `RESOLUTION_TIGHTENING` times tighter, a bound on
            the residual's error (`find_periodic_gait`); None where not measured (an
            iterate whose residual is below ``tol``, or ``resolution=False``). A
            residual below it cannot be told from zero.
        steps: how each iterate was reached ("start", "newton", "newton ×0.5", ...,
            "fixed point").
        multipliers: Floquet multipliers at the last iterate (complex, by decreasing modulus).
        neutral: the neutral moves removed.
        converged: the last residual is below ``tol`` or below its resolution.
        tol: the tolerance the search was given.
        drift: the neutral move over one stride: centre-of-mass x, y (m) and base yaw (rad)
            of the next touchdown relative to this one (only the neutral ones).
        run_time: wall-clock time of the search (s).
    """

    foot: str
    t: float
    q: np.ndarray
    v: np.ndarray
    stride: Stride
    residuals: list[float]
    steps: list[str]
    multipliers: np.ndarray
    neutral: tuple[str, ...]
    converged: bool
    drift: dict
    run_time: float
    resolutions: list[float | None] = field(default_factory=list)
    tol: float | None = None

    @property
    def resolution(self) -> float | None:
        """The map's resolution at the last iterate (see ``resolutions``)."""
        return self.resolutions[-1] if self.resolutions else None

    @property
    def resolved(self) -> bool:
        """Converged by the resolution rule: the last residual is above ``tol`` but
        not above what the map resolves there."""
        return self.converged and self.tol is not None and self.residuals[-1] > self.tol and self.resolution is not None

    def to_dict(self) -> dict:
        """The result as JSON-ready data (what ``contactdiff stride --json`` prints)."""
        return {
            "foot": self.foot,
            "t": self.t,
            "q": self.q.tolist(),
            "v": self.v.tolist(),
            "stride_time": self.stride.stride_time,
            "period": self.stride.period,
            "residuals": list(self.residuals),
            "steps": list(self.steps),
            "resolutions": list(self.resolutions),
            "tol": self.tol,
            "resolved": self.resolved,
            "multipliers": [[float(m.real), float(m.imag)] for m in self.multipliers],
            "moduli": [float(abs(m)) for m in self.multipliers],
            "neutral": list(self.neutral),
            "converged": self.converged,
            "drift": dict(self.drift),
            "differentiable": self.stride.differentiable,
            "simultaneous": list(self.stride.simultaneous),
            "why_not_differentiable": self.why_not_differentiable(),
            "run_time": self.run_time,
        }

    def why_not_differentiable(self) -> list[str]:
        """The stride's notes on its non-differentiable events (simultaneous landings
        whose orders disagree, cascades ended by the Zeno rule, grazing)."""
        return self.stride.trajectory.why_not_differentiable()

    def format(self) -> str:
        """The result as the text ``contactdiff stride`` prints: residuals, stride, multipliers."""
        s = self.stride
        lines = [
            f"stride map of {s.scene_name}, section: touchdown of {self.foot} (state just before impact)",
            f"  stride time {s.stride_time:.12g} s" + (f" (clock period {s.period:g} s)" if s.period else ""),
            "  neutral moves removed: "
            + (", ".join(self.neutral) or "none")
            + ("".join(f"; {k} {v:+.6g} per stride" for k, v in self.drift.items())),
            "",
            "  iteration  step            residual   resolution",
        ]
        resolutions = list(self.resolutions) + [None] * (len(self.residuals) - len(self.resolutions))
        for k, (step, r, res) in enumerate(zip(self.steps, self.residuals, resolutions)):
            lines.append(f"  {k:9d}  {step:<14}  {r:.3e}" + (f"  {res:.3e}" if res is not None else ""))
        if self.resolved:
            lines.append(
                f"  converged to the map's resolution: the residual {self.residuals[-1]:.2e} is below "
                f"{self.resolution:.2e}, twice its change when this stride is computed again at "
                f"{RESOLUTION_TIGHTENING:g} times tighter tolerances (a bound on its error); tol "
                f"{self.tol:g} is below what the map resolves. A periodic gait to that accuracy "
                "(up to the neutral moves)"
            )
        elif self.converged:
            lines.append("  converged: a periodic gait (up to the neutral moves)")
        elif len(self.steps) == 1:
            lines.append(
                "  one stride, no Newton iterations: the multipliers are those of this stride's map, "
                "a stability measure only at a periodic gait (residual 0)"
            )
        else:
            lines.append(
                "  NOT converged: the multipliers are those of the last iterate"
                + (
                    f" (its residual {self.residuals[-1]:.2e} is above the map's resolution "
                    f"{self.resolution:.2e} there)"
                    if self.resolution is not None
                    else ""
                )
            )
        lines += [
            "",
            f"  Floquet multipliers ({len(self.multipliers)}, section coordinates, by modulus):",
            f"  {'#':>3}  {'real':>14}  {'imag':>14}  {'|λ|':>12}",
        ]
        for k, m in enumerate(self.multipliers):
            lines.append(f"  {k:3d}  {m.real:14.8g}  {m.imag:14.8g}  {abs(m):12.8g}")
        top = max((abs(m) for m in self.multipliers), default=0.0)
        verdict = "stable (all inside the unit circle)" if top < 1 - 1e-9 else "not asymptotically stable"
        lines.append(f"  largest |λ| = {top:.8g}: {verdict}")
        if not s.differentiable:
            why = self.why_not_differentiable()
            lines.append(
                "  note: an event of the stride is not differentiable; the multipliers are those of "
                "the branch taken" + (":" if why else "")
            )
            lines += [f"    {n}" for n in why[:4]] + ([f"    ... {len(why) - 4} more"] if len(why) > 4 else [])
        if s.simultaneous:
            lines.append(
                f"  note: {', '.join(s.simultaneous)} land(s) at the same instant as {self.foot}: the "
                "stride map is discontinuous there and these are one-sided multipliers (the other "
                "feet landing later); choose a foot that lands alone"
            )
        lines.append(f"  run time {self.run_time:.2f} s")
        return "\n".join(lines)


# ----------------------------------------------------------------------------------
# periodic gaits
# ----------------------------------------------------------------------------------
def _reduced_residual(scene, stride, B, neutral, clock) -> tuple[np.ndarray, dict]:
    q_aligned, moved = align(scene, stride.q, stride.q0, neutral)
    delta = np.concatenate([pin.difference(scene.model, stride.q0, q_aligned), stride.v - stride.v0])
    if clock is not None:
        delta = np.append(delta, math.remainder(stride.t - stride.t0, clock))
    return B.T @ delta, moved


def floquet_multipliers(scene: Scene, stride: Stride, neutral: Sequence[str] | None = None) -> np.ndarray:
    """Eigenvalues of the stride map restricted to the section, neutral moves removed:
    ``eig(Bᵀ J B)`` with ``B = section_basis(...)`` at the stride's start and ``J`` its
    (extended) Jacobian, by decreasing modulus. Meaningful at a (relative) fixed point.

    Args:
        scene: the stride's scene.
        stride: a `Stride` with its Jacobian.
        neutral: neutral moves to remove (default: those the scene admits, `available_neutral`).
    """
    neutral = _check_neutral(scene, neutral, stride.q0, stride.v0, stride.t0)
    B = section_basis(scene, stride.foot, stride.q0, neutral, stride.period)
    return _sorted_eigenvalues(B.T @ stride.extended_jacobian() @ B)


def find_periodic_gait(
    scene: Scene,
    foot: str,
    q: ArrayLike | None = None,
    v: ArrayLike | None = None,
    t: float = 0.0,
    *,
    iterations: int = 8,
    tol: float = 1e-9,
    neutral: Sequence[str] | None = None,
    period: float | None = None,
    t_max: float = 10.0,
    min_stride: float | None = None,
    min_flight: float | None = None,
    warmup: float = 0.0,
    line_search: int = 4,
    resolution: bool = True,
    rtol: float = STRIDE_RTOL,
    atol: float = STRIDE_ATOL,
    method: str = STRIDE_METHOD,
    **options,
) -> PeriodicGait:
    """Approach a periodic gait by Newton's method on the stride map, reduced state.

    The unknowns are the section coordinates ``s`` (`section_basis`: along the
    foot's guard, orthogonal to the neutral moves, plus the phase of a
    clock-driven scene); the residual is ``r = Bᵀ (x'' ⊖ x)`` with ``x''`` the next
    touchdown aligned back by the neutral moves (`align`) and, with a clock, the
    phase slip ``remainder(t' - t, period)``. The Newton step solves
    ``(Bᵀ J B - I) s = -r`` (least squares: a family of orbits, multiplier 1, gives
    the nearest member); if a full step does not reduce ``|r|``, it is halved up to
    ``line_search`` times, and if that fails too the next iterate is the map's own
    image ``x''`` (a fixed-point step, which converges where all multipliers are
    inside the unit circle). Each new iterate is moved back onto the guard
    (`onto_section`). Every stride is simulated with its Jacobian.

    **Resolution.** A residual is only as accurate as the strides it comes from:
    their integration error and, on rigid robots, rounding amplified by impact
    cascades (a foot re-landing nanoseconds after another's impact; the solo12
    trot's map, computed twice with different roundings, differs by ~1e-7 in
    ``|r|``). Below that level Newton steps only shuffle the noise. So at each
    iterate whose residual is above ``tol`` the same stride is computed once more
    (no Jacobian) at ``rtol`` and ``atol`` divided by `RESOLUTION_TIGHTENING`.
    If that at least halves the error ``e`` of ``r``, then
    ``|e| <= |r - r_tight| + |e|/2``, so ``|e| <= 2 |r - r_tight|``: this bound is
    the map's resolution there. If ``|r|`` is not above it, ``r`` cannot be told
    from zero and the search stops, converged to the map's resolution
    (`PeriodicGait.resolved`). Where rounding noise rather than integration error
    dominates, the tighter run is another sample of that noise and the bound an
    estimate of its size. This costs one stride per iterate and is skipped where
    ``|r| <= tol``.

    Args:
        scene: the `Scene`.
        foot: the contact whose touchdowns define the section.
        q: start configuration (nq,); default the scene's initial state. A start
            not on the section is first carried to the foot's next touchdown
            (`first_touchdown`).
        v: start velocity (nv,), tangent space; default the scene's.
        t: start time (s).
        warmup: time (s) simulated from the start before that (no sensitivities): a
            stable gait settles towards its cycle on its own, by a factor of about
            the largest multiplier's modulus per stride, and Newton then starts near it.
        iterations: largest number of Newton steps.
        tol: stop when ``|r|`` is below this (mixed units, see `PeriodicGait.residuals`).
        neutral: neutral moves removed (default: those the scene admits, `available_neutral`).
        period: clock period (s); default from the scene (`scene_period`).
        t_max: longest stride (s).
        min_stride: shortest stride (s), see `stride_map`.
        min_flight: shortest flight before the touchdown that ends a stride (s), see
            `stride_map`.
        line_search: halvings of a Newton step before the fixed-point fallback.
        resolution: also stop where the residual is within the map's resolution
            (above); False stops only at ``tol``.
        rtol: relative tolerance of the strides' simulations.
        atol: absolute tolerance (m, rad, m/s).
        method: the stepper (`contactdiff.integration.options.SIMULATE_METHODS`).
        **options: further fields of `SimulateOptions`.

    Returns:
        The `PeriodicGait` with the residual of every iterate and the multipliers at the last one.
    """
    started = time.perf_counter()
    i = _foot_index(scene, foot)
    iterations = int(check_number("find_periodic_gait", "iterations", iterations, minimum=0))
    tol = check_number("find_periodic_gait", "tol", tol, minimum=0.0)
    clock = _resolve_period(scene, period)
    warmup = check_number("find_periodic_gait", "warmup", warmup, minimum=0.0)
    sim = dict(
        t_max=t_max,
        min_stride=min_stride,
        min_flight=min_flight,
        period=False if clock is None else clock,
        rtol=rtol,
        atol=atol,
        method=method,
        **options,
    )
    q = scene.q0 if q is None else np.array(q, dtype=float)
    v = scene.v0 if v is None else np.array(v, dtype=float)
    if warmup > 0:
        settled = simulate(scene, t + warmup, q, v, t0=t, rtol=rtol, atol=atol, method=method, **options)
        t, q, v = settled.t, settled.q, settled.v
    kin = scene.kinematics
    kin.update(q, v)
    if warmup > 0 or abs(scene.contacts[i].gap(kin)) > SECTION_TOL or not scene.contacts[i].rows(kin)[0] @ v < 0:
        t, q, v = first_touchdown(
            scene,
            foot,
            q,
            v,
            t,
            t_max=t_max,
            min_flight=_min_flight(min_flight, clock, "find_periodic_gait"),
            rtol=rtol,
            atol=atol,
            method=method,
            **options,
        )
    neutral = _check_neutral(scene, neutral, q, v, t)

    def evaluate(q, v, t):
        stride = stride_map(scene, foot, q, v, t, **sim)
        B = section_basis(scene, foot, stride.q0, neutral, clock)
        r, moved = _reduced_residual(scene, stride, B, neutral, clock)
        return stride, B, r, moved

    def moved_along(stride, B, s):
        step = B @ s
        nv = scene.nv
        q1 = onto_section(scene, foot, pin.integrate(scene.model, stride.q0, step[:nv]))
        v1 = stride.v0 + step[nv : 2 * nv]
        t1 = stride.t0 + (step[2 * nv] if clock is not None else 0.0)
        return q1, v1, t1

    def resolved_here(stride, B, r) -> bool:
        """Measure the map's resolution at this iterate; whether the residual is within it."""
        resolutions[-1] = _map_resolution(scene, foot, stride, B, r, neutral, clock, sim)
        return resolutions[-1] is not None and residuals[-1] <= resolutions[-1]

    stride, B, r, moved = evaluate(q, v, t)
    residuals, steps = [float(np.linalg.norm(r))], ["start"]
    resolutions: list[float | None] = [None]
    for n in range(iterations + 1):
        # the resolution is measured only in a search (iterations > 0), at each iterate above tol
        if residuals[-1] <= tol or (resolution and iterations and resolved_here(stride, B, r)) or n == iterations:
            break
        A = B.T @ stride.extended_jacobian() @ B - np.eye(B.shape[1])
        s = -np.linalg.lstsq(A, r, rcond=None)[0]
        accepted, scale = None, 1.0
        for k in range(line_search + 1):
            try:
                trial = evaluate(*moved_along(stride, B, scale * s))
            except (StrideError, InvalidInputError, InconsistentStateError):
                trial = None  # the step left the gait's domain (no touchdown, not approaching, penetrating)
            if trial is not None and np.linalg.norm(trial[2]) < residuals[-1]:
                accepted = (trial, "newton" if k == 0 else f"newton ×{scale:g}")
                break
            scale *= 0.5
        if accepted is None:
            q_next, _ = align(scene, stride.q, stride.q0, neutral)
            t_next = stride.t0 + math.remainder(stride.t - stride.t0, clock) if clock is not None else stride.t
            accepted = (evaluate(onto_section(scene, foot, q_next), stride.v, t_next), "fixed point")
        (stride, B, r, moved), label = accepted
        residuals.append(float(np.linalg.norm(r)))
        steps.append(label)
        resolutions.append(None)
    multipliers = _sorted_eigenvalues(B.T @ stride.extended_jacobian() @ B)
    converged = residuals[-1] <= tol or (resolutions[-1] is not None and residuals[-1] <= resolutions[-1])
    return PeriodicGait(
        foot=foot,
        t=stride.t0,
        q=stride.q0,
        v=stride.v0,
        stride=stride,
        residuals=residuals,
        steps=steps,
        multipliers=multipliers,
        neutral=tuple(neutral),
        converged=converged,
        drift=moved,
        run_time=time.perf_counter() - started,
        resolutions=resolutions,
        tol=tol,
    )


def _map_resolution(scene, foot, stride, B, r, neutral, clock, sim) -> float | None:
    """``2 |r - r_tight|``: twice the change of the reduced residual ``r`` of ``stride``
    when the stride is computed again at tolerances `RESOLUTION_TIGHTENING` times
    tighter (without its Jacobian), a bound on the error of ``r``
    (`find_periodic_gait`); None if those tolerances are below the stepper's floor
    (100 eps) or that stride fails."""
    rtol, atol = sim["rtol"] / RESOLUTION_TIGHTENING, np.asarray(sim["atol"]) / RESOLUTION_TIGHTENING
    if rtol < RTOL_MIN:
        return None
    try:
        again = stride_map(
            scene,
            foot,
            stride.q0,
            stride.v0,
            stride.t0,
            jacobian=False,
            **(sim | {"rtol": rtol, "atol": atol if atol.ndim else float(atol)}),
        )
    except (StrideError, InvalidInputError, InconsistentStateError):
        return None
    r_tight, _ = _reduced_residual(scene, again, B, neutral, clock)
    return 2.0 * float(np.linalg.norm(r - r_tight))
