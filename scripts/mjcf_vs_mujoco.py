"""Mass matrix and bias forces of every MJCF model in a folder, contactdiff (Pinocchio) against MuJoCo.

For each model's main file (`decoupling_atlas.menagerie_models`) that contactdiff loads:
MuJoCo compiles the file as given when every mesh file it names is there (a downloaded
Menagerie folder; bodies weighed by meshes then compare the loader's mesh inertia with
MuJoCo's), else a copy without its meshes (`mujoco_reference.stripped_copy`; the
Menagerie files beside the repository come without them), and at ``--states`` random states
(`mujoco_reference.random_states`) the script prints the largest relative
difference ``max|M_pin - M_mj| / max|M_mj|`` (MuJoCo's matrix in Pinocchio's
coordinates, `contactdiff.model.mjcf.mujoco_velocity_map`) and the same for the
bias forces. Needs the ``mujoco`` package (the test extra).

    python scripts/mjcf_vs_mujoco.py [--menagerie DIR] [--states N]

The last column says which file MuJoCo compiled (``as given`` or ``stripped``) and the run
time of load and comparison.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "tests" / "model"), str(ROOT / "scripts")]

from decoupling_atlas import MENAGERIE, menagerie_models  # noqa: E402
from mujoco_reference import MujocoReference, random_states, stripped_copy  # noqa: E402

import contactdiff as cd  # noqa: E402
from contactdiff.errors import ContactDiffError  # noqa: E402
from contactdiff.model.mjcf_xml import asset_files, read_document  # noqa: E402


def compare(path: Path, states: int, folder: Path) -> tuple[float, float, bool]:
    """Largest relative difference of M and of the bias forces over ``states`` random states,
    and whether MuJoCo compiled the file as given (all its meshes there)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        robot = cd.load_robot(path)
    meshes = [p for tag, p in asset_files(read_document(path).root, path.resolve().parent) if tag == "mesh"]
    as_given = all(p.is_file() for p in meshes)
    reference = MujocoReference(robot.model, path if as_given else stripped_copy(path, folder))
    worst_m = worst_b = 0.0
    for q, v in random_states(robot.model, states):
        M_mj, b_mj = reference.dynamics(q, v)
        M = pin.crba(robot.model, robot.new_data(), q)
        M = np.triu(M) + np.triu(M, 1).T
        b = pin.nle(robot.model, robot.new_data(), q, v)
        worst_m = max(worst_m, np.abs(M - M_mj).max() / np.abs(M_mj).max())
        worst_b = max(worst_b, np.abs(b - b_mj).max() / max(np.abs(b_mj).max(), 1e-300))
    return worst_m, worst_b, as_given


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--menagerie", type=Path, default=MENAGERIE)
    parser.add_argument("--states", type=int, default=10)
    parser.add_argument("--quick", action="store_true", help="the first model at two states (a smoke run)")
    args = parser.parse_args(argv)
    if args.quick:
        args.states = 2
    print(f"| model | max rel. diff of M | max rel. diff of bias | MuJoCo's file, time ({args.states} random states) |")
    print("|---|---|---|---|")
    for label, path in menagerie_models(args.menagerie)[: 1 if args.quick else None]:
        started = time.perf_counter()
        with tempfile.TemporaryDirectory() as folder:
            try:
                m, b, as_given = compare(Path(path), args.states, Path(folder))
            except ContactDiffError as exc:
                print(f"| {label} | not loaded: {type(exc).__name__} | | |")
                continue
        seconds = time.perf_counter() - started
        print(f"| {label} | {m:.1e} | {b:.1e} | {'as given' if as_given else 'stripped'}, {seconds:.2f} s |")


if __name__ == "__main__":
    main()
