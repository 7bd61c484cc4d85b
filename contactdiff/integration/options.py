"""The options of a simulation: one frozen object, validated once.

`SimulateOptions` is what `simulate`, the hybrid loop and the stride map share;
`simulate(scene, T, rtol=1e-10)` builds one from keywords, and
``options.replace(rtol=1e-10)`` changes a few fields of an existing one.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from ..errors import InvalidInputError, check_count, check_member, check_number
from ..ode.factory import METHODS

AUTO = "auto"
SIMULATE_METHODS = (AUTO,) + METHODS
"""Valid ``method`` names: ``"auto"`` (`contactdiff.ode.method_choice`) or a stepper."""
MAX_STEPS = 200_000
"""Default step budget (accepted steps)."""
RTOL_MIN = 100 * np.finfo(float).eps
"""Smallest relative tolerance: below it the steps' own round-off exceeds the tolerance."""
RTOL_MAX = 0.1
"""Largest relative tolerance: beyond it a step's error estimate no longer means anything."""
ATOL_MAX = 0.1
"""Largest absolute tolerance (m, rad, m/s): beyond it the error of a step can exceed the
sizes of the robots the tolerance guards (foot heights, link lengths)."""


class OnGrazing(StrEnum):
    """What a grazing touchdown or a near-grazing miss does."""

    EVENT = "event"
    """record a ``grazing`` event (a miss: a note) and go on"""
    RAISE = "raise"
    """raise `GrazingError`"""


class JacobianError(StrEnum):
    """Which errors choose the steps of a run that carries a flow Jacobian."""

    CONTROL = "control"
    """the state's and the flow Jacobian's: a step is accepted only if both local
    errors are within the tolerances (CVODES' ``errconS = true``)"""
    STATE = "state"
    """the state's alone (CVODES' ``errconS = false``): the steps are those of the run
    without the Jacobian, which is propagated over them by the same method"""


@dataclass(frozen=True, kw_only=True)
class SimulateOptions:
    """Options of `simulate` (and of the stride map, which runs the same loop).

    Attributes:
        rtol, atol: error tolerances of each step (relative, in [`RTOL_MIN`,
            `RTOL_MAX`]; absolute in m, rad, m/s, in (0, `ATOL_MAX`]).
        method: ``"auto"`` (explicit DOP853, switching to Radau IIA while the
            explicit steps are limited by stability rather than accuracy, see
            `contactdiff.ode.method_choice`; the steps of each are in
            ``traj.stats``) or a stepper of `METHODS` used throughout
            (``"Radau"`` for stiff scenes).
        jacobian: also compute the flow Jacobian ``traj.jacobian`` (d x(t_final) /
            d x0, tangent space) and each event's saltation matrix and time gradient.
        jacobian_error: a `JacobianError` (or its value), with ``jacobian`` or
            ``parameters``: ``"control"`` chooses each step from the state's and the flow
            Jacobian's local errors; ``"state"`` from the state's alone, so the steps, the
            events and the state are those of the run without derivatives and the
            Jacobian is the exact derivative of that discrete run (on vector spaces) but
            its own error is not controlled (see docs/design.md for when that loses
            accuracy and how much it saves).
        parameters: names of scene parameters (`Scene.parameter_names`) to
            differentiate with respect to: ``traj.parameter_jacobian`` (d x(t_final) /
            d p) and each event's parameter blocks. Without ``jacobian`` only those
            columns are propagated (cheaper than the state's 2nv); with it, both.
        max_events: largest number of events before `TooManyEventsError`.
        max_steps: largest number of accepted steps (>= 1) before `TooManyStepsError`
            (its ``.trajectory`` holds the run so far); the default `MAX_STEPS`
            lets a quadruped trot run for two minutes of simulated time (about
            1,500 steps per second) and stops a runaway run (steps far shorter
            than the horizon: a body spinning at 1e6 rad/s needs 1e-6-s steps).
        simultaneous_tol: guards crossing within this time of the first (s) form
            one simultaneous event.
        zeno_speed: a contact closing slower than this (m/s) does not bounce: the
            sequence ends and it stays closed.
        grazing_speed: a touchdown slower than this (m/s) is grazing.
        on_grazing: an `OnGrazing` (or its value): ``"event"`` records a grazing
            event and goes on; ``"raise"`` raises `GrazingError`, also for a
            near-grazing miss (see ``grazing_gap``).
        grazing_gap: a contact whose gap comes down to within this distance (m) of
            0 and turns back up is a near-grazing miss: the integration error cannot
            tell whether it touched (a note, counted in ``stats.near_grazing_misses``,
            or `GrazingError`); default 10 (atol + rtol |q|_inf) at that step.
        project_tol: active-gap drift (m) beyond which the state is projected back
            onto the constraints; default ``atol``.
        max_step: largest step (s).
        dense: keep every step's interpolant, so that ``traj.at`` and ``traj.sample``
            give the state at any time (kB a step, tens of thousands of steps a
            minute on a quadruped trot); without it a run keeps its events,
            segments and final state only, nothing per step.
        sample_times: times (s) at which to record the state, and with ``jacobian`` or
            ``parameters`` the flow Jacobian, on ``traj.samples`` (a `Samples`), from
            the same run; finite, non-decreasing, within ``[t0, t_final]`` (checked by
            `simulate`). Steps end on them (`contactdiff.integration.samples`). A sample
            at an event's time takes the state after the event.
        progress: called after every accepted step as ``progress(t, events, steps)``
            (time in s, events and accepted steps so far), e.g. to draw a progress
            bar; ``None`` for none.

    Raises:
        InvalidInputError: a bad value (the message names the field and its valid range).
    """

    rtol: float = 1e-8
    atol: float = 1e-10
    method: str = AUTO
    jacobian: bool = False
    jacobian_error: JacobianError = JacobianError.CONTROL
    parameters: tuple[str, ...] = ()
    max_events: int = 10_000
    max_steps: int = MAX_STEPS
    simultaneous_tol: float = 1e-9
    zeno_speed: float = 1e-6
    grazing_speed: float = 1e-9
    on_grazing: OnGrazing = OnGrazing.EVENT
    grazing_gap: float | None = None
    project_tol: float | None = None
    max_step: float = np.inf
    dense: bool = False
    sample_times: tuple[float, ...] = ()
    progress: Callable[[float, int, int], None] | None = None

    def __post_init__(self) -> None:
        set_ = object.__setattr__  # frozen: normalise each field once
        if self.method not in SIMULATE_METHODS:
            raise InvalidInputError(f"unknown method {self.method!r}; valid: {', '.join(SIMULATE_METHODS)}")
        set_(self, "on_grazing", check_member("on_grazing", self.on_grazing, OnGrazing))
        set_(self, "jacobian_error", check_member("jacobian_error", self.jacobian_error, JacobianError))
        set_(self, "rtol", _in_range("rtol", self.rtol, RTOL_MIN, RTOL_MAX))
        set_(self, "atol", _in_range("atol", self.atol, 0.0, ATOL_MAX, open_low=True))
        set_(self, "jacobian", bool(self.jacobian))
        names = (self.parameters,) if isinstance(self.parameters, str) else self.parameters
        try:
            names = tuple(names)
        except TypeError:
            raise InvalidInputError(f"simulate: parameters must be parameter names, got {self.parameters!r}") from None
        if not all(isinstance(n, str) for n in names):
            raise InvalidInputError(f"simulate: parameters must be parameter names (str), got {self.parameters!r}")
        if len(set(names)) != len(names):
            raise InvalidInputError(f"simulate: parameters name one twice: {self.parameters!r}")
        set_(self, "parameters", names)
        set_(self, "dense", bool(self.dense))
        set_(self, "sample_times", _sample_times(self.sample_times))
        set_(self, "max_events", check_count("simulate", "max_events", self.max_events))
        set_(self, "max_steps", check_count("simulate", "max_steps", self.max_steps, minimum=1))
        for name in ("simultaneous_tol", "zeno_speed", "grazing_speed"):
            set_(self, name, check_number("simulate", name, getattr(self, name), minimum=0.0))
        if self.grazing_gap is not None:
            set_(self, "grazing_gap", check_number("simulate", "grazing_gap", self.grazing_gap, minimum=0.0))
        if self.project_tol is not None:
            set_(self, "project_tol", _in_range("project_tol", self.project_tol, 0.0, np.inf, open_low=True))
        set_(self, "max_step", check_number("simulate", "max_step", self.max_step, allow_inf=True))
        if not self.max_step > 0:
            raise InvalidInputError(f"simulate: max_step must be > 0 s, got {self.max_step!r}")
        if self.progress is not None and not callable(self.progress):
            raise InvalidInputError(f"simulate: progress must be a callable or None, got {self.progress!r}")

    def replace(self, **changes) -> SimulateOptions:
        """A copy with some fields changed; an unknown name lists the valid ones."""
        unknown = sorted(set(changes) - set(field_names()))
        if unknown:
            raise InvalidInputError(
                f"unknown simulation option(s) {', '.join(unknown)}; valid: {', '.join(field_names())}"
            )
        return dataclasses.replace(self, **changes)

    @property
    def resolved_project_tol(self) -> float:
        """``project_tol``, or ``atol`` where it was left at its default."""
        return self.atol if self.project_tol is None else self.project_tol


def field_names() -> list[str]:
    """Names of the fields of `SimulateOptions`."""
    return [f.name for f in dataclasses.fields(SimulateOptions)]


def _sample_times(times) -> tuple[float, ...]:
    """``sample_times`` as a tuple of finite, non-decreasing floats (s); None: none."""
    if times is None:
        return ()
    try:
        values = np.asarray(times, dtype=float)
    except (TypeError, ValueError):
        raise InvalidInputError(f"simulate: sample_times must be a sequence of times (s), got {times!r}") from None
    if values.ndim != 1:
        raise InvalidInputError(f"simulate: sample_times must be a 1-D sequence of times (s), got shape {values.shape}")
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        k = bad[0]
        raise InvalidInputError(f"simulate: sample_times[{k}] = {float(values[k])!r} is not a finite time (s)")
    back = np.flatnonzero(np.diff(values) < 0.0)
    if back.size:
        k = back[0] + 1
        raise InvalidInputError(
            f"simulate: sample_times must be non-decreasing; sample_times[{k}] = "
            f"{float(values[k])!r} s comes after sample_times[{k - 1}] = "
            f"{float(values[k - 1])!r} s"
        )
    return tuple(float(t) for t in values)


def _in_range(name: str, value, low: float, high: float, *, open_low: bool = False) -> float:
    x = check_number("simulate", name, value)
    if not (low < x if open_low else low <= x) or x > high:
        interval = f"({low:g}, {high:g}]" if open_low else f"[{low:.3g}, {high:g}]"
        raise InvalidInputError(f"simulate: {name} must be in {interval}, got {value!r}")
    return x
