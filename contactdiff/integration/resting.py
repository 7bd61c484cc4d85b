"""An impact against a resting contact: the outcome if a perturbation opens it.

A contact closed with zero normal force *rests*: it sits on the boundary of
lifting, and an arbitrarily small perturbation of the state opens it by an
arbitrarily small gap. When another contact lands while one rests and the two
are coupled through the inverse mass (``G_jr = A_j M^-1 A_r^T != 0``), the
impact law resolves them together (the run's outcome), whereas with the
resting contact open the landing is resolved alone and the resting contact
is met later, a cascade of impacts at (almost) the same instant. The two
outcomes differ by a finite amount in general (three equal balls in a row
with a plastic end: the simultaneous impact bounces the first ball back, the
cascade stops it), so the flow is not differentiable there, however the run
itself resolves it; `NonSmooth.RESTING_CONTACT` says so with both outcomes.

`resting_contacts` finds the contacts; `cascade_outcome` computes the other
outcome: the impact without them, then, as long as a contact approaches, the
impact of the approaching ones (with the loaded contacts), each with its own
restitution.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from ..dynamics.impacts import resolve_impact
from ..dynamics.mode import ModeDynamics

RESTING_FORCE_TOL = 1e-9
"""A contact's normal force (N) at most this share of the scale (the mode's largest
force or the robot's weight, whichever is larger) counts as zero: resting."""

COUPLING_TOL = 1e-9
"""``|G_jr| / sqrt(G_jj G_rr)`` below this counts as decoupled (the paper's orthogonality)."""

CASCADE_ROUNDS = 100
"""Impacts of a cascade computed at most (an elastic row can pass a pulse back and forth)."""

APPROACH_TOL = 1e-12
"""A normal speed below ``-APPROACH_TOL`` times the pre-impact speed scale approaches (m/s)."""


def resting_contacts(
    dyn: ModeDynamics,
    q: np.ndarray,
    v_minus: np.ndarray,
    t: float,
    mode: Sequence[int],
    closed: Sequence[int],
    touching: Sequence[int],
) -> dict[int, dict[int, float]]:
    """The contacts of the impact's ``closed`` (keys) that rest at ``(q, v_minus, t)`` and are
    coupled to a landing contact of ``touching`` (scene indices), each with its coupling
    coefficients ``{landing index: G_jr / sqrt(G_jj G_rr)}``. Resting: not landing, and in
    ``mode`` with a zero normal force, or closed outside it (no force at all)."""
    mode = tuple(mode)
    landing = [i for i in touching if i not in dyn.contacts_of(mode)]
    others = [k for k in closed if dyn.contact_index(k) not in touching]
    if not landing or not others:
        return {}
    loaded = set()
    if mode:
        forces = dyn.solve(q, v_minus, t, mode).normal_forces()
        weight = pin.computeTotalMass(dyn.model) * float(np.linalg.norm(dyn.model.gravity.linear))
        scale = max(weight, float(np.max(np.abs(forces))))
        loaded = {k for k, f in zip(mode, forces) if abs(f) > RESTING_FORCE_TOL * scale}
    candidates = [k for k in others if k not in loaded]
    if not candidates:
        return {}
    dyn.kin.update(q, v_minus)
    rows = {i: dyn.scene.contacts[i].rows(dyn.kin)[0] for i in landing + [dyn.contact_index(k) for k in candidates]}
    Minv = pin.computeMinverse(dyn.model, dyn.data, q)
    out = {}
    for k in candidates:
        r = dyn.contact_index(k)
        g_rr = float(rows[r] @ Minv @ rows[r])
        coupled = {}
        for j in landing:
            g_jj, g_jr = float(rows[j] @ Minv @ rows[j]), float(rows[j] @ Minv @ rows[r])
            relative = g_jr / np.sqrt(g_jj * g_rr)
            if abs(relative) > COUPLING_TOL:
                coupled[j] = relative
        if coupled:
            out[k] = coupled
    return out


def cascade_outcome(
    dyn: ModeDynamics,
    q: np.ndarray,
    v_minus: np.ndarray,
    closed: Sequence[int],
    resting: Sequence[int],
    touching: Sequence[int],
) -> tuple[np.ndarray, int]:
    """Velocity after the impact of ``closed`` (keys) with the ``resting`` ones (keys, among
    ``closed``) open, and the cascade that follows; and the number of impacts.

    The first impact closes the landing contacts (``touching``, scene indices) and the
    loaded ones (the others of ``closed``); each later one the loaded contacts and those
    that approach then, each with its own restitution (a contact that separates takes
    part in no impact: it is met again only if it approaches). Returns ``(v_plus,
    impacts)``; ``impacts`` is ``CASCADE_ROUNDS + 1`` where the cascade had not ended by
    then (``v_plus`` is the velocity it reached)."""
    held = [k for k in closed if k not in resting and dyn.contact_index(k) not in touching]
    landing = [k for k in closed if dyn.contact_index(k) in touching]
    dyn.kin.update(q, v_minus)
    normal = {k: dyn.scene.contacts[dyn.contact_index(k)].rows(dyn.kin)[0] for k in closed}  # rows at q
    scale = max(1.0, float(np.max(np.abs([row @ v_minus for row in normal.values()]))))
    v = resolve_impact(dyn, q, v_minus, held + landing).v_plus
    for impacts in range(1, CASCADE_ROUNDS + 1):
        approaching = [k for k in closed if k not in held and normal[k] @ v < -APPROACH_TOL * scale]
        if not approaching:
            return v, impacts
        v = resolve_impact(dyn, q, v, held + approaching).v_plus
    return v, CASCADE_ROUNDS + 1
