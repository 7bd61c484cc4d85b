"""What a run records besides its states (part of `contactdiff.integration.trajectory`,
which re-exports every name): its events (`Event`, `EventKind`, the `NonSmooth`
reasons of a non-differentiable one), its segments of smooth flow (`Segment`), why
it ended (`Termination`) and its counters (`RunStats`). Times in seconds, states
as in the rest of the package."""

from __future__ import annotations

import bisect
from dataclasses import asdict, dataclass, field
from enum import Enum, StrEnum

import numpy as np

from ..errors import unknown_name


class EventKind(StrEnum):
    """What happened at an event. A `StrEnum`: each kind compares equal to its value
    (``event.kind == "touchdown"``), and prints, formats and writes to JSON as it."""

    TOUCHDOWN = "touchdown"
    """contacts close and stay closed (impact)"""
    LIFT_OFF = "lift-off"
    """an active contact's normal force reaches zero and it leaves"""
    SLIP = "slip"
    """a sticking contact's normal force reaches zero but leaving would let it sink, so it
    slides (normal row only) until a later lift-off, or a contact with Coulomb friction
    starts to slip (its tangential force reached the cone, or it stopped but friction
    cannot hold it)"""
    STICK = "stick"
    """a slipping contact stopped and sticks"""
    BOUNCE = "bounce"
    """an impact after which the contact leaves again"""
    GRAZING = "grazing"
    """a contact closes with zero normal speed"""
    ZENO = "zeno"
    """an impact below the Zeno speed, after which the contact stays closed"""
    BEAR = "bear"
    """a closed contact the others held at zero gap starts to bear (its compatible load
    turned to pushing: no impulse, `contactdiff.integration.held`)"""


EVENT_KINDS = tuple(EventKind)
"""Every `EventKind`, in the order of the sweeps' ``events:<kind>`` columns."""


class NonSmooth(Enum):
    """Why the flow is not differentiable at an event (it has only a piecewise-linear,
    Bouligand, derivative there)."""

    ORDER = "the landing orders of a simultaneous touchdown give different saltation matrices"
    GRAZING = "a contact closed with zero normal speed"
    ZENO_CASCADE = "an impact cascade was ended by the Zeno rule (a contact lifted slower than zeno_speed kept closed)"
    RESTING_CONTACT = (
        "a contact landed while a contact coupled to it through the inverse mass rested (closed "
        "with zero normal force): opened by a perturbation, the impact is a cascade with another "
        "outcome (`Event.outcomes`)"
    )
    FRICTION_THRESHOLD = (
        "the tangential force sits on the friction cone's boundary without crossing it "
        "(neighbouring runs stick or slip: the stick/slip threshold)"
    )
    PAINLEVE_JAM = (
        "a slip stopped at a dynamic jam (Painlevé: its normal force grew without bound as it "
        "stopped, `contactdiff.integration.jam`): the stop is taken at the last accepted state, "
        "and its saltation is that of a stop there, not a derivative through the jam"
    )
    FINAL_TIME = (
        "a contact touches at the final time with nonzero normal speed (neighbouring runs land "
        "before or after it: the final state has one-sided derivatives; "
        "`Trajectory.final_nonsmooth`, `contactdiff.integration.final_time`)"
    )


class Termination(StrEnum):
    """Why a run ended."""

    T_FINAL = "t_final"
    """it reached its final time"""
    MAX_EVENTS = "max_events"
    """the event budget ran out (`TooManyEventsError`)"""
    MAX_STEPS = "max_steps"
    """the step budget ran out (`TooManyStepsError`)"""
    STEP_COLLAPSE = "step_collapse"
    """the steps collapsed with no event (`StepCollapseError`)"""
    STOPPED = "stopped"
    """a terminal event stopped it (`HybridLoop.on_event`)"""


@dataclass(kw_only=True)
class RunStats:
    """Counters of one run.

    Attributes:
        steps, rejected_steps: accepted steps and rejected step attempts.
        dynamics_evaluations: mode solves by the vector field (stages, guards).
        stepper_evaluations, jacobian_evaluations: field and Jacobian calls of the steppers.
        derivative_evaluations: mode solves with derivatives.
        events, projections: events, and projections back onto the constraints.
        method: the ``method`` asked for; steps_by_method: accepted steps of each stepper.
        method_switches: ``[t, method]`` of every switch of ``method="auto"``.
        stiffness_probes, probe_evaluations: spectral-radius probes of ``"auto"``
            and the mode solves they cost.
        near_grazing_misses: near-grazing misses (see `SimulateOptions.grazing_gap`).
    """

    steps: int = 0
    rejected_steps: int = 0
    dynamics_evaluations: int = 0
    stepper_evaluations: int = 0
    jacobian_evaluations: int = 0
    derivative_evaluations: int = 0
    events: int = 0
    projections: int = 0
    method: str = ""
    steps_by_method: dict[str, int] = field(default_factory=dict)
    method_switches: list[list] = field(default_factory=list)
    stiffness_probes: int = 0
    probe_evaluations: int = 0
    near_grazing_misses: int = 0

    def to_dict(self) -> dict:
        """Every counter as a JSON-ready dict."""
        return asdict(self)


@dataclass(kw_only=True)
class Event:
    """One instant at which the contact mode changes.

    Attributes:
        t: time (s).
        kind: an `EventKind` (a string given is turned into one).
        contacts: names of the contacts whose guard fired.
        simultaneous: several guards fired within the simultaneity tolerance.
        q: configuration at the event.
        v_minus, v_plus: velocity before and after (equal without impact).
        impulses: normal impulse of every contact closed at the event (N s).
        mode_before, mode_after: names of the active contacts (sticking or sliding).
        normal_speeds: ``A_i v-`` of the firing contacts (m/s, negative when closing).
        saltation: saltation matrix Ξ (2nv × 2nv) when the Jacobian was asked for.
        time_gradient: derivative of the event time with respect to the initial
            state (2nv,), tangent space, when the Jacobian was asked for.
            (``saltation`` is also there when only parameters were asked for.)
        parameter_saltation: with parameters, the saltation's parameter block Ξ_p
            (2nv × p): ``∂x+/∂p = Ξ ∂x-/∂p + Ξ_p`` (`contactdiff.integration.parameter_jumps`).
        parameter_time_gradient: with parameters, the derivative of the event time
            with respect to them (s per unit of each, p,).
        reference_jump, parameter_reference_jump: at an event whose guard reads the forces
            while a slip from rest still follows its onset's reference ``θ``
            (`contactdiff.integration.band`), the term ``(F+ - F-) h_θ w / rate`` the flow
            Jacobian gains there besides the saltation: ``∂x+/∂x0 = Ξ ∂x-/∂x0 +
            reference_jump`` (2nv × 2nv, with the Jacobian) and ``∂x+/∂p = Ξ ∂x-/∂p + Ξ_p +
            parameter_reference_jump`` (2nv × p, with parameters); None elsewhere.
        nonsmooth: why the flow is not differentiable here, each `NonSmooth`
            reason with its remark (empty where it is differentiable).
        saltation_orders: at a simultaneous touchdown, the saltation matrix of
            every landing order (keys: contact names in landing order).
        sliding: the contacts of ``mode_after`` that slide (normal row only).
        outcomes: at an impact against a resting contact (`NonSmooth.RESTING_CONTACT`),
            the velocity after it (nv,) of each outcome: ``"simultaneous"`` (the run's,
            ``v_plus``) and ``"cascade"`` (the resting contacts opened by a perturbation;
            `contactdiff.integration.resting`).
    """

    t: float
    kind: EventKind
    contacts: tuple[str, ...]
    simultaneous: bool
    q: np.ndarray
    v_minus: np.ndarray
    v_plus: np.ndarray
    impulses: dict[str, float]
    mode_before: tuple[str, ...]
    mode_after: tuple[str, ...]
    normal_speeds: dict[str, float] = field(default_factory=dict)
    saltation: np.ndarray | None = None
    time_gradient: np.ndarray | None = None
    nonsmooth: dict[NonSmooth, str] = field(default_factory=dict)
    saltation_orders: dict | None = None
    sliding: tuple[str, ...] = ()
    parameter_saltation: np.ndarray | None = None
    parameter_time_gradient: np.ndarray | None = None
    outcomes: dict[str, np.ndarray] | None = None
    reference_jump: np.ndarray | None = None
    parameter_reference_jump: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.kind not in EVENT_KINDS:
            raise unknown_name("event kind", self.kind, EVENT_KINDS)
        self.kind = EventKind(self.kind)

    @property
    def differentiable(self) -> bool:
        """False where the flow has only a piecewise-linear (Bouligand) derivative:
        the landing orders of a simultaneous event disagree, a grazing touchdown,
        an impact cascade cut off by the Zeno rule, an impact against a resting
        contact, the stick/slip threshold (see ``nonsmooth``)."""
        return not self.nonsmooth

    def to_dict(self) -> dict:
        """JSON-ready form: arrays as lists, ``differentiable``, ``nonsmooth`` reasons by
        lower-case name, and the saltation matrices when the Jacobian was asked for."""
        extra = {}
        if self.saltation is not None:
            extra["saltation"] = self.saltation.tolist()
            if self.time_gradient is not None:
                extra["time_gradient"] = self.time_gradient.tolist()
        if self.parameter_saltation is not None:
            extra["parameter_saltation"] = self.parameter_saltation.tolist()
            if self.parameter_time_gradient is not None:
                extra["parameter_time_gradient"] = self.parameter_time_gradient.tolist()
        for name in ("reference_jump", "parameter_reference_jump"):
            if (value := getattr(self, name)) is not None:
                extra[name] = value.tolist()
        if self.outcomes:
            extra["outcomes"] = {name: v.tolist() for name, v in self.outcomes.items()}
        if self.saltation_orders:
            extra["saltation_orders"] = {" > ".join(k): m.tolist() for k, m in self.saltation_orders.items()}
        return extra | {
            "t": self.t,
            "kind": str(self.kind),
            "contacts": list(self.contacts),
            "simultaneous": self.simultaneous,
            "q": self.q.tolist(),
            "v_minus": self.v_minus.tolist(),
            "v_plus": self.v_plus.tolist(),
            "impulses": dict(self.impulses),
            "mode_before": list(self.mode_before),
            "mode_after": list(self.mode_after),
            "normal_speeds": dict(self.normal_speeds),
            "differentiable": self.differentiable,
            "sliding": list(self.sliding),
            "nonsmooth": {reason.name.lower(): remark for reason, remark in self.nonsmooth.items()},
        }


@dataclass(kw_only=True)
class Segment:
    """Smooth flow in one contact mode between two events (or the ends).

    Attributes:
        t0, t1: start and end time (s).
        mode: names of the active contacts (sticking or sliding).
        pieces: dense outputs of the accepted steps, each callable ``(t) -> (q, v)``
            with attributes ``t_old`` and ``t``.
    """

    t0: float
    t1: float
    mode: tuple[str, ...]
    pieces: list = field(default_factory=list, repr=False)
    sliding: tuple[str, ...] = ()

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """State ``(q, v)`` (nq,), (nv,) at time ``t`` (s) on the dense output of the step
        containing it (the first or last step's beyond the segment's ends)."""
        starts = [p.t_old for p in self.pieces]
        i = max(0, min(bisect.bisect_right(starts, t) - 1, len(self.pieces) - 1))
        q, v = self.pieces[i](t)
        return np.array(q, dtype=float), np.array(v, dtype=float)
