"""The decoupling checker: how far a scene is from the paper's assumptions.

Two conditions, each measured with numbers (docs/design.md §2, paper §3):

* **Orthogonality** (continuity of the flow): for every pair of contacts, the
  normalised inverse-mass coupling ``G_ij / sqrt(G_ii G_jj)`` with
  ``G = A M^-1 A^T`` (normal rows), at configurations where both contacts are
  closed: the scene's initial pose and seeded random poses, each projected onto
  ``a_i = a_j = 0`` by Gauss–Newton.
* **Limbs decoupled through the body** (differentiability through simultaneous
  contact): coordinates are split into one limb per contact (the coordinates on
  that contact's kinematic chain and on no other contact's) and the body (the
  rest). Then the mass matrix must be block diagonal with each block depending
  on its own coordinates, each gap must depend on its limb only, each limb's
  effort on its limb and the body only, and the body's effort additively on the
  limbs (zero mixed second derivatives across two limbs). Efforts here are
  ``tau - nle``: the scene's efforts minus Coriolis and gravity.

**A foot of several points.** A foot that touches at several points (an MJCF
leaf body with several collision spheres: Unitree G1's four under each ankle) is
one limb with several contacts (``robot.foot_choice.limbs``): its limb holds the
coordinates of all its points' chains, each of its gaps must depend on that limb
only, and the orthogonality pairs are between contacts of different limbs. The
couplings of two points of one foot (one rigid body: near 1 in general) are
reported apart (``within_limb``) and do not enter the verdict, which is about
limbs; the order in which one foot's points touch still changes outcomes, and a
note says so when they are coupled.

Every measure is relative (dimensionless) and compared with ``tol``. Verdicts:
``decoupled`` (all measures within tol: outcomes differentiable through
simultaneous contact), ``orthogonal only`` (couplings within tol but the limb
assumption fails: continuous, not differentiable in general) and ``coupled``
(some coupling above tol: outcomes jump when the contact order changes).
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InvalidInputError, check_count
from ..model.feet import FootRule
from ..model.robot import Robot
from ..model.scene import Scene
from ..scenes.scene_file import load_source
from .decoupling_measures import Checker
from .decoupling_report import COUPLED, DECOUPLED, ORTHOGONAL_ONLY, VERDICTS, DecouplingReport, PairCoupling, Term


# -- the checker ------------------------------------------------------------------------
def check_decoupling(
    source: Scene | Robot | str | Path,
    *,
    samples: int = 20,
    seed: int = 0,
    armature: float = 0.0,
    tol: float = 1e-9,
    spread: float = 0.4,
    states: Sequence[tuple[ArrayLike, ArrayLike, float]] | None = None,
) -> DecouplingReport:
    """Check a scene (or a robot on its feet) against the paper's assumptions.

    Args:
        source: a `Scene`, a `Robot` (ground contacts at its feet) or any SOURCE
            accepted by `load_source`.
        samples: random poses besides the reference (seeded by ``seed``).
        seed: seed of the random generator (``numpy.random.default_rng``) of the
            sampled poses and velocities.
        armature: rotor inertia added to the actuated joints (kg m²) before checking.
        tol: relative size below which a coupling or term counts as zero.
        spread: half-width of the uniform random perturbation of every coordinate
            around the reference pose (rad or m), and of the random velocities.
        states: optional ``(q, v)`` pairs or ``(q, v, t)`` triples (e.g. touchdown
            states of a gait, ``t`` in s, 0 if left out) at which to measure
            instead: the couplings at each ``q`` as given (no projection) and the
            limb terms at each ``(q, v)``, with the efforts at time ``t`` (a
            clock-driven controller's gains and targets depend on it); ``samples``
            and ``seed`` are then not used. Each ``q`` has ``nq`` entries, each
            ``v`` ``nv``.

    Returns:
        A `DecouplingReport`.
    """
    scene = _as_scene(source)
    samples = check_count("check_decoupling", "samples", samples)
    seed = check_count("check_decoupling", "seed", seed)
    if not (np.isfinite(tol) and tol > 0):
        raise InvalidInputError(f"tol must be a positive number, got {tol!r}")
    if armature:
        scene = scene.with_armature(armature)
    feet = scene.foot_choice.describe() if scene.foot_choice else ""
    groups = _limb_groups(scene)
    if len(groups) < 2:
        return DecouplingReport(
            scene=scene.name,
            robot=scene.robot.name,
            armature=float(armature),
            tol=float(tol),
            samples=0,
            seed=int(seed),
            body=[],
            limbs={},
            pairs=[],
            terms=[],
            verdict=None,
            feet=feet,
            reason=_nothing_to_check(scene, groups),
        )
    checker = Checker(scene, np.random.default_rng(seed), spread, groups)
    notes = []
    if states is not None:
        states = _given_states(scene, states)
        samples = 0
        notes.append(f"measured at {len(states)} given state(s), not at sampled poses")
    if armature and not scene.robot.actuated:
        notes.append(f"robot {scene.robot.name!r} has no actuated joints: armature changes nothing")
    poses = None if states is None else [q for q, _, _ in states]
    limb_of = checker.limb_of
    all_pairs = [
        (limb_of[i] == limb_of[j], checker.pair_coupling(i, j, samples, poses))
        for i, j in itertools.combinations(range(len(scene.contacts)), 2)
    ]
    pairs = [p for within, p in all_pairs if not within]
    within_limb = [p for within, p in all_pairs if within]
    terms = checker.assumption_terms(samples, states)
    for t in terms:
        t.ok = bool(t.value <= tol)
    for p in pairs + within_limb:
        if p.max > tol:
            p.verdict = COUPLED
        else:
            involved = [t for t in terms if not t.contacts or set(t.contacts) & set(p.contacts)]
            p.verdict = DECOUPLED if all(t.ok for t in involved) else ORTHOGONAL_ONLY
    for limb, members in groups:
        worst = max((p.max for p in within_limb if p.contacts[0] in members), default=0.0)
        if len(members) > 1 and worst > tol:
            notes.append(
                f"the points of limb {limb} ({', '.join(members)}) are coupled to each other "
                f"(up to {worst:.3g}): the order in which they touch changes outcomes; "
                "the verdict is about limbs"
            )
    if any(p.verdict == COUPLED for p in pairs):
        verdict = COUPLED
    elif all(t.ok for t in terms):
        verdict = DECOUPLED
    else:
        verdict = ORTHOGONAL_ONLY
    model = scene.model
    return DecouplingReport(
        scene=scene.name,
        robot=scene.robot.name,
        armature=float(armature),
        tol=float(tol),
        samples=samples,
        seed=int(seed),
        body=[model.names[j] for j in checker.joints_of(checker.body)],
        limbs={
            limb: [model.names[j] for j in checker.joints_of(coords)]
            for (limb, _), coords in zip(groups, checker.limbs)
        },
        pairs=pairs,
        terms=terms,
        verdict=verdict,
        notes=notes,
        feet=feet,
        within_limb=within_limb,
        limb_contacts={limb: list(members) for limb, members in groups},
    )


def _limb_groups(scene: Scene) -> list[tuple[str, tuple[str, ...]]]:
    """``(limb, contact names)`` in contact order: the ground contacts at the feet of one
    foot of several points (``robot.foot_choice.limbs``) are one limb named after that
    foot; every other contact is a limb of its own, named after the contact."""
    choice = scene.robot.foot_choice
    foot_limb = {f: limb for limb, feet in (choice.limbs if choice else {}).items() for f in feet}
    groups: dict[str, list[str]] = {}
    for c in scene.contact_specs:
        limb = foot_limb.get(c.frame, c.name) if c.against is None else c.name
        groups.setdefault(limb, []).append(c.name)
    return [(limb, tuple(members)) for limb, members in groups.items()]


def _nothing_to_check(scene: Scene, groups) -> str:
    """Why a scene with fewer than two contacts (or limbs) has no verdict, with the way out."""
    names = scene.contact_names
    if len(names) >= 2:  # several points of one foot
        ((limb, members),) = groups
        return f"fewer than two limbs (1: {limb}, contacts {', '.join(members)})"
    text = f"fewer than two contacts ({len(names)}{': ' + ', '.join(names) if names else ''})"
    rule = scene.foot_choice.rule if scene.foot_choice else None
    if rule is FootRule.FIXED_BASE:
        text += (
            f"; robot {scene.robot.name!r} has a fixed base and gets no feet: load it with a "
            "floating base (--floating-base, floating_base=True) or choose feet (--feet, feet=)"
        )
    elif rule is FootRule.LOWEST_END_FRAMES:
        text += (
            f"; {'no limb of the robot ends' if not names else 'no other limb ends'} near the ground "
            "at the reference pose: choose feet by hand (--feet, feet=) to check other frames"
        )
    return text


def _given_states(scene: Scene, states) -> list[tuple[np.ndarray, np.ndarray, float]]:
    """``states`` as a non-empty list of finite ``(q, v, t)`` of the scene's sizes
    (``t = 0`` where a pair was given)."""
    nq, nv = scene.robot.nq, scene.nv
    try:
        given = [tuple(s) for s in states]
        if any(len(s) not in (2, 3) for s in given):
            raise ValueError
        triples = [
            (np.array(s[0], dtype=float), np.array(s[1], dtype=float), float(s[2]) if len(s) == 3 else 0.0)
            for s in given
        ]
    except (TypeError, ValueError):
        raise InvalidInputError(
            f"states must be (q, v) pairs or (q, v, t) triples of numbers, got {states!r}"
        ) from None
    if not triples:
        raise InvalidInputError("states must hold at least one (q, v) pair, got none")
    for k, (q, v, t) in enumerate(triples):
        if q.shape != (nq,) or v.shape != (nv,):
            raise InvalidInputError(
                f"states[{k}]: q must have shape ({nq},) and v ({nv},); got {q.shape} and {v.shape}"
            )
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(v)) and np.isfinite(t)):
            raise InvalidInputError(f"states[{k}] has non-finite entries: q={q}, v={v}, t={t}")
    return triples


def _as_scene(source) -> Scene:
    if isinstance(source, Scene):
        return source
    if isinstance(source, Robot):
        return Scene.from_robot(source)
    if isinstance(source, (str, Path)):
        return load_source(source)
    raise InvalidInputError(f"source must be a Scene, a Robot or a name/path, got {source!r}")


__all__ = [
    "COUPLED",
    "DECOUPLED",
    "ORTHOGONAL_ONLY",
    "VERDICTS",
    "DecouplingReport",
    "PairCoupling",
    "Term",
    "check_decoupling",
]
