"""Cost of one mode evaluation, with and without derivatives, against Pinocchio's own calls.

    python scripts/mode_dynamics_cost.py [SCENE ...] [--quick]

For each scene (default: solo12_drop and planar_trot_soft) prints the time of
`ModeDynamics.solve` in flight and with every contact active, plain and with
derivatives, next to the Pinocchio calls it is built on: the floor a Python
evaluation cannot go below. Best of 3 repeats of 300 calls each (µs per call;
``--quick``: one repeat of 3 calls, a smoke run).
"""

from __future__ import annotations

import argparse
import timeit

import numpy as np
import pinocchio as pin

from contactdiff.dynamics.mode import ModeDynamics
from contactdiff.scenes.scene_file import load_scene


def _us(fn, number: int = 300, repeat: int = 3) -> float:
    return min(timeit.repeat(fn, number=number, repeat=repeat)) / number * 1e6


def report(name: str, number: int = 300, repeat: int = 3) -> None:
    scene = load_scene(name)
    dyn, model = ModeDynamics(scene), scene.model
    data = model.createData()
    q = scene.q0
    v = 0.1 * np.random.default_rng(0).standard_normal(scene.nv)
    tau = np.zeros(scene.nv)
    every = tuple(range(len(scene.contacts)))
    print(f"{name} (nv = {scene.nv}, {len(every)} contacts), µs per call")
    rows = [
        ("solve, flight", lambda: dyn.solve(q, v, 0.0, ())),
        ("solve, flight, derivatives", lambda: dyn.solve(q, v, 0.0, (), derivatives=True)),
        ("solve, all contacts", lambda: dyn.solve(q, v, 0.0, every)),
        ("solve, all contacts, derivatives", lambda: dyn.solve(q, v, 0.0, every, derivatives=True)),
        ("pin.aba", lambda: pin.aba(model, data, q, v, tau)),
        ("pin.computeABADerivatives", lambda: pin.computeABADerivatives(model, data, q, v, tau)),
        ("pin.computeMinverse", lambda: pin.computeMinverse(model, data, q)),
        ("pin.computeRNEADerivatives", lambda: pin.computeRNEADerivatives(model, data, q, v, tau)),
    ]
    for label, fn in rows:
        print(f"  {label:<34} {_us(fn, number, repeat):8.1f}")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "scenes",
        nargs="*",
        metavar="SCENE",
        default=["solo12_drop", "planar_trot_soft"],
        help="shipped scenes (default solo12_drop planar_trot_soft)",
    )
    parser.add_argument("--quick", action="store_true", help="one repeat of 3 calls per line: a smoke run")
    args = parser.parse_args(argv)
    for name in args.scenes:
        report(name, *((3, 1) if args.quick else (300, 3)))


if __name__ == "__main__":
    main()
