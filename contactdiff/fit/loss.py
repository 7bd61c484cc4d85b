"""`Loss`: how a fit's residual rows count in its cost (least squares or a robust loss).

A few recordings far off (a chaotic window whose bounce the model cannot follow)
dominate a sum of squares; scipy's robust losses count a row's square ``z =
(r / f_scale)²`` through a ``ρ(z)`` that grows like ``z`` near zero and slower
beyond 1, so rows beyond ``f_scale`` weigh less. A robust loss needs a start
near the answer: far from it every row is beyond ``f_scale`` and the cost is
flat in the right direction.
"""

from __future__ import annotations

from enum import StrEnum

import numpy as np


class Loss(StrEnum):
    """How residual rows count in the cost (scipy's ``loss``, on ``z = (r / f_scale)²``):
    ``linear`` the sum of squares; ``soft_l1`` ``2(√(1+z) − 1)`` and ``huber`` (``z`` up to 1,
    ``2√z − 1`` beyond) grow linearly beyond ``f_scale``; ``cauchy`` ``ln(1 + z)``
    logarithmically: a few rows far off (a chaotic window) weigh less."""

    LINEAR = "linear"
    SOFT_L1 = "soft_l1"
    HUBER = "huber"
    CAUCHY = "cauchy"

    def cost(self, r: np.ndarray, f_scale: float) -> float:
        """Half the sum of ``f_scale² ρ((r / f_scale)²)`` (scipy's cost)."""
        z = (np.asarray(r) / f_scale) ** 2
        if self is Loss.LINEAR:
            rho = z
        elif self is Loss.SOFT_L1:
            rho = 2.0 * (np.sqrt(1.0 + z) - 1.0)
        elif self is Loss.HUBER:
            rho = np.where(z <= 1.0, z, 2.0 * np.sqrt(z) - 1.0)
        else:
            rho = np.log1p(z)
        return 0.5 * f_scale**2 * float(np.sum(rho))

    def weights(self, r: np.ndarray, f_scale: float) -> np.ndarray:
        """Each row's ``ρ'(z)``: the weight of its square in the Gauss–Newton step at ``r``
        (1 for ``linear``; for a robust loss below 1 beyond ``f_scale``)."""
        z = (np.asarray(r) / f_scale) ** 2
        if self is Loss.LINEAR:
            return np.ones_like(z)
        if self is Loss.SOFT_L1:
            return 1.0 / np.sqrt(1.0 + z)
        if self is Loss.HUBER:
            return np.where(z <= 1.0, 1.0, 1.0 / np.sqrt(np.maximum(z, 1.0)))
        return 1.0 / (1.0 + z)


__all__ = ["Loss"]
