"""Choosing the stepper of ``simulate(method="auto")``: explicit unless stability limits it.

An explicit Runge–Kutta step of size ``h`` is stable only while ``h ρ`` stays
inside the method's stability region, ``ρ`` being the spectral radius of the
flow's first-order Jacobian

    DF = [[G, I], [∂a/∂q, ∂a/∂v]]     (tangent space; G = -ad(v) on Lie groups)

of the current contact mode (1/s). DOP853's region reaches ``|h λ| ≈ 6.4`` on
the negative real axis and ``≈ 6.0`` on the imaginary axis. When the
accuracy asked for would allow longer steps than that — a stiff spring whose
fast motion is damped out or was never excited — error control holds ``h ρ``
near the boundary step after step: the explicit method is limited by
stability, and an implicit method (Radau IIA, stable for every ``h``) is
cheaper. When the fast motion is excited and undamped (a stiff spring ringing
after an impact) every accurate method must resolve it; the explicit steps
then have ``h ρ`` well below the boundary and the explicit method is cheaper.

The rule (after Hairer's stiffness detection in DOP853 and LSODA's switching):

* ``ρ`` is measured once a mode has taken `PROBE_AFTER` steps (shorter modes
  never pay for it), by Arnoldi's method on difference quotients of the
  mode's accelerations (`spectral_radius`: at most `KRYLOV` + 1 evaluations,
  no derivatives, so a run without ``jacobian=True`` stays free of derivative
  work), and again at the current state before any switch;
* explicit to stiff: `SWITCH_COUNT` of the last `WINDOW` explicit steps had
  ``h ρ >= STIFF_RATIO`` (two thirds of the stability boundary);
* stiff to explicit: `SWITCH_COUNT` of the last `WINDOW` Radau steps had
  ``h ρ <= EXPLICIT_RATIO`` (steps an explicit method takes stably and, being
  of higher order, at least as long for the same accuracy);
* a trial: one of the first `TRIAL_STEPS` Radau steps after a switch from
  explicit must reach ``1 / TRIAL_MARGIN`` of the median explicit step of the
  window that asked for it (Radau's first steps after a switch are about the
  explicit ones and grow slowly: its controller keeps a step, and its LU, while
  the factor is near 1). If none does, Radau is clearly not cheaper here (explicit steps with ``h ρ >= 3`` can be
  limited by accuracy, not stability: a flow Jacobian's columns, resolved by
  the error control, hold DOP853's steps at ``h ρ ≈ 4.5`` on a solo12 drop,
  where Radau's own error control then takes steps 14 times shorter): the
  chooser returns to explicit at once and refuses Radau for the rest of the
  mode.

The choice carries over from mode to mode: a run starts explicit, and a mode
that follows a stiff one starts stiff.

**Round-off.** Step sizes carry the last bits of the arithmetic (a BLAS
kernel's order of summation moves an error norm, and a step accepted on one
CPU can be rejected on another), so any rule on step sizes decides a little
differently on different CPUs; the rule is made so that such a difference
cannot change much. The two thresholds are a factor of three apart
(hysteresis), each on a count of 12 steps out of 15 rather than on one step,
and the steps of each regime sit far from them: stability-limited DOP853
steps at ``h ρ ≈ 5-7``, Radau steps of a stiff mode at ``h ρ`` in the tens
to thousands, those resolving a fast motion below 1. Where a run's steps do
sit near ``STIFF_RATIO`` (accuracy-limited explicit steps growing through
it), the trial bounds what a switch made on one CPU and not on another costs:
at most `TRIAL_STEPS` Radau steps, not a stiff stretch of Radau steps
shorter than the explicit ones it replaced. Results agree to the tolerance
whichever method takes a step; counts of steps and evaluations can differ
by the trial's few steps.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from ..errors import OutsideDomainError

EXPLICIT, STIFF = "DOP853", "Radau"
STIFF_RATIO = 3.0  # h ρ of a stability-limited DOP853 step (boundary ≈ 6; ~3-4 at rtol 1e-12)
EXPLICIT_RATIO = 1.0  # h ρ of a Radau step that resolves the fastest motion
WINDOW = 15  # steps looked at (Hairer's DOP853 declares stiffness after 15)
SWITCH_COUNT = 12  # of which this many must agree
TRIAL_STEPS = 3  # Radau steps after a switch from explicit, of which one must reach
TRIAL_MARGIN = 4.0  # 1 / TRIAL_MARGIN of the explicit steps' median (module doc)
PROBE_AFTER = 8  # steps in a mode before ρ is measured
KRYLOV = 12  # Arnoldi products (accel calls) of one measurement of ρ


def field_probe(accel, group=None):
    """``probe(q, v, t)``: the `spectral_radius` of the field ``accel(t, q, v)`` at a state,
    for `MethodChooser`; NaN where a probe point leaves the field's domain (an
    `OutsideDomainError`): no measure, and the method stays."""

    def probe(q: np.ndarray, v: np.ndarray, t: float) -> float:
        try:
            return spectral_radius(accel, q, v, t, group)
        except OutsideDomainError:
            return math.nan

    return probe


def spectral_radius(accel, q: np.ndarray, v: np.ndarray, t: float, group=None, krylov: int = KRYLOV) -> float:
    """Largest ``|λ|`` of the first-order tangent-space Jacobian ``DF`` of ``dv/dt = accel``
    at ``(q, v, t)`` (1/s), without derivatives.

    Arnoldi's method on ``DF`` with ``min(krylov, 2 nv)`` products, each a forward
    difference of ``accel`` along the direction (one ``accel`` call): the Ritz value
    of largest modulus. With ``2 nv <= krylov`` the Krylov space is the whole
    tangent space and the Ritz values are the eigenvalues of the difference
    Jacobian; beyond, the extreme eigenvalues are the ones Arnoldi finds first.
    The start vector is fixed (seeded), so the estimate is reproducible.

    Args:
        accel: ``accel(t, q, v) -> dv/dt`` (nv,).
        q: configuration (nq,).
        v: velocity (nv,), tangent space.
        t: time (s).
        group: the configuration's Lie group (a `steppers.PinocchioGroup`) or None
            for a vector space (``q ⊕ δq = q + δq``).
        krylov: largest number of products.
    """
    nv = v.size
    n = 2 * nv
    lie = group is not None and not group.is_vector_space
    G = group.velocity_jacobian_q(q, v) if lie else None
    a0 = np.asarray(accel(t, q, v), dtype=float)
    size = max(1.0, float(np.max(np.abs(q))), float(np.max(np.abs(v))))
    eps = np.sqrt(np.finfo(float).eps) * size

    def product(w):
        wq, wv = w[:nv], w[nv:]
        q_eps = group.integrate(q, eps * wq) if group is not None else q + eps * wq
        out = np.empty(n)
        out[:nv] = wv + (G @ wq if lie else 0.0)
        out[nv:] = (np.asarray(accel(t, q_eps, v + eps * wv), dtype=float) - a0) / eps
        return out

    m = min(int(krylov), n)
    V = np.zeros((n, m + 1))
    H = np.zeros((m + 1, m))
    w = np.random.default_rng(0).standard_normal(n)
    V[:, 0] = w / np.linalg.norm(w)
    k = m
    for j in range(m):
        u = product(V[:, j])
        for i in range(j + 1):  # modified Gram-Schmidt
            H[i, j] = V[:, i] @ u
            u -= H[i, j] * V[:, i]
        H[j + 1, j] = np.linalg.norm(u)
        if H[j + 1, j] <= 1e-12 * max(1.0, np.abs(H[: j + 1, j]).max()):
            k = j + 1  # invariant subspace: its eigenvalues are exact
            break
        V[:, j + 1] = u / H[j + 1, j]
    return float(np.max(np.abs(np.linalg.eigvals(H[:k, :k])))) if k else 0.0


class MethodChooser:
    """Decides, after every accepted step, whether ``method="auto"`` should switch.

    Args:
        probe: ``probe(q, v, t) -> ρ`` of the current mode at a state (1/s).

    Attributes:
        method: the stepper in use (`EXPLICIT` or `STIFF`).
        rho: ``ρ`` of the current mode once measured, else None.
        n_probes: how many times ``ρ`` was measured.
    """

    def __init__(self, probe):
        self.probe = probe
        self.method = EXPLICIT
        self.rho: float | None = None
        self.n_probes = 0
        self._steps: deque[float] = deque(maxlen=WINDOW)
        self._mode_steps = 0
        self._trial: list[float] | None = None  # Radau's steps since a switch, while on trial
        self._explicit_step = 0.0  # median explicit step (s) of the window that switched
        self._refused = False  # a trial failed in this mode: no Radau until the next

    def new_mode(self, probe) -> None:
        """A mode starts: forget ``ρ`` and the steps of the last one (a trial under way
        goes on: it judges the method, whose steps restart short after an event)."""
        self.probe, self.rho = probe, None
        self._steps.clear()
        self._mode_steps = 0
        self._refused = False

    def _count(self, rho: float) -> int:
        if self.method == EXPLICIT:
            return sum(h * rho >= STIFF_RATIO for h in self._steps)
        return sum(h * rho <= EXPLICIT_RATIO for h in self._steps)

    def after_step(self, h: float, q: np.ndarray, v: np.ndarray, t: float) -> str | None:
        """Record an accepted step of size ``h`` (s) ending at ``(q, v, t)``; return the
        method to switch to, or None to go on."""
        self._steps.append(h)
        self._mode_steps += 1
        if self._trial is not None:
            self._trial.append(h)
            if max(self._trial) * TRIAL_MARGIN >= self._explicit_step:
                self._trial = None  # Radau's steps are not clearly shorter: the switch stands
            elif len(self._trial) >= TRIAL_STEPS:
                self._trial, self._refused = None, True
                self.method = EXPLICIT
                self._steps.clear()
                if self.rho is None:  # a mode that began during the trial: its ρ, for the switch's note
                    self.rho = self._measure(q, v, t)
                return self.method
        if self._mode_steps < PROBE_AFTER or (self._refused and self.method == EXPLICIT):
            return None
        if self.rho is None:
            self.rho = self._measure(q, v, t)
        if len(self._steps) < SWITCH_COUNT or self._count(self.rho) < SWITCH_COUNT:
            return None
        self.rho = self._measure(q, v, t)  # confirm at the current state
        if self._count(self.rho) < SWITCH_COUNT:
            return None
        if self.method == EXPLICIT:
            self._explicit_step = float(np.median(self._steps))
            self._trial = []
        else:
            self._trial = None
        self.method = STIFF if self.method == EXPLICIT else EXPLICIT
        self._steps.clear()
        return self.method

    def _measure(self, q, v, t) -> float:
        self.n_probes += 1
        return self.probe(q, v, t)
