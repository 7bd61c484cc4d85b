"""What a mode's solve returns: its accelerations and forces (`ModeSolution`) and
their derivatives (`ModeDerivatives`); the solve is `contactdiff.dynamics.mode`'s."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class ModeSolution:
    """Accelerations and forces of one mode at one state.

    Attributes:
        ddq: joint accelerations (nv,), tangent space.
        forces: row forces (n_rows,), rows stacked in the order of ``active``.
        active: indices of the active contacts.
        row_slices: for each active contact, its slice of ``forces``.
    """

    ddq: np.ndarray
    forces: np.ndarray
    active: tuple[int, ...]
    row_slices: tuple[slice, ...]

    def normal_forces(self) -> np.ndarray:
        """Normal force of each active contact (N), in the order of ``active``."""
        return np.array([self.forces[s.start] for s in self.row_slices])

    def row_forces(self) -> list[np.ndarray]:
        """Row forces of each active contact (N: normal, then tangential), in the order
        of ``active``."""
        return [self.forces[s] for s in self.row_slices]


@dataclass
class ModeDerivatives:
    """Derivatives of a `ModeSolution` in the tangent space (each column a perturbation).

    ``ddq_dtau`` (nv × nv) and ``forces_dtau`` (n_rows × nv) are the responses to a
    generalised force added to the efforts (``M^-1`` in flight, the constrained
    inverse mass in contact): a parameter that enters as a generalised force ``∂f/∂p``
    moves the solution by ``ddq_dtau @ ∂f/∂p`` (`contactdiff.dynamics.parameter_forces`).
    """

    ddq_dq: np.ndarray
    ddq_dv: np.ndarray
    forces_dq: np.ndarray
    forces_dv: np.ndarray
    ddq_dtau: np.ndarray
    forces_dtau: np.ndarray
