"""Events of Coulomb friction: stick → slip, slip → stick, and the mode after them.

A mixin of `contactdiff.integration.hybrid.HybridLoop` (its state as for
`contactdiff.integration.event_resets`). Neither event has a jump of the state:

* **stick → slip** (guard: the cone margin ``h = μ λ_N - ||λ_T||`` of a sticking
  contact reaching 0). The contact slips along ``s = -λ_T / ||λ_T||``, the
  direction its tangential force resisted: the slip's friction ``-μ λ_N s`` then
  equals the sticking force, so the field is continuous and ``Ξ = I`` (plus
  round-off) as at a lift-off.
* **slip → stick** (guard: the slip velocity along its direction reaching 0, in
  3-D the whole slip velocity: `contactdiff.dynamics.slip`). The contact sticks
  if the sticking force lies in the cone; otherwise friction cannot hold it and
  it slips on, along ``-λ_T / ||λ_T||`` of the sticking force it would need (a
  planar contact reverses). The field jumps; the reset holds the contact's rows
  (`held_velocity`, removing the slip velocity left by the integration error),
  so ``Ξ = DR + (F+ - DR F-) Dh / (Dh F-)``.

**Slips at rest stop together.** Holding the stopped contact moves the slip velocity
of every contact coupled to it (a face's corners share one body). A contact that
slips on slower than the slip-speed floor ``ε`` (``zeno_speed``) is at rest within
the integration's noise: its direction is then its reference ``r``, not its own
(`contactdiff.dynamics.slip`), and ``r``, set before the reset, may point along the
slip as well as against it. Its friction ``-μ λ_N r`` then drives the slip instead of
stopping it, and its stop guard, which fires only past ``-ε`` for a slip that starts
at noise, does not see it: the slip creeps through the band ``[ε, 2ε]`` where the
direction turns, at steps of microseconds, while real friction would stop it in
``|u_T| / (μ g)`` (below a microsecond). So every such slip stops with the fired one
(`resting_slips`, repeated until the hold leaves none), as a crossing of the same
instant, and the mode choice below decides, from the sticking forces, which of them
slip on (from rest, along ``-λ_T / ||λ_T||``). The event's saltation is that of the
fired guard with the reset holding every stopped contact; the others' stops, within
``ε / (μ g)`` of it, are merged into it (as the Zeno rule merges bounces below
``zeno_speed``).

**Held contacts bear again at a stop.** A contact released at a lift-off whose
rows depend on those of the contacts that stay (a face's corner whose compatible
load would pull, `contactdiff.dynamics.redundant`) keeps a gap and a gap speed of
exactly zero while the others hold it, so no gap guard brings it back (within a
mode its compatible load is watched, `contactdiff.integration.held`). Where a
slip → stick event leaves every active contact at rest, the mode after it is
chosen again over the active contacts and such held ones, all sticking, by the
compatible-load principle (`held_at_rest`): the held ones join when every load is
then positive and inside its cone. The motion is the same (their rows add no
constraint); the loads, and the guards that follow, are the principle's.

Differentiability: a crossing is transversal when the guard's rate is not zero.
The flow is not differentiable where the tangential force only touches the cone
(stick → slip with a vanishing rate: neighbours on one side stay stuck), or
where a stopped contact's sticking force lies on the cone's boundary (neighbours
stick or slip on): the paper's stick/slip threshold. Those events carry
`NonSmooth.FRICTION_THRESHOLD` with the numbers.
"""

from __future__ import annotations

import numpy as np

from ..dynamics.mode import ModeDynamics, ModeSolution
from ..dynamics.redundant import row_rank
from ..dynamics.slip import reference_turn
from ..errors import PainleveError, SolverError
from .guards import Guard, GuardKind
from .loop_events import LoopEvents
from .parameter_jumps import ParameterJumps
from .projection import held_velocity, held_velocity_jacobian, mode_rows
from .sensitivity import saltation, vector_field
from .trajectory import Event, EventKind, NonSmooth

THRESHOLD_TOL = 1e-9
"""Relative distance to the friction cone's boundary (of ``μ λ_N``), and relative
guard rate (per second, of ``μ λ_N``), below which an event sits on the stick/slip
threshold (round-off of the forces is about 1e-14 relative)."""


SLIPPING_FLOORS = 10.0
"""A sticking contact that leaves its cone while slipping faster than this many slip-speed
floors (``zeno_speed``, as an impact's creeping rule) slips along its own slip."""


def settle_friction(
    dyn: ModeDynamics,
    q: np.ndarray,
    v: np.ndarray,
    t: float,
    mode: tuple[int, ...],
    from_rest: list | None = None,
    references: dict[int, np.ndarray] | None = None,
) -> tuple[tuple[int, ...], ModeSolution]:
    """The mode after Coulomb's law on ``mode`` at ``(q, v, t)``.

    A sticking contact whose sticking force leaves the cone slips along
    ``-λ_T / ||λ_T||`` (its reference direction is set on ``dyn``), and the solve is
    repeated until every sticking contact is inside its cone. Returns the mode and
    its `ModeSolution` there. ``from_rest``, if given, gets ``(scene index, mode)`` for
    each contact that slips from rest, in order, ``mode`` the one whose sticking force
    set its reference (`FrictionEvents._onset_columns`). ``references``, if given, gets
    each slip reference set on ``dyn.slip_reference`` (``{scene index: unit vector}``).

    Raises:
        PainleveError: a slipping contact has no consistent force (Painlevé).
        SolverError: no settled mode within ``2 n + 1`` rounds.
    """
    mode = tuple(sorted(mode))
    for _ in range(2 * len(mode) + 1):
        sol = dyn.solve(q, v, t, mode)
        over = []
        for key, f in zip(mode, sol.row_forces()):
            c = dyn.contact(key)
            if c.holds_cone:
                tangential = float(np.linalg.norm(f[1:]))
                if tangential > c.spec.mu * f[0] + THRESHOLD_TOL * max(abs(f[0]), tangential):
                    over.append((key, f))
        if not over:
            return mode, sol
        keys = list(mode)
        for key, f in over:
            index = dyn.contact_index(key)
            # along the force it resisted, unless it already slips (a sliding face's corner
            # an impact left with a sticking key): then along its slip
            slip = dyn.contact(key).rows(dyn.kin)[1:] @ v
            speed = float(np.linalg.norm(slip))
            moving = speed > SLIPPING_FLOORS * dyn.slip_speed_floor
            dyn.slip_reference[index] = slip / speed if moving else -f[1:] / np.linalg.norm(f[1:])
            if references is not None:
                references[index] = dyn.slip_reference[index]
            if not moving and from_rest is not None:
                from_rest.append((index, mode))
            keys[keys.index(key)] = dyn.sliding_key(index)
        mode = tuple(sorted(keys))
    raise SolverError(f"no mode satisfies Coulomb's law for contacts {mode} at t = {t!r}")


def resting_slips(dyn: ModeDynamics, q: np.ndarray, v: np.ndarray, mode: tuple[int, ...]) -> list[int]:
    """The slipping keys of ``mode`` whose slip speed ``||A_T v||`` at ``(q, v)`` (``v``
    after a slip → stick event's reset) is at most the slip-speed floor
    (``dyn.slip_speed_floor``, m/s): slips at rest within the integration's noise, which
    stop with the event (module doc)."""
    dyn.kin.update(q, v)
    return [
        key
        for key in mode
        if dyn.contact(key).slips
        and float(np.linalg.norm(dyn.contact(key).full.rows(dyn.kin)[1:] @ v)) <= dyn.slip_speed_floor
    ]


def held_at_rest(
    dyn: ModeDynamics,
    q: np.ndarray,
    v: np.ndarray,
    t: float,
    mode: tuple[int, ...],
    closed: list[int],
    speed_tol: float,
) -> tuple[tuple[int, ...], ModeSolution] | None:
    """The mode with the held contacts among ``closed`` bearing again (module doc), or
    None where none joins.

    Args:
        dyn: the scene's `ModeDynamics` (its kinematics cache is moved to ``(q, v)``).
        q: configuration (nq,).
        v: velocity (nv,), tangent space, after the event's reset.
        t: time (s), for time-dependent efforts.
        mode: the mode after a slip → stick event, at ``(q, v)`` (its rows held).
        closed: scene indices of the contacts not in ``mode`` whose gap is closed and
            whose gap speed is zero (within ``speed_tol``, m/s).
        speed_tol: m/s; ``mode``'s contacts must all be at rest within it.

    Returns:
        ``(mode, solution)`` with every contact sticking, the held ones included, when
        every contact of ``mode`` is at rest, the held ones' rows (sticking) add no rank
        to ``mode``'s, and the principle's loads of the whole set push (beyond
        round-off, `THRESHOLD_TOL` of the largest) inside their cones.
    """
    if not closed:
        return None
    resting = tuple(sorted(dyn.contact_index(k) for k in mode))
    dyn.kin.update(q, v)
    A = mode_rows(dyn, resting)
    if np.max(np.abs(A @ v)) > speed_tol:
        return None
    rank = row_rank(A)
    held = [i for i in closed if row_rank(np.vstack([A, dyn.contact(i).rows(dyn.kin)])) == rank]
    if not held:
        return None
    try:
        new_mode, sol = settle_friction(dyn, q, v, t, tuple(sorted(resting + tuple(held))))
    except (PainleveError, SolverError):
        return None
    normal = np.array([f[0] for f in sol.row_forces()])
    if any(dyn.is_sliding(k) for k in new_mode) or normal.min() <= THRESHOLD_TOL * normal.max():
        return None
    return new_mode, sol


def refuse_ambiguous_slip(dyn: ModeDynamics, q, v, t, candidates, mode) -> None:
    """Raise `PainleveError` where a slipping candidate left out of ``mode`` (it would
    separate) could also slide on with a pushing force: Painlevé's non-uniqueness. Each
    such candidate's slipping mode is solved (`ModeDynamics.solve` refuses a
    non-positive ``A_n M^-1 F^T``)."""
    for key in candidates:
        if dyn.contact(key).slips and key not in mode:
            try:
                dyn.solve(q, v, t, tuple(sorted(set(mode) | {key})))
            except PainleveError as exc:
                raise PainleveError(f"{exc}; here it could also separate: two consistent motions") from None


def cone_guard(dyn: ModeDynamics, t: float, q, v, mode, key: int):
    """The stick → slip guard of ``key`` in ``mode``: ``(Dh, F-, h_t, solved, μ λ_N)`` with
    ``h = w · λ_rows``, ``w = (μ, -λ_T/||λ_T||)`` its gradient along the rows' forces, and
    ``solved = (solution, derivatives, row slice, w)`` for the parameters' block."""
    mode = tuple(mode)
    sol, der = dyn.solve(q, v, t, mode, derivatives=True)
    rows = sol.row_slices[mode.index(key)]
    f = sol.forces[rows]
    mu = dyn.contact(key).spec.mu
    w = np.concatenate(([mu], -f[1:] / np.linalg.norm(f[1:])))
    Dh = np.concatenate([w @ der.forces_dq[rows], w @ der.forces_dv[rows]])
    h_t = 0.0
    dyn.kin.update(q, v)
    tau_t = dyn.scene.tau_time_derivative(dyn.kin, t)
    if np.any(tau_t):  # the forces are affine in the efforts
        tau = dyn.scene.tau(dyn.kin, t)
        h_t = float(w @ (dyn.solve(q, v, t, mode, tau=tau + tau_t).forces[rows] - f))
    return Dh, np.concatenate([v, sol.ddq]), h_t, (sol, der, rows, w), mu * f[0]


def stop_guard(dyn: ModeDynamics, q, v, key: int) -> np.ndarray:
    """Gradient (2nv,) of the slip → stick guard ``h = s · A_T(q) v`` of slipping key ``key``
    (``s`` its slip direction, held fixed: the guard of `contactdiff.dynamics.slip`)."""
    kin = dyn.kin
    kin.update(q, v, derivatives=True)
    full = dyn.contact(key).full
    A_T = full.rows(kin)[1:]
    s = dyn.slip_direction(dyn.contact_index(key), A_T @ v, jacobian=False)[0]
    return np.concatenate([s @ full.rows_velocity_dq(kin)[1:], s @ A_T])


class FrictionEvents(LoopEvents):
    """The loop's stick → slip and slip → stick events (module doc)."""

    def _friction_event(self, t, q, v, mode, fired: list[Guard]):
        dyn = self.dyn
        cone = [g.contact for g in fired if g.kind is GuardKind.CONE]
        stops = [g.contact for g in fired if g.kind is GuardKind.STOP]
        mode = tuple(mode)
        sol = dyn.solve(q, v, t, mode)
        forces = dict(zip(mode, sol.row_forces()))
        keys = list(mode)
        for k in cone:
            f = forces[k]
            dyn.slip_reference[k] = -f[1:] / np.linalg.norm(f[1:])
            keys[keys.index(k)] = dyn.sliding_key(k)
        for k in stops:
            keys[keys.index(k)] = dyn.contact_index(k)
        new_mode = tuple(sorted(keys))
        v_plus = held_velocity(dyn, q, v, new_mode) if stops else v
        starting = {dyn.sliding_key(k) for k in cone}  # slipping from rest at this event
        while stops and (resting := [k for k in resting_slips(dyn, q, v_plus, new_mode) if k not in starting]):
            # they stop with the fired ones, as crossings of the same instant (module doc)
            fired.extend(Guard(GuardKind.STOP, k) for k in resting)
            stops += resting
            new_mode = tuple(sorted(dyn.contact_index(k) if k in resting else k for k in new_mode))
            v_plus = held_velocity(dyn, q, v, new_mode)
        from_rest: list = []
        new_mode, settled = settle_friction(dyn, q, v_plus, t, new_mode, from_rest)
        if stops:
            gaps, rates = self.gaps_and_rates(q, v_plus)
            active = dyn.contacts_of(new_mode)
            closed = [
                i
                for i, (g, r) in enumerate(zip(gaps, rates))
                if i not in active and g <= self.gap_tol and abs(r) <= self.options.grazing_speed
            ]
            bearing = held_at_rest(dyn, q, v_plus, t, new_mode, closed, self.options.grazing_speed)
            if bearing is not None:
                new_mode, settled = bearing
        stuck = [dyn.contact_index(k) for k in stops if dyn.contact_index(k) in new_mode]
        kind = EventKind.STICK if stuck and not cone else EventKind.SLIP
        event = self._impulseless_event(t, kind, cone + stops, len(fired) > 1, q, v, v_plus, mode, new_mode)
        if cone:
            Dh, F_minus, h_t, solved, cone_size = cone_guard(dyn, t, q, v, mode, cone[0])
            DR = None
        else:
            Dh, F_minus, h_t, cone_size = stop_guard(dyn, q, v, stops[0]), np.concatenate([v, sol.ddq]), 0.0, None
            DR = held_velocity_jacobian(dyn, q, v_plus, new_mode) if stuck else None
        F_plus = vector_field(dyn, q, v_plus, t, new_mode)
        rate = float(Dh @ F_minus) + h_t
        self._threshold_note(event, t, cone, stuck, rate, cone_size, settled)
        if self.sensitive:
            n2 = 2 * self.scene.nv
            xi = saltation(np.eye(n2) if DR is None else DR, Dh, F_minus, F_plus, h_t)
            h_p = xi_p = None
            if self.jumps:
                if cone:
                    sol_k, der_k, rows, w = solved
                    parameter_forces = self.jumps.forces
                    h_p = w @ der_k.forces_dtau[rows] @ parameter_forces.mode_forces(dyn, sol_k, q, v, t)
                    # the cone's own size: ∂(μ λ_N)/∂μ = λ_N at fixed forces
                    columns = parameter_forces.friction_columns.get(dyn.contact_index(cone[0]), [])
                    h_p[columns] += sol_k.forces[rows.start]
                else:
                    h_p = np.zeros(self.jumps.p)  # the slip velocity does not depend on the parameters
                xi_p = ParameterJumps.saltation(None, h_p, DR, F_minus, F_plus, rate)
            found = [(dyn.contact_index(k), mode, v) for k in cone] + [(i, m, v_plus) for i, m in from_rest]
            if found:
                dt = -(Dh @ self.phi)  # ∂t/∂ of phi's columns (as the parameters' saltation)
                if h_p is not None:
                    dt[self.n_state :] -= h_p
                dt /= rate
                if self.band_dt is not None:  # through an earlier onset's θ (`BandEvents`)
                    dt += self.band_dt
                moved = self.phi + np.outer(F_minus, dt)  # the event's state before its reset
                self._onset_columns(t, q, found, moved if DR is None else DR @ moved, dt, new_mode)
            self._attach_sensitivity(event, xi, Dh, F_minus, h_t, xi_p=xi_p, h_p=h_p)
        self.events.append(event)
        return new_mode, v_plus

    def _onset_columns(self, t, q, found, moved: np.ndarray, dt: np.ndarray, new_mode) -> None:
        """Set ``self.onsets`` (`contactdiff.integration.mode_field.ModeField`) for the 3-D
        contacts that slip from rest from this event on, along ``r = -λ_T/||λ_T||`` of their
        sticking force: ``w = ∂θ/∂`` of the flow Jacobian's columns, ``θ`` the angle of ``r``
        (``δθ = r⊥ · δr = -r⊥ · δλ_T / ||λ_T||``).

        Args:
            t: the event's time (s).
            q: its configuration.
            found: ``(scene index, mode, v)`` per contact, in the order their references
                were set: ``λ_T`` is the contact's sticking force in ``mode`` at ``(q, v)``.
                A contact set later (a round of `settle_friction` with earlier ones
                slipping) also moves with the earlier ones' ``θ`` (through their force
                ``-μ λ_N A_Tᵀ ∂s/∂θ``).
            moved: ``∂x/∂`` of phi's columns (2nv × m) at the event's state after its
                reset, moved with the event's time: ``DR (φ + F- ∂t/∂)``.
            dt: ``∂t/∂`` of phi's columns (m,): ``λ_T`` moves with time through the efforts.
            new_mode: the mode after the event (a contact that does not slip in it is skipped).
        """
        dyn = self.dyn
        floor = dyn.slip_speed_floor
        for index, mode, v in found:
            if dyn.sliding_key(index) not in new_mode:
                continue
            mode = tuple(mode)
            sol, der = dyn.solve(q, v, t, mode, derivatives=True)
            rows = sol.row_slices[mode.index(index)]
            lam_T = sol.forces[rows][1:]
            if len(lam_T) != 2:
                continue
            r = dyn.slip_reference[index]
            turn = -np.array([-r[1], r[0]]) / float(np.linalg.norm(lam_T))  # ∂θ/∂λ_T
            w = np.concatenate([turn @ der.forces_dq[rows][1:], turn @ der.forces_dv[rows][1:]]) @ moved
            dyn.kin.update(q, v)
            tau_t = dyn.scene.tau_time_derivative(dyn.kin, t)
            if np.any(tau_t):  # the forces are affine in the efforts
                tau = dyn.scene.tau(dyn.kin, t) + tau_t
                w += float(turn @ (dyn.solve(q, v, t, mode, tau=tau).forces[rows][1:] - lam_T)) * dt
                dyn.kin.update(q, v)
            if self.jumps:
                w[self.n_state :] += turn @ der.forces_dtau[rows][1:] @ self.jumps.forces.mode_forces(dyn, sol, q, v, t)
            for key, other in zip(sol.active, sol.row_slices):  # earlier slips from rest in this mode
                earlier = self.onsets.get(dyn.contact_index(key))
                if earlier is None or not dyn.is_sliding(key):
                    continue
                A_T = dyn.contact(key).full.rows(dyn.kin)[1:]
                ds = reference_turn(A_T @ v, dyn.slip_reference[dyn.contact_index(key)], floor)
                if ds is not None:
                    force = -dyn.contact(key).spec.mu * sol.forces[other.start] * (A_T.T @ ds)
                    w += float(turn @ der.forces_dtau[rows][1:] @ force) * earlier
            self.onsets[index] = w

    def _threshold_note(self, event: Event, t, cone, stuck, rate, cone_size, settled: ModeSolution) -> None:
        """Mark an event on the stick/slip threshold as not differentiable (module doc);
        ``cone_size`` is ``μ λ_N`` of a stick → slip event's contact, ``settled`` the
        solution of the mode after the event."""
        dyn = self.dyn
        if cone:
            scale = max(abs(cone_size), 1e-300)
            if abs(rate) <= THRESHOLD_TOL * scale:
                event.nonsmooth[NonSmooth.FRICTION_THRESHOLD] = self._note(
                    f"not differentiable at t = {t:.12g}: the tangential force of {', '.join(event.contacts)} "
                    f"touches the friction cone without crossing it (cone margin rate {rate:.3g} N/s)"
                )
            return
        for key, f in zip(settled.active, settled.row_forces()):
            if dyn.contact_index(key) in stuck:
                mu_n, tangential = dyn.contact(key).spec.mu * f[0], float(np.linalg.norm(f[1:]))
                if mu_n - tangential <= THRESHOLD_TOL * max(mu_n, 1e-300):
                    event.nonsmooth[NonSmooth.FRICTION_THRESHOLD] = self._note(
                        f"not differentiable at t = {t:.12g}: {self.names[dyn.contact_index(key)]} stopped with its "
                        f"sticking force on the friction cone (|λ_T| = {tangential:.6g} N, μ λ_N = {mu_n:.6g} N): "
                        "neighbouring runs stick or slip on"
                    )
