"""Impact with Coulomb friction of finite coefficient (pure numpy, no Pinocchio).

The law
-------
Each closed contact ``k`` owns a normal row ``n_k`` and 0, 1 (planar) or 2
(spatial) tangential rows ``t_k``, laid out by a `ContactRows`. With the
Delassus matrix ``G = A M^-1 A^T`` (symmetric positive semidefinite) and the
pre-impact row velocities ``u- = A v-``, the row impulses ``Λ`` give the
post-impact row velocities ``u+ = u- + G Λ`` (and ``v+ = v- + M^-1 A^T Λ``).
:func:`solve_frictional_impact` finds ``Λ`` such that, for every contact:

* **Normal, Newton's kinematic restitution with complementarity**:
  ``Λ_N >= 0``, ``w_N = u+_N + e u-_N >= 0`` and ``Λ_N w_N = 0``; ``e`` in
  [0, 1], replaced by 0 for a contact that is not approaching (``u-_N >= 0``),
  as `contactdiff.dynamics.impacts.resolve_impact` does.
* **Tangential, Coulomb's law with maximal dissipation on the post-impact slip**
  (Moreau's impact law with Newton's coefficient on the normal):
  ``||Λ_T|| <= μ Λ_N``; if ``||u+_T|| > 0`` then ``Λ_T = -μ Λ_N u+_T / ||u+_T||``
  (*slide*), else the contact *sticks* (``u+_T = 0``, ``Λ_T`` anywhere in the
  cone). ``μ = inf`` is the sticking contact of `solve_contact_lcp` (tangential
  rows are equalities ``u+_T = 0``, no cone); ``μ = 0`` and contacts without
  tangential rows are frictionless (``Λ_T = 0``).

Each contact ends `ContactState.OPEN` (``Λ = 0``), ``STICK`` or ``SLIDE``. A
closed contact without friction (no tangential rows, or ``μ = 0``) is reported
``SLIDE``: its tangential motion is free.

How it is solved, and what "exact" means
----------------------------------------
By enumeration of the contacts' states. For each candidate the equalities are
solved: open ``Λ_k = 0``; stick ``w_N = 0`` and ``u+_T = 0``; slide ``w_N = 0``
and ``Λ_T = -μ Λ_N s`` with the unit slip direction ``s`` an unknown. For
given ``s`` this is one linear system; ``s`` is ``±1`` on a planar contact
(both signs are tried) and ``(cos θ, sin θ)`` on a spatial one, where ``θ``
solves ``atan2(u+_T(θ)) = θ``: with one spatial sliding contact as every root
of the cross form below, in closed form (a quartic's roots on the unit circle,
`contactdiff.dynamics.slip_circle`), each polished by Newton (where that form
gives no answer, by a scan of the circle, also split beside the poles of ``Λ_N``,
then bisection and a Newton polish, and the sign changes of the cross form
polished too: a slip that vanishes at one direction, its impulse on the cone's
edge, is a root of that form only);
with several by Newton's method with a line search on the smooth cross form
``s_k x u+_T,k(θ) = 0`` (no angle wrap, and no ``1/||u+_T||`` that makes a root
with a small slip a needle in ``θ``), run at once from the pre-impact slip,
an approximate solution of the whole law (projected Gauss-Seidel), the
frictionless slip and every local minimum of a grid on the torus; the grid is
skipped where a bound proves the map from the slip angles to the slips' angles
a contraction, whose one root Newton finds from the first three (see
`contactdiff.dynamics.friction_slip`). The roots of a candidate are tried
nearest the pre-impact slip directions first. Every condition of the
law is then checked on the candidate, and the first candidate that satisfies
all within the tolerance is returned. Two rejections skip work without changing
which candidate that is: a candidate whose closed contact pulls, by far more than
the tolerance, at every slip angle of its sliders (a bound over all angles,
`contactdiff.dynamics.slip_lowrank`) is not searched, and a candidate's roots that
break an inequality of the law by that much are rejected in one batch before the
others are checked one by one. "Exact" means: the true circular cone
(no polyhedral approximation, no regularisation or penalty), and an answer
that satisfies every condition of the law up to the scaled residual ``tol``
(about 1e-15 in practice: the linear solves are backward stable and Newton
converges quadratically). It does not mean the search is complete: for
several spatial sliding contacts without the contraction's proof a root may lie
between the grid's basins
(none missed in 9000 random problems of 1-3 spatial contacts with ``e`` in
[0, 1]; the earlier search on the angle residual, without the poles in the
one-slider scan, missed 6 of the first 1800), so a `SolverError` there is
not a proof that no solution exists (for planar and
sticking contacts the search is finite and complete).

Enumeration order and tie rule
------------------------------
When a contact has a finite ``μ > 0``, the candidate that an approximate
solution of the law points to (projected Gauss-Seidel, `SlipDirections.fixed_point`:
open where its normal impulse is zero, sticking where its slip is zero, else
sliding) is tried first and checked like any other: where it is right, the
dozens of candidates before it in the order below (each a search for slip
directions) are skipped. Otherwise, and when that candidate fails: closed
sets from most contacts to fewest, lexicographic in the contact indices within
a size (the order of `solve_contact_lcp`: contacts stay engaged where they
can); within a closed set, fewest sliding contacts first (stick before slide),
lexicographic within a count; a planar sliding contact tries the sign of its
pre-impact slip first (+1 if there is none). With friction the
law may have several solutions (strong coupling, large ``μ``); the first valid
candidate in this order is returned (the approximate solution's, if valid). With
``μ = inf`` or ``0`` everywhere there is no first guess, and this is exactly the
active set that `solve_contact_lcp` enumerates first.

Redundant rows
--------------
When rows are dependent (the four corners of a face landing flat: normal rows of
rank 3), a candidate's equality system is singular and the law alone leaves the
impulses undetermined. They are then the impulses of equal compliant supports in
the rigid limit (`contactdiff.dynamics.redundant`): on the candidate's equality
rows, in the range of those rows. The approximate solution is not taken as it
is there (projected Gauss-Seidel on a singular ``G`` converges to some solution, not
to the principle's): its pattern is first completed by closing every contact it
leaves without impulse at zero normal speed, and a guessed solution that leaves such
a contact open is not taken; the enumeration's order (most contacts closed first)
decides otherwise.

Energy (known limit)
--------------------
The change of kinetic energy is ``ΔT = Λ^T u- + ½ Λ^T G Λ = ½ Λ^T (u- + u+)``
(from ``v+ = v- + M^-1 A^T Λ``). With ``e = 0`` it is never positive: normal
rows give ``Λ_N u+_N = 0``, tangential rows ``Λ_T . u+_T = -μ Λ_N ||u+_T|| <= 0``,
so ``ΔT = Λ^T u+ - ½ Λ^T G Λ <= 0``. With ``e > 0`` the normal rows add
``-e Λ_N u-_N >= 0``, and when the tangential impulse couples into the normal
velocity (``G_NT != 0``) Newton's kinematic restitution can *increase* the
energy even with finite friction (Kane's paradox; e.g. a planar contact with
``e = 1`` that sticks, see the tests; about 4 % of random coupled problems
with ``e`` in [0, 1], sticking or sliding, one contact or several). This is a property of the law, not a
numerical error: the result reports ``energy_change`` and ``energy_gain``, and
``on_energy_gain="raise"`` raises `EnergyGainError` instead.

Existence: with ``μ = inf`` a sticking solution may not exist (Painleve-type,
see `solve_contact_lcp`); with finite ``μ`` the enumeration raises
`SolverError` naming the best candidate if none is valid.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterator, Sequence

import numpy as np

from ..errors import EnergyGainError, InvalidInputError, SolverError
from .impact_candidate import ContactState, FrictionalImpact, ImpactCandidates, describe_states
from .lcp_problem import DEFAULT_TOL, ContactRows, as_real_array, as_row_vector, validate_lcp

__all__ = [
    "ContactState",
    "EnergyGainError",
    "FrictionalImpact",
    "solve_frictional_impact",
    "FRICTION_ENUMERATE_MAX",
]

#: Largest number of contacts accepted (at most 3^n state candidates, times
#: the slip signs of planar sliding contacts).
FRICTION_ENUMERATE_MAX = 8

# A normal impulse, or a post-impact slip, below this share of its scale in the
# approximate solution (`SlipDirections.fixed_point`) is taken for zero in the
# candidate tried first: its sweeps stop at 1e-14 relative change (or at the cap,
# `friction_slip._FP_SWEEPS`), so a contact that should open or stick is far below this.
_GUESS_ZERO = 1e-6


def solve_frictional_impact(
    G: np.ndarray,
    u_minus: np.ndarray | Sequence[float],
    rows: ContactRows,
    restitution: float | np.ndarray | Sequence[float],
    friction: float | np.ndarray | Sequence[float],
    *,
    tol: float = DEFAULT_TOL,
    on_energy_gain: str = "flag",
) -> FrictionalImpact:
    """Solve the frictional impact law of the module doc by enumeration.

    Args:
        G: Delassus matrix ``A M^-1 A^T`` over all rows, shape ``(m, m)``,
            symmetric positive semidefinite (symmetry checked to a relative
            1e-8, then enforced).
        u_minus: Pre-impact row velocities ``A v-``, shape ``(m,)``.
        rows: Row layout (normal row, then 0-2 tangential rows per contact).
        restitution: Newton coefficient in [0, 1], scalar or one per contact.
        friction: Coulomb coefficient ``μ >= 0`` or ``inf`` (sticking), scalar
            or one per contact; ignored for contacts without tangential rows.
        tol: Acceptance tolerance on the scaled residual
            (`contactdiff.dynamics.lcp_problem.DEFAULT_TOL`).
        on_energy_gain: ``"flag"`` (default: set ``energy_gain``) or
            ``"raise"`` (raise `EnergyGainError`).

    Returns:
        The first valid candidate in the enumeration order of the module doc.

    Raises:
        InvalidInputError: Bad shapes, non-finite entries, asymmetric ``G``,
            ``e`` outside [0, 1], negative or NaN ``μ``, bad ``tol`` or
            ``on_energy_gain``, more than `FRICTION_ENUMERATE_MAX` contacts.
        SolverError: No candidate is valid; the message names the best one.
        EnergyGainError: ``on_energy_gain="raise"`` and the solution gains energy.
    """
    if not isinstance(rows, ContactRows):
        raise InvalidInputError(f"rows must be a ContactRows; got {type(rows).__name__}")
    m, n = rows.n_rows, rows.n_contacts
    G, _ = validate_lcp(G, np.zeros(m), rows, tol, "auto")
    u = as_row_vector(u_minus, "u_minus", m)
    e = _per_contact(restitution, "restitution", n)
    bad = ~np.isfinite(e) | (e < 0.0) | (e > 1.0)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise InvalidInputError(f"restitution of contact {k} is {float(e[k])!r}; valid: 0 <= e <= 1")
    mu = _per_contact(friction, "friction", n)
    bad = np.isnan(mu) | (mu < 0.0)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise InvalidInputError(f"friction coefficient of contact {k} is {float(mu[k])!r}; valid: mu >= 0 or inf")
    if on_energy_gain not in ("flag", "raise"):
        raise InvalidInputError(f"on_energy_gain is {on_energy_gain!r}; valid: 'flag', 'raise'")
    if n > FRICTION_ENUMERATE_MAX:
        raise InvalidInputError(f"solve_frictional_impact accepts at most {FRICTION_ENUMERATE_MAX} contacts; got {n}")
    normal = np.array(rows.normal, dtype=np.intp)
    e = np.where(u[normal] < 0.0, e, 0.0)
    if n == 0:
        return FrictionalImpact(np.zeros(0), np.zeros(0), (), (), e, 0.0, "enumerate", 0.0, False, 0)
    prob = _Impact(G, u, rows, e, mu, tol)
    out = prob.solve()
    if out.energy_gain and on_energy_gain == "raise":
        raise EnergyGainError(
            f"frictional impact: the solution gains kinetic energy dT = {out.energy_change:.6g} "
            f"(states {describe_states(out.states)}, restitution {e.tolist()}, friction {mu.tolist()}); "
            "Newton's kinematic restitution with friction coupling (Kane's paradox)"
        )
    return out


# --------------------------------------------------------------------------
# internals


def _per_contact(value: object, name: str, n: int) -> np.ndarray:
    arr = as_real_array(value, name)
    if arr.ndim == 0:
        return np.full(n, float(arr))
    if arr.shape != (n,):
        raise InvalidInputError(f"{name} has shape {arr.shape}; valid: scalar or ({n},), one per contact")
    return arr.astype(float, copy=True)


class _Impact(ImpactCandidates):
    """One validated problem: its candidates enumerated in the documented order, the
    approximate solution's first (`contactdiff.dynamics.impact_candidate` solves and
    checks each)."""

    # ---- enumeration ---------------------------------------------------
    def candidates(self) -> Iterator[tuple[tuple[ContactState, ...], tuple[int, ...]]]:
        """State tuples in the documented order, with the spatial sliders."""
        n = self.n
        for size in range(n, -1, -1):
            for closed in itertools.combinations(range(n), size):
                choice = [k for k in closed if not self.frictionless[k] and not self.sticky[k]]
                for n_slide in range(len(choice) + 1):
                    for sliding in itertools.combinations(choice, n_slide):
                        st = [ContactState.OPEN] * n
                        for k in closed:
                            if self.frictionless[k] or k in sliding:
                                st[k] = ContactState.SLIDE
                            else:
                                st[k] = ContactState.STICK
                        yield tuple(st), sliding

    def predicted(self, complete: bool = False) -> tuple[tuple[ContactState, ...], tuple[int, ...]] | None:
        """The candidate an approximate solution of the law points to (`fixed_point`):
        open where its normal impulse is below `_GUESS_ZERO` of the largest, sticking
        where its post-impact slip is below `_GUESS_ZERO` of the velocity scale, else
        sliding; None without a contact of finite positive ``μ`` (the enumeration is
        then linear solves only).

        With ``complete``, a contact the approximation leaves without impulse but
        closing at zero normal speed (``w_N`` below `_GUESS_ZERO` of the velocity
        scale) is closed too: with dependent rows the approximation puts the load on
        some of the contacts that hold the same motion, the principle on all of them
        (module doc, "Redundant rows")."""
        if all(self.frictionless[k] or self.sticky[k] for k in range(self.n)):
            return None
        lam, up = self.fixed_point()
        lam_max = float(np.abs(lam).max())
        if not np.isfinite(lam_max) or lam_max == 0.0:
            return None
        vscale = self.bmax + self.gmax * lam_max
        states = []
        for k in range(self.n):
            t, n = self.tang[k], self.normal[k]
            w_n = up[n] + self.e[k] * self.u[n]
            if lam[n] <= _GUESS_ZERO * lam_max and not (complete and abs(w_n) <= _GUESS_ZERO * vscale):
                states.append(ContactState.OPEN)
            elif self.frictionless[k]:
                states.append(ContactState.SLIDE)
            elif self.sticky[k] or np.linalg.norm(up[t]) <= _GUESS_ZERO * vscale:
                states.append(ContactState.STICK)
            else:
                states.append(ContactState.SLIDE)
        sliding = tuple(k for k, st in enumerate(states) if st is ContactState.SLIDE and not self.frictionless[k])
        return tuple(states), sliding

    def solve(self) -> FrictionalImpact:
        # with dependent rows the approximation's pattern completed first, then as it is
        guesses = [self.predicted(complete=True), self.predicted()] if self.redundant else [self.predicted()]
        # the guesses that failed (a candidate is a function of the problem: tried again in
        # the enumeration, it fails again; it is counted, and its search's failure noted, again)
        failed: dict[tuple, bool] = {}
        for guess in dict.fromkeys(g for g in guesses if g is not None):
            states, sliding = guess
            planar = [k for k in sliding if self.tang[k].size == 1]
            spatial = [k for k in sliding if self.tang[k].size == 2]
            _, up = self.fixed_point()
            signs = {k: (1.0 if up[self.tang[k][0]] >= 0.0 else -1.0) for k in planar}
            self.tried += 1
            noted = len(self.newton_failed)
            out = self.try_candidate(states, signs, spatial)
            if out is not None:
                return out
            failed[(states, tuple(sorted(signs.items())))] = len(self.newton_failed) > noted
        for states, sliding in self.candidates():
            planar = [k for k in sliding if self.tang[k].size == 1]
            spatial = [k for k in sliding if self.tang[k].size == 2]
            pref = {k: (1.0 if self.u[self.tang[k][0]] >= 0.0 else -1.0) for k in planar}
            for flips in itertools.product((1.0, -1.0), repeat=len(planar)):
                signs = {k: pref[k] * f for k, f in zip(planar, flips)}
                self.tried += 1
                key = (states, tuple(sorted(signs.items())))
                if key in failed:
                    if failed[key]:
                        self.newton_failed.append(describe_states(states, signs))
                    continue
                out = self.try_candidate(states, signs, spatial)
                if out is not None:
                    return out
        res, where = self.best
        extra = ""
        if self.newton_failed:
            extra = (
                f"; Newton found no slip direction for {len(self.newton_failed)} candidate(s), "
                f"e.g. {self.newton_failed[0]} (a spatial slip direction may have been missed)"
            )
        u_txt = np.array2string(self.u, precision=6, max_line_width=200)
        raise SolverError(
            f"frictional impact: no valid state candidate among {self.tried} for G of size "
            f"{self.m}x{self.m} ({self.n} contacts), u- = {u_txt}, restitution {self.e.tolist()}, "
            f"friction {self.mu.tolist()}; best scaled residual {res:.3g} with states {where} "
            f"(tol {self.tol:g}){extra}"
        )
