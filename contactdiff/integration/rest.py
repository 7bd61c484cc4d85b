"""Rest: a run that has come to rest in a mode goes to its final time in one step.

(With sample times still to take, it goes to each of them in one step, and from the
last to the final time.)

A run at rest still pays for every step to its final time, and at rest the steps
are bounded by round-off, not by the motion: along the directions a closed contact
holds, a mode's field is a double integrator (the contact forces hold it at the
acceleration level), so the forces' round-off (~1e-13 m/s² on a standing
quadruped) moves Radau's Newton iterates by ``h²`` times it. Newton stops
converging once that reaches its tolerance, at steps of ~10 s for solo12 standing
at rtol = 1e-8: 1e9 s would take 1e8 steps. No step-size rule can lift that bound
(a 1e8-s step moves its stages by ~1e3 m along those directions); the run has to
know it rests.

`RestCheck` says so after an accepted step when

* the remaining time is within ``max_step`` (a user's shorter ``max_step`` is kept);
* the scene is autonomous from then on (`Scene.autonomous_from`: no effort depends
  on time; joint targets past their last knot);
* no contact of the mode slips, every normal force and every sticking contact's
  cone margin is positive by more than `FORCE_MARGIN` of the weight, and every open
  contact's gap is above `GAP_MARGIN` times ``atol``: no guard is near;
* the mode's field linearised at the state, on the tangent space of its manifold
  (``D J D``, ``D`` the projection's derivative, `projection.projection_jacobian`,
  which drops the held directions that projections keep on the manifold), has no
  eigenvalue whose growth over the remaining time exceeds ``e`` (the rest is stable,
  or neutral: a robot standing anywhere on the floor);
* that linearised flow, started from the state, moves it over the remaining time
  by at most `REST_TOL` of the tolerance (RMS of ``d / (atol + rtol |y|)``): the
  state is an equilibrium to well within one step's error.

The run then ends at ``x + d`` (the held row velocities removed first, as a projection
of the state does) with the flow Jacobian ``exp(J T) phi``, the variational equation
the stepper integrates (the index-reduced convention: columns off the manifold are
carried, not projected, `contactdiff.integration.projection`), and for parameters
``+ ∫_0^T exp(J s) ds (0, J_p)``: one matrix exponential of the augmented matrix
(Van Loan). A note says so. The velocity check runs first at
no cost; a full check that fails is tried again after twice as many steps (1, 2,
4, ...), so a run that stays just short of rest pays a few checks, not one a step.
Runs that do not rest are unchanged; a run that rests ends within ``REST_TOL`` of the
tolerance of where it would have crept to.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
from scipy.linalg import expm

from ..ode.dense import DenseOutput
from .guards import GuardKind
from .projection import held_velocity, projection_jacobian

REST_TOL = 0.1
"""Largest motion left (RMS over the state, in units of ``atol + rtol |y|``) of a state at
rest. A standing solo12 is at 4e-3 (its state carries the run's round-off); a state still
settling moves by many tolerances."""

FORCE_MARGIN = 1e-6
"""Smallest normal force and cone margin of a contact at rest, as a share of the weight
(N): a contact that carries nothing rests on the edge of lifting off."""

GAP_MARGIN = 100.0
"""Smallest gap of an open contact at rest, in units of ``atol`` (m)."""


class RestCheck:
    """Checks a run's accepted steps for rest and ends the run there (module doc).

    Args:
        loop: the `HybridLoop` (its scene, dynamics, options, final time and parameter blocks).
    """

    def __init__(self, loop):
        self.loop = loop
        o = loop.options
        nv = loop.scene.nv
        atol = np.broadcast_to(np.asarray(o.atol, dtype=float), (2 * nv,))
        self.atol, self.rtol, self.nv = atol, o.rtol, nv
        self.weight = pin.computeTotalMass(loop.scene.model) * float(np.linalg.norm(loop.scene.model.gravity.linear))
        self._wait = 1  # steps before the next full check
        self._skip = 0
        # the rest under way (its start and end, s; its note) when it goes on past a sample time
        self._resting_from, self._scale_seen, self._jumps = -np.inf, 0.0, 0
        self._segment: object | None = None  # the mode's segment of the rest under way
        self._note: str | None = None

    def settle(self, stepper, field, mode, segment, t_to: float) -> bool:
        """After an accepted step with no event: if the run rests (module doc), move the
        stepper to ``t_to`` (s: the final time, or the next sample time before it) in one
        step of the linearised flow (state, flow Jacobian), extend ``segment`` and note it
        (one note for a rest that goes on across sample times). Returns whether it did."""
        loop = self.loop
        t, remaining = stepper.t, t_to - stepper.t
        if not 0.0 < remaining <= loop.options.max_step or field.slipping:
            return False  # (a max_step shorter than the rest: the user's own steps)
        nv = self.nv
        v = stepper.v
        if _rms(v / (self.atol[nv:] + self.rtol * np.abs(v))) > REST_TOL:
            self._wait, self._skip = 1, 0
            return False
        if self._skip > 0:
            self._skip -= 1
            return False
        rest = self._rest(t, stepper.q, v, remaining, field, mode, stepper)
        if rest is None:
            self._skip, self._wait = self._wait, 2 * self._wait
            return False
        q1, v1, d, phi1, slowest = rest
        if loop.options.dense:
            y0 = np.concatenate((stepper.q, v)) if stepper._vs else np.concatenate((np.zeros(nv), v))
            change = np.concatenate((d[:nv], v1 - v))[None, :]  # the held velocity's removal, then the flow's
            segment.pieces.append(
                DenseOutput(
                    t,
                    t_to,
                    remaining,
                    y0,
                    change,
                    None if stepper._vs else stepper.group,
                    None if stepper._vs else stepper.q,
                    nv,
                )
            )
        stepper.t_bound = t_to  # (a step cut short at a sample or breakpoint left it there)
        stepper.restart(t_to, q1, v1, phi=phi1)
        stepper.n_steps += 1
        segment.t1 = t_to
        self._wait, self._skip = 1, 0  # still at rest after a sample time: checked at once
        decay = "neutral" if slowest == 0.0 else f"slowest decay {slowest:.3g} /s"
        scale = _rms(d / self._scale(stepper.q, v, stepper))
        start, jumps = t, 1
        if self._segment is segment and self._note is not None:  # the same rest (one mode), past sample times
            start, jumps, scale = self._resting_from, self._jumps + 1, max(scale, self._scale_seen)
            loop.notes.remove(self._note)
        end = "t_final" if t_to == loop.t_final else "t"
        steps = "one step" if jumps == 1 else f"{jumps} steps (one to each sample time)"
        self._note = (
            f"at rest from t = {start:.12g} s in mode ({', '.join(segment.mode) or 'free flight'}): an "
            f"equilibrium of the mode to {scale:.2g} of the tolerance, stable ({decay}); stepped to "
            f"{end} = {t_to:g} s in {steps} of its linearised flow"
        )
        loop.notes.append(self._note)
        self._resting_from, self._segment, self._scale_seen, self._jumps = start, segment, scale, jumps
        return True

    def _scale(self, q, v, stepper) -> np.ndarray:
        """``atol + rtol |y|`` at ``(q, v)``, per tangent component (the stepper's error scale)."""
        mag_q = np.abs(q) if stepper._vs else stepper.group.magnitude(q)
        return self.atol + self.rtol * np.concatenate((mag_q, np.abs(v)))

    def _rest(self, t, q, v_in, remaining, field, mode, stepper):
        """``(q1, v1, d, phi1, slowest decay rate)`` at the final time if ``(t, q, v)`` rests, else None."""
        loop = self.loop
        if not loop.scene.autonomous_from(t) or not self._clear_of_guards(t, q, v_in, field, mode):
            return None
        # the row velocities the contacts hold, removed (the projection's velocity part): the
        # mode's flow keeps them constant, and a foot held at 1e-12 m/s would slide 1e-3 m in 1e9 s
        v = held_velocity(loop.dyn, q, v_in, mode)
        nv, n = self.nv, 2 * self.nv
        a = field.accel(t, q, v)
        Jq, Jv = field.jac(t, q, v)
        J = np.zeros((n, n))
        J[:nv, nv:] = np.eye(nv)
        if not stepper._vs:
            J[:nv, :nv] = stepper.group.velocity_jacobian_q(q, v)
        J[nv:, :nv], J[nv:, nv:] = Jq, Jv
        D = projection_jacobian(loop.dyn, q, v, mode)
        Jm = D @ J @ D
        eigenvalues = np.linalg.eigvals(Jm)
        if not np.isfinite(eigenvalues).all() or np.max(eigenvalues.real) * remaining > 1.0:
            return None  # an unstable rest: its round-off grows
        motion = np.zeros((n + 1, n + 1))
        motion[:n, :n], motion[:n, n] = Jm, D @ np.concatenate((v, a))
        d = expm(motion * remaining)[:n, n]
        if not np.isfinite(d).all() or _rms(d / self._scale(q, v, stepper)) > REST_TOL:
            return None
        q1 = q + d[:nv] if stepper._vs else stepper.group.integrate(q, d[:nv])
        phi1 = None
        if stepper.phi is not None:  # the variational equation the stepper integrates, phi' = J phi (+ (0, J_p))
            p = 0 if loop.jumps is None else loop.jumps.p
            flow = np.zeros((n + p, n + p))
            flow[:n, :n] = J
            if p:
                flow[nv:n, n:] = field.parameter_jac(t, q, v)
            E = expm(flow * remaining)
            phi1 = E[:n, :n] @ stepper.phi
            if p:
                phi1[:, loop.n_state :] += E[:n, n:]
            if not np.isfinite(phi1).all():
                return None
        stable = -eigenvalues.real[eigenvalues.real < -1e-9 * max(1.0, float(np.max(np.abs(eigenvalues))))]
        return q1, v + d[nv:], d, phi1, float(np.min(stable)) if stable.size else 0.0

    def _clear_of_guards(self, t, q, v, field, mode) -> bool:
        """No guard near: forces and cone margins above `FORCE_MARGIN` of the weight, open
        gaps above `GAP_MARGIN` atol."""
        loop = self.loop
        values = field.guard_values(t, q, v)
        if any(g.kind not in (GuardKind.FORCE, GuardKind.CONE) for g in field.guards):
            return False
        if values.size and np.min(values) <= FORCE_MARGIN * self.weight:
            return False
        held = loop.dyn.contacts_of(mode)
        gaps = loop.scene.gaps(q)
        floor = GAP_MARGIN * float(np.min(self.atol[: self.nv]))
        return all(g > floor for i, g in enumerate(gaps) if i not in held)


def _rms(x: np.ndarray) -> float:
    return math.sqrt(float(np.vdot(x, x)) / x.size) if x.size else 0.0
