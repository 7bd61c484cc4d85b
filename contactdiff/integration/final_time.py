"""A contact that touches at the final time: the final state's one-sided derivatives.

A run ends at ``T`` with no event for a contact whose gap reaches zero at ``T``
itself (the gap ends at 0, not below it: no crossing), and a landing a round-off
before ``T`` is an event followed by a step of that round-off. Either way the
final state ``x(T; x0)`` has a kink there: initial states on one side land before
``T`` (an impact), those on the other side after it (none), so it has two
one-sided derivatives, the run's Jacobian being one of them. No event of the run
can say so; `final_touches` does, for the run's verdict
(`Trajectory.final_nonsmooth`, `NonSmooth.FINAL_TIME`).

A contact touches at ``T`` when, with a normal speed above ``grazing_speed`` (a
slower one is a grazing touch, not an impact), it is open and its gap would close
within ``simultaneous_tol`` (the time within which two guards are one event), or it
landed (touchdown, bounce) within ``simultaneous_tol`` before ``T``.
"""

from __future__ import annotations

import numpy as np

from .options import SimulateOptions
from .trajectory import Event

IMPACT_KINDS = ("touchdown", "bounce")
"""Event kinds with an impact at a nonzero normal speed (a Zeno end closes below the
Zeno speed, a grazing touch at zero speed)."""


def final_touches(
    names,
    gaps: np.ndarray,
    rates: np.ndarray,
    held: set[int],
    events: list[Event],
    t_final: float,
    options: SimulateOptions,
) -> list[str]:
    """Remarks, one per contact touching at ``t_final`` (module doc); empty if none.

    Args:
        names: the scene's contact names, in scene order.
        gaps: every contact's gap at ``t_final`` (m).
        rates: every contact's gap rate at ``t_final`` (m/s, negative when closing).
        held: scene indices of the contacts closed in the final mode.
        events: the run's events, in time order.
        t_final: the final time (s).
        options: the run's options (``simultaneous_tol``, ``grazing_speed``).
    """
    tol, slow = options.simultaneous_tol, options.grazing_speed
    remarks = []
    for i, name in enumerate(names):
        if i in held or not rates[i] < -slow:
            continue
        if gaps[i] <= tol * -rates[i]:
            remarks.append(
                f"{name} touches at the final time t = {t_final:.12g} (gap {gaps[i]:.3g} m closing at "
                f"{-rates[i]:.3g} m/s): the final state has one-sided derivatives only; the Jacobian "
                "is the one of the side on which it has not landed yet"
            )
    for event in reversed(events):
        if event.t < t_final - tol:
            break
        if event.kind not in IMPACT_KINDS:
            continue
        for name in event.contacts:
            if -event.normal_speeds.get(name, 0.0) > slow:
                remarks.append(
                    f"{name} landed at t = {event.t:.12g}, within simultaneous_tol of the final time "
                    f"{t_final:.12g}: the final state has one-sided derivatives only; the Jacobian "
                    "is the one of the side on which it has landed"
                )
    return remarks
