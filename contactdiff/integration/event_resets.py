"""What the hybrid loop does at an event: the reset, the next mode, and the saltation
matrices of the state and of the parameters.

A mixin of `contactdiff.integration.hybrid.HybridLoop` (its state: ``dyn``, ``kin``,
``contacts``, ``names``, ``options``, ``events``, ``notes``, ``phi``, ``n_state``,
``jumps``, ``sensitive``, ``gap_tol``): lift-offs and slips change the mode without
a jump; touchdowns apply the impact law to every closed contact, with the Zeno rule
for cascades; each event gets its saltation matrix, event-time gradient and, with
parameters, their blocks (`contactdiff.integration.parameter_jumps`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..dynamics.frictional_impact import ContactState
from ..dynamics.impacts import choose_mode, liftoff_mode, resolve_impact
from ..dynamics.redundant import row_rank
from ..errors import GrazingError
from .friction_events import refuse_ambiguous_slip, settle_friction
from .guards import Guard, GuardKind
from .loop_events import LoopEvents
from .options import OnGrazing
from .parameter_jumps import ParameterJumps
from .projection import close, held_velocity, held_velocity_jacobian, mode_rows
from .resting import CASCADE_ROUNDS, cascade_outcome, resting_contacts
from .sensitivity import (
    VanishingSlipError,
    gap_gradient,
    impact_reset_jacobian,
    liftoff_guard,
    saltation,
    simultaneous_saltation,
    vector_field,
)
from .trajectory import Event, EventKind, NonSmooth

CREEP_FACTOR = 10.0
"""A contact that an impact leaves slipping slower than this many slip-speed floors
(``zeno_speed``) is held and sticks or slips by its forces: in an impact cascade the
tangential impulses are as small as the normal ones (1e-7 N s on ANYmal), and so is
the slip they leave (1e-6 m/s), whose direction is then the cascade's noise."""
SPEED_TOL = 1e-12
"""m/s: a post-impact normal speed below this (scaled by the impact's speeds) counts as zero."""
RESTING_GAP_TOL = 1e-9
"""Outcomes of an impact against a resting contact differing by less than this share of
the velocities (the impact law's round-off is about 1e-15 of them) count as one."""


class EventResets(LoopEvents):
    """The loop's event handling (module doc)."""

    def _event(self, t, q, v, mode, fired: list[Guard]):
        dyn = self.dyn
        touching = [g.contact for g in fired if g.kind is GuardKind.GAP]
        releasing = [g.contact for g in fired if g.kind is GuardKind.FORCE]
        bearing = [g.contact for g in fired if g.kind is GuardKind.BEAR]
        if bearing and len(bearing) == len(fired):  # held contacts bear (`contactdiff.integration.held`)
            return self._bear_event(t, q, v, mode, bearing)
        gripping = [g.contact for g in fired if g.kind is GuardKind.GRIP]
        if gripping and len(gripping) == len(fired):  # slips held at zero stick (the same module)
            return self._grip_event(t, q, v, mode, gripping)
        # with other guards at once, a held contact's load is watched again in the next
        # mode (its guard fires at that mode's start if it still pushes)
        if not touching and not releasing:  # Coulomb friction's own events
            return self._friction_event(t, q, v, mode, fired)
        if touching:
            # every contact closed at the instant takes part (docs/design.md §2), also one whose
            # guard did not fire within simultaneous_tol: left out, it would start the
            # next step closed and be skipped by _crossings (no peak), i.e. penetrate
            gaps, _ = self.gaps_and_rates(q, v)
            active = dyn.contacts_of(mode)
            near = [i for i, g in enumerate(gaps) if g <= self.gap_tol and i not in active]
            closed = sorted(set(mode) | set(touching) | set(near))
            return self._impact(t, q, v, mode, closed, touching, releasing)
        # a released sticking contact that would sink (the tangential force it carried
        # pressed it down) slides instead: normal row only, until its force vanishes
        unheld = self._unheld(q, v, mode, releasing)
        new_mode = liftoff_mode(dyn, q, v, t, mode, releasing, unheld)
        kind = (
            EventKind.SLIP
            if any(dyn.is_sliding(k) and k not in mode and k not in unheld for k in new_mode)
            else EventKind.LIFT_OFF
        )
        event = self._impulseless_event(t, kind, releasing, len(releasing) > 1, q, v, v, mode, new_mode)
        if self.sensitive:
            # guard: the normal force of the first releasing contact; with several at once
            # (a simultaneous lift-off) the saltation is the product of the single
            # lift-offs in turn (each releasing contact's guard in the mode left by the
            # earlier ones): a sticking contact's force jump is not carried by another's guard
            guard = liftoff_guard(dyn, t, q, v, mode, releasing[0])
            h_p = self.jumps.force_guard(q, v, t, mode, releasing[0]) if self.jumps else None
            xi, xi_p = self._liftoff_sequence(t, q, v, mode, releasing, new_mode, guard, h_p)
            self._attach_sensitivity(event, xi, *guard, xi_p=xi_p, h_p=h_p)
        self.events.append(event)
        return new_mode, v

    def _unheld(self, q, v, mode, releasing) -> list[int]:
        """Keys of the closed contacts outside ``mode`` at zero normal speed whose normal
        row the contacts staying after the release of ``releasing`` do not hold (rank of
        the rows, `contactdiff.dynamics.redundant.row_rank`): the contacts the release
        may let sink (`liftoff_mode`). One slipping with Coulomb friction enters as
        sliding along its slip; one slipping without it is left to its gap."""
        dyn, speed = self.dyn, self.options.grazing_speed
        gaps, rates = self.gaps_and_rates(q, v)
        active = dyn.contacts_of(mode)
        closed = [
            i for i, (g, r) in enumerate(zip(gaps, rates)) if i not in active and g <= self.gap_tol and abs(r) <= speed
        ]
        if not closed:
            return []
        dyn.kin.update(q, v)
        staying = [k for k in mode if k not in releasing]
        A = mode_rows(dyn, staying) if staying else np.zeros((0, self.scene.nv))
        rank = row_rank(A)
        keys = []
        for i in closed:
            rows = dyn.contact(i).rows(dyn.kin)
            if row_rank(np.vstack([A, rows[:1]])) == rank:
                continue  # held at zero gap by the staying contacts
            slip = rows[1:] @ v
            if len(slip) and np.max(np.abs(slip)) > speed:
                if not self.contacts[i].spec.coulomb:
                    continue
                dyn.slip_reference[i] = slip / np.linalg.norm(slip)
                keys.append(dyn.sliding_key(i))
            else:
                keys.append(i)
        return keys

    def _liftoff_sequence(self, t, q, v, mode, releasing, new_mode, first_guard, first_h_p=None):
        """Saltation of the lift-off of ``releasing`` from ``mode``, one contact after the
        other in the given order at the same state (no jump: each force is zero there);
        ``first_guard`` is the first one's `liftoff_guard` and ``first_h_p`` its
        parameter derivative (`ParameterJumps.force_guard`, with parameters). Returns
        ``(Ξ, Ξ_p)``, the parameter block None without parameters."""
        n2 = 2 * self.scene.nv
        xi, current = np.eye(n2), tuple(mode)
        xi_p = np.zeros((n2, self.jumps.p)) if self.jumps else None
        for n, k in enumerate(releasing):
            slide = self.dyn.sliding_key(k) if not self.dyn.is_sliding(k) else None
            after = (
                tuple(new_mode)
                if n == len(releasing) - 1
                else tuple(sorted([i for i in current if i != k] + ([slide] if slide in new_mode else [])))
            )
            Dh, F_minus, h_t = first_guard if n == 0 else liftoff_guard(self.dyn, t, q, v, current, k)
            F_plus = vector_field(self.dyn, q, v, t, after)
            xi_k = saltation(np.eye(n2), Dh, F_minus, F_plus, h_t)
            xi = xi_k @ xi
            if xi_p is not None:
                h_p = first_h_p if n == 0 else self.jumps.force_guard(q, v, t, current, k)
                xi_p = xi_k @ xi_p + ParameterJumps.saltation(
                    None, h_p, None, F_minus, F_plus, float(Dh @ F_minus) + h_t
                )
            current = after
        return xi, xi_p

    def _resting_outcomes(self, t, q, v_minus, v_plus, mode, closed, touching, nonsmooth):
        """Where a landing meets a coupled resting contact (`contactdiff.integration.resting`):
        mark ``nonsmooth`` and return both outcomes, if they differ; else None."""
        dyn = self.dyn
        resting = resting_contacts(dyn, q, v_minus, t, mode, closed, touching)
        if not resting:
            return None
        v_cascade, impacts = cascade_outcome(dyn, q, v_minus, closed, list(resting), touching)
        dyn.kin.update(q, v_plus)
        scale = max(float(np.max(np.abs(v_minus))), float(np.max(np.abs(v_plus))), 1e-300)
        gap = float(np.max(np.abs(v_cascade - v_plus)))
        if gap <= RESTING_GAP_TOL * scale:
            return None
        pairs = "; ".join(
            f"{self.names[dyn.contact_index(k)]} (coupling "
            + ", ".join(f"{self.names[j]} {c:.3g}" for j, c in coupled.items())
            + ")"
            for k, coupled in resting.items()
        )
        ended = f"{impacts} impacts" if impacts <= CASCADE_ROUNDS else f"not ended after {CASCADE_ROUNDS} impacts"
        nonsmooth[NonSmooth.RESTING_CONTACT] = self._note(
            f"not differentiable at t = {t:.12g}: {', '.join(self.names[i] for i in touching)} landed against "
            f"resting {pairs}; opened by a perturbation, the impact is a cascade ({ended}) whose velocity after "
            f"differs by up to {gap:.3g} (event.outcomes)"
        )
        return {"simultaneous": v_plus.copy(), "cascade": v_cascade}

    def _impact(self, t, q, v_minus, mode, closed, touching, releasing=(), initial=False):
        """Impact of the ``closed`` contacts (keys: a sliding contact takes part with its
        normal row), ``touching`` being those whose guard fired (at the start,
        ``initial``: all closed contacts, with no guard and no grazing)."""
        q = close(self.dyn, q, closed)
        self.kin.update(q, v_minus)
        speeds = {i: float(self.contacts[i].rows(self.kin)[0] @ v_minus) for i in touching}
        grazing = [] if initial else [i for i in touching if abs(speeds[i]) <= self.options.grazing_speed]
        if grazing and self.options.on_grazing is OnGrazing.RAISE:
            raise GrazingError(
                f"grazing touchdown of {', '.join(self.names[i] for i in grazing)} at t = {t:.17g}: "
                f"normal speed {max(abs(speeds[i]) for i in grazing):.3g} m/s <= grazing_speed "
                f"{self.options.grazing_speed:g}; the flow is not differentiable there"
            )
        dyn = self.dyn
        e = np.array([dyn.contact(k).restitution for k in closed])
        zeno = [i for i in touching if self.contacts[i].restitution > 0 and abs(speeds[i]) < self.options.zeno_speed]
        for i in zeno:
            e[closed.index(i)] = 0.0
        impact = resolve_impact(dyn, q, v_minus, closed, e)
        impact_keys = list(closed)
        v_plus = impact.v_plus
        creeping: list[int] = []
        if impact.states is not None:  # Coulomb friction: each contact sticks or slides on
            closed, creeping = self._friction_keys(q, impact, closed)
            if creeping:  # a slip below the noise floor is held: the contact sticks or slips by its forces
                v_plus = held_velocity(dyn, q, v_plus, creeping)
        v_crept = v_plus  # after the impact and the creeping slips' hold
        scale = max(1.0, float(np.max(np.abs(impact.normal_speeds_before))))
        leaving = set(dyn.contacts_of(releasing))  # a releasing contact leaves whatever its key
        staying = [
            k
            for k, s in zip(closed, impact.normal_speeds_after)
            if s <= SPEED_TOL * scale and dyn.contact_index(k) not in leaving
        ]
        # The Zeno rule for impact cascades: a closed contact that this impact would
        # lift slower than zeno_speed does not leave (with several sticking feet an
        # impact at one foot lifts another by a little, whose return lifts a third,
        # and so on, a geometric series of ever slower impacts); its separating speed
        # is removed M-orthogonally if the mode keeps it. This includes a landing
        # contact with no restitution left (plastic, or a bounce ended above) that
        # the impact law itself lifts: a sticking contact whose slip only a pulling
        # impulse could stop takes a tangential impulse alone and leaves
        # (`resolve_impact`), and if its flight brings it back slipping the same
        # way, its landings form a geometric series as well. Left to leave, it
        # would rise by (speed)² / (2 |normal acceleration|), far below what the
        # dense output resolves, and come back only through the sinking rule of
        # `_crossings`, i.e. below the ground by the grazing band, landing again
        # at sqrt(2 |acceleration| band) (ANYmal's trot: 1e-7 m, 1 cm/s). A contact
        # with restitution left bounces by its own law, ended on its approach speed.
        settling = [
            k
            for k, s, e_k in zip(closed, impact.normal_speeds_after, impact.restitution)
            if SPEED_TOL * scale < s < self.options.zeno_speed
            and dyn.contact_index(k) not in leaving
            and (dyn.contact_index(k) not in touching or e_k == 0.0)
        ]
        new_mode = choose_mode(dyn, q, v_plus, t, staying + settling)
        from_rest: list = []  # the contacts that slip from rest after the impact (`_onset_columns`)
        if impact.states is not None:
            refuse_ambiguous_slip(dyn, q, v_plus, t, staying + settling, new_mode)
            new_mode, _ = settle_friction(dyn, q, v_plus, t, new_mode, from_rest)
            from_rest = [(i, m, v_plus) for i, m in from_rest]
        settled = [i for i in dyn.contacts_of(settling) if i in dyn.contacts_of(new_mode)]
        nonsmooth = {}  # the cascade rule's cut-off and a grazing touchdown are not smooth
        if settled:
            v_plus = held_velocity(self.dyn, q, v_plus, new_mode)
            nonsmooth[NonSmooth.ZENO_CASCADE] = self._note(
                f"Zeno: impact cascade ended at t = {t:.12g}: {', '.join(self.names[i] for i in settled)} "
                f"kept closed (lifted slower than zeno_speed = {self.options.zeno_speed:g} m/s)"
            )
        # a landing slower than zeno_speed ends its bounces: its own restitution set to
        # zero, or, lifted by the impact law, kept closed by the rule above
        ended = sorted(set(zeno) | {i for i in settled if i in touching and abs(speeds[i]) < self.options.zeno_speed})
        if grazing:
            kind = EventKind.GRAZING
            nonsmooth[NonSmooth.GRAZING] = self._note(
                f"grazing touchdown of {', '.join(self.names[i] for i in grazing)} at t = {t:.12g}"
            )
        elif ended:
            kind = EventKind.ZENO
            self.notes.append(
                f"Zeno: bounces of {', '.join(self.names[i] for i in ended)} ended at t = {t:.12g} "
                f"(impact speed below zeno_speed = {self.options.zeno_speed:g} m/s); contact kept closed"
            )
        elif any(i in dyn.contacts_of(new_mode) for i in touching):
            kind = EventKind.TOUCHDOWN
        else:
            kind = EventKind.BOUNCE
        outcomes = (
            None if initial else self._resting_outcomes(t, q, v_minus, v_plus, mode, impact_keys, touching, nonsmooth)
        )
        impulses = {self.names[dyn.contact_index(k)]: float(x) for k, x in zip(closed, impact.impulses)}
        event = Event(
            t=t,
            kind=kind,
            contacts=self._mode_names(touching),
            simultaneous=len(touching) > 1,
            q=q.copy(),
            v_minus=v_minus.copy(),
            v_plus=v_plus.copy(),
            impulses=impulses,
            mode_before=self._mode_names(mode),
            mode_after=self._mode_names(new_mode),
            normal_speeds={self.names[i]: s for i, s in speeds.items()},
            sliding=self._sliding_names(new_mode),
            nonsmooth=nonsmooth,
            outcomes=outcomes,
        )

        def reset_jacobian():
            try:
                DR = impact_reset_jacobian(self.dyn, q, v_minus, impact)
            except VanishingSlipError as exc:  # a stick/slip threshold: flagged, its direction held
                event.nonsmooth[NonSmooth.FRICTION_THRESHOLD] = self._note(f"not differentiable at t = {t:.12g}: {exc}")
                DR = impact_reset_jacobian(self.dyn, q, v_minus, impact, hold_vanishing=True)
            return holds(DR)

        def holds(D):
            """``D`` (of the impact's velocities) through the holds that follow: the creeping
            slips', then the settled contacts' (each's Jacobian at the velocity it holds; the
            term of ``dP/dq`` on the rows' velocities before it, of the creeping or lifting
            speed's size, is left out, as for a projection)."""
            if creeping:
                D = held_velocity_jacobian(self.dyn, q, v_crept, creeping) @ D
            if settled:  # the reset is the impact followed by holding the settled contacts
                D = held_velocity_jacobian(self.dyn, q, v_plus, new_mode) @ D
            return D

        def reset_parameters():
            live = [k for k in closed if dyn.contact_index(k) not in zeno]
            return holds(self.jumps.impact(q, v_minus, impact, live))

        if self.sensitive and initial:
            # no guard at t0: perturbations keep the start time, only the reset acts
            event.saltation = reset_jacobian()
            if self.options.jacobian:
                event.time_gradient = np.zeros(2 * self.scene.nv)
            if self.jumps:
                event.parameter_saltation = reset_parameters()
                event.parameter_time_gradient = np.zeros(self.jumps.p)
            if from_rest:
                self._onset_columns(
                    t, q, from_rest, self.jacobians.after(self.phi, event), np.zeros(self.phi.shape[1]), new_mode
                )
        elif self.sensitive:
            F_minus = vector_field(self.dyn, q, v_minus, t, mode)
            guard = min(touching, key=lambda i: speeds[i])
            Dh = gap_gradient(self.dyn, q, guard)
            h_p = xi_p = None
            if self.jumps:
                h_p = self.jumps.gap_guard(guard)
            if len(touching) > 1:
                sim = self._landing_orders(event, t, q, v_minus, mode, touching, closed, e)
                xi = sim.matrix
                if self.jumps:  # the simultaneous reset plus one guard term per contact
                    xi_p = reset_parameters()
                    for k, (jump, rate) in sim.corrections.items():
                        xi_p += np.outer(jump, self.jumps.gap_guard(k)) / rate
                event.saltation_orders = {tuple(self.names[i] for i in k): m for k, m in sim.orders.items()}
            else:
                DR = reset_jacobian()
                F_plus = vector_field(self.dyn, q, v_plus, t, new_mode)
                xi = saltation(DR, Dh, F_minus, F_plus)
                R_p = reset_parameters() if self.jumps else None
                if self.jumps:
                    xi_p = ParameterJumps.saltation(R_p, h_p, DR, F_minus, F_plus, float(Dh @ F_minus))
                if from_rest:  # the state after the reset, moved with the event's time
                    dt = -(Dh @ self.phi)
                    if h_p is not None:
                        dt[self.n_state :] -= h_p
                    dt /= float(Dh @ F_minus)
                    moved = DR @ (self.phi + np.outer(F_minus, dt))
                    if R_p is not None:
                        moved[:, self.n_state :] += R_p
                    self._onset_columns(t, q, from_rest, moved, dt, new_mode)
            self._attach_sensitivity(event, xi, Dh, F_minus, xi_p=xi_p, h_p=h_p)
            if from_rest and len(touching) > 1:  # the state after the reset at the event's time
                self._simultaneous_onsets(t, q, v_plus, Dh, F_minus, event, xi_p, h_p, from_rest, new_mode)
        elif len(touching) > 1 and not initial:  # the verdict must not depend on what was asked for
            self._landing_orders(event, t, q, v_minus, mode, touching, closed, e, verdict_only=True)
        self.events.append(event)
        return new_mode, v_plus

    def _simultaneous_onsets(self, t, q, v_plus, Dh, F_minus, event, xi_p, h_p, from_rest, new_mode) -> None:
        """The slips from rest that Coulomb's law settles after a simultaneous landing
        (`_onset_columns`): the state after the reset moved with the event's time,
        ``Ξ φ + Ξ_p + F+ ∂t`` (for a single landing ``DR (φ + F- ∂t) + ∂R/∂p``), ``∂t`` that of
        the guard the event's time gradient uses. ``event`` carries its saltation matrix
        ``Ξ``: ``Ξ φ`` is the product the stepper restarts from (`EventJacobians.salted`)."""
        assert self.phi is not None  # called only in a sensitive run
        rate = float(Dh @ F_minus)
        dt = -(Dh @ self.phi)
        if h_p is not None:
            dt[self.n_state :] -= h_p
        dt /= rate
        moved = self.jacobians.salted(self.phi, event) + np.outer(vector_field(self.dyn, q, v_plus, t, new_mode), dt)
        if xi_p is not None:
            moved[:, self.n_state :] += xi_p
        self._onset_columns(t, q, from_rest, moved, dt, new_mode)

    def _landing_orders(self, event, t, q, v_minus, mode, touching, closed, e, verdict_only=False):
        """The saltation matrices of every landing order of a simultaneous touchdown
        (`simultaneous_saltation`), flagging ``event`` with `NonSmooth.ORDER` where they
        differ; ``verdict_only`` (a run without sensitivities) stops at the first two
        orders that disagree."""
        override = {i: e[closed.index(i)] for i in closed}
        sim = simultaneous_saltation(self.dyn, t, q, v_minus, mode, touching, override, verdict_only=verdict_only)
        if sim.unresolved:
            event.nonsmooth[NonSmooth.ORDER] = self._note(
                f"not differentiable at t = {t:.12g}: {len(sim.unresolved)} of the landing orders of "
                f"{', '.join(self.names[i] for i in touching)} have no impact solution the impact law's "
                f"search finds, or no derivative there, so the orders cannot be compared "
                f"({next(iter(sim.unresolved.values()))})"
            )
        elif not sim.differentiable:
            by = "by" if sim.complete else "by at least"
            event.nonsmooth[NonSmooth.ORDER] = self._note(
                f"not differentiable at t = {t:.12g}: the landing orders of "
                f"{', '.join(self.names[i] for i in touching)} give saltation matrices "
                f"differing {by} {sim.spread:.2e} (relative)"
            )
        return sim

    def _friction_keys(self, q, impact, before: Sequence[int]) -> tuple[list[int], list[int]]:
        """The keys of a frictional impact's contacts after it, and the closed ones whose
        slip is below `CREEP_FACTOR` noise floors (``dyn.slip_speed_floor``). A contact with Coulomb
        friction that slides faster takes its slipping key, its slip direction the
        impact's; a slower one keeps its sticking key (its forces decide, afterwards).
        One that slid before and that the law leaves open at zero normal speed with no
        impulse (a grazing landing's neighbours) slides on along its own slip, not along
        a direction an earlier mode left (a stale one makes its slip look stopped, and
        the stop holds a sliding face still), if that slip is above the same floors; a
        slower one is creeping too (given a sliding key, a corner of an edge at rest
        slid with its full friction, which put the other corner, whose sticking force
        needed 1 % of its cone, on its cone's edge: the two alternated between slip and
        stop). ``before``: the contacts' keys before the impact, in the order of
        ``impact.contacts`` (which holds scene indices with Coulomb friction)."""
        dyn, keys, creeping = self.dyn, [], []
        dyn.kin.update(q, impact.v_plus)
        scale = max(1.0, float(np.max(np.abs(impact.normal_speeds_before))))
        for k, key_before, state, s, u_n in zip(
            impact.contacts, before, impact.states, impact.slide_directions, impact.normal_speeds_after, strict=True
        ):
            contact = dyn.contact(k)
            sliding = state is ContactState.SLIDE and np.any(s)  # the law leaves it sliding along s
            # or left open at zero normal speed after sliding: it stays in the mode, along its own slip
            left_open = state is ContactState.OPEN and dyn.is_sliding(key_before)
            if contact.spec.coulomb and (sliding or left_open):
                u_T = contact.rows(dyn.kin)[1:] @ impact.v_plus
                slip = float(np.linalg.norm(u_T))
                if slip > CREEP_FACTOR * dyn.slip_speed_floor:
                    dyn.slip_reference[k] = np.array(s, dtype=float) if sliding else u_T / slip
                    k = dyn.sliding_key(k)
                elif u_n <= SPEED_TOL * scale:  # slower: held as a creeping slip
                    creeping.append(k)
            keys.append(k)
        return keys, creeping

    def _attach_sensitivity(
        self,
        event: Event,
        xi: np.ndarray,
        Dh: np.ndarray,
        F_minus: np.ndarray,
        h_t: float = 0.0,
        xi_p: np.ndarray | None = None,
        h_p: np.ndarray | None = None,
    ) -> None:
        """Saltation matrix and event-time gradient ``-Dh Φ- / (Dh F- + h_t)`` (implicit
        functions; ``h_t`` the guard's explicit time rate); with parameters also their
        block ``xi_p`` and time gradient ``-(Dh Φ-_p + h_p) / (Dh F- + h_t)``."""
        n = self.n_state
        rate = float(Dh @ F_minus) + h_t
        event.saltation = xi
        assert self.phi is not None  # set before every event of a run with derivatives
        band = np.zeros(self.phi.shape[1]) if self.band_dt is None else self.band_dt  # an onset's θ (`BandEvents`)
        if self.options.jacobian:
            event.time_gradient = -(Dh @ self.phi[:, :n]) / rate + band[:n]
        if self.jumps is not None:
            event.parameter_saltation = xi_p
            event.parameter_time_gradient = -(Dh @ self.phi[:, n:] + h_p) / rate + band[n:]

    def _note(self, text: str) -> str:
        """Add a note to the run's notes; return it (for an event's ``nonsmooth``)."""
        self.notes.append(text)
        return text
