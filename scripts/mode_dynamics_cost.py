"""Cost of one mode evaluation, with and without derivatives, against Pinocchio's own calls.

    python scripts/mode_dynamics_cost.py [SCENE ...]

For each scene (default: solo12_drop and planar_trot_soft) prints the time of
`ModeDynamics.solve` in flight and with every contact active, plain and with
derivatives, next to the Pinocchio calls it is built on: the floor a Python
evaluation cannot go below. Best of 3 repeats of 300 calls each (µs per call).
"""

from __future__ import annotations

import sys
import timeit

import numpy as np
import pinocchio as pin

from contactdiff.dynamics.mode import ModeDynamics
from contactdiff.model.scene_file import load_scene


def _us(fn, number: int = 300) -> float:
    return min(timeit.repeat(fn, number=number, repeat=3)) / number * 1e6


def report(name: str) -> None:
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
        print(f"  {label:<34} {_us(fn):8.1f}")


def main() -> None:
    for name in sys.argv[1:] or ["solo12_drop", "planar_trot_soft"]:
        report(name)


if __name__ == "__main__":
    main()
