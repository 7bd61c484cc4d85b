"""Full benchmark: error against run time of contactdiff and its baselines.

    python scripts/bench_error_vs_time.py [--repeats N] [--json out.json] [--out PNG]
    python scripts/bench_error_vs_time.py --quick --out /tmp/bench.png   # the bench's --quick sweep, seconds

Runs `contactdiff.bench.runner.run_bench` on every scene, writes
docs/bench_error_vs_time.png (or ``--out``) and prints the tables (ratios measured in this run).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from contactdiff.bench.runner import run_bench
from contactdiff.plotting import plot_bench

ROOT = Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--json", metavar="PATH", help="also write the results as JSON")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "bench_error_vs_time.png", help="PNG to write")
    parser.add_argument(
        "--quick", action="store_true", help="the bench's own quick sweep (run_bench(quick=True)), one repeat: seconds"
    )
    args = parser.parse_args(argv)
    result = run_bench(repeats=1 if args.quick else args.repeats, quick=args.quick)
    out = args.out
    out.parent.mkdir(parents=True, exist_ok=True)
    plot_bench(result, out)
    print(result.format())
    print(f"\nplot written to {out}")
    if args.json:
        Path(args.json).write_text(json.dumps(result.to_dict(), indent=2))


if __name__ == "__main__":
    main()
