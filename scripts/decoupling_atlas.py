"""The decoupling atlas: every MuJoCo Menagerie model beside the repository and every
example-robot-data robot with feet, loaded and checked for limb decoupling.

For each Menagerie model, its ``scene.xml`` where it has one (the model's file
included, a floor added, and Cassie's ``home`` keyframe), else its own file. For
each model (one point of a sweep, `contactdiff.sweeps.sweep`, on local worker
processes): load it (`contactdiff.load_robot`; an MJCF file through
`contactdiff.model.mjcf`), record why not when it does not load, its feet and the
rule that chose them, then run the checker (`contactdiff.check_decoupling`,
``--samples`` random poses): the largest normalised inverse-mass coupling between
two feet, the worst term of the limb-decoupling assumption, the verdict, and the
run time of load and check together (one worker process per model).

A fixed-base model with two or more leaf limbs (a hand) is checked with a contact at
the end body of each leaf limb (its fingertips, "given by hand" in the table); a
fixed-base chain (an arm) has one end, and nothing to couple.

Menagerie models downloaded by the user (``--extra DIR``, each model in its own folder as in
the Menagerie repository, meshes included where they were downloaded; ``--extra-source``
says where they came from) are checked beside them, and the table gives each row's origin.

    python scripts/decoupling_atlas.py [--menagerie DIR] [--extra DIR --extra-source TEXT] [--samples N]
        [--jobs N] [--out docs/results/atlas.md]
"""

from __future__ import annotations

import argparse
import re
import textwrap
import time
import warnings
from pathlib import Path

import pinocchio as pin

import contactdiff as cd
from contactdiff.model.robot_files import QUADRUPEDS, example_robot_data_names
from contactdiff.sweeps import sweep

ROOT = Path(__file__).resolve().parents[1]
MENAGERIE = ROOT.parent / "shared" / "data" / "menagerie"
KINDS = {
    "unitree_go2": "quadruped",
    "agility_cassie": "biped",
    "berkeley_humanoid": "humanoid (legs)",
    "wonik_allegro": "hand",
    "leap_hand": "hand",
    "kuka_iiwa_14": "arm",
    "universal_robots_ur5e": "arm",
    "unitree_go1": "quadruped",
    "unitree_a1": "quadruped",
    "anybotics_anymal_b": "quadruped",
    "anybotics_anymal_c": "quadruped",
    "boston_dynamics_spot": "quadruped",
    "google_barkour_v0": "quadruped",
    "google_barkour_vb": "quadruped",
    "unitree_g1": "humanoid",
    "unitree_h1": "humanoid",
    "robotis_op3": "humanoid",
    "booster_t1": "humanoid",
    "apptronik_apollo": "humanoid",
    "fourier_n1": "humanoid",
    "pal_talos": "humanoid",
    "shadow_hand": "hand",
    "shadow_dexee": "hand",
    "franka_emika_panda": "arm",
    "robotiq_2f85": "gripper",
}
LEGGED_OR_HAND = ("quadruped", "biped", "humanoid", "hand")
# The model's own file where a Menagerie folder holds several (variants, MJX versions, parts).
MAIN_FILES = {
    "unitree_g1": "g1.xml",
    "franka_emika_panda": "panda.xml",
    "pal_talos": "talos.xml",
    "shadow_hand": "right_hand.xml",
    "wonik_allegro": "right_hand.xml",
    "boston_dynamics_spot": "spot.xml",
    "anybotics_anymal_c": "anymal_c.xml",
    "google_barkour_v0": "barkour_v0.xml",
    "google_barkour_vb": "barkour_vb.xml",
    "leap_hand": "right_hand.xml",
}


def menagerie_models(folder: Path, scenes: bool = False) -> list[tuple[str, str]]:
    """``(label, path)`` of each model folder's main file: `MAIN_FILES`' entry, else each ``.xml``
    that is neither a scene nor an MJX variant. With ``scenes``, the folder's scene of that file
    where there is one (``scene.xml``, ``scene_<file>.xml`` or ``scene_<side>.xml`` that includes
    it; it adds a floor and may hold the ``home`` keyframe, as Cassie's does)."""
    found = []
    for sub in sorted(p for p in folder.iterdir() if p.is_dir()):
        if sub.name in MAIN_FILES:
            mains = [sub / MAIN_FILES[sub.name]] if (sub / MAIN_FILES[sub.name]).is_file() else []
        else:
            mains = [p for p in sorted(sub.glob("*.xml")) if not p.name.startswith("scene") and "mjx" not in p.name]
        for path in mains:
            chosen = _scene_of(path) if scenes else None
            chosen = chosen or path
            found.append((f"{sub.name}/{chosen.name}", str(chosen)))
    return found


def _scene_of(path: Path) -> Path | None:
    """The scene file beside ``path`` that includes it and adds no joints (a hand's scene may
    add a free object to hold: a second tree), or None."""
    for name in ("scene.xml", f"scene_{path.name}", f"scene_{path.stem.split('_')[0]}.xml"):
        scene = path.parent / name
        text = scene.read_text(errors="replace") if scene.is_file() else ""
        if f'file="{path.name}"' in text and "<joint" not in text and "<freejoint" not in text:
            return scene
    return None


def leaf_end_bodies(robot) -> list[str]:
    """The last body frame of each leaf joint (a hand's fingertips)."""
    model = robot.model
    parents = set(model.parents[1:])
    ends = []
    for j in range(1, model.njoints):
        if j in parents:
            continue
        bodies = [f.name for f in model.frames if f.parentJoint == j and f.type == pin.FrameType.BODY]
        if bodies:
            ends.append(bodies[-1])
    return ends


def atlas_scene(source: str, hand: bool = False):
    """The model's scene: a robot on its feet (a ``hand`` on its fingertips), with the load's
    warnings kept on it."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        robot = cd.load_robot(source)
        if hand and not robot.floating_base and not robot.feet:
            ends = leaf_end_bodies(robot)
            if len(ends) >= 2:
                robot = cd.load_robot(source, feet=ends)
    scene = cd.Scene.from_robot(robot)
    notes = [_short(str(w.message)) for w in caught if "left out" in str(w.message)]
    scene.atlas_notes = list(dict.fromkeys(notes))  # a hand loads twice (its fingertips given)
    return scene


def _short(note: str) -> str:
    """A load's warning without the lists of joint names and the advice (the table's cell)."""
    note = re.sub(r"of (\d+) joint\(s\) \([^)]*\)", r"of \1 joint(s)", note)
    return note.replace(" (passive forces: give them as efforts, e.g. JointSpring)", " (passive forces)")


def atlas_row(scene, point, samples: int = 8) -> dict:
    """The checker's numbers for one model (a sweep job)."""
    report = cd.check_decoupling(scene, samples=samples)
    worst = max(report.terms, key=lambda t: t.value, default=None)
    mass = max((t for t in report.terms if t.condition == "mass matrix"), key=lambda t: t.value, default=None)
    choice = scene.foot_choice
    return {
        "floating": scene.robot.floating_base,
        "nv": scene.robot.nv,
        "feet": ", ".join(scene.robot.feet) or "-",
        "rule": choice.rule.name.lower() if choice else "-",
        "feet_shown": _feet_shown(scene.robot.feet, choice.limbs if choice else {}),
        "coupling": report.max_coupling if report.pairs else None,
        "within": max((p.max for p in report.within_limb), default=None),
        "worst_term": f"{worst.condition} ({worst.where}): {worst.value:.2e}" if worst else "-",
        "worst_mass_term": f"{mass.where}: {mass.value:.2e}" if mass else "-",
        "verdict": report.verdict or f"none: {report.reason}",
        "notes": "; ".join(scene.atlas_notes),
    }


def _feet_shown(feet, limbs: dict) -> str:
    """The feet, a foot of several sphere points shown once as its body with their number."""
    limb_of = {f: limb for limb, points in limbs.items() for f in points}
    shown = dict.fromkeys(f"{limb_of[f]} ({len(limbs[limb_of[f]])} points)" if f in limb_of else f for f in feet)
    return ", ".join(shown) or "-"


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--menagerie", type=Path, default=MENAGERIE)
    parser.add_argument("--extra", type=Path, help="a folder of downloaded Menagerie model folders")
    parser.add_argument(
        "--extra-source",
        default="downloaded",
        help="where the --extra models came from (e.g. 'mujoco_menagerie at commit abc1234')",
    )
    parser.add_argument(
        "--quick", action="store_true", help="one Menagerie model and solo12, two poses each (a smoke run; give --out)"
    )
    parser.add_argument("--samples", type=int, default=8, help="random poses of each check (default 8)")
    parser.add_argument("--jobs", type=int, default=1, help="worker processes (default 1: run times on one core)")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "results" / "atlas.md")
    args = parser.parse_args(argv)
    if args.quick:
        args.samples = 2

    models = [("menagerie", label, path) for label, path in menagerie_models(args.menagerie, scenes=True)]
    if args.extra is not None:
        models += [("downloaded", label, path) for label, path in menagerie_models(args.extra, scenes=True)]
    models += [("example-robot-data", name, name) for name in example_robot_data_names()]
    if args.quick:
        models = [m for m in models if m[0] == "menagerie"][:1] + [m for m in models if m[1] == "solo12"]
    started = time.perf_counter()
    points = [{"arg:source": path, "arg:hand": KINDS.get(label.split("/")[0]) == "hand"} for _, label, path in models]
    result = sweep(atlas_scene, points, lambda scene, point: atlas_row(scene, point, args.samples), n_jobs=args.jobs)
    wall = time.perf_counter() - started
    lines = [
        _header(args, wall),
        "",
        "| source | model | kind | loads | feet (rule) | max coupling | within a foot | worst decoupling term "
        "| worst mass-matrix term | verdict | time [s] |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    skipped, failed = [], []
    loaded: dict[str, tuple[str, bool]] = {}  # Menagerie folder: (kind, loaded and checked from some copy)
    slowest = max(
        ((row.run_time, label) for (origin, label, _), row in zip(models, result) if origin != "example-robot-data"),
        default=(0.0, "-"),
    )
    for (origin, label, _), row in zip(models, result):
        kind = KINDS.get(label.split("/")[0], "quadruped" if label in QUADRUPEDS else "")
        if row.error is not None:
            message = _cell(row.error.message.replace(str(args.menagerie.resolve()), "menagerie"))
            if origin != "example-robot-data":
                loaded.setdefault(label.split("/")[0], (kind, False))
                lines.append(f"| {origin} | {label} | {kind} | no: {message} | | | | | | | {row.run_time:.2f} |")
            else:
                failed.append(f"{label} ({message})")
            continue
        out = row.outputs
        feet = [] if out["feet"] == "-" else out["feet"].split(", ")
        if origin == "example-robot-data" and len(feet) < 2:
            skipped.append(label)
            continue
        kind = kind or (f"legged, {len(feet)} feet" if out["floating"] else "fixed base")
        if origin != "example-robot-data":
            loaded[label.split("/")[0]] = (kind, True)
        coupling = "-" if out["coupling"] is None else f"{out['coupling']:.2e}"
        within = "-" if out["within"] is None else f"{out['within']:.2e}"
        loads = "yes" + (f" ({_cell(out['notes'])})" if out["notes"] else "")
        lines.append(
            f"| {origin} | {label} | {kind} | {loads} | {out['feet_shown']} ({out['rule']}) | {coupling} | "
            f"{within} | "
            f"{_cell(out['worst_term'])} | {_cell(out['worst_mass_term'])} | "
            f"{_cell(out['verdict'].split(';')[0])} | {row.run_time:.2f} |"
        )
    lines += [
        "",
        _ratio(loaded) + f" Slowest Menagerie check: {slowest[1]}, {slowest[0]:.2f} s (load and check, "
        "one worker process).",
        "",
        f"Not in the table: {len(skipped)} example-robot-data robots with fewer "
        "than two feet (fixed bases, arms, flying arms): " + ", ".join(sorted(skipped)) + ".",
    ]
    if failed:
        lines += ["", f"example-robot-data robots that do not load ({len(failed)}): " + "; ".join(failed) + "."]
    args.out.write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    print(f"atlas written to {args.out}")


def _ratio(loaded: dict[str, tuple[str, bool]]) -> str:
    """The share of Menagerie legged robots and hands that load and are checked (a model counts
    once, loaded when one of its copies loads)."""
    counted = {name: ok for name, (kind, ok) in loaded.items() if kind.startswith(LEGGED_OR_HAND)}
    missed = sorted(name for name, ok in counted.items() if not ok)
    share = sum(counted.values()) / max(len(counted), 1)
    return (
        f"Menagerie legged robots and hands that load and are checked: {sum(counted.values())} of "
        f"{len(counted)} ({100 * share:.0f} %)" + (f"; not loaded: {', '.join(missed)}." if missed else ".")
    )


def _header(args, wall: float) -> str:
    extra = ""
    command = f"python scripts/decoupling_atlas.py --samples {args.samples} --jobs {args.jobs}"
    if args.extra is not None:
        command += f" --extra MENAGERIE_DOWNLOAD --extra-source '{args.extra_source}'"
        extra = "\n\n" + textwrap.fill(
            f"Rows marked *downloaded* are Menagerie models {args.extra_source}, each folder as in the "
            "repository (its XML files and the mesh files the download had), in a folder outside the repository "
            "(MENAGERIE_DOWNLOAD in the command); rows marked *menagerie* are the XML-only copies beside the "
            "repository. The share of legged robots and hands below counts each model once (loaded when one of "
            "its copies loads); arms and grippers are not counted.",
            100,
        )
    return f"""# Decoupling atlas

Every MuJoCo Menagerie model beside the repository (`../shared/data/menagerie`, XML only) and every
example-robot-data robot with feet, loaded and checked for limb decoupling
(`contactdiff.check_decoupling`, {args.samples} random poses besides the reference). Written by

    {command}

(whole run {wall:.0f} s wall time, {args.jobs} worker process(es); the machine was shared with other
jobs, so the times are upper bounds). Columns: *max coupling* is the largest normalised inverse-mass
coupling |G_ij| / sqrt(G_ii G_jj) between two limbs' contacts over the sampled poses (a foot of several
sphere points, shown as its body with their number, is one limb); *within a foot* the largest coupling
between two points of one such foot, reported apart (one rigid body: not limb coupling, not in the
verdict; `-` when every foot is one point); *worst decoupling term* the
largest term of the limb-decoupling assumption (docs/python-api.md, `check_decoupling`); *time* the
load and the check of the model in its worker process. Feet rules: `mjcf_spheres` (the model's
collision spheres on leaf bodies), `lowest_end_frames` (docs/models.md), `given` (a hand's fingertips:
the end body of each leaf limb), `fixed_base` (an arm: no feet).{extra}"""


def _cell(text: str) -> str:
    """Table-safe text; a file's full path shortened to its name (the table names no machine's folders)."""
    text = re.sub(r"'/[^']*/([^/']+)'", r"'\1'", str(text))
    return text.replace("|", "/").replace("\n", " ")


if __name__ == "__main__":
    main()
