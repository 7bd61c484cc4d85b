"""What the hybrid loop's event mixins share.

`contactdiff.integration.event_resets.EventResets`, `.friction_events.FrictionEvents`
and `.held.HeldEvents` are mixins of `contactdiff.integration.hybrid.HybridLoop`: they
read the loop's state and call each other's handlers. `LoopEvents`, their base, declares
that state once for the type checker (nothing of it exists at run time but through
`HybridLoop`) and records an event that moves no velocity by an impulse.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .trajectory import Event, EventKind

if TYPE_CHECKING:
    from ..dynamics.mode import ModeDynamics
    from ..model.contacts import BoundContact
    from ..model.kinematics import Kinematics
    from ..model.scene import Scene
    from .event_jacobians import EventJacobians
    from .guards import Guard
    from .options import SimulateOptions
    from .parameter_jumps import ParameterJumps


class LoopEvents:
    """Base of the loop's event mixins (module doc)."""

    if TYPE_CHECKING:  # the state they borrow from HybridLoop (set there), for the type checker only
        scene: Scene
        dyn: ModeDynamics
        kin: Kinematics
        contacts: list[BoundContact]
        names: list[str]
        options: SimulateOptions
        events: list[Event]
        notes: list[str]
        phi: np.ndarray | None
        n_state: int
        jumps: ParameterJumps | None
        sensitive: bool
        gap_tol: float
        onsets: dict[int, np.ndarray]
        band_dt: np.ndarray | None
        jacobians: EventJacobians

        def gaps_and_rates(self, q, v) -> tuple[np.ndarray, np.ndarray]:
            """Every contact's gap (m) and gap rate (m/s) at ``(q, v)`` (`HybridLoop.gaps_and_rates`)."""
            ...

        def _mode_names(self, mode) -> tuple[str, ...]: ...
        def _sliding_names(self, mode) -> tuple[str, ...]: ...
        def _note(self, text: str) -> str: ...
        def _friction_event(self, t, q, v, mode, fired: list[Guard]): ...
        def _bear_event(self, t, q, v, mode, bearing: list[int]): ...
        def _grip_event(self, t, q, v, mode, gripping: list[int]): ...
        def _onset_columns(self, t, q, found, moved: np.ndarray, dt: np.ndarray, new_mode) -> None: ...
        def _attach_sensitivity(
            self,
            event: Event,
            xi: np.ndarray,
            Dh: np.ndarray,
            F_minus: np.ndarray,
            h_t: float = 0.0,
            xi_p: np.ndarray | None = None,
            h_p: np.ndarray | None = None,
        ) -> None: ...

    def _impulseless_event(
        self, t: float, kind: EventKind, contacts, simultaneous: bool, q, v_minus, v_plus, mode, new_mode
    ) -> Event:
        """The record of an event at ``(t, q)`` with no impulse (a lift-off, a slip or a stop,
        a held contact bearing): ``contacts`` (scene keys) fired it, the velocity goes from
        ``v_minus`` to ``v_plus`` (m/s, rad/s; tangent space) by the rows the new mode holds
        only, and the mode from ``mode`` to ``new_mode`` (contact keys)."""
        return Event(
            t=t,
            kind=kind,
            contacts=self._mode_names(contacts),
            simultaneous=simultaneous,
            q=q.copy(),
            v_minus=v_minus.copy(),
            v_plus=v_plus.copy(),
            impulses={},
            mode_before=self._mode_names(mode),
            mode_after=self._mode_names(new_mode),
            sliding=self._sliding_names(new_mode),
        )
