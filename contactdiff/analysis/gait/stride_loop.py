"""The hybrid loop of one stride (`StrideLoop`): stopped at a foot's touchdown,
keeping the flow Jacobian just before it (the mathematics, the full saltation
matrix at the start, is in `contactdiff.analysis.gait.stride`)."""

from __future__ import annotations

import numpy as np

from ...dynamics.impacts import choose_mode
from ...errors import InvalidInputError
from ...integration.hybrid import HybridLoop
from ...integration.options import SimulateOptions
from ...integration.parameter_jumps import ParameterJumps
from ...integration.sensitivity import gap_gradient, saltation, touchdown, vector_field
from ...integration.trajectory import Event, EventKind


class StrideLoop(HybridLoop):
    """The hybrid loop, stopped at the first touchdown of one contact after ``t0``
    that follows at least ``min_stride`` and a flight of at least ``min_flight``
    (a terminal event, `HybridLoop.on_event`).

    Records the state and flow Jacobian just before that impact, and replaces the
    reset Jacobian of an impact at ``t0`` by the full saltation matrix of the
    foot's guard (see `contactdiff.analysis.gait.stride`)."""

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
        saltation matrix of the foot's guard (`contactdiff.analysis.gait.stride`)."""
        n = len(self.events)
        mode, v_plus = super().initial_mode(q, v)
        if not (self.options.jacobian and len(self.events) > n and self.names[self.foot] in self.events[-1].contacts):
            return mode, v_plus
        start = self.events[-1]
        closed = [i for i in range(len(self.contacts)) if self.names[i] in start.impulses]
        _, rates = self.gaps_and_rates(start.q, v)
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
            if self.jumps is not None:  # the same guard term for the parameters (stride's notes)
                start.parameter_saltation = ParameterJumps.saltation(
                    start.parameter_saltation,
                    self.jumps.gap_guard(self.foot),
                    start.saltation,
                    F_minus,
                    F_plus,
                    float(Dh @ F_minus),
                )
        start.saltation = xi
        self.initial_saltation = self.jacobian_after(start)
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
