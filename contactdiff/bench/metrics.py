"""How far a run is from its reference: final-state error, event-time error, and
the run time at which a curve of error against time reaches a target."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from ..model.scene import Scene


def state_error(scene: Scene, q, v, q_ref, v_ref) -> float:
    """``max(|q ⊖ q_ref|_inf, |v - v_ref|_inf)``, inf for a non-finite state."""
    if not (np.all(np.isfinite(q)) and np.all(np.isfinite(v))):
        return math.inf
    dq = pin.difference(scene.model, np.asarray(q_ref), np.asarray(q))
    return float(max(np.max(np.abs(dq)), np.max(np.abs(np.asarray(v) - v_ref))))


def event_error(times: Sequence[float], ref: Sequence[float]) -> float | None:
    """Largest difference of event times matched by order (common prefix), None if none."""
    n = min(len(times), len(ref))
    return float(max(abs(a - b) for a, b in zip(times[:n], ref[:n]))) if n else None


def time_at_error(points: Sequence[tuple[float, float]], target: float) -> tuple[float | None, str]:
    """Run time at which a curve of ``(time, error)`` first reaches ``target``.

    Log-log interpolation between the last point above and the first point at or
    below the target (in order of time). Returns ``(None, note)`` if never reached;
    if the cheapest point is already below, its time (an upper bound).
    """
    pts = sorted(points)
    for j, (t, e) in enumerate(pts):
        if e <= target:
            if j == 0:
                return t, "upper bound (cheapest run already below)"
            t0, e0 = pts[j - 1]
            le0, le1 = math.log(e0), math.log(max(e, 1e-300))
            s = (math.log(target) - le0) / (le1 - le0)
            return math.exp(math.log(t0) + s * (math.log(t) - math.log(t0))), ""
    if not pts:
        return None, "no runs"
    best = min(pts, key=lambda p: p[1])
    note = f"not reached (best {best[1]:.1e} at {1e3 * best[0]:.1f} ms"
    (t0, e0), (t1, e1) = pts[-2:] if len(pts) > 1 else (pts[0], pts[0])
    if len(pts) > 1 and e1 < e0 and t1 > t0:  # extend the last segment of the curve
        t_x = math.exp(
            math.log(t1)
            + (math.log(target) - math.log(e1)) * (math.log(t1) - math.log(t0)) / (math.log(e1) - math.log(e0))
        )
        note += f"; its last segment extended reaches it at ~{t_x:.3g} s"
    return None, note + ")"
