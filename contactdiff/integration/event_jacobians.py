"""The flow Jacobian across a run's events: ``[I, 0]`` at the start, and just after an
event ``Ξ φ`` plus the parameters' block ``Ξ_p`` and the terms through a slip's reference
in the band (`Event.reference_jump`, `Event.parameter_reference_jump`).

``φ``'s columns are the state's ``n_state`` (2nv with ``jacobian``, else 0), then the
parameters'. The product ``Ξ φ`` is formed once per event, saltation matrix and ``φ``
(the same arrays): the onsets carried from an event (`HeldEvents._held_onsets`,
`EventResets._simultaneous_onsets`) and the stepper's restart after it read one product.
The hybrid loop holds one `EventJacobians` as ``jacobians``.
"""

from __future__ import annotations

import numpy as np

from .run_records import Event


class EventJacobians:
    """The flow Jacobian at the start and across events (module doc).

    Args:
        nv: the tangent space's dimension (the state has 2nv coordinates).
        n_state: ``φ``'s state columns (2nv with ``jacobian``, else 0).
        n_parameters: its parameter columns.
    """

    def __init__(self, nv: int, n_state: int, n_parameters: int):
        self.nv, self.n_state, self.n_parameters = nv, n_state, n_parameters
        self._last: tuple[Event, np.ndarray, np.ndarray, np.ndarray] | None = None  # `salted`'s

    def identity(self) -> np.ndarray:
        """The flow Jacobian at the start: ``[I, 0]`` (2nv × (2nv + p)); without the state's
        Jacobian, the p parameter columns only (zero)."""
        n = 2 * self.nv
        phi = np.zeros((n, self.n_state + self.n_parameters))
        phi[:, : self.n_state] = np.eye(n, self.n_state)
        return phi

    def after(self, phi: np.ndarray | None, event: Event) -> np.ndarray:
        """The flow Jacobian just after ``event`` from ``phi`` just before: ``Ξ phi``, plus
        ``Ξ_p`` on the parameter columns, plus the event's terms through a slip's reference in
        the band (``reference_jump``, ``parameter_reference_jump``: `Event`)."""
        assert phi is not None and event.saltation is not None  # called only in a sensitive run
        out = self.salted(phi, event).copy()
        n = self.n_state
        if event.parameter_saltation is not None:
            out[:, n:] += event.parameter_saltation
        if event.reference_jump is not None:
            out[:, :n] += event.reference_jump
        if event.parameter_reference_jump is not None:
            out[:, n:] += event.parameter_reference_jump
        return out

    def salted(self, phi: np.ndarray, event: Event) -> np.ndarray:
        """``Ξ phi``, ``event``'s saltation matrix times ``phi``, formed once per event,
        saltation matrix and ``phi`` (module doc). Read-only: copy it to write into it."""
        last = self._last
        if last is not None and last[0] is event and last[1] is event.saltation and last[2] is phi:
            return last[3]
        assert event.saltation is not None  # called only in a sensitive run
        product = event.saltation @ phi
        self._last = (event, event.saltation, phi, product)
        return product
