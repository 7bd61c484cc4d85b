"""How fast a sweep runs: one worker against two, the engine's cost per point, Dask's rows.

A sweep of N solo12 trots (`robots/solo12_trot.toml`, T simulated seconds each,
about a second of run time for T = 2 s; the points vary the controller's gain
``trot:kp`` around its value, 10 N m/rad), measured in one run, R repeats in
rotation so that the shared machine's load falls on every variant alike:

* **direct**: the same N runs in a plain loop in this process (the scene loaded
  once, then ``scene.with_parameters(point)`` and ``simulate`` per point), no sweep;
* **1 worker**: ``sweep(..., n_jobs=1)``, in this process;
* **2 workers, cold**: ``sweep(..., n_jobs=2)`` with loky's worker processes
  stopped before (each worker starts Python, imports contactdiff, builds the scene);
* **2 workers, warm**: the same again at once (loky keeps its workers);
* **Dask**: once, on a local cluster of 2 one-thread workers started by the sweep,
  its rows compared with the 1-worker rows (run time excluded).

It prints the medians, the speed-ups of 2 workers over 1 (cold and warm), and
the engine's cost per point, as a fraction of a point's run time:

* in this process: (1 worker - direct) / N;
* with 2 workers: (2 x warm - sum of the rows' run times) / N, what the workers
  spend outside the runs (task and result transfer, idle time at the end);
* worker start-up: cold - warm.

    python scripts/sweep_bench.py [--points 8] [--t-final 2] [--repeats 3] [--no-dask] [--json]
    python scripts/sweep_bench.py --quick   # 2 trots of 0.05 s, one repeat, no Dask: a smoke run
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import statistics
import time

import numpy as np

import contactdiff as cd
from contactdiff.sweeps import grid, sweep

SCENE = "solo12_trot"
GAIN = "trot:kp"


def points(n: int):
    """N gains from 9 to 11 N m/rad (the trot's own is 10)."""
    return grid({GAIN: np.linspace(9.0, 11.0, n)})


def direct(n: int, t_final: float) -> tuple[float, list[float]]:
    """The runs in a plain loop: total wall time and each run's time (s)."""
    times = []
    started = time.perf_counter()
    scene = cd.load_scene(SCENE)
    for point in points(n):
        t = time.perf_counter()
        cd.simulate(scene.with_parameters(point), t_final)
        times.append(time.perf_counter() - t)
    return time.perf_counter() - started, times


def stop_workers() -> None:
    """Stop loky's kept worker processes, so that the next sweep starts its own."""
    from joblib.externals.loky import get_reusable_executor

    get_reusable_executor().shutdown(wait=True)


def machine() -> dict:
    cpu = platform.processor()
    try:
        cpu = next(line.split(":", 1)[1].strip() for line in open("/proc/cpuinfo") if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    import joblib

    return {
        "cpu": cpu,
        "cores": os.cpu_count(),
        "system": platform.platform(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "joblib": joblib.__version__,
    }


def busy_seconds() -> float:
    """CPU seconds the whole machine has been busy (all cores, every process; /proc/stat)."""
    try:
        with open("/proc/stat") as f:
            fields = [int(x) for x in f.readline().split()[1:]]
    except OSError:
        return math.nan
    return (sum(fields) - fields[3] - fields[4]) / os.sysconf("SC_CLK_TCK")


def phase(run):
    """``run()`` timed: its result, its wall time (s), and the cores the machine kept busy on average."""
    busy, started = busy_seconds(), time.perf_counter()
    result = run()
    wall = time.perf_counter() - started
    return result, wall, (busy_seconds() - busy) / wall


def measure(n: int, t_final: float, repeats: int, dask: bool) -> dict:
    names = ("direct", "1 worker", "2 workers, cold", "2 workers, warm")
    walls = {k: [] for k in names}
    busy = {k: [] for k in names}
    ratios = {"cold": [], "warm": []}
    run_times, direct_times, reference = [], [], None
    for _ in range(repeats):
        times, wall, cores = phase(lambda: direct(n, t_final)[1])
        direct_times += times
        walls["direct"].append(wall)
        busy["direct"].append(cores)
        one, wall, cores = phase(lambda: sweep(SCENE, points(n), t_final=t_final, progress=False, n_jobs=1))
        walls["1 worker"].append(wall)
        busy["1 worker"].append(cores)
        stop_workers()
        for name in names[2:]:
            two, wall, cores = phase(lambda: sweep(SCENE, points(n), t_final=t_final, progress=False, n_jobs=2))
            walls[name].append(wall)
            busy[name].append(cores)
            ratios[name.split(", ")[1]].append(walls["1 worker"][-1] / wall)
        run_times.append(sum(r.run_time for r in two))
        reference = reference or [r.to_dict(run_time=False) for r in one]
        for rows in (one, two):
            if [r.to_dict(run_time=False) for r in rows] != reference:
                raise SystemExit("rows differ between runs of the same sweep")
    median = {k: statistics.median(v) for k, v in walls.items()}
    per_run = statistics.median(direct_times)
    out = {
        "scene": SCENE,
        "points": n,
        "t_final": t_final,
        "repeats": repeats,
        "machine": machine(),
        "median_wall_s": median,
        "median_busy_cores": {k: statistics.median(v) for k, v in busy.items()},
        "median_run_s": per_run,
        "speedup_cold": statistics.median(ratios["cold"]),
        "speedup_warm": statistics.median(ratios["warm"]),
        "overhead_in_process": (median["1 worker"] - median["direct"]) / n / per_run,
        "overhead_two_workers": (2 * median["2 workers, warm"] - statistics.median(run_times)) / n / per_run,
        "worker_start_up_s": median["2 workers, cold"] - median["2 workers, warm"],
    }
    if dask:
        rows, wall, _ = phase(
            lambda: sweep(SCENE, points(n), t_final=t_final, progress=False, backend="dask", n_jobs=2)
        )
        out["dask_wall_s"] = wall
        out["dask_rows_identical"] = [r.to_dict(run_time=False) for r in rows] == reference
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=8, help="trots in the sweep (default 8)")
    parser.add_argument("--t-final", type=float, default=2.0, help="simulated time of each trot, s (default 2)")
    parser.add_argument("--repeats", type=int, default=3, help="repeats, medians kept (default 3)")
    parser.add_argument("--no-dask", action="store_true", help="skip the Dask run")
    parser.add_argument("--json", action="store_true")
    parser.add_argument(
        "--quick", action="store_true", help="a smoke run of seconds: 2 trots of 0.05 s, one repeat, no Dask"
    )
    args = parser.parse_args(argv)
    if args.quick:
        args.points, args.t_final, args.repeats, args.no_dask = 2, 0.05, 1, True
    result = measure(args.points, args.t_final, args.repeats, not args.no_dask)
    if args.json:
        print(json.dumps(result, indent=2))
        return 0
    m = result["machine"]
    print(
        f"{result['points']} {SCENE} runs of {result['t_final']:g} s, median of {result['repeats']} "
        f"(median run {result['median_run_s']:.3f} s); {m['cpu']}, {m['cores']} cores, Python {m['python']}, "
        f"numpy {m['numpy']}, joblib {m['joblib']}"
    )
    print("  variant           wall   cores busy (all processes; above 1 in a one-process variant: other work)")
    for name, wall in result["median_wall_s"].items():
        print(f"  {name:<16} {wall:6.2f} s  {result['median_busy_cores'][name]:.2f}")
    print(
        f"speed-up of 2 workers over 1 (median of the repeats' ratios): {result['speedup_cold']:.2f} cold "
        f"(workers started by the sweep), {result['speedup_warm']:.2f} warm (workers kept)"
    )
    print(
        f"engine cost per point, over the run time: {100 * result['overhead_in_process']:.2f} % in this process, "
        f"{100 * result['overhead_two_workers']:.2f} % with 2 workers; worker start-up "
        f"{result['worker_start_up_s']:.2f} s per sweep"
    )
    if "dask_wall_s" in result:
        print(
            f"Dask, local cluster of 2: {result['dask_wall_s']:.2f} s (cluster start included), rows "
            + ("identical" if result["dask_rows_identical"] else "DIFFERENT")
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
