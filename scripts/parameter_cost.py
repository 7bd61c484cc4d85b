"""What parameter sensitivities cost: the tilted solo12 drop (0.3 s, 33 events).

Timed in one process, the runs of each line taken in turn round after round (median
of 5 rounds; default tolerances, rtol 1e-8):

* the plain run, the run with the state's flow Jacobian (2nv = 36 columns), the run
  with the parameter Jacobian of all of solo12's inertial parameters (13 bodies × 10:
  mass, centre of mass, inertia about it; 130 columns), and the run with both: the
  aim is the parameter Jacobian at most 2 times the state's;
* for p = 1, 2, 4, 8 inertial parameters of the base, one run with those p
  parameters' Jacobian against the 2p plain runs of a central finite difference;
* what each gives at the default tolerances, for the first two of those (the
  base's mass and centre of mass x): the largest error of the column, relative to
  its size, against a run with the parameters at rtol 1e-12, atol 1e-13.

    python scripts/parameter_cost.py [--rounds 5] [--json]
    python scripts/parameter_cost.py --quick   # 0.1 s simulated, one round, p = 1 only: a smoke run
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import numpy as np
import pinocchio as pin
from scipy.spatial.transform import Rotation

import contactdiff as cd

T_FINAL = 0.3


def tilted_drop() -> cd.Scene:
    """solo12_drop rolled 0.03 and pitched 0.05 rad, raised 1 cm: feet land one at a time."""
    scene = cd.load_scene("solo12_drop")
    q = scene.q0.copy()
    q[3:7] = Rotation.from_euler("xyz", [0.03, 0.05, 0.0]).as_quat()
    q[2] += 0.01
    return scene.with_state(q)


def _interleaved(jobs: dict, rounds: int) -> dict[str, float]:
    times: dict[str, list[float]] = {name: [] for name in jobs}
    for _ in range(rounds):
        for name, job in jobs.items():
            start = time.perf_counter()
            job()
            times[name].append(time.perf_counter() - start)
    return {name: statistics.median(t) for name, t in times.items()}


def measure(rounds: int, t_final: float = T_FINAL, counts: tuple[int, ...] = (1, 2, 4, 8)) -> dict:
    """The module doc's times and accuracies: runs of ``t_final`` s, FD against ``counts`` parameters."""
    scene = tilted_drop()
    inertial = [n for n in scene.parameter_names() if n.startswith("body:")]
    base = [n for n in inertial if n.startswith("body:base_link:")]
    values = dict(zip(inertial, scene.parameter_values(inertial)))

    def step(name):
        return 1e-5 * (abs(values[name]) or 1.0)

    def central(name):
        plus, minus = (
            cd.simulate(scene.with_parameters({name: values[name] + sign * step(name)}), t_final) for sign in (1, -1)
        )
        return np.concatenate([pin.difference(scene.model, minus.q, plus.q), plus.v - minus.v]) / (2 * step(name))

    def fd(names):
        def run():  # the 2p perturbed plain runs of a central difference
            for name in names:
                central(name)

        return run

    jobs = {
        "plain": lambda: cd.simulate(scene, t_final),
        "jacobian": lambda: cd.simulate(scene, t_final, jacobian=True),
        f"{len(inertial)} inertial": lambda: cd.simulate(scene, t_final, parameters=inertial),
        f"jacobian + {len(inertial)} inertial": lambda: cd.simulate(scene, t_final, jacobian=True, parameters=inertial),
    }
    for p in counts:
        names = base[:p]
        jobs[f"{p} parameters"] = lambda names=names: cd.simulate(scene, t_final, parameters=names)
        jobs[f"FD, {2 * p} runs"] = fd(names)
    t = _interleaved(jobs, rounds)
    rows = {
        "times_s": t,
        "events": len(cd.simulate(scene, t_final).events),
        "parameters": len(inertial),
        "all_inertial_over_jacobian": t[f"{len(inertial)} inertial"] / t["jacobian"],
        "both_over_jacobian": t[f"jacobian + {len(inertial)} inertial"] / t["jacobian"],
        "fd_over_one_run": {p: t[f"FD, {2 * p} runs"] / t[f"{p} parameters"] for p in counts},
        "t_final": t_final,
    }
    checked = base[:2]
    reference = cd.simulate(scene, t_final, parameters=checked, rtol=1e-12, atol=1e-13).parameter_jacobian
    exact = cd.simulate(scene, t_final, parameters=checked).parameter_jacobian
    rows["accuracy"] = {}
    for k, name in enumerate(checked):
        size = np.abs(reference[:, k]).max()
        rows["accuracy"][name] = {
            "exact": float(np.abs(exact[:, k] - reference[:, k]).max() / size),
            "finite_difference": float(np.abs(central(name) - reference[:, k]).max() / size),
        }
    return rows


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=int, default=5, help="rounds of interleaved runs (median kept)")
    parser.add_argument("--json", action="store_true", help="print the results as JSON")
    parser.add_argument("--quick", action="store_true", help="0.1 s simulated, one round, p = 1: a smoke run")
    args = parser.parse_args(argv)
    if args.quick:
        args.rounds = 1
    rows = measure(args.rounds, 0.1, (1,)) if args.quick else measure(args.rounds)
    if args.json:
        print(json.dumps(rows, indent=2))
        return
    print(f"tilted solo12 drop, {rows['t_final']} s, {rows['events']} events; median of {args.rounds} rounds")
    for name, t in rows["times_s"].items():
        print(f"  {name:<28} {t:7.3f} s")
    print(
        f"parameter Jacobian of all {rows['parameters']} inertial parameters / state Jacobian alone: "
        f"{rows['all_inertial_over_jacobian']:.2f} (aim <= 2); both / state Jacobian: "
        f"{rows['both_over_jacobian']:.2f}"
    )
    for p, ratio in rows["fd_over_one_run"].items():
        print(f"  p = {p}: 2p FD runs / one run with p parameters: {ratio:.2f} (aim > 1 for p >= 2)")
    print("error of a column at the default tolerances, relative to its size (reference: rtol 1e-12):")
    for name, err in rows["accuracy"].items():
        print(
            f"  {name:<28} exact {err['exact']:.1e}   central difference (h = 1e-5 |p|) {err['finite_difference']:.1e}"
        )


if __name__ == "__main__":
    main()
