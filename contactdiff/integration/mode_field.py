"""The vector field of one contact mode, as a stepper sees it: accelerations, their
Jacobian, their parameter Jacobian, and the values of the mode's own guards (normal
forces, friction cone margins, slip speeds, the loads of contacts it holds at zero gap)
at the last point, with counters."""

from __future__ import annotations

from collections import OrderedDict

import numpy as np

from ..dynamics.mode import ModeDynamics
from ..dynamics.parameter_forces import ParameterForces
from ..dynamics.slip import reference_turn
from .guards import Guard, GuardKind, mode_guards
from .held import bear_value, grip_value


class ModeField:
    """Vector field of one mode for the stepper, remembering its last forces.

    With ``fused`` (a flow Jacobian by an explicit method) every evaluation also
    differentiates the mode: the stepper asks for the Jacobian at the very
    stage points whose accelerations it evaluated, and one solve with
    derivatives costs less than a plain solve followed by a derivative solve.
    The derivatives of the last few points are kept for `jac` and
    `parameter_jac`. With ``parameters`` (`ParameterForces`) each derivative
    solve also gives ``∂ddq/∂p``. ``held`` (``{scene index: key}``,
    `contactdiff.integration.held.held_contacts`): the contacts the mode holds at zero
    gap, each watched by a `GuardKind.BEAR` guard; ``held_slips`` (sliding keys,
    `contactdiff.integration.held.held_slips`): the slips it holds at zero, each watched
    by a `GuardKind.GRIP` guard.

    ``onsets`` (``{scene index: w}``): the 3-D slips that started from rest at the
    event the mode began with (or before it, still in the band: `contactdiff.integration.band`)
    and still follow the reference ``r`` set there; ``w``
    (m,) is ``∂θ/∂`` of the flow Jacobian's columns (the state's and the parameters'),
    ``θ`` the angle of ``r`` in the tangent plane. While the slip is below ``2 floor``
    the field depends on ``r`` (`contactdiff.dynamics.slip.reference_turn`), so every
    column of the variational equation is forced with ``(∂ddq/∂θ) w``: `parameter_jac`
    returns that forcing (nv × m), the parameters' own ``∂ddq/∂p`` in its last p
    columns. `advance` drops a slip once it leaves the band (its reference is then its
    own direction, no longer ``r``).
    """

    _KEEP = 32  # points remembered: more than the stages of one step

    def __init__(
        self,
        dyn: ModeDynamics,
        mode: tuple[int, ...],
        fused: bool = False,
        parameters: ParameterForces | None = None,
        held: dict[int, int] | None = None,
        onsets: dict[int, np.ndarray] | None = None,
        held_slips: list[int] | None = None,
    ):
        self.dyn, self.mode, self.fused, self.parameters = dyn, mode, fused, parameters
        self.onsets: dict[int, np.ndarray] = onsets if onsets is not None else {}
        """The slips from rest still on their onset's reference: scene index → ``∂θ/∂`` columns."""
        self.held: dict[int, int] = dict(held or {})
        """The contacts the mode holds at zero gap: scene index → key in the enlarged set."""
        self._plain = dyn.accelerator(mode)
        self.last = None  # (t, q, v) of the last accel, and its row forces' source
        self._last_forces = None
        self.guards: list[Guard] = (
            mode_guards(dyn, mode)
            + [Guard(GuardKind.BEAR, i) for i in self.held]
            + [Guard(GuardKind.GRIP, key) for key in held_slips or ()]
        )
        """The mode's force-level and slip guards, in the order of `guard_values`."""
        self._positions = {key: k for k, key in enumerate(mode)}
        self.slipping = any(g.kind is GuardKind.STOP for g in self.guards) or any(
            dyn.is_sliding(key) for key in self.held.values()
        )
        """Whether a contact slips with Coulomb friction (its direction is followed, `advance`)."""
        self.n_solve = self.n_derivatives = 0
        self._derivatives: OrderedDict = OrderedDict()

    def accel(self, t, q, v):
        """Accelerations ``ddq`` (nv,) of the mode at time ``t`` (s) and state ``(q, v)``; with
        ``fused`` also differentiates the mode and keeps the derivatives for `jac`."""
        self.n_solve += 1
        self.last = (t, q, v)
        if self.fused:
            sol = self._differentiate(t, q, v)
            self._last_forces = sol.row_forces
            return sol.ddq
        self._last_forces = self._plain.row_forces
        return self._plain(q, v, t)

    def _differentiate(self, t, q, v):
        """Solve with derivatives at ``(t, q, v)`` and keep them; the solution."""
        self.n_derivatives += 1
        sol, der = self.dyn.solve(q, v, t, self.mode, derivatives=True)
        ddq_dp = np.zeros((len(v), 0))
        if self.parameters is not None:
            ddq_dp = der.ddq_dtau @ self.parameters.mode_forces(self.dyn, sol, q, v, t)
        if self.onsets:
            ddq_dp = self._onset_forcing(sol, der, v, ddq_dp)
        self._derivatives[(t, q.tobytes(), v.tobytes())] = (der.ddq_dq, der.ddq_dv, ddq_dp)
        if len(self._derivatives) > self._KEEP:
            self._derivatives.popitem(last=False)
        return sol

    def _onset_forcing(self, sol, der, v, ddq_dp: np.ndarray) -> np.ndarray:
        """The variational equation's forcing (nv × m) with the onsets' terms (class doc):
        ``Σ (∂ddq/∂θ) w`` over every column, ``ddq_dp`` added on the last p. A turn of
        ``s`` moves the slipping force ``F^T λ_N`` by ``-μ λ_N A_T^T ∂s/∂θ``, a generalised
        force at fixed state (``dyn.kin`` is at ``(q, v)`` after the solve)."""
        dyn = self.dyn
        m = len(next(iter(self.onsets.values())))
        out = np.zeros((len(v), m))
        out[:, m - ddq_dp.shape[1] :] = ddq_dp
        for key, rows in zip(sol.active, sol.row_slices):
            index = dyn.contact_index(key)
            w = self.onsets.get(index)
            if w is None or not dyn.is_sliding(key):
                continue
            A_T = dyn.contact(key).full.rows(dyn.kin)[1:]
            ds = reference_turn(A_T @ v, dyn.slip_reference[index], dyn.slip_speed_floor)
            if ds is not None:
                force = -dyn.contact(key).spec.mu * sol.forces[rows.start] * (A_T.T @ ds)
                out += np.outer(der.ddq_dtau @ force, w)
        return out

    def _known(self, t, q, v):
        known = self._derivatives.get((t, q.tobytes(), v.tobytes()))
        if known is None:
            self._differentiate(t, q, v)
            known = self._derivatives[(t, q.tobytes(), v.tobytes())]
        return known

    def jac(self, t, q, v):
        """``(d ddq/dq, d ddq/dv)``, each (nv × nv), tangent space, at time ``t`` (s) and
        ``(q, v)`` (kept from a fused `accel` at that point, or solved)."""
        return self._known(t, q, v)[:2]

    def parameter_jac(self, t, q, v):
        """``d ddq/dp`` (nv × p) at time ``t`` (s) and ``(q, v)``, for the field's ``parameters``
        (nv × 0 without); with ``onsets`` the forcing of every column (nv × m, class doc)."""
        return self._known(t, q, v)[2]

    def row_forces(self, t, q, v) -> list[np.ndarray]:
        """Row forces (N) of the mode's contacts (order of ``mode``) at time ``t`` (s) and
        ``(q, v)``, reusing the last `accel` solve when it was at that point."""
        last = self.last
        if (
            last is not None
            and last[0] == t
            and (last[1] is q or np.array_equal(last[1], q))
            and (last[2] is v or np.array_equal(last[2], v))
        ):  # the stepper's end point is its last stage
            return self._last_forces()
        return self.dyn.solve(q, v, t, self.mode).row_forces()

    def normal_forces(self, t, q, v) -> np.ndarray:
        """Normal forces (N) of the mode's contacts (order of ``mode``) at ``(t, q, v)``."""
        return np.array([f[0] for f in self.row_forces(t, q, v)])

    def guard_values(self, t, q, v) -> np.ndarray:
        """Value of each guard of `guards` at time ``t`` (s) and ``(q, v)``; a guard fires
        where its value crosses 0 downward: a normal force (N), a sticking contact's cone
        margin ``μ λ_N - ||λ_T||`` (N), a slipping contact's slip velocity along its
        reference direction (m/s, `contactdiff.dynamics.slip`), minus a held contact's
        load in the enlarged set (N, `contactdiff.integration.held`), the sticking force's distance
        outside the cone of a slip the mode holds at zero (N, the same module)."""
        if not self.guards:
            return np.zeros(0)
        forces = self.row_forces(t, q, v)
        values = np.empty(len(self.guards))
        for j, guard in enumerate(self.guards):
            if guard.kind is GuardKind.BEAR:
                values[j] = bear_value(self.dyn, q, v, t, self.mode, self.held[guard.contact])
                continue
            if guard.kind is GuardKind.GRIP:
                values[j] = grip_value(self.dyn, q, v, t, self.mode, guard.contact)
                continue
            k = self._positions[guard.contact]
            if guard.kind is GuardKind.FORCE:
                values[j] = forces[k][0]
            elif guard.kind is GuardKind.CONE:
                values[j] = self.dyn.contact(guard.contact).spec.mu * forces[k][0] - np.linalg.norm(forces[k][1:])
            else:
                values[j] = self.slip_speed(guard.contact, q, v)
        return values

    def _slip(self, key: int, q, v) -> tuple[int, np.ndarray, np.ndarray]:
        """Scene index, slip velocity ``u_T`` (m/s) and slip direction of slipping key ``key``."""
        dyn = self.dyn
        dyn.kin.update(q, v)
        index = dyn.contact_index(key)
        u_T = dyn.contact(key).full.rows(dyn.kin)[1:] @ v
        return index, u_T, dyn.slip_direction(index, u_T, jacobian=False)[0]

    def slip_speed(self, key: int, q, v) -> float:
        """Slip velocity (m/s) of slipping contact key ``key`` along its reference direction."""
        _, u_T, s = self._slip(key, q, v)
        return float(s @ u_T)

    def onsets_in_band(self, q, v) -> list[int]:
        """Scene indices of the `onsets` whose slip at ``(q, v)`` is still below ``2 floor``,
        where the field depends on the onset's reference (class doc)."""
        band = 2.0 * self.dyn.slip_speed_floor
        return [
            index for index in self.onsets if np.linalg.norm(self._slip(self.dyn.sliding_key(index), q, v)[1]) < band
        ]

    def advance(self, q, v) -> None:
        """After an accepted step ending at ``(q, v)``: each 3-D slip continues along its
        direction there (the reference of `contactdiff.dynamics.slip`), unless its speed
        is in the band ``[0, 2 floor)`` where the direction depends on the reference: there
        the reference stays, so the field is the same before and after the step (the
        stepper keeps the end point's field value and Jacobian for the next step)."""
        keys = [g.contact for g in self.guards if g.kind is GuardKind.STOP]
        keys += [key for key in self.held.values() if self.dyn.is_sliding(key)]  # a held contact's too
        for key in keys:
            index, u_T, s = self._slip(key, q, v)
            if len(u_T) == 2 and np.hypot(u_T[0], u_T[1]) >= 2.0 * self.dyn.slip_speed_floor:
                self.dyn.slip_reference[index] = s
                self.onsets.pop(index, None)  # out of the band: the onset's reference no longer acts
