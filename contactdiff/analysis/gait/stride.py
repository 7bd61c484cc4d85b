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

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from ...dynamics.mode import ModeDynamics
from ...errors import InconsistentStateError, InvalidInputError, StrideError, check_number
from ...dynamics.impacts import choose_mode
from ...integration.hybrid import HybridLoop, simulate
from ...integration.options import SimulateOptions
from ...model.scene import Scene
from ...integration.sensitivity import gap_gradient, saltation, touchdown, vector_field
from ...integration.trajectory import Trajectory

NEUTRAL_NAMES = ("x", "y", "yaw")
"""Neutral moves: world translations along x and y, rotation about the vertical (free-flyer)."""

MIN_FLIGHT_SHARE = 0.05
"""Default ``min_flight`` of a clock-driven scene, as a share of its clock period."""

SECTION_TOL = 1e-9
"""Largest gap (m) of the foot at a state given as a point of the section; it is then closed exactly."""

RESOLUTION_TIGHTENING = 10.0
"""`find_periodic_gait` measures the map's resolution against the same stride at
``rtol`` and ``atol`` divided by this (a tenfold tightening at least halves the
integration error: DOP853's shrinks about 7.7 times, 10^(8/9))."""

_SYMMETRY_TOL = 1e-9  # relative change of gaps and accelerations under a neutral move that counts as none
_IMPACT_KINDS = ("touchdown", "bounce")

def _positive_duration(owner: str, name: str, value) -> float:
    x = check_number(owner, name, value, minimum=0.0)
    if x <= 0:
        raise InvalidInputError(f"{owner}: {name} must be > 0 s, got {value!r}")
    return x


# ----------------------------------------------------------------------------------
# results
# ----------------------------------------------------------------------------------
@dataclass
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

    def summary(self) -> dict:
        out = {"scene": self.scene_name, "foot": self.foot, "t0": self.t0, "t": self.t,
               "stride_time": self.stride_time, "q0": self.q0.tolist(), "v0": self.v0.tolist(),
               "q": self.q.tolist(), "v": self.v.tolist(), "period": self.period,
               "events": [f"{e.t:.12g} {e.kind} {'+'.join(e.contacts)}" for e in self.trajectory.events],
               "differentiable": self.differentiable, "simultaneous": list(self.simultaneous)}
        if self.jacobian is not None:
            out |= {"jacobian": self.jacobian.tolist(), "time_gradient": self.time_gradient.tolist(),
                    "start_time_column": self.start_time_column.tolist(),
                    "start_time_derivative": self.start_time_derivative}
        return out


@dataclass
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
        return (self.converged and self.tol is not None and self.residuals[-1] > self.tol
                and self.resolution is not None)

    def to_dict(self) -> dict:
        return {"foot": self.foot, "t": self.t, "q": self.q.tolist(), "v": self.v.tolist(),
                "stride_time": self.stride.stride_time, "period": self.stride.period,
                "residuals": list(self.residuals), "steps": list(self.steps),
                "resolutions": list(self.resolutions), "tol": self.tol, "resolved": self.resolved,
                "multipliers": [[float(m.real), float(m.imag)] for m in self.multipliers],
                "moduli": [float(abs(m)) for m in self.multipliers],
                "neutral": list(self.neutral), "converged": self.converged, "drift": dict(self.drift),
                "differentiable": self.stride.differentiable, "simultaneous": list(self.stride.simultaneous),
                "why_not_differentiable": self.why_not_differentiable(), "run_time": self.run_time}

    def why_not_differentiable(self) -> list[str]:
        """The stride's notes on its non-differentiable events (simultaneous landings
        whose orders disagree, cascades ended by the Zeno rule, grazing)."""
        return self.stride.trajectory.why_not_differentiable()

    def format(self) -> str:
        s = self.stride
        lines = [f"stride map of {s.scene_name}, section: touchdown of {self.foot} (state just before impact)",
                 f"  stride time {s.stride_time:.12g} s" + (f" (clock period {s.period:g} s)" if s.period else ""),
                 "  neutral moves removed: " + (", ".join(self.neutral) or "none")
                 + ("".join(f"; {k} {v:+.6g} per stride" for k, v in self.drift.items())),
                 "", "  iteration  step            residual   resolution"]
        resolutions = list(self.resolutions) + [None] * (len(self.residuals) - len(self.resolutions))
        for k, (step, r, res) in enumerate(zip(self.steps, self.residuals, resolutions)):
            lines.append(f"  {k:9d}  {step:<14}  {r:.3e}" + (f"  {res:.3e}" if res is not None else ""))
        if self.resolved:
            lines.append(f"  converged to the map's resolution: the residual {self.residuals[-1]:.2e} is below "
                         f"{self.resolution:.2e}, twice its change when this stride is computed again at "
                         f"{RESOLUTION_TIGHTENING:g} times tighter tolerances (a bound on its error); tol "
                         f"{self.tol:g} is below what the map resolves. A periodic gait to that accuracy "
                         "(up to the neutral moves)")
        elif self.converged:
            lines.append("  converged: a periodic gait (up to the neutral moves)")
        elif len(self.steps) == 1:
            lines.append("  one stride, no Newton iterations: the multipliers are those of this stride's map, "
                         "a stability measure only at a periodic gait (residual 0)")
        else:
            lines.append("  NOT converged: the multipliers are those of the last iterate"
                         + (f" (its residual {self.residuals[-1]:.2e} is above the map's resolution "
                            f"{self.resolution:.2e} there)" if self.resolution is not None else ""))
        lines += ["", f"  Floquet multipliers ({len(self.multipliers)}, section coordinates, by modulus):",
                  f"  {'#':>3}  {'real':>14}  {'imag':>14}  {'|λ|':>12}"]
        for k, m in enumerate(self.multipliers):
            lines.append(f"  {k:3d}  {m.real:14.8g}  {m.imag:14.8g}  {abs(m):12.8g}")
        top = max((abs(m) for m in self.multipliers), default=0.0)
        verdict = "stable (all inside the unit circle)" if top < 1 - 1e-9 else "not asymptotically stable"
        lines.append(f"  largest |λ| = {top:.8g}: {verdict}")
        if not s.differentiable:
            why = self.why_not_differentiable()
            lines.append("  note: an event of the stride is not differentiable; the multipliers are those of "
                         "the branch taken" + (":" if why else ""))
            lines += [f"    {n}" for n in why[:4]] + ([f"    ... {len(why) - 4} more"] if len(why) > 4 else [])
        if s.simultaneous:
            lines.append(f"  note: {', '.join(s.simultaneous)} land(s) at the same instant as {self.foot}: the "
                         "stride map is discontinuous there and these are one-sided multipliers (the other "
                         "feet landing later); choose a foot that lands alone")
        lines.append(f"  run time {self.run_time:.2f} s")
        return "\n".join(lines)


# ----------------------------------------------------------------------------------
# the clock, neutral moves, the section
# ----------------------------------------------------------------------------------
def scene_period(scene: Scene) -> float | None:
    """Clock period (s) of the scene's clock-driven efforts (those with a ``period``
    attribute), or None if it has none. Different periods are an error."""
    periods = {float(e.period) for e in scene.effort_specs if getattr(e, "period", None) is not None}
    if len(periods) > 1:
        raise InvalidInputError(f"scene {scene.name!r} has efforts with different clock periods "
                                f"{sorted(periods)}; pass period= explicitly")
    return periods.pop() if periods else None


def _resolve_period(scene: Scene, period) -> float | None:
    if period is None:
        return scene_period(scene)
    if period is False:
        return None
    value = check_number("stride map", "period", period, minimum=0.0)
    if value <= 0:
        raise InvalidInputError(f"stride map: period must be > 0 s, got {period!r}")
    return value


def _joint_jacobian_stack(scene: Scene, q: np.ndarray) -> np.ndarray:
    """Joint Jacobians (LOCAL_WORLD_ALIGNED: world axes at each joint origin), stacked, 6 rows per joint."""
    model, data = scene.model, scene.robot.new_data()
    pin.computeJointJacobians(model, data, q)
    return np.vstack([pin.getJointJacobian(model, data, j, pin.LOCAL_WORLD_ALIGNED).reshape(6, model.nv)
                      for j in range(1, model.njoints)])


def _neutral_vector(scene: Scene, q: np.ndarray, name: str) -> np.ndarray | None:
    """Tangent vector (nv,) of the neutral move ``name`` at ``q``, or None if the
    joints cannot realise it (every joint origin moving by it, no joint turning)."""
    nv = scene.nv
    if name == "yaw":
        if not scene.robot.floating_base:
            return None
        R = pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix()
        d = np.zeros(nv)
        d[3:6] = R.T @ np.array([0.0, 0.0, 1.0])  # base frame: rotation about the world vertical
        return d
    axis = {"x": 0, "y": 1}[name]
    jac = _joint_jacobian_stack(scene, q)
    target = np.zeros(jac.shape[0])
    target[axis::6] = 1.0
    d, *_ = np.linalg.lstsq(jac, target, rcond=None)
    return d if np.linalg.norm(jac @ d - target) <= 1e-9 * math.sqrt(target.size) else None


def _is_symmetry(scene: Scene, q: np.ndarray, v: np.ndarray, t: float, direction: np.ndarray) -> bool:
    """The gaps and the free-flight accelerations are unchanged by a finite move along ``direction``."""
    dyn = ModeDynamics(scene)
    moved = pin.integrate(scene.model, q, 0.3 * direction)
    g0, g1 = scene.gaps(q), scene.gaps(moved)
    a0, a1 = dyn.solve(q, v, t, ()).ddq, dyn.solve(moved, v, t, ()).ddq
    scale = 1.0 + max(np.abs(g0).max(initial=0.0), np.abs(a0).max(initial=0.0))
    return max(np.abs(g1 - g0).max(initial=0.0), np.abs(a1 - a0).max(initial=0.0)) <= _SYMMETRY_TOL * scale


def available_neutral(scene: Scene, q: np.ndarray | None = None, v: np.ndarray | None = None,
                      t: float = 0.0) -> tuple[str, ...]:
    """Neutral moves of `NEUTRAL_NAMES` the scene admits at ``(q, v, t)`` (default
    its initial state): realisable by the joints and leaving gaps and dynamics unchanged."""
    q = scene.q0 if q is None else np.asarray(q, dtype=float)
    v = scene.v0 if v is None else np.asarray(v, dtype=float)
    out = []
    for name in NEUTRAL_NAMES:
        d = _neutral_vector(scene, q, name)
        if d is not None and _is_symmetry(scene, q, v, t, d):
            out.append(name)
    return tuple(out)


def _check_neutral(scene: Scene, neutral, q, v, t) -> tuple[str, ...]:
    if neutral is None:
        return available_neutral(scene, q, v, t)
    if isinstance(neutral, str):
        neutral = [n for n in neutral.replace(",", " ").split() if n]
    names = tuple(neutral)
    for name in names:
        if name not in NEUTRAL_NAMES:
            raise InvalidInputError(f"unknown neutral move {name!r}; valid: {', '.join(NEUTRAL_NAMES)}")
    valid = available_neutral(scene, q, v, t)
    bad = [n for n in names if n not in valid]
    if bad:
        raise InvalidInputError(f"scene {scene.name!r} does not admit the neutral move(s) {', '.join(bad)} "
                                f"(not realisable by its joints, or not a symmetry); valid here: "
                                f"{', '.join(valid) or '(none)'}")
    return names


def neutral_directions(scene: Scene, q: np.ndarray, neutral: Sequence[str]) -> np.ndarray:
    """Tangent vectors (2nv × k) of the neutral moves at ``q`` (velocity part zero)."""
    cols = []
    for name in neutral:
        d = _neutral_vector(scene, q, name)
        if d is None:
            raise InvalidInputError(f"neutral move {name!r} is not realisable by the joints of {scene.name!r}")
        cols.append(np.concatenate([d, np.zeros(scene.nv)]))
    return np.array(cols).T.reshape(2 * scene.nv, len(cols))


def section_basis(scene: Scene, foot: str, q: np.ndarray, neutral: Sequence[str] = (),
                  period: float | None = None) -> np.ndarray:
    """Orthonormal section coordinates at ``q``: a basis (n × m) of the tangent
    vectors with ``Dh δx = 0`` (along the foot's guard) orthogonal to the neutral
    moves; with a clock (``period``) one more row and column for the phase τ.
    ``n = 2nv (+1)``, ``m = 2nv - 1 - len(neutral) (+1)``."""
    i = scene.contact_index(foot)
    Dh = gap_gradient(ModeDynamics(scene), q, i)
    constraints = np.vstack([Dh[None, :], neutral_directions(scene, q, neutral).T])
    # null space of the constraints: right singular vectors beyond their rank
    _, s, vt = np.linalg.svd(constraints)
    rank = int(np.sum(s > 1e-10 * max(s[0], 1.0)))
    B = vt[rank:].T
    if period is None:
        return B
    n, m = B.shape
    out = np.zeros((n + 1, m + 1))
    out[:n, :m] = B
    out[n, m] = 1.0
    return out


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


def _sorted_eigenvalues(A: np.ndarray) -> np.ndarray:
    lam = np.linalg.eigvals(A) if A.size else np.zeros(0, dtype=complex)
    return lam[np.lexsort((-lam.imag, -np.abs(lam)))].astype(complex)


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

    def __init__(self, scene, foot: int, t0, t_max, q0, v0, options: SimulateOptions,
                 min_stride: float = 0.0, min_flight: float = 0.0):
        super().__init__(scene, t0, t_max, q0, v0, options)
        self.foot, self.t_earliest, self.min_flight = foot, t0 + min_stride, min_flight
        # last time the foot was on the ground (s); the start counts as such, so a
        # foot a few nanometres up after a restart does not "land" at once
        self.last_contact = t0
        self.hit = None  # (event, mode before as keys, Φ just before)
        self.start = None  # (mode before, F- at the start, contacts landing with the foot)

    def initial_mode(self, q, v):
        n = len(self.events)
        mode, v_plus = super().initial_mode(q, v)
        if not (self.options.jacobian and len(self.events) > n and self.names[self.foot] in self.events[-1].contacts):
            return mode, v_plus
        start = self.events[-1]
        closed = [i for i in range(len(self.contacts)) if self.names[i] in start.impulses]
        _, rates = self._gaps_and_rates(start.q, v)
        landing = [i for i in closed if i != self.foot and rates[i] < -self.options.grazing_speed]
        before = choose_mode(self.dyn, start.q, v, self.t0,
                             [i for i in closed if i != self.foot and i not in landing])
        F_minus = vector_field(self.dyn, start.q, v, self.t0, before)
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
            self.notes.append(f"the start touchdown of {self.names[self.foot]} is simultaneous with "
                              f"{', '.join(self.names[k] for k in landing)}: one-sided derivative "
                              "(those landing at the same time or later)")
        else:
            Dh = gap_gradient(self.dyn, start.q, self.foot)
            F_plus = vector_field(self.dyn, start.q, v_plus, self.t0, mode)
            xi = saltation(start.saltation, Dh, F_minus, F_plus)
        start.saltation = self.initial_saltation = xi
        self.start = (before, F_minus, tuple(self.names[k] for k in landing))
        return mode, v_plus

    def on_event(self, event, mode_before, phi_before) -> bool:
        """The foot's touchdown that ends the stride is terminal; every event where the
        foot is on the ground moves the start of its flight."""
        stop = False
        if (self.names[self.foot] in event.contacts and event.kind not in ("lift-off", "slip")
                and event.t >= self.t_earliest and event.t - self.last_contact >= self.min_flight
                and self.hit is None):
            self.hit = (event, tuple(mode_before), phi_before)
            stop = True
        if self._touches(event):
            self.last_contact = event.t
        return stop

    def _touches(self, event) -> bool:
        """Whether the foot is on the ground at ``event`` (before, in or after it)."""
        name = self.names[self.foot]
        return (name in event.contacts or name in event.impulses or name in event.mode_before
                or name in event.mode_after)


def _foot_index(scene: Scene, foot: str) -> int:
    if not isinstance(scene, Scene):
        raise InvalidInputError(f"scene must be a Scene (see load_scene), got {scene!r}")
    return scene.contact_index(foot)


def onto_section(scene: Scene, foot: str, q: np.ndarray, tol: float = 1e-15) -> np.ndarray:
    """``q`` moved onto ``a_foot(q) = 0`` by Gauss–Newton along the gap gradient (tangent space)."""
    i = _foot_index(scene, foot)
    kin, contact, zero = scene.kinematics, scene.contacts[i], np.zeros(scene.nv)
    q = np.array(q, dtype=float)
    for _ in range(20):
        kin.update(q, zero)
        gap = contact.gap(kin)
        if abs(gap) <= tol:
            break
        row = contact.rows(kin)[0]
        if not row @ row > 0:
            raise InvalidInputError(f"the gap of {foot!r} does not depend on q here: no section to move onto")
        q = pin.integrate(scene.model, q, -row * gap / float(row @ row))
    return q


def stride_map(scene: Scene, foot: str, q, v, t: float = 0.0, *, t_max: float = 10.0,
               min_stride: float | None = None, min_flight: float | None = None,
               period: float | None = None, jacobian: bool = True,
               rtol: float = 1e-10, atol: float = 1e-12, method: str = "DOP853", max_events: int = 1000,
               **options) -> Stride:
    """The stride map of ``foot``: from just before one of its touchdowns to just before the next.

    Args:
        scene: the `Scene`.
        foot: name of the contact whose touchdowns bound the stride.
        q, v: start state on the section: the foot's gap within `SECTION_TOL` of 0
            (it is closed exactly) and approaching (``A_foot v < 0``); q (nq,), v (nv,).
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
        rtol, atol, method, max_events, **options: passed to the simulation (see `simulate`).

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
            "start from first_touchdown(...) or move q with onto_section(...)")
    if not rate < 0:
        raise InvalidInputError(
            f"stride map: {foot!r} must be approaching the ground at the start (normal speed < 0), "
            f"got {rate:.3e} m/s")
    q = onto_section(scene, foot, q)
    min_stride = (0.5 * clock if clock else 0.0) if min_stride is None else \
        check_number("stride map", "min_stride", min_stride, minimum=0.0)
    if min_stride >= t_max:
        raise InvalidInputError(f"stride map: min_stride ({min_stride:g} s) must be below t_max ({t_max:g} s)")
    return _run_stride(scene, i, q, v, t, t + t_max, clock, jacobian, require_start=True, min_stride=min_stride,
                       min_flight=_min_flight(min_flight, clock, "stride map"),
                       rtol=rtol, atol=atol, method=method, max_events=max_events, **options)


def _min_flight(value, clock: float | None, where: str) -> float:
    if value is None:
        return MIN_FLIGHT_SHARE * clock if clock else 0.0
    return check_number(where, "min_flight", value, minimum=0.0)


def first_touchdown(scene: Scene, foot: str, q=None, v=None, t: float = 0.0, *, t_max: float = 10.0,
                    min_flight: float | None = None, rtol: float = 1e-10, atol: float = 1e-12,
                    method: str = "DOP853", max_events: int = 1000,
                    **options) -> tuple[float, np.ndarray, np.ndarray]:
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
    s = _run_stride(scene, i, q, v, t, t + _positive_duration("first touchdown", "t_max", t_max),
                    None, False, require_start=False,
                    min_flight=_min_flight(min_flight, scene_period(scene), "first touchdown"),
                    rtol=rtol, atol=atol, method=method, max_events=max_events, **options)
    return s.t, s.q, s.v


def _run_stride(scene, i, q, v, t0, t_end, clock, jacobian, require_start, min_stride: float = 0.0,
                min_flight: float = 0.0, **options) -> Stride:
    foot = scene.contact_names[i]
    run = StrideLoop(scene, i, t0, t_end, q, v, SimulateOptions(jacobian=jacobian).replace(**options),
                     min_stride=min_stride, min_flight=min_flight)
    traj = run.run()
    if run.hit is None:
        seen = ", ".join(f"{e.kind} {'+'.join(e.contacts)} at {e.t:.6g}" for e in traj.events[-6:]) or "none"
        raise StrideError(f"{foot!r} did not touch down again between t = {t0:g} and t_max = {t_end:g} s "
                          f"(last events: {seen}); raise t_max or check that the gait returns to the ground")
    event, mode, phi = run.hit
    if event.kind not in _IMPACT_KINDS:
        raise StrideError(f"the touchdown of {foot!r} at t = {event.t:.12g} is a {event.kind} event "
                          f"(normal speed {event.normal_speeds.get(foot, float('nan')):.3e} m/s): the section "
                          "is not crossed transversally, so the stride map has no derivative there")
    if require_start and (not traj.events or traj.events[0].t != t0 or foot not in traj.events[0].contacts):
        raise StrideError(f"no impact of {foot!r} at the start t = {t0:g}: the start is not a touchdown")
    t, q1, v1 = event.t, event.q.copy(), event.v_minus.copy()
    J = tg = col = dt = None
    if jacobian:
        dyn = run.dyn
        Dh = gap_gradient(dyn, q1, i)
        F = vector_field(dyn, q1, v1, t, mode)
        rate = float(Dh @ F)
        project = np.eye(F.size) - np.outer(F, Dh) / rate
        J = project @ phi
        tg = -(Dh @ phi) / rate
        F0 = run.start[1] if run.start is not None else vector_field(dyn, q, v, t0, ())
        col = -(project @ (phi @ F0))
        dt = float(Dh @ (phi @ F0)) / rate
        for x in (J, tg, col):
            if not np.all(np.isfinite(x)):
                raise StrideError(f"the stride Jacobian of {foot!r} is not finite (touchdown rate {rate:.3e})")
    together = set(run.start[2] if run.start is not None else ()) | set(event.contacts)
    return Stride(scene.name, foot, t0, traj.q0.copy(), traj.v0.copy(), t, q1, v1, J, tg, col, dt,
                  clock, traj, tuple(sorted(together - {foot})))


# ----------------------------------------------------------------------------------
# periodic gaits
# ----------------------------------------------------------------------------------
def _yaw(q: np.ndarray) -> float:
    R = pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix()
    return math.atan2(R[1, 0], R[0, 0])


def align(scene: Scene, q: np.ndarray, q_ref: np.ndarray, neutral: Sequence[str]) -> tuple[np.ndarray, dict]:
    """``q`` moved by the neutral moves so that its base yaw and centre-of-mass x, y
    match ``q_ref``'s (only the moves in ``neutral``); also returns the move undone
    (``{"x": m, "y": m, "yaw": rad}``, the part of ``q`` beyond ``q_ref``)."""
    model, data = scene.model, scene.robot.new_data()
    q = np.array(q, dtype=float)
    moved = {}
    if "yaw" in neutral:
        dpsi = math.atan2(math.sin(_yaw(q) - _yaw(q_ref)), math.cos(_yaw(q) - _yaw(q_ref)))
        q = pin.integrate(model, q, -dpsi * _neutral_vector(scene, q, "yaw"))
        moved["yaw"] = dpsi
    com, com_ref = pin.centerOfMass(model, data, q).copy(), pin.centerOfMass(model, data, q_ref).copy()
    for name, axis in (("x", 0), ("y", 1)):
        if name in neutral:
            shift = float(com[axis] - com_ref[axis])
            q = pin.integrate(model, q, -shift * _neutral_vector(scene, q, name))
            moved[name] = shift
    return q, moved


def _reduced_residual(scene, stride, B, neutral, clock) -> tuple[np.ndarray, dict]:
    q_aligned, moved = align(scene, stride.q, stride.q0, neutral)
    delta = np.concatenate([pin.difference(scene.model, stride.q0, q_aligned), stride.v - stride.v0])
    if clock is not None:
        delta = np.append(delta, math.remainder(stride.t - stride.t0, clock))
    return B.T @ delta, moved


def find_periodic_gait(scene: Scene, foot: str, q=None, v=None, t: float = 0.0, *,
                       iterations: int = 8, tol: float = 1e-9, neutral: Sequence[str] | None = None,
                       period: float | None = None, t_max: float = 10.0, min_stride: float | None = None,
                       min_flight: float | None = None, warmup: float = 0.0,
                       line_search: int = 4, resolution: bool = True, rtol: float = 1e-10,
                       atol: float = 1e-12, method: str = "DOP853", **options) -> PeriodicGait:
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
        scene, foot: the scene and the contact whose touchdowns define the section.
        q, v, t: start; if not on the section (default: the scene's initial state),
            it is first carried to the foot's next touchdown (`first_touchdown`).
        warmup: time (s) simulated from the start before that (no sensitivities): a
            stable gait settles towards its cycle on its own, by a factor of about
            the largest multiplier's modulus per stride, and Newton then starts near it.
        iterations: largest number of Newton steps.
        tol: stop when ``|r|`` is below this (mixed units, see `PeriodicGait.residuals`).
        neutral: neutral moves removed (default: those the scene admits, `available_neutral`).
        period: clock period (s); default from the scene (`scene_period`).
        t_max: longest stride (s).
        min_stride, min_flight: shortest stride and shortest flight before the
            touchdown that ends it (s), see `stride_map`.
        line_search: halvings of a Newton step before the fixed-point fallback.
        resolution: also stop where the residual is within the map's resolution
            (above); False stops only at ``tol``.
        rtol, atol, method, **options: simulation options.

    Returns:
        The `PeriodicGait` with the residual of every iterate and the multipliers at the last one.
    """
    started = time.perf_counter()
    i = _foot_index(scene, foot)
    iterations = int(check_number("find_periodic_gait", "iterations", iterations, minimum=0))
    tol = check_number("find_periodic_gait", "tol", tol, minimum=0.0)
    clock = _resolve_period(scene, period)
    warmup = check_number("find_periodic_gait", "warmup", warmup, minimum=0.0)
    sim = dict(t_max=t_max, min_stride=min_stride, min_flight=min_flight, period=False if clock is None else clock,
               rtol=rtol, atol=atol, method=method, **options)
    q = scene.q0 if q is None else np.array(q, dtype=float)
    v = scene.v0 if v is None else np.array(v, dtype=float)
    if warmup > 0:
        settled = simulate(scene, t + warmup, q, v, t0=t, rtol=rtol, atol=atol, method=method, **options)
        t, q, v = settled.t, settled.q, settled.v
    kin = scene.kinematics
    kin.update(q, v)
    if warmup > 0 or abs(scene.contacts[i].gap(kin)) > SECTION_TOL or not scene.contacts[i].rows(kin)[0] @ v < 0:
        t, q, v = first_touchdown(scene, foot, q, v, t, t_max=t_max,
                                  min_flight=_min_flight(min_flight, clock, "find_periodic_gait"),
                                  rtol=rtol, atol=atol, method=method, **options)
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
        v1 = stride.v0 + step[nv:2 * nv]
        t1 = stride.t0 + (step[2 * nv] if clock is not None else 0.0)
        return q1, v1, t1

    def resolved_here(stride, B, r) -> bool:
        """Measure the map's resolution at this iterate; whether the residual is within it."""
        resolutions[-1] = _map_resolution(scene, foot, stride, B, r, neutral, clock, sim)
        return resolutions[-1] is not None and residuals[-1] <= resolutions[-1]

    stride, B, r, moved = evaluate(q, v, t)
    residuals, steps, resolutions = [float(np.linalg.norm(r))], ["start"], [None]
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
    return PeriodicGait(foot, stride.t0, stride.q0, stride.v0, stride, residuals, steps, multipliers,
                        tuple(neutral), converged, moved, time.perf_counter() - started, resolutions, tol)


def _map_resolution(scene, foot, stride, B, r, neutral, clock, sim) -> float | None:
    """``2 |r - r_tight|``: twice the change of the reduced residual ``r`` of ``stride``
    when the stride is computed again at tolerances `RESOLUTION_TIGHTENING` times
    tighter (without its Jacobian), a bound on the error of ``r``
    (`find_periodic_gait`); None if those tolerances are below the stepper's floor
    (100 eps) or that stride fails."""
    rtol, atol = sim["rtol"] / RESOLUTION_TIGHTENING, np.asarray(sim["atol"]) / RESOLUTION_TIGHTENING
    if rtol < 100 * np.finfo(float).eps:
        return None
    try:
        again = stride_map(scene, foot, stride.q0, stride.v0, stride.t0, jacobian=False,
                           **(sim | {"rtol": rtol, "atol": atol if atol.ndim else float(atol)}))
    except (StrideError, InvalidInputError, InconsistentStateError):
        return None
    r_tight, _ = _reduced_residual(scene, again, B, neutral, clock)
    return 2.0 * float(np.linalg.norm(r - r_tight))


# ----------------------------------------------------------------------------------
# the stroboscopic map
# ----------------------------------------------------------------------------------
@dataclass
class PeriodMap:
    """The stroboscopic map ``x(t0) -> x(t0 + period)`` of a clock-driven scene.

    Attributes:
        t0, q0, v0, t, q, v: start and end.
        jacobian: the flow Jacobian over one period (2nv × 2nv, tangent space).
        multipliers: eigenvalues of ``Bᵀ J B`` with ``B`` orthonormal to the neutral
            moves, by decreasing modulus (the map of an autonomous scene has one
            more multiplier 1, along the flow).
        trajectory: the run.
    """

    t0: float
    q0: np.ndarray
    v0: np.ndarray
    t: float
    q: np.ndarray
    v: np.ndarray
    jacobian: np.ndarray
    multipliers: np.ndarray
    trajectory: Trajectory = field(repr=False)


def period_map(scene: Scene, q=None, v=None, t: float = 0.0, *, period: float | None = None,
               neutral: Sequence[str] | None = None, rtol: float = 1e-10, atol: float = 1e-12,
               **options) -> PeriodMap:
    """The state after one clock period and its Jacobian (the stroboscopic Poincaré map).

    Args:
        scene: the `Scene`; q, v, t: start (default the scene's initial state, t = 0).
        period: the period (s); default the scene's clock period (`scene_period`).
        neutral: neutral moves removed from the multipliers (default `available_neutral`).
        rtol, atol, **options: passed to `simulate`.
    """
    clock = _resolve_period(scene, period)
    if clock is None:
        raise InvalidInputError(f"scene {scene.name!r} has no clock-driven effort; pass period= (s)")
    q = scene.q0 if q is None else np.array(q, dtype=float)
    v = scene.v0 if v is None else np.array(v, dtype=float)
    t = check_number("period map", "t", t)
    traj = simulate(scene, t + clock, q, v, t0=t, jacobian=True, rtol=rtol, atol=atol, **options)
    neutral = _check_neutral(scene, neutral, q, v, t)
    N = neutral_directions(scene, q, neutral)
    if N.shape[1]:
        _, s, vt = np.linalg.svd(N.T)
        B = vt[int(np.sum(s > 1e-10)):].T
    else:
        B = np.eye(2 * scene.nv)
    return PeriodMap(t, traj.q0, traj.v0, traj.t, traj.q, traj.v, traj.jacobian,
                     _sorted_eigenvalues(B.T @ traj.jacobian @ B), traj)
