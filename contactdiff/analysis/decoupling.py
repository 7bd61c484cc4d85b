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
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike

from ..errors import InvalidInputError, check_count
from ..jsonable import to_jsonable
from ..model.feet import FootRule
from ..model.robot import Robot
from ..model.scene import Scene
from ..scenes.scene_file import load_source

DECOUPLED, ORTHOGONAL_ONLY, COUPLED = "decoupled", "orthogonal only", "coupled"
VERDICTS = (DECOUPLED, ORTHOGONAL_ONLY, COUPLED)

_FD_STEP = 1e-5  # central differences of analytic first derivatives: error ~1e-10 relative
_PROJECTION_TOL = 1e-12  # m, gap after projection onto a_i = a_j = 0


@dataclass
class PairCoupling:
    """Normalised inverse-mass coupling of two contacts over the closed configurations.

    Attributes:
        contacts: the two contact names.
        reference: coupling at the scene's pose projected onto both contacts closed.
        max, median: largest and typical absolute coupling over all projected poses.
        samples: number of poses that projected (reference included).
        verdict: the pair's verdict (see module docstring).
    """

    contacts: tuple[str, str]
    reference: float
    max: float
    median: float
    samples: int
    verdict: str = ""


@dataclass
class Term:
    """One measured term of the limb-decoupling assumption.

    Attributes:
        condition: ``mass matrix``, ``gap``, ``limb effort`` or ``body effort``.
        where: what was measured (block, contact or limbs involved).
        value: largest relative size over the sampled states (0 means exactly decoupled).
        contacts: the contacts whose limbs the term involves.
        ok: ``value <= tol``.
    """

    condition: str
    where: str
    value: float
    contacts: tuple[str, ...]
    ok: bool = True


@dataclass
class DecouplingReport:
    """Everything `check_decoupling` measured; ``to_dict()`` is the JSON form.

    ``verdict`` is ``None`` when there is nothing to check (fewer than two
    contacts, or fewer than two limbs); ``reason`` then says why. ``feet`` says how
    a robot's feet were chosen (empty for a scene file's contacts). ``limbs`` maps
    each limb (a contact's name, or the name of a foot of several points) to its
    coordinates and ``limb_contacts`` to its contacts; ``pairs`` are the couplings
    between limbs, ``within_limb`` those between two points of one foot (module
    notes: not part of the verdict).
    """

    scene: str
    robot: str
    armature: float
    tol: float
    samples: int
    seed: int
    body: list[str]
    limbs: dict[str, list[str]]
    pairs: list[PairCoupling]
    terms: list[Term]
    verdict: str | None
    notes: list[str] = field(default_factory=list)
    feet: str = ""
    reason: str = ""
    within_limb: list[PairCoupling] = field(default_factory=list)
    limb_contacts: dict[str, list[str]] = field(default_factory=dict)

    @property
    def max_coupling(self) -> float:
        """Largest coupling between two limbs (0 with fewer than two limbs)."""
        return max((p.max for p in self.pairs), default=0.0)

    def failed_terms(self) -> list[Term]:
        """The terms of the limb assumption above ``tol`` (``ok`` false), in measured order."""
        return [t for t in self.terms if not t.ok]

    def to_dict(self) -> dict:
        """JSON-ready form: every field, plus ``max_coupling``."""
        d = asdict(self)
        d["max_coupling"] = self.max_coupling
        return to_jsonable(d)

    def format(self) -> str:
        """A readable multi-line report."""
        lines = [
            f"decoupling check: scene {self.scene} (robot {self.robot}"
            + (f", armature {self.armature:g}" if self.armature else "")
            + ")"
        ]
        if self.feet:
            lines.append(f"  {self.feet}")
        if self.verdict is None:
            return "\n".join(
                lines + ["", f"verdict: none - nothing to check: {self.reason}"] + [f"  note: {n}" for n in self.notes]
            )
        lines.append(f"  body: {', '.join(self.body) or '(none)'}")
        for name, coords in self.limbs.items():
            points = self.limb_contacts.get(name, [name])
            of = f" (contacts {', '.join(points)})" if points != [name] else ""
            lines.append(f"  limb of {name}{of}: {', '.join(coords) or '(none: its gap moves with the body)'}")
        lines.append("")
        header = ("pair", "reference", "max", "median", "verdict")
        if self.pairs:
            lines.append(f"orthogonality  |G_ij| / sqrt(G_ii G_jj) at closed contacts ({self.pairs[0].samples} poses)")
            lines += _table(header, _pair_rows(self.pairs))
            if self.within_limb:
                lines.append("within one limb (points of one foot; not part of the verdict)")
                lines += _table(header, _pair_rows(self.within_limb))
        else:
            lines.append("orthogonality: fewer than two contacts, nothing to couple")
        lines.append("")
        lines.append(f"limbs decoupled through the body (relative sizes, tol {self.tol:g})")
        lines += _table(
            ("condition", "where", "size", "ok"),
            [(t.condition, t.where, f"{t.value:.3e}", "yes" if t.ok else "NO") for t in self.terms],
        )
        lines.append("")
        lines.append(f"verdict: {self.verdict.upper()} - " + _VERDICT_MEANING[self.verdict])
        for t in self.failed_terms()[:5]:
            lines.append(f"  breaks: {t.condition} {t.where} ({t.value:.3e})")
        lines += [f"  note: {n}" for n in self.notes]
        return "\n".join(lines)


_VERDICT_MEANING = {
    DECOUPLED: "outcomes are differentiable through simultaneous contact",
    ORTHOGONAL_ONLY: "outcomes are continuous but in general not differentiable when contact order changes",
    COUPLED: "outcomes jump when the order of contacts changes",
}


def _pair_rows(pairs: list[PairCoupling]) -> list[tuple[str, ...]]:
    return [
        (f"{p.contacts[0]} / {p.contacts[1]}", f"{p.reference:.3e}", f"{p.max:.3e}", f"{p.median:.3e}", p.verdict)
        for p in pairs
    ]


def _table(header, rows) -> list[str]:
    widths = [max(len(str(r[i])) for r in [header, *rows]) for i in range(len(header))]
    fmt = "  " + "  ".join(f"{{:<{w}}}" for w in widths)
    return [fmt.format(*header), fmt.format(*("-" * w for w in widths))] + [fmt.format(*r) for r in rows]


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
    checker = _Checker(scene, np.random.default_rng(seed), spread, groups)
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


class _Checker:
    """The measurements of one check; coordinates are tangent (velocity) indices."""

    def __init__(self, scene: Scene, rng: np.random.Generator, spread: float, groups):
        self.scene, self.rng, self.spread = scene, rng, float(spread)
        self.model, self.robot = scene.model, scene.robot
        self.data = self.model.createData()
        self.kin = scene.kinematics
        # one limb per group of contacts (`_limb_groups`): its chains' coordinates, no other limb's
        index = {name: i for i, name in enumerate(scene.contact_names)}
        self.members = [[index[n] for n in members] for _, members in groups]
        self.limb_names = [limb for limb, _ in groups]
        self.limb_of = {i: g for g, members in enumerate(self.members) for i in members}
        supports = [set().union(*(self._support(scene.contacts[i]) for i in members)) for members in self.members]
        self.limbs = [s - set().union(*(o for k, o in enumerate(supports) if k != i)) for i, s in enumerate(supports)]
        self.body = set(range(self.model.nv)) - set().union(*self.limbs)
        self.v_joint = {}  # tangent index -> joint id
        for jid in range(1, self.model.njoints):
            j = self.model.joints[jid]
            for k in range(j.idx_v, j.idx_v + j.nv):
                self.v_joint[k] = jid

    def joints_of(self, coords: set[int]) -> list[int]:
        return sorted({self.v_joint[k] for k in coords})

    def _support(self, contact) -> set[int]:
        """Tangent coordinates on the kinematic chain(s) of a contact's frame(s)."""
        coords: set[int] = set()
        for fid in (contact.fid, contact.against_fid):
            if fid is None:
                continue
            for jid in self.model.supports[self.model.frames[fid].parentJoint]:
                if jid == 0:
                    continue
                j = self.model.joints[jid]
                coords.update(range(j.idx_v, j.idx_v + j.nv))
        return coords

    # -- poses -------------------------------------------------------------------------
    def _random_pose(self) -> np.ndarray:
        dq = self.rng.uniform(-self.spread, self.spread, self.model.nv)
        return self.robot.integrate(self.scene.q0, dq)

    def _project(self, q: np.ndarray, idx: list[int]) -> np.ndarray | None:
        """Gauss–Newton (minimum-norm steps) onto the closed set of contacts ``idx``."""
        zero = np.zeros(self.model.nv)
        for _ in range(50):
            self.kin.update(q, zero)
            gaps = np.array([self.scene.contacts[i].gap(self.kin) for i in idx])
            if np.max(np.abs(gaps)) <= _PROJECTION_TOL:
                return q
            A = np.vstack([self.scene.contacts[i].rows(self.kin)[:1] for i in idx])
            q = self.robot.integrate(q, -np.linalg.lstsq(A, gaps, rcond=None)[0])
        return None

    def _poses(self, idx: list[int], samples: int) -> list[np.ndarray]:
        poses = [self._project(self.scene.q0.copy(), idx)]
        poses += [self._project(self._random_pose(), idx) for _ in range(samples)]
        return [q for q in poses if q is not None]

    # -- orthogonality -------------------------------------------------------------------
    def _coupling(self, q: np.ndarray, i: int, j: int) -> float:
        self.kin.update(q, np.zeros(self.model.nv))
        A = np.vstack([self.scene.contacts[k].rows(self.kin)[:1] for k in (i, j)])
        Minv = pin.computeMinverse(self.model, self.data, q)
        G = A @ Minv @ A.T
        return float(abs(G[0, 1]) / np.sqrt(G[0, 0] * G[1, 1]))

    def pair_coupling(self, i: int, j: int, samples: int, poses=None) -> PairCoupling:
        """Coupling over projected reference and random poses, or at ``poses`` as given."""
        poses = self._poses([i, j], samples) if poses is None else poses
        values = [self._coupling(q, i, j) for q in poses]
        names = self.scene.contact_names
        ref = values[0] if poses and poses[0] is not None else float("nan")
        return PairCoupling((names[i], names[j]), ref, float(np.max(values)), float(np.median(values)), len(values))

    # -- limb assumption -----------------------------------------------------------------
    def _effort_jacobian(self, q: np.ndarray, v: np.ndarray, t: float = 0.0) -> np.ndarray:
        """``[d f/dq, d f/dv]`` of ``f = tau - nle`` at time ``t`` (s) (nv × 2nv)."""
        self.kin.update(q, v, derivatives=True)
        dtau_dq, dtau_dv = self.scene.tau_derivatives(self.kin, t)
        dn_dq, dn_dv, _ = pin.computeRNEADerivatives(self.model, self.data, q, v, np.zeros(self.model.nv))
        return np.hstack([dtau_dq - dn_dq, dtau_dv - dn_dv])

    def assumption_terms(self, samples: int, states=None) -> list[Term]:
        """Terms over projected poses with random velocities at t = 0, or at ``states``
        ((q, v, t) triples)."""
        nv, names = self.model.nv, self.scene.contact_names
        if states is None:
            all_closed = list(range(len(self.scene.contacts)))
            poses = self._poses(all_closed, samples) or [self.scene.q0]
            states = [(q, self.rng.uniform(-self.spread, self.spread, nv), 0.0) for q in poses]
        limb_names = self.limb_names
        blocks = [("body", self.body)] + [(f"limb {n}", limb) for n, limb in zip(limb_names, self.limbs)]
        owners = [()] + [tuple(names[i] for i in members) for members in self.members]
        # largest relative size of each term over the poses, keyed by block/limb indices
        mass: dict[tuple[int, int], float] = {}  # by pair of limbs
        dep: dict[int, float] = {}
        effort: dict[int, float] = {}
        additive: dict[tuple[int, int], float] = {}  # by pair of limbs
        gap = np.zeros(len(names))
        for q, v, t in states:
            M = pin.crba(self.model, self.data, q)
            diag = np.sqrt(np.abs(np.diag(M)))
            scale = np.where(diag > 0, diag, 1.0)
            Mn = M / np.outer(scale, scale)
            for ia, ib in itertools.combinations(range(len(blocks)), 2):
                ca, cb = sorted(blocks[ia][1]), sorted(blocks[ib][1])
                if ca and cb:
                    key = (ia, ib)
                    mass[key] = max(mass.get(key, 0.0), float(np.max(np.abs(Mn[np.ix_(ca, cb)]))))
            # block j of M may depend only on coordinates of block j
            dM = self._mass_derivative(q)
            for ib, (_, coords) in enumerate(blocks):
                c = sorted(coords)
                others = [k for k in range(nv) if k not in coords]
                if c and others:
                    value = np.max(np.abs(dM[np.ix_(c, c, others)])) / max(np.max(np.abs(M[np.ix_(c, c)])), 1e-300)
                    dep[ib] = max(dep.get(ib, 0.0), float(value))
            # each gap depends on its limb only
            self.kin.update(q, np.zeros(nv))
            for i, contact in enumerate(self.scene.contacts):
                row = contact.rows(self.kin)[0]
                outside = [k for k in range(nv) if k not in self.limbs[self.limb_of[i]]]
                if outside:
                    gap[i] = max(gap[i], float(np.max(np.abs(row[outside])) / max(np.max(np.abs(row)), 1e-300)))
            # efforts
            Df = self._effort_jacobian(q, v, t)
            fscale = max(float(np.max(np.abs(Df))), 1.0)
            for i, limb in enumerate(self.limbs):
                other = sorted(set().union(*(other_limb for k, other_limb in enumerate(self.limbs) if k != i)))
                if limb and other:
                    cols = other + [nv + k for k in other]
                    value = float(np.max(np.abs(Df[np.ix_(sorted(limb), cols)]))) / fscale
                    effort[i] = max(effort.get(i, 0.0), value)
            body = sorted(self.body)
            if body:
                for i, j in itertools.combinations(range(len(self.limbs)), 2):
                    if not (self.limbs[i] and self.limbs[j]):  # a contact of the body alone (an object
                        continue  # on the ground): no mixed derivative
                    value = self._mixed_body_derivative(q, v, t, body, self.limbs[i], self.limbs[j]) / fscale
                    additive[(i, j)] = max(additive.get((i, j), 0.0), value)
        terms = []
        for (ia, ib), value in mass.items():
            terms.append(
                Term("mass matrix", f"block {blocks[ia][0]} / {blocks[ib][0]}", value, owners[ia] + owners[ib])
            )
        for ib, value in dep.items():
            terms.append(Term("mass matrix", f"block {blocks[ib][0]} depends on other coordinates", value, owners[ib]))
        for i, value in enumerate(gap):
            terms.append(Term("gap", f"{names[i]} depends on coordinates outside its limb", float(value), (names[i],)))
        for i, value in effort.items():
            terms.append(Term("limb effort", f"limb {limb_names[i]} depends on other limbs", value, owners[i + 1]))
        for (i, j), value in additive.items():
            terms.append(
                Term(
                    "body effort",
                    f"not additive in limbs {limb_names[i]} and {limb_names[j]}",
                    value,
                    owners[i + 1] + owners[j + 1],
                )
            )
        return terms

    def _mass_derivative(self, q: np.ndarray) -> np.ndarray:
        """``dM[a, b, k] = d M_ab / d q_k`` by central differences of ``crba``."""
        nv = self.model.nv
        dM = np.empty((nv, nv, nv))
        for k in range(nv):
            e = np.zeros(nv)
            e[k] = _FD_STEP
            dM[:, :, k] = (
                pin.crba(self.model, self.data, self.robot.integrate(q, e))
                - pin.crba(self.model, self.data, self.robot.integrate(q, -e))
            ) / (2 * _FD_STEP)
        return dM

    def _mixed_body_derivative(self, q, v, t, body, limb_i, limb_j) -> float:
        """Largest ``|d² f_body / dx_i dx_j|`` over coordinates ``x_i`` of limb i and
        ``x_j`` of limb j (positions and velocities): central differences in ``x_j``
        of the analytic first derivatives in ``x_i``."""
        nv = self.model.nv
        cols = sorted(limb_i) + [nv + k for k in sorted(limb_i)]
        worst = 0.0
        for k in sorted(limb_j):
            e = np.zeros(nv)
            e[k] = _FD_STEP
            for (q_plus, v_plus), (q_minus, v_minus) in (
                ((self.robot.integrate(q, e), v), (self.robot.integrate(q, -e), v)),
                ((q, v + e), (q, v - e)),
            ):
                diff = self._effort_jacobian(q_plus, v_plus, t) - self._effort_jacobian(q_minus, v_minus, t)
                worst = max(worst, float(np.max(np.abs(diff[np.ix_(body, cols)]))) / (2 * _FD_STEP))
        return worst
