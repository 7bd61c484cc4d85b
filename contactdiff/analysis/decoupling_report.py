"""The decoupling check's result: its verdicts, each pair's coupling, each limb
assumption's term, and the report's text and JSON forms (the checker is
`contactdiff.analysis.decoupling`)."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

from ..jsonable import to_jsonable

DECOUPLED, ORTHOGONAL_ONLY, COUPLED = "decoupled", "orthogonal only", "coupled"


VERDICTS = (DECOUPLED, ORTHOGONAL_ONLY, COUPLED)


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
