"""Baselines for the benchmarks, on the same dynamics as `contactdiff.simulate`.

Both use `ModeDynamics` (accelerations and forces of a contact mode) and the
same contact complementarity problem (`contactdiff.dynamics.complementarity`), so a comparison with
`simulate` measures the integration scheme, not the model.

`solve_ivp_baseline`
    What a user would write by hand around `scipy.integrate.solve_ivp`: the
    state ``y = (q, v)`` (vector-space scenes only, ``nq == nv``), one terminal
    event function per guard of the current mode (the gap of each inactive
    contact and the normal force of each active contact, both firing downward
    through 0). At an event the contacts closed at that instant (gap below
    ``contact_tol``) take the impact law `resolve_impact`, `choose_mode` (after
    a lift-off `liftoff_mode`) picks the next mode, and `solve_ivp` restarts. Guards at the same instant (value
    within ``contact_tol``) fire together. No projection onto the active
    constraints (they drift at the integration error).

`time_stepping_baseline`
    Fixed-step, impulse-based time stepping as MuJoCo/Bullet-style simulators
    do (semi-implicit Euler with a velocity-level LCP each step):

    1. ``a_free`` = unconstrained acceleration at ``(q_n, v_n)`` (efforts, gravity,
       Coriolis), ``v* = v_n + dt a_free``;
    2. candidate contacts: gap ``<= gap_threshold`` or predicted to penetrate,
       ``gap + dt A_n v* < 0``;
    3. impulses ``Λ`` from the contact LCP of `contactdiff.dynamics.complementarity` with
       ``v_{n+1} = v* + M^-1 A^T Λ``, Newton restitution ``w_n = A_n v_{n+1} +
       e A_n v* >= 0`` on normal rows (``e`` the contact's, 0 if not approaching),
       tangential rows of sticking contacts stopped;
    4. ``q_{n+1} = q_n ⊕ dt v_{n+1}`` (`pinocchio.integrate`: any Lie group).

    There is no position correction: a contact that closes within a step stops
    (or bounces) up to ``dt |A_n v|`` early, and active contacts drift by
    O(dt) over a run. Both errors are first order in ``dt``. Event times are
    step times ``t_n``: a contact starting to carry impulse (touchdown or
    bounce) or ceasing to carry it after at least two steps (lift-off); changes
    in the same step form one event.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin
from scipy.integrate import solve_ivp
from scipy.linalg import cho_factor, cho_solve

from ..dynamics.complementarity import ContactRows, impact_rhs, solve_contact_lcp
from ..dynamics.impacts import choose_mode, liftoff_mode, resolve_impact
from ..dynamics.mode import ModeDynamics
from ..errors import IntegrationError, InvalidInputError
from ..integration.trajectory import RunStats
from ..model.scene import Scene


@dataclass
class BaselineResult:
    """Outcome of a baseline run.

    Attributes:
        t, q, v: final time and state.
        event_times: times of the events, in order.
        event_contacts: contact names of each event.
        stats: a `RunStats` with ``dynamics_evaluations`` (calls of
            `ModeDynamics.solve`), ``steps``, ``events`` and, for solve_ivp,
            ``stepper_evaluations`` (its right-hand-side calls).
    """

    t: float
    q: np.ndarray
    v: np.ndarray
    event_times: list[float] = field(default_factory=list)
    event_contacts: list[tuple[str, ...]] = field(default_factory=list)
    stats: RunStats = field(default_factory=RunStats)


class _Counted:
    """`ModeDynamics.solve` with a call counter and a one-entry cache."""

    def __init__(self, scene: Scene):
        self.dyn = ModeDynamics(scene)
        self.n = 0
        self._last = None

    def solve(self, q, v, t, mode):
        last = self._last
        if (
            last is not None
            and last[0] == t
            and last[3] == mode
            and np.array_equal(last[1], q)
            and np.array_equal(last[2], v)
        ):
            return last[4]
        self.n += 1
        sol = self.dyn.solve(q, v, t, mode)
        self._last = (t, q.copy(), v.copy(), mode, sol)
        return sol


def solve_ivp_baseline(
    scene: Scene,
    t_final: float,
    rtol: float = 1e-8,
    atol: float = 1e-10,
    method: str = "DOP853",
    *,
    contact_tol: float = 1e-8,
    max_events: int = 1000,
) -> BaselineResult:
    """Event-driven simulation with plain `scipy.integrate.solve_ivp` (see the module doc).

    Raises:
        InvalidInputError: the scene has a Lie-group configuration (``nq != nv``).
        IntegrationError: solve_ivp failed, or more than ``max_events`` events.
    """
    if scene.robot.nq != scene.nv:
        raise InvalidInputError(
            f"solve_ivp_baseline needs a vector-space configuration (nq == nv); scene "
            f"{scene.name!r} has nq = {scene.robot.nq}, nv = {scene.nv} (free-flyer or "
            "continuous joints): use time_stepping_baseline or simulate"
        )
    nv, contacts, names = scene.nv, scene.contacts, scene.contact_names
    f = _Counted(scene)
    kin = f.dyn.kin

    def gap(q, i):
        kin.update(q, np.zeros(nv))
        return contacts[i].gap(kin)

    def make_rhs(mode):
        def rhs(t, y):
            return np.concatenate([y[nv:], f.solve(y[:nv], y[nv:], t, mode).ddq])

        return rhs

    def guards(mode):
        """``((kind, key or contact), event function)`` of every guard of ``mode`` (keys
        of `contactdiff.dynamics.mode`: a sliding contact's force guard has its sliding key)."""
        events = []
        for k, key in enumerate(mode):

            def ev(t, y, k=k, mode=mode):
                return f.solve(y[:nv], y[nv:], t, mode).normal_forces()[k]

            events.append((("force", key), ev))
        active = f.dyn.contacts_of(mode)
        for i in (i for i in range(len(contacts)) if i not in active):
            events.append((("gap", i), lambda t, y, i=i: gap(y[:nv], i)))
        for _, ev in events:
            ev.terminal, ev.direction = True, -1
        return events

    t, q, v = 0.0, scene.q0.copy(), scene.v0.copy()
    gaps = scene.gaps(q)
    closed = [i for i, g in enumerate(gaps) if g <= contact_tol]
    mode = choose_mode(f.dyn, q, v, t, closed) if closed else ()
    times, fired_names = [], []
    nfev = steps = 0
    while t < t_final:
        mode = tuple(sorted(mode))
        evs = guards(mode)
        sol = solve_ivp(
            make_rhs(mode),
            (t, t_final),
            np.concatenate([q, v]),
            method=method,
            rtol=rtol,
            atol=atol,
            events=[e for _, e in evs],
        )
        nfev += sol.nfev
        steps += len(sol.t) - 1
        if sol.status == -1:
            raise IntegrationError(f"solve_ivp failed at t = {sol.t[-1]}: {sol.message}")
        t, q, v = float(sol.t[-1]), sol.y[:nv, -1].copy(), sol.y[nv:, -1].copy()
        if sol.status == 0:
            break
        # which guards fire at this instant: the terminal one, and any within contact_tol
        gaps = scene.gaps(q)
        forces = f.solve(q, v, t, mode).normal_forces() if mode else np.zeros(0)
        scale = max(1.0, float(np.max(np.abs(forces)))) if mode else 1.0
        active = f.dyn.contacts_of(mode)
        touching = [i for i in range(len(contacts)) if i not in active and gaps[i] <= contact_tol]
        releasing = [key for k, key in enumerate(mode) if forces[k] <= contact_tol * scale]
        terminal = [guard for (guard, _), te in zip(evs, sol.t_events) if len(te) and te[-1] == t]
        for kind, i in terminal:  # the guard that stopped solve_ivp fires even outside contact_tol
            if kind == "force" and i not in releasing:
                releasing.append(i)
            elif kind == "gap" and i not in touching:
                touching.append(i)
        if touching:
            closed = sorted(set(mode) | set(touching))
            impact = resolve_impact(f.dyn, q, v, closed)
            v = impact.v_plus
            speed = max(1.0, float(np.max(np.abs(impact.normal_speeds_before))))
            staying = [
                i for i, s in zip(closed, impact.normal_speeds_after) if s <= 1e-12 * speed and i not in releasing
            ]
            mode = choose_mode(f.dyn, q, v, t, staying)
            fired = touching + releasing
        else:
            fired = releasing
            mode = liftoff_mode(f.dyn, q, v, t, mode, releasing)
        times.append(t)
        fired_names.append(tuple(names[i] for i in sorted(set(f.dyn.contacts_of(fired)))))
        if len(times) > max_events:
            raise IntegrationError(f"solve_ivp_baseline: more than {max_events} events by t = {t}")
    return BaselineResult(
        t,
        q,
        v,
        times,
        fired_names,
        RunStats(
            dynamics_evaluations=f.n, stepper_evaluations=nfev, steps=steps, events=len(times), method="solve_ivp"
        ),
    )


def time_stepping_baseline(
    scene: Scene, t_final: float, dt: float, *, gap_threshold: float = 0.0, gap_term: bool = True
) -> BaselineResult:
    """Fixed-step impulse-based time stepping (see the module doc) from 0 to ``t_final``.

    The last step is shortened to end exactly at ``t_final``.
    """
    if not (dt > 0 and np.isfinite(dt)):
        raise InvalidInputError(f"time_stepping_baseline: dt must be > 0, got {dt!r}")
    model = scene.model
    contacts, names = scene.contacts, scene.contact_names
    dyn = ModeDynamics(scene)
    kin, data = dyn.kin, dyn.data
    q, v, t = scene.q0.copy(), scene.v0.copy(), 0.0
    n_steps = int(np.ceil(t_final / dt - 1e-9))
    carrying = np.zeros(len(contacts), dtype=int)  # consecutive steps with impulse
    times, fired_names = [], []
    for n in range(n_steps):
        h = min(dt, t_final - t)
        a_free = dyn.solve(q, v, t, ()).ddq  # updates kin at (q, v)
        v_star = v + h * a_free
        A_all = [c.rows(kin) for c in contacts]
        gaps = np.array([c.gap(kin) for c in contacts])
        cand = [
            i
            for i in range(len(contacts))
            if gaps[i] <= gap_threshold or gaps[i] + h * float(A_all[i][0] @ v_star) < 0.0
        ]
        now = np.zeros(len(contacts), dtype=bool)
        if cand:
            A = np.vstack([A_all[i] for i in cand])
            rows = ContactRows.from_sizes([contacts[i].n_rows for i in cand])
            MinvAT = cho_solve(cho_factor(pin.crba(model, data, q)), A.T)
            Av = A @ v_star
            e = np.array([contacts[i].restitution for i in cand])
            e[Av[list(rows.normal)] >= 0.0] = 0.0
            b = impact_rhs(Av, e, rows)
            if gap_term:
                plastic = [k for k, i in enumerate(cand) if contacts[i].restitution == 0.0]
                b[[rows.normal[k] for k in plastic]] += gaps[[cand[k] for k in plastic]] / h
            sol = solve_contact_lcp(A @ MinvAT, b, rows, on_infeasible="relax")
            v_next = v_star + MinvAT @ sol.x
            for k, i in enumerate(cand):
                now[i] = sol.x[rows.normal[k]] > 0.0
        else:
            v_next = v_star
        started = [i for i in range(len(contacts)) if now[i] and carrying[i] == 0]
        ended = [i for i in range(len(contacts)) if not now[i] and carrying[i] >= 2]
        if started or ended:
            times.append(t)
            fired_names.append(tuple(names[i] for i in sorted(started + ended)))
        carrying = np.where(now, carrying + 1, 0)
        if not np.all(np.isfinite(v_next)) or np.max(np.abs(v_next)) > 1e8:
            raise IntegrationError(
                f"time_stepping_baseline diverged at t = {t:.6g} with dt = {dt:g} "
                "(explicit efforts too stiff for this step)"
            )
        q = pin.integrate(model, q, h * v_next)
        v = v_next
        t = t_final if n == n_steps - 1 else t + h
    return BaselineResult(
        t,
        q,
        v,
        times,
        fired_names,
        RunStats(dynamics_evaluations=n_steps, steps=n_steps, events=len(times), method="time-stepping"),
    )


__all__ = ["BaselineResult", "solve_ivp_baseline", "time_stepping_baseline"]
