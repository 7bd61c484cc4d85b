"""A contact slipping with Coulomb friction: its slip direction and force row.

A contact with friction coefficient ``μ`` that slips keeps its normal row
``A_n`` as a constraint (zero normal acceleration) and carries the force
``λ_N (n - μ s)`` at the contact point: in generalised coordinates
``F^T λ_N`` with the *force row*

    F = A_n - μ s^T A_T,

``A_T`` the contact's tangential rows (one on a planar model, two in 3-D,
with the rolling terms of a round contact) and ``s`` the unit slip direction
in tangent coordinates (`slip_direction`).

**Slip direction.** In 3-D, ``s = u_T / ||u_T||`` with ``u_T = A_T v`` the
slip velocity; on a planar contact ``s = ±1`` is fixed for the whole slip.
The 3-D direction is continued through the stop: where ``u_T`` points against
the contact's *reference* ``r`` (its direction at the last accepted step that
ended outside the band below), past
the stop, ``s`` is ``r`` itself, as on a planar contact, so the stop is the zero
of ``r · u_T``, a sign change the guards locate like any other. Not
``-u_T / ||u_T||``, the continuation along the slip's own direction: past the
stop that field pushes ``u_T`` away from its line (a transverse slip ``w``
grows as ``ẇ = μ λ_N w / (m ||u_T||)``, the mirror of the damping that turns a
slip onto its final direction before the stop), so the stages of a step that
crosses the stop amplify their round-off there, and the step's interpolant
carried that error back to before the stop: stop times 100 times the
integration tolerance off, which differed with the last bits of the
arithmetic (the BLAS kernel). Below a floor ``ε`` (`SLIP_SPEED_EPS`; the hybrid loop raises it to its
``zeno_speed``, above the integration error of ``u_T``) ``s`` is the reference
``r`` itself: at the onset of a slip from sticking ``u_T`` grows from 0 and its
direction there is noise. Between ``ε`` and ``2ε`` it turns from ``r`` to the
slip's own direction ``ŵ`` along ``b = a ŵ + (1 - a) r``, ``s = b / ||b||``,
with the smooth step ``a(x)``, ``x = ||u_T|| / ε - 1`` (`_turn`): the field is
smooth through the band (a slip whose direction is not the reference's would
otherwise jump there, and no step could cross it), and exact above ``2ε``.
``a`` is C^∞ (every derivative zero at both ends), not the cubic ``3x² - 2x³``:
the cubic left the field's Jacobian with a kink at each end of the band, and a
slip that starts from rest with its reference at an angle to the direction it
grows in (the sticking force's direction, where the tangential inverse mass is
not isotropic) creeps at a speed just above ``ε`` while it turns, so every step
straddled the kink and the flow Jacobian's error estimate did not shrink with
the step (steps of 1e-10 s: a collapse).
Inside the band ``r`` stays as it entered (`ModeField.advance`): the turn is
then a function of the state, the flow of one vector field. Set to ``s`` after
every accepted step there, it turned ``s`` by a share ``a`` of the remaining
angle *per step*, a field that changed between steps: the steps' first stage
and Jacobian (kept from the step before) belonged to the old field, and with
the flow Jacobian's error controlled its estimate did not shrink with the step
(``ds/du_T`` is of order ``|ŵ - r| / ε`` there): a slip that started from
rest at an angle to its reference collapsed the steps, and the flow Jacobian
ignored how ``r`` depended on the steps.
The reference of a slip from rest is a function of the onset's state, held: the
flow Jacobian carries ``∂s/∂r`` (`reference_turn`) times ``r``'s derivative at the
onset (`contactdiff.integration.mode_field.ModeField`, docs/design.md).

**Painlevé's paradox.** With one slipping contact the normal force solves
``g λ_N = -b`` with ``g = A_n M^-1 F^T``: where ``g <= 0`` a normal force
pushes the contact *into* the ground, and the sliding problem has no solution
(``b < 0``) or two (``b > 0``). `PainleveError` names it (`painleve_check`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..errors import PainleveError

if TYPE_CHECKING:
    from ..model.contacts import BoundContact

SLIP_SPEED_EPS = 1e-10
"""m/s: a 3-D slip slower than this takes its direction from the reference (a
slip just starting from sticking; round-off in the slip velocity of a unit-scale
model is about 1e-16 m/s)."""


def _turn(x: float) -> tuple[float, float]:
    """The share ``a`` of the slip's own direction at ``x`` in [0, 1] across the band, and
    ``da/dx``: ``a = ψ(x) / (ψ(x) + ψ(1 - x))`` with ``ψ(x) = exp(-1/x)``, 0 at 0 and 1 at 1
    with every derivative zero at both ends (C^∞, module doc)."""
    if x <= 0.0 or x >= 1.0:
        return (0.0 if x <= 0.0 else 1.0), 0.0
    p, m = math.exp(-1.0 / x), math.exp(-1.0 / (1.0 - x))
    total = p + m
    return p / total, p * m * (1.0 / (x * x) + 1.0 / ((1.0 - x) ** 2)) / (total * total)


def slip_direction(
    slip_velocity: np.ndarray, reference: np.ndarray | None, floor: float = SLIP_SPEED_EPS, jacobian: bool = True
) -> tuple[np.ndarray, np.ndarray | None]:
    """Unit slip direction ``s`` (tangent coordinates) and ``ds/du_T`` (module doc).

    Args:
        slip_velocity: the tangential row velocities ``u_T = A_T v`` (m/s), 1 or 2.
        reference: the unit direction the slip continues along (the planar sign, or
            the 3-D direction at the last accepted step); None: the slip's own.
        floor: slip speed (m/s) below which the reference is the direction.
        jacobian: also ``ds/du_T``; False: ``D`` is None (a solve without derivatives
            reads ``s`` alone, and the same ``s``).

    Returns:
        ``(s, D)``: ``D = (I - s s^T) / ||u_T||`` in 3-D above ``2 floor`` (the
        band's blend below it), None where ``s`` does not depend on ``u_T``
        (planar, a slip too slow, or one past its stop: against the reference).
        With no reference and no slip, ``s`` is zero (no friction direction).
    """
    u = np.asarray(slip_velocity, dtype=float)
    if len(u) == 1:
        if reference is not None:
            return np.asarray(reference, dtype=float), None
        return np.array([1.0 if u[0] >= 0.0 else -1.0]), None
    speed = float(np.hypot(u[0], u[1]))
    if speed <= floor or (reference is None and speed <= SLIP_SPEED_EPS):
        return (np.zeros(2) if reference is None else np.asarray(reference, dtype=float)), None
    s = u / speed
    if reference is not None and s @ reference < 0.0:  # past a stop: the reference (module doc)
        return np.asarray(reference, dtype=float), None
    if reference is None or speed >= 2.0 * floor:
        return s, ((np.eye(2) - np.outer(s, s)) / speed if jacobian else None)
    # the band [floor, 2 floor]: from the reference to the slip's own direction (module doc)
    r = np.asarray(reference, dtype=float)
    a, da = _turn(speed / floor - 1.0)
    da /= floor  # da / d||u||
    b = a * s + (1.0 - a) * r
    norm = float(np.linalg.norm(b))
    blended = b / norm
    if not jacobian:
        return blended, None
    # db/du = da ŵ-derivative terms: (ŵ - r) ŵᵀ da + a (I - ŵ ŵᵀ) / ||u||
    db_dw = np.outer(s - r, s) * da + a * (np.eye(2) - np.outer(s, s)) / speed
    return blended, (np.eye(2) - np.outer(blended, blended)) / norm @ db_dw


def reference_turn(slip_velocity: np.ndarray, reference: np.ndarray, floor: float) -> np.ndarray | None:
    """``∂s/∂θ`` (2,) of a 3-D slip direction (`slip_direction`) at fixed ``u_T`` when its
    reference ``r`` turns by the angle ``θ`` (rad) in the tangent plane, ``∂r/∂θ = r⊥``
    (``r`` turned by +90°); None where ``s`` does not depend on ``r`` (above ``2 floor``,
    where ``s`` is the slip's own direction).

    Below ``floor`` and past a stop ``s = r``: ``r⊥``. In the band ``s = b / ||b||``,
    ``b = a ŵ + (1 - a) r``: ``(1 - a) (I - s sᵀ) r⊥ / ||b||``.
    """
    u = np.asarray(slip_velocity, dtype=float)
    r = np.asarray(reference, dtype=float)
    turned = np.array([-r[1], r[0]])
    speed = float(np.hypot(u[0], u[1]))
    if speed <= floor or u @ r < 0.0:
        return turned
    if speed >= 2.0 * floor:
        return None
    a, _ = _turn(speed / floor - 1.0)
    b = a * (u / speed) + (1.0 - a) * r
    norm = float(np.linalg.norm(b))
    s = b / norm
    return (1.0 - a) * (turned - s * (s @ turned)) / norm


@dataclass
class SlipRow:
    """The force row of one slipping contact at one state (module doc).

    Attributes:
        row: index of the contact's (normal) row in the mode's stacked rows.
        index: scene index of the contact.
        mu: Coulomb coefficient.
        direction: unit slip direction ``s`` (tangent coordinates).
        direction_jacobian: ``ds/du_T`` (None where constant).
        tangent_rows: ``A_T`` (k × nv).
        force_row: ``F = A_n - μ s^T A_T`` (nv,).
        full: the bound contact with all its rows.
    """

    row: int
    index: int
    mu: float
    direction: np.ndarray
    direction_jacobian: np.ndarray | None
    tangent_rows: np.ndarray
    force_row: np.ndarray
    full: BoundContact

    @classmethod
    def at(cls, dyn, key: int, row: int, kin, v: np.ndarray, jacobian: bool = True) -> SlipRow:
        """The slip row of contact key ``key`` (a slipping view of ``dyn``) at the state
        of ``kin`` with velocity ``v``; ``jacobian``: with ``ds/du_T`` (else None)."""
        full = dyn.contact(key).full
        index = dyn.contact_index(key)
        A = full.rows(kin)
        s, D = dyn.slip_direction(index, A[1:] @ v, jacobian)
        mu = full.spec.mu
        return cls(row, index, mu, s, D, A[1:], A[0] - mu * (s @ A[1:]), full)

    def force_derivatives(self, kin, normal_force: float) -> np.ndarray:
        """``d(F^T λ_N)/d(q, v)`` at fixed ``λ_N`` (nv × 2nv): through the rows at fixed
        ``s``, and through ``s(u_T)`` with ``u_T = A_T(q) v`` (needs ``kin`` updated with
        derivatives)."""
        nv = self.tangent_rows.shape[1]
        out = np.zeros((nv, 2 * nv))
        lam = normal_force * np.concatenate(([1.0], -self.mu * self.direction))
        out[:, :nv] = self.full.rows_transpose_dq(kin, lam)
        if self.direction_jacobian is not None:
            coef = -self.mu * normal_force * self.tangent_rows.T @ self.direction_jacobian
            out[:, :nv] += coef @ self.full.rows_velocity_dq(kin)[1:]
            out[:, nv:] += coef @ self.tangent_rows
        return out


def painleve_check(G: np.ndarray, slips, names) -> None:
    """Raise `PainleveError` where a slipping contact's own block ``g = A_n M^-1 F^T`` of
    ``G`` is not positive (module doc); ``slips`` are the mode's `SlipRow`, ``names``
    the scene's contact names."""
    diagonal = G.diagonal()
    floor = 1e-12 * max(1e-300, float(np.abs(diagonal).max()))
    for slip in slips:
        g = float(diagonal[slip.row])
        if g <= floor:
            raise PainleveError(
                f"contact {names[slip.index]!r} slipping with mu = {slip.mu:g} along {slip.direction.tolist()}: "
                f"A_n M^-1 (A_n - mu s^T A_T)^T = {g:.6g} <= 0, so a pushing normal force accelerates it into the "
                "ground: the sliding problem has no solution or two (Painlevé's paradox)",
                contact=slip.index,
            )
