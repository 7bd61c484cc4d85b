"""How decoupled is a real robot: the checker and the order gap at a trot's diagonal touchdowns.

For each example-robot-data quadruped, at the diagonal touchdowns of its
simulated trot (`contactdiff.control.trot_scenes.trot_scene`; sticking, plastic feet; the
state source is `contactdiff.analysis.trot_touchdowns`), with and
without reflected rotor inertia (armature, kg m² on every actuated joint,
swept over the values in ARMATURES):

* the decoupling checker's numbers at those states: the landing pair's coupling
  |G_ij| / sqrt(G_ii G_jj), the largest over all six foot pairs, and the
  limb-assumption terms (worst mass-matrix term; the gap term is 1 on every
  floating-base robot, since a foot's height moves with the base);
* the order gap (`contactdiff.analysis.order_gap`, at the event's time, with the other
  pair's stance feet active): how different the post-impact velocity
  (kinetic-energy norm, relative to the impact's velocity jump) and the
  saltation matrix (relative max norm) are when one foot of the pair lands
  first versus the other.

Each number is the largest over the robot's touchdown states; the table gives
how many there are. ``--states standing`` measures instead one trot-like
touchdown built from the standing pose (`contactdiff.analysis.order_gap.diagonal_touchdown`:
no efforts, the other pair in the air).

Then the compliant-feet trend on solo12 (`contactdiff.model.compliance`), at the
standing-pose touchdown whatever ``--states`` says (compliant feet change the
robot, so the trot would need its own simulation): each foot on a spring along
the shank carrying a foot mass taken from the lower leg, over a stiffness ×
foot-mass grid: coupling and order gap at the touchdown (sticking and
frictionless feet), and the gap between the two one-sided derivatives of the
base's state (pose and velocity) HORIZON seconds later, where the stiffness
acts (at the touchdown itself the spring is at rest and the stiffness enters
nothing).

The robots, and the trend's cases, run in parallel on local worker processes
(`contactdiff.sweep`; ``--jobs N``, default one per core).

    python scripts/quadruped_decoupling_table.py [--json] [--plot out.png] [--robots solo12 a1]
                                                 [--states trot|standing] [--no-trend] [--jobs N]
    python scripts/quadruped_decoupling_table.py --quick [--plot out.png]   # a smoke run of seconds

``--quick``: solo12 only, in this process, and the trend over two foot masses and two
stiffnesses.
"""

from __future__ import annotations

import argparse
import json
import math

import numpy as np

import contactdiff as cd
from contactdiff.analysis.order_gap import diagonal_touchdown, order_gap
from contactdiff.analysis.trot_touchdowns import (  # noqa: F401  (the tests read them here too)
    STATE_SOURCES,
    TROT_MAX_PARTNER_GAP,
    TROT_MIN_SPEED,
    touchdown_states,
    trot_touchdowns,
)
from contactdiff.model.compliance import add_compliant_feet, compliant_state
from contactdiff.sweeps import sweep

# Reflected rotor inertia I_rotor · N² (kg m²) at each actuated joint: (low, high) bracket per robot.
ARMATURES = {
    # T-motor MN4004-class rotor ~1e-5 kg m² (bell of ~25 g at ~20 mm) up to the 4.5e-5 kg m² often
    # quoted for the actuator module, through the 1:9 belt transmission (N² = 81).
    "solo12": (8e-4, 3.6e-3),
    # ANYdrive: series-elastic. At an impact the output sees the spring, not the rotor: ~0.
    # Rigid-gear equivalent (rotor ~4e-5 kg m² × 50²): ~0.1 -- an upper bound, not what a touchdown feels.
    "anymal": (0.0, 0.1),
    # Unitree A1/Go1/Go2: rotor 1.118e-4 kg m² (the rotor links of the go1/go2 URDFs), gear 6.33 at the
    # hip and thigh (4.5e-3) and 1.5 times more at the knee (~1.0e-2; MuJoCo Menagerie's go2 uses 0.01).
    "a1": (4.5e-3, 1.0e-2),
    "go1": (4.5e-3, 1.0e-2),
    "go2": (4.5e-3, 1.0e-2),
    # HyQ: hydraulic cylinders and rotary actuators, no gearbox. Piston and rod (~0.3 kg) on a ~4 cm
    # lever: ~5e-4; 2e-3 allows for the oil column and the valve-side inertia.
    "hyq": (5e-4, 2e-3),
}

TREND_ROBOT = "solo12"
TREND_ARMATURE = 3.6e-3  # kg m², solo12's high bracket
TREND_FOOT_MASSES = (1e-2, 3e-3, 1e-3, 3e-4)  # kg; solo12's shank (38 g) can give at most ~20 g at the foot
TREND_STIFFNESSES = (1e3, 1e4, 1e5)  # N/m
HORIZON = 0.02  # s after the touchdown
SIM = dict(rtol=1e-8, atol=1e-10)


# -- measurements ----------------------------------------------------------------------
def measure(scene, states, armature: float) -> dict:
    """Checker numbers and order gap at the touchdown states (worst over the states)."""
    scene = scene.with_armature(armature) if armature else scene
    names = scene.contact_names
    report = cd.check_decoupling(scene, states=[(s.q, s.v, s.t) for s in states])
    row = {"armature": armature, "max_coupling": report.max_coupling}
    pairs = {frozenset(names[k] for k in s.pair) for s in states}
    row["pair_coupling"] = max(p.max for p in report.pairs if frozenset(p.contacts) in pairs)
    mass = [t for t in report.terms if t.condition == "mass matrix"]
    worst_mass = max(mass, key=lambda t: t.value)
    row["mass_term"], row["mass_term_where"] = worst_mass.value, worst_mass.where
    row["gap_term"] = max(t.value for t in report.terms if t.condition == "gap")
    row["other_terms"] = max((t.value for t in report.terms if t.condition not in ("mass matrix", "gap")), default=0.0)
    row["verdict"] = report.verdict
    gaps = [order_gap(scene, s.q, s.v, s.pair, mode=s.mode, t=s.t) for s in states]
    row["outcome_gap"] = max(g.outcome for g in gaps)
    row["saltation_gap"] = max(g.saltation for g in gaps)
    row["saltation_spread"] = max(g.saltation_spread for g in gaps)
    row["per_state"] = [
        {
            "outcome": g.outcome,
            "saltation": g.saltation,
            "saltation_spread": g.saltation_spread,
            "impact_jump": g.impact_jump,
            "mode_after": {"->".join(k): list(m) for k, m in g.mode_after.items()},
        }
        for g in gaps
    ]
    row["modes_after"] = sorted({m for g in gaps for m in map(tuple, g.mode_after.values())})
    return row


def describe_states(scene, states) -> list[dict]:
    """Per state: time, landing pair, other pair's stance, closed partner gap, landing speeds."""
    kin, names = scene.kinematics, scene.contact_names
    out = []
    for s in states:
        kin.update(s.q, s.v)
        out.append(
            {
                "t": s.t,
                "pair": [names[k] for k in s.pair],
                "mode": [names[k] for k in s.mode],
                "partner_gap": s.partner_gap,
                "landing_speeds": [float(-scene.contacts[k].rows(kin)[0] @ s.v) for k in s.pair],
            }
        )
    return out


def touchdown_scene(robot: str, states: str = "trot"):
    """The scene of `touchdown_states` for a sweep's workers: it carries its touchdown
    states and their label as ``scene.touchdowns`` (the trot is simulated once per
    worker and robot)."""
    scene, found, label = touchdown_states(robot, states)
    scene.touchdowns = (found, label)
    return scene


def robot_rows(scene, point) -> dict:
    """A sweep job: the rows of one robot, at armature 0 and its ARMATURES bracket."""
    states, label = scene.touchdowns
    described = describe_states(scene, states)
    low, high = ARMATURES[point["arg:robot"]]
    return {
        "rows": [
            measure(scene, states, armature)
            | dict(robot=point["arg:robot"], source=label, states=len(states), touchdowns=described)
            for armature in sorted({0.0, low, high})
        ]
    }


def robot_table(robots, source: str = "trot", n_jobs: int | None = None) -> list[dict]:
    """One row per robot and armature (0 and the robot's ARMATURES bracket), the robots
    run in parallel (`contactdiff.sweep`, ``n_jobs`` worker processes, default one per core)."""
    result = sweep(
        touchdown_scene,
        [{"arg:robot": name} for name in robots],
        robot_rows,
        fixed={"arg:states": source},
        n_jobs=n_jobs,
    )
    return [row for r in result.raise_failure() for row in r.outputs["rows"]]


def trend_scene(friction: str, foot_mass: float | None, stiffness: float | None):
    """Solo12 at TREND_ARMATURE with ``friction`` feet, compliant ones (``foot_mass`` kg on a
    spring of ``stiffness`` N/m along the shank) unless ``foot_mass`` is None; it carries its
    standing-pose diagonal touchdown (`diagonal_touchdown`; no trot, no efforts) as
    ``scene.touchdown = (q, v, pair)``."""
    base = cd.Scene.from_robot(cd.load_robot(TREND_ROBOT), friction=friction).with_armature(TREND_ARMATURE)
    q, v, pair = diagonal_touchdown(base)
    if foot_mass is None:
        base.touchdown = (q, v, pair)
        return base
    scene = add_compliant_feet(base, stiffness, foot_mass)
    scene.touchdown = (*compliant_state(base.robot, scene.robot, q, v), pair)
    return scene


def trend_row(scene, point) -> dict:
    """A sweep job: coupling and order gap at the touchdown; with sticking feet also the
    gap between the one-sided derivatives HORIZON seconds later."""
    q, v, pair = scene.touchdown
    stick = point["arg:friction"] == "stick"
    report = cd.check_decoupling(scene, states=[(q, v)])
    names = {scene.contact_names[k] for k in pair}
    gap = order_gap(scene, q, v, pair, horizon=HORIZON if stick else None, jacobian=stick, simulate_options=SIM)
    return {
        "pair_coupling": next(p.max for p in report.pairs if set(p.contacts) == names),
        "max_coupling": report.max_coupling,
        "outcome_gap": gap.outcome,
        "saltation_gap": gap.saltation,
        "saltation_spread": gap.saltation_spread,
        "later_saltation_gap": gap.later_saltation,
        "later_base_saltation_gap": gap.later_saltation_on(range(6)) if gap.horizon else None,
    }


def trend_table(n_jobs: int | None = None, masses=TREND_FOOT_MASSES, stiffnesses=TREND_STIFFNESSES) -> list[dict]:
    """Compliant feet on solo12 over foot mass (kg) × stiffness (N/m) (and rigid feet), sticking and
    frictionless, at TREND_ARMATURE, at the standing-pose diagonal touchdown; the cases run
    in parallel (`contactdiff.sweep`)."""
    cases = [(None, None)] + [(m, k) for m in masses for k in stiffnesses]
    points = [{"arg:friction": f, "arg:foot_mass": m, "arg:stiffness": k} for f in ("stick", "none") for m, k in cases]
    result = sweep(trend_scene, points, trend_row, n_jobs=n_jobs)
    return [
        {
            "friction": r.point["arg:friction"],
            "foot_mass": r.point["arg:foot_mass"],
            "stiffness": r.point["arg:stiffness"],
            **r.outputs,
        }
        for r in result.raise_failure()
    ]


# -- output ----------------------------------------------------------------------------
def _e(x) -> str:
    return "-" if x is None else ("0" if x == 0 else f"{x:.1e}")


def print_tables(rows, trend) -> None:
    sources = sorted({r["source"] for r in rows})
    print(
        "touchdown: " + "; ".join(sources) + "; a diagonal pair lands, sticking plastic feet; "
        "states = touchdown states per robot (each number is the largest over them)\n"
    )
    print(
        "| robot | states | armature (kg m²) | pair coupling | max coupling (6 pairs) | worst M term (body/limb) "
        "| order gap: outcome | order gap: saltation | saltation spread |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(
            f"| {r['robot']} | {r['states']} | {_e(r['armature'])} | {_e(r['pair_coupling'])} "
            f"| {_e(r['max_coupling'])} | {_e(r['mass_term'])} | {_e(r['outcome_gap'])} "
            f"| {_e(r['saltation_gap'])} | {_e(r['saltation_spread'])} |"
        )
    gap_terms = sorted({r["gap_term"] for r in rows})
    print(
        f"\ngap term (foot height depends on coordinates outside its leg): {', '.join(map(_e, gap_terms))} "
        f"on every robot; effort terms: {_e(max(r['other_terms'] for r in rows))}; verdicts: "
        + ", ".join(sorted({r["verdict"] for r in rows}))
    )
    print("\ntouchdown states (time; landing pair; partner gap closed; landing speeds; other pair's stance):")
    for r in {r["robot"]: r for r in rows}.values():
        print(
            f"  {r['robot']}: "
            + "; ".join(
                f"t={d['t']:.4f} s {'+'.join(d['pair'])} {d['partner_gap'] * 1e3:.1f} mm "
                f"{'/'.join(f'{s:.2f}' for s in d['landing_speeds'])} m/s [{', '.join(d['mode'])}]"
                for d in r["touchdowns"]
            )
        )
    if not trend:
        return
    print(
        f"\ncompliant feet on {TREND_ROBOT} (armature {TREND_ARMATURE:g} kg m², foot mass taken from the shank, "
        f"spring along the shank; later = {HORIZON * 1e3:g} ms after touchdown)\n"
    )
    print(
        "| foot mass (g) | stiffness (N/m) | pair coupling | order gap: outcome | saltation (stick) "
        "| saltation (frictionless) | base derivatives later (stick) |"
    )
    print("|---|---|---|---|---|---|---|")
    by_key = {(r["friction"], r["foot_mass"], r["stiffness"]): r for r in trend}
    for (friction, mass, k), r in by_key.items():
        if friction != "stick":
            continue
        free = by_key[("none", mass, k)]
        label = "rigid" if mass is None else f"{mass * 1e3:g}"
        print(
            f"| {label} | {'-' if k is None else f'{k:g}'} | {_e(r['pair_coupling'])} | {_e(r['outcome_gap'])} "
            f"| {_e(r['saltation_gap'])} | {_e(free['saltation_gap'])} | {_e(r['later_base_saltation_gap'])} |"
        )


def plot_trend(trend, path: str) -> None:
    import matplotlib.pyplot as plt

    fig = trend_figure(trend)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def trend_figure(trend):
    """The foot-mass trend (rows of `compliance_trend`) as a two-panel figure."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4), constrained_layout=True)
    foot_masses = list(dict.fromkeys(r["foot_mass"] for r in trend if r["foot_mass"] is not None))
    stiffnesses = list(dict.fromkeys(r["stiffness"] for r in trend if r["stiffness"] is not None))
    masses = np.array(foot_masses) * 1e3
    k0 = stiffnesses[0]
    rigid = {r["friction"]: r for r in trend if r["foot_mass"] is None}

    def series(friction, key, k=k0):
        return [
            next(r[key] for r in trend if r["friction"] == friction and r["foot_mass"] == m and r["stiffness"] == k)
            for m in foot_masses
        ]

    ax = axes[0]
    ax.loglog(masses, series("stick", "pair_coupling"), "o-", label="pair coupling")
    ax.loglog(masses, series("stick", "saltation_gap"), "s-", label="saltation gap, sticking feet")
    ax.loglog(masses, series("none", "saltation_gap"), "^-", label="saltation gap, frictionless feet")
    for key, style in (("pair_coupling", "C0"), ("saltation_gap", "C1")):
        ax.axhline(rigid["stick"][key], color=style, ls=":", lw=1)
    ax.axhline(rigid["none"]["saltation_gap"], color="C2", ls=":", lw=1)
    ax.set_xlabel("foot mass (g)")
    ax.set_ylabel("relative size (dimensionless)")
    ax.set_title("at touchdown (dotted: rigid feet)")
    ax.legend(fontsize=8)
    ax = axes[1]
    for k in stiffnesses:
        ax.loglog(masses, series("stick", "later_base_saltation_gap", k), "o-", label=f"k = {k:g} N/m")
    ax.axhline(rigid["stick"]["later_base_saltation_gap"], color="k", ls=":", lw=1, label="rigid feet")
    ax.set_xlabel("foot mass (g)")
    ax.set_ylabel("relative derivative gap (dimensionless)")
    ax.set_title(f"base-state derivative gap {HORIZON * 1e3:g} ms later (sticking feet)")
    ax.legend(fontsize=8)
    fig.suptitle(f"{TREND_ROBOT} with compliant feet, armature {TREND_ARMATURE:g} kg m²")
    return fig


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", nargs="+", default=list(cd.QUADRUPEDS), choices=list(cd.QUADRUPEDS))
    parser.add_argument(
        "--states",
        choices=STATE_SOURCES,
        default="trot",
        help="touchdown states: the simulated trot's (default), or one built from the standing pose",
    )
    parser.add_argument("--no-trend", action="store_true", help="skip the compliant-feet trend on solo12")
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--plot", metavar="PNG", help="draw the compliant-feet trend")
    parser.add_argument(
        "--jobs",
        type=int,
        default=None,
        metavar="N",
        help="worker processes (default: one per core; 1 runs in this process)",
    )
    parser.add_argument(
        "--quick", action="store_true", help="a smoke run of seconds: solo12, one process, a 2 x 2 trend"
    )
    args = parser.parse_args(argv)
    grid = {}
    if args.quick:
        args.robots, args.jobs = ["solo12"], 1
        grid = {"masses": TREND_FOOT_MASSES[::2], "stiffnesses": TREND_STIFFNESSES[:2]}
    rows = robot_table(args.robots, args.states, args.jobs)
    trend = [] if args.no_trend else trend_table(args.jobs, **grid)
    if args.json:
        clean = lambda x: None if isinstance(x, float) and not math.isfinite(x) else x  # noqa: E731
        print(
            json.dumps(
                {"armatures": ARMATURES, "robots": rows, "trend": trend},
                indent=2,
                default=lambda o: o.tolist() if hasattr(o, "tolist") else clean(o),
            )
        )
    else:
        print_tables(rows, trend)
    if args.plot and trend:
        plot_trend(trend, args.plot)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
