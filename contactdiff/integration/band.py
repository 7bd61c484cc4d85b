"""Events while a slip from rest still follows its onset's reference.

A 3-D slip from rest follows the reference ``r`` its onset set (``θ`` its angle in
the tangent plane) until it is faster than ``2 ε`` (`contactdiff.dynamics.slip`), and
the flow Jacobian carries ``θ`` as a parameter born at the onset: a row
``w = ∂θ/∂`` of its columns, and the forcing ``(∂ddq/∂θ) w`` of every column
(`contactdiff.integration.mode_field.ModeField`). An event before the slip leaves the
band (the *band*) meets a field that depends on ``θ``:

* **its guard.** A guard that reads the mode's forces (a normal force at a lift-off,
  a cone margin, a held contact's load) moves with ``θ`` at a fixed state, through the
  slip's friction ``-μ λ_N A_Tᵀ s(θ)``: ``∂λ/∂θ = (∂λ/∂τ) (-μ λ_N A_Tᵀ ∂s/∂θ)``. Its time
  moves by ``∂t/∂θ = -h_θ / (Dh F- + h_t)``, as a parameter's, so every column's by
  ``-h_θ w / rate`` (``band_dt``), and the flow Jacobian after the event gains
  ``(F+ - F-) h_θ w / rate`` (the reset of such an event is the identity), recorded on the
  event as ``reference_jump`` and ``parameter_reference_jump`` (`Event`), which the loop
  applies with the saltation. That term vanishes in exact arithmetic: at each of these
  guards the field is continuous (a lift-off's and a bear's force is zero there, and a slip
  from the cone's edge starts with the sticking force), so it is of the size of the event's
  location error (measured 1e-31 at a lift-off: tests/integration/test_band_events.py),
  while the time's term is not. A gap guard
  reads no force (``h_θ = 0``), nor does another contact's slip (a stop).
* **its reset.** An impact's law reads the velocities only, a stop's hold the mode's
  rows: neither depends on ``θ``.
* **after it.** A contact that slides on with the same reference and is still in the
  band keeps its term (``w`` unchanged: ``θ`` is the onset's); one the event stops,
  lifts, or gives a new direction (an impact) leaves it.

Not formed (the run leaves a note that the reference is held from there): a stop of the
band's own slip (its guard ``s(θ) · u_T``, which fires only past ``-ε``, at a turn the
reference does not describe), and several guards at once of which one reads forces. The
first is bounded by the floor: its guard moves by ``h_θ = (∂s/∂θ) · u_T``, at most the
slip's speed (below ``2 ε``), and what a shift of the stop's time changes after it is
``F+ - DR F-``, whose velocity rows are the stuck mode's accelerations at ``v+`` and at
``v-`` (the hold ``DR`` maps the slipping field's accelerations onto the stuck mode's: the
friction ``F^T λ`` lies in the rows it holds), apart by the slip left, again below ``2 ε``:
the term left out is of order ``ε² |w| / rate`` (1e-13 |w| at ``zeno_speed`` 1e-6 m/s and a
stop's deceleration of ``μ g``). The second is not small in general.

Cost: per event in the band, one derivative solve of the mode (two for a held
contact's bearing) and one vector field of each mode; none otherwise.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..dynamics.slip import reference_turn
from .friction_events import cone_guard
from .guards import Guard, GuardKind
from .held import HoldingField, bear_guard, enlarged
from .loop_events import LoopEvents
from .sensitivity import liftoff_guard, vector_field

if TYPE_CHECKING:
    from .mode_field import ModeField

FORCE_GUARDS = (GuardKind.FORCE, GuardKind.CONE, GuardKind.BEAR)
"""The guards that read the mode's forces, and so move with a reference ``θ``."""


@dataclass
class BandOnset:
    """A slip from rest in the band at an event: its ``w = ∂θ/∂`` of the flow Jacobian's
    columns (m,) and its reference direction ``r`` (tangent coordinates) before it."""

    w: np.ndarray
    reference: np.ndarray


def reference_forces(dyn, sol, v, band: dict[int, BandOnset]) -> dict[int, np.ndarray]:
    """Generalised force ``-μ λ_N A_Tᵀ ∂s/∂θ`` (nv,) of each slip of ``band`` that slides in
    ``sol`` (a `ModeSolution`, ``dyn.kin`` at its state, velocity ``v``) and whose direction
    still depends on its reference: the response of the field to a turn of ``θ``."""
    out = {}
    for key, rows in zip(sol.active, sol.row_slices):
        index = dyn.contact_index(key)
        if index not in band or not dyn.is_sliding(key):
            continue
        A_T = dyn.contact(key).full.rows(dyn.kin)[1:]
        ds = reference_turn(A_T @ v, dyn.slip_reference[index], dyn.slip_speed_floor)
        if ds is not None:
            out[index] = -dyn.contact(key).spec.mu * sol.forces[rows.start] * (A_T.T @ ds)
    return out


def guard_reference_rates(dyn, t, q, v, mode, guard: Guard, band, held_key: int | None = None):
    """The rate ``Dh F- + h_t`` of a guard that reads the forces (`FORCE_GUARDS`) of ``mode``
    at ``(t, q, v)``, and its ``h_θ = ∂h/∂θ`` at that fixed state for each slip of ``band``
    (scene indices) whose direction depends on its reference there (module doc):
    ``(rate, {index: h_θ})``. ``held_key``: the held contact's key of a `GuardKind.BEAR`
    guard (its guard is minus its load in the set of ``mode`` and it)."""
    mode = tuple(mode)
    weights = None
    if guard.kind is GuardKind.BEAR:
        if held_key is None:
            raise ValueError(f"a bearing guard of contact {guard.contact} needs its held key")
        key = held_key
        Dh, h_t = bear_guard(dyn, t, q, v, mode, key)
        rate = float(Dh @ vector_field(dyn, q, v, t, mode)) + h_t
        solved, sign = enlarged(mode, key), -1.0
    else:
        key, solved, sign = guard.contact, mode, 1.0
        if guard.kind is GuardKind.FORCE:
            Dh, F_minus, h_t = liftoff_guard(dyn, t, q, v, mode, key)
        else:
            Dh, F_minus, h_t, (_, _, _, weights), _ = cone_guard(dyn, t, q, v, mode, key)
        rate = float(Dh @ F_minus) + h_t
    sol, der = dyn.solve(q, v, t, solved, derivatives=True)
    rows = sol.row_slices[solved.index(key)]
    rates = {}
    for index, force in reference_forces(dyn, sol, v, band).items():
        response = der.forces_dtau[rows] @ force
        rates[index] = sign * float(response[0] if weights is None else weights @ response)
    return rate, rates


class BandEvents(LoopEvents):
    """The loop's handling of an event in the band (module doc); a mixin of
    `contactdiff.integration.hybrid.HybridLoop`."""

    if TYPE_CHECKING:  # besides the state of every event mixin (LoopEvents)
        fields: Sequence[HoldingField]  # the loop's ModeField objects

    # band_dt (LoopEvents): ∂t/∂ of the columns that the event's guard adds through the band's
    # θ (m,), while an event in the band is processed; None otherwise

    def _band_onsets(self, field: ModeField, q, v) -> dict[int, BandOnset]:
        """At an event at ``(q, v)``: the slips from rest still in the band (`ModeField`,
        `contactdiff.integration.band`), which alone keep their term in ``self.onsets`` through
        the event; the others' references no longer act."""
        band = {}
        if self.onsets:
            band = {i: BandOnset(self.onsets[i], self.dyn.slip_reference[i].copy()) for i in field.onsets_in_band(q, v)}
        self.onsets = {i: onset.w for i, onset in band.items()}
        return band

    def _band_guard(self, band: dict[int, BandOnset], t, q, v, mode, fired: list[Guard]) -> bool:
        """Before the event at ``(t, q, v)`` in ``mode``: set `band_dt` from its guard's
        ``h_θ`` (module doc). False where that is not formed (module doc)."""
        self.band_dt = None
        reading = [g for g in fired if g.kind in FORCE_GUARDS]
        if any(g.kind is GuardKind.STOP and self.dyn.contact_index(g.contact) in band for g in fired):
            return False
        # a held slip's guard reads the forces with it sticking: its own θ is gone, another's acts
        gripping = {self.dyn.contact_index(g.contact) for g in fired if g.kind is GuardKind.GRIP}
        if gripping and set(band) - gripping:
            return False
        if not reading:
            return True  # gap and other slips' stop guards: no θ in the guard
        if len(fired) > 1:
            return False
        guard = reading[0]
        held_key = self.fields[-1].held[guard.contact] if guard.kind is GuardKind.BEAR else None
        rate, rates = guard_reference_rates(self.dyn, t, q, v, mode, guard, band, held_key)
        assert self.phi is not None  # onsets are carried only with a flow Jacobian
        dt = np.zeros(self.phi.shape[1])
        for index, h_theta in rates.items():
            dt -= h_theta * band[index].w / rate
        self.band_dt = dt
        return True

    def _band_after(self, band: dict[int, BandOnset], t, q, v, mode, new_mode, v_plus, exact: bool):
        """After the event: the correction ``(F+ - F-) ⊗ (-band_dt)`` to the flow Jacobian just
        after it (2nv × m, or None), and the band's slips that keep their term in
        ``self.onsets`` (module doc); notes the ones whose term ends where it is not formed."""
        dyn, floor = self.dyn, self.dyn.slip_speed_floor
        correction = None
        if exact and self.band_dt is not None and np.any(self.band_dt):
            jump = vector_field(dyn, q, v_plus, t, new_mode) - vector_field(dyn, q, v, t, mode)
            correction = -np.outer(jump, self.band_dt)
        self.band_dt = None
        dyn.kin.update(q, v_plus)
        for index, onset in band.items():
            key = dyn.sliding_key(index)
            if self.onsets.get(index) is onset.w:  # not replaced by a new onset at this event
                if (
                    exact
                    and key in new_mode
                    and np.array_equal(dyn.slip_reference[index], onset.reference)
                    and float(np.linalg.norm(dyn.contact(key).full.rows(dyn.kin)[1:] @ v_plus)) < 2.0 * floor
                ):
                    continue  # it slides on with its reference, in the band: its term goes on
                del self.onsets[index]
            if not exact and key in mode:  # a held contact's reference acts once it bears
                self.notes.append(
                    f"flow Jacobian: from t = {t:.12g} it holds the reference direction of "
                    f"{self.names[index]}'s slip from rest fixed (an event before the slip "
                    f"reached 2 zeno_speed = {2.0 * floor:.3g} m/s whose dependence on it is not formed)"
                )
        return correction


__all__ = ["BandEvents", "BandOnset", "guard_reference_rates", "reference_forces"]
