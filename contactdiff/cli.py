"""The ``contactdiff`` command line.

    contactdiff check SOURCE [--samples N] [--seed S] [--armature X] [--tol T] [--json]

SOURCE is a scene (TOML path or a name of robots/) or a robot (URDF path or
example-robot-data name; its feet get ground contacts). Errors print one line
and exit with status 2.
"""

from __future__ import annotations

import argparse
import json
import sys

from .errors import ContactDiffError


def _positive_int(text: str) -> int:
    value = int(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {value}")
    return value


def _nonnegative_float(text: str) -> float:
    value = float(text)
    if not value >= 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"must be a finite number >= 0, got {text}")
    return value


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="contactdiff",
        description="Differentiability through contact: check robots for limb decoupling.")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    check = sub.add_parser(
        "check", help="decoupling / orthogonality report of a scene or robot",
        description="Measure how far a scene is from the paper's assumptions: inverse-mass "
                    "coupling of every contact pair, and limbs decoupled through the body.")
    check.add_argument("source", metavar="SOURCE",
                       help="scene (TOML path or robots/ name) or robot (URDF path or "
                            "example-robot-data name such as solo12)")
    check.add_argument("--samples", type=_positive_int, default=20,
                       help="random poses besides the reference (default 20)")
    check.add_argument("--seed", type=int, default=0, help="seed of the random poses (default 0)")
    check.add_argument("--armature", type=_nonnegative_float, default=0.0,
                       help="rotor inertia added to actuated joints, kg m^2; the report "
                            "is compared with the one without it")
    check.add_argument("--tol", type=float, default=1e-9,
                       help="relative size below which a coupling counts as zero (default 1e-9)")
    check.add_argument("--json", action="store_true", help="print the report as JSON")
    check.set_defaults(run=_run_check)
    return parser


def _run_check(args) -> int:
    from .checks import check_decoupling
    from .scene import load_source

    scene = load_source(args.source)
    options = dict(samples=args.samples, seed=args.seed, tol=args.tol)
    report = check_decoupling(scene, armature=args.armature, **options)
    baseline = check_decoupling(scene, **options) if args.armature else None
    if args.json:
        out = report.to_dict()
        if baseline is not None:
            out["without_armature"] = baseline.to_dict()
        print(json.dumps(out, indent=2))
        return 0
    print(report.format())
    if baseline is not None:
        print(f"\narmature {args.armature:g}: max coupling {baseline.max_coupling:.3e} -> "
              f"{report.max_coupling:.3e}; verdict {baseline.verdict} -> {report.verdict}")
    return 0


def main(argv: list[str] | None = None) -> int:
    """Run the command line; return the exit status (0 ok, 2 bad input or model)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.run(args)
    except ContactDiffError as exc:
        print(f"contactdiff {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
