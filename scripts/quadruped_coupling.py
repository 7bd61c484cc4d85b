"""Orthogonality of the six example-robot-data quadrupeds, with and without rotor inertia.

Prints a markdown table: for each robot the largest normalised inverse-mass
coupling |G_ij| / sqrt(G_ii G_jj) over the six foot pairs (median and max over
the standing pose and seeded random poses with both feet on the ground), for
several armature values (kg m^2 added to every actuated joint).

    python scripts/quadruped_coupling.py [--samples 20] [--json]
    python scripts/quadruped_coupling.py --quick   # one random pose per robot: a smoke run
"""

import argparse
import json

import contactdiff as cd

ARMATURES = (0.0, 1e-3, 1e-2, 1e-1)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=20)
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--quick", action="store_true", help="one random pose per robot: a smoke run")
    args = parser.parse_args(argv)
    if args.quick:
        args.samples = 1
    rows = []
    for name in cd.QUADRUPEDS:
        scene = cd.load_source(name)
        row = {"robot": name}
        for armature in ARMATURES:
            report = cd.check_decoupling(scene, samples=args.samples, armature=armature)
            row[armature] = {
                "max": report.max_coupling,
                "reference": max(p.reference for p in report.pairs),
                "verdict": report.verdict,
            }
        rows.append(row)
    if args.json:
        print(
            json.dumps(
                [{k if isinstance(k, str) else f"armature={k:g}": v for k, v in r.items()} for r in rows], indent=2
            )
        )
        return
    head = " | ".join(f"armature {a:g}" for a in ARMATURES)
    print(f"| robot | {head} |")
    print("|---" * (len(ARMATURES) + 1) + "|")
    for r in rows:
        cells = " | ".join(f"{r[a]['reference']:.1e} / {r[a]['max']:.1e}" for a in ARMATURES)
        print(f"| {r['robot']} | {cells} |")
    print(
        "\ncells: max coupling at the standing pose / max over standing + "
        f"{args.samples} random poses; every verdict: "
        + ", ".join(sorted({r[a]["verdict"] for r in rows for a in ARMATURES}))
    )


if __name__ == "__main__":
    main()
