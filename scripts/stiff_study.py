"""Cost against leg stiffness for Radau, DOP853 and method="auto" (docs/stiff_cost.png).

planar_trot_soft with both leg springs scaled by 1 ... 1e7 (contactdiff.bench.extreme_cases.stiffness_sweep),
run to t = 1.2 (touchdown at t = 1) at rtol 1e-8, atol 1e-10:

* legs with damping ratio 1: the fast motion decays, the problem is stiff;
* the shipped undamped legs: the touchdown rings them at sqrt(2k) rad/s, which every
  accurate method must resolve (Radau, about ten times DOP853's cost there, is skipped
  above 1e4 x).

Prints the study tables (error against a tight reference, run time, steps,
evaluations) and draws run time and dynamics evaluations against the stiffness.

    python scripts/stiff_study.py                 # the sweep and the figure (a few minutes)
    python scripts/stiff_study.py --quick         # 1 and 10 x only, a smoke run of seconds (figure: --figure)
    python scripts/stiff_study.py --all           # also every other study and the footprint
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from contactdiff.bench import extreme_cases as studies
from contactdiff.bench.footprint import measure_footprint

FIGURE = Path(__file__).resolve().parent.parent / "docs" / "stiff_cost.png"
SCALES = (1, 10, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7)
COLORS = {"auto": "tab:green", "DOP853": "tab:blue", "Radau": "tab:red"}


def plot(damped, undamped, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 2, figsize=(10, 7), sharex=True)
    for col, (rows, title) in enumerate(
        ((damped, "legs with damping ratio 1 (stiff)"), (undamped, "undamped legs (ringing after touchdown)"))
    ):
        for method, color in COLORS.items():
            pts = [
                (float(r.parameter.split("x ")[1]), r)
                for r in rows
                if r.method == method and not r.outcome.startswith("skipped") and r.steps > 0
            ]
            if not pts:
                continue
            xs = [p[0] for p in pts]
            axes[0, col].loglog(xs, [p[1].time for p in pts], "o-", color=color, label=method, ms=4)
            axes[1, col].loglog(xs, [p[1].evaluations for p in pts], "o-", color=color, label=method, ms=4)
        xs = [s for s in SCALES]
        ref = [r for r in rows if r.method == "DOP853" and r.steps > 0]
        if ref:  # sqrt(k) guide through DOP853's stiffest point
            e0, s0 = ref[-1].evaluations, float(ref[-1].parameter.split("x ")[1])
            axes[1, col].loglog(xs, [e0 * math.sqrt(s / s0) for s in xs], ":", color="gray", label="∝ sqrt(k)")
        axes[0, col].set_title(title, fontsize=10)
        axes[0, col].set_ylabel("run time (s)")
        axes[1, col].set_ylabel("dynamics evaluations")
        axes[1, col].set_xlabel("leg stiffness / nominal (27)")
        for ax in axes[:, col]:
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize=8)
    fig.suptitle("planar_trot_soft to t = 1.2, rtol 1e-8: cost against leg stiffness", fontsize=11)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--quick",
        action="store_true",
        help="stiffness 1 and 10 x only, a smoke run; the figure only if --figure is given",
    )
    parser.add_argument("--all", action="store_true", help="also the other studies and the footprint")
    parser.add_argument("--json", metavar="PATH", help="write every row as JSON")
    parser.add_argument("--figure", help=f"figure path (default {FIGURE})")
    args = parser.parse_args(argv)
    scales = SCALES[:2] if args.quick else SCALES
    damped = studies.stiffness_sweep(scales=scales, damping_ratio=1.0)
    undamped = studies.stiffness_sweep(
        scales=scales,
        damping_ratio=0.0,
        skip=lambda s, m: "ringing: ~10x DOP853 cost" if m == "Radau" and s > 1e4 else None,
    )
    result = studies.StudyResult(damped + undamped)
    print(result.format())
    for rows, label in ((damped, "damped"), (undamped, "undamped")):
        print(
            f"{label}: steps by method of auto: "
            + "; ".join(f"{r.parameter}: {r.details.get('steps_by_method')}" for r in rows if r.method == "auto")
        )
    if args.all:
        rest = studies.StudyResult(
            studies.tiny_mass_study()
            + studies.grazing_study()
            + studies.simultaneous_study()
            + studies.zeno_study()
            + studies.elastic_study(impacts=10_000)
            + studies.bad_input_study()
        )
        print(rest.format())
        result.rows += rest.rows
        fp = measure_footprint(quick=False)
        print(fp.format())
    if not args.quick or args.figure:
        figure = Path(args.figure or FIGURE)
        plot(damped, undamped, figure)
        print(f"figure written to {figure}")
    if args.json:
        Path(args.json).write_text(json.dumps(result.to_dict(), indent=2))
    return 0 if all(r.ok for r in result.rows) else 1


if __name__ == "__main__":
    sys.exit(main())
