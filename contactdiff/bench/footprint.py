"""Only what a scene needs: measured.

`measure_footprint` returns a `Footprint` (a dict with ``format()``) of four
measurements, each counted (not timed) where a count says it, so tests can
assert them:

* **derivative work**: calls of Pinocchio's derivative algorithms and solves of
  the mode dynamics with derivatives, in ``simulate`` with and without
  ``jacobian=True`` (the default ``method="auto"`` measures stiffness by
  difference quotients, so a plain run does none until it switches to Radau,
  whose Newton matrix needs the mode's Jacobian);
* **no geometry**: the time of ``load_robot`` (dynamics only) against
  example-robot-data's own ``load`` (which also builds the visual and collision
  models from the meshes), median of a few, and the number of geometry objects
  each keeps;
* **only listed contacts and efforts**: solo12 with contacts on two of its four
  feet and one spring: the frames whose positions, Jacobians or accelerations
  are queried, and which efforts are evaluated (placements of all frames come
  from one Pinocchio call; everything per frame is computed for the listed
  frames only);
* **no plotting library**: the modules that ``import contactdiff`` loads, in a
  fresh interpreter.
"""

from __future__ import annotations

import statistics
import subprocess
import sys
import time
from collections import Counter
from contextlib import contextmanager

import numpy as np
import pinocchio as pin

from ..dynamics.mode import ModeDynamics
from ..integration.hybrid import simulate
from ..model.efforts import Spring
from ..model.kinematics import Kinematics
from ..model.robot_files import load_robot
from ..model.scene import Scene
from ..scenes.scene_file import load_scene

DERIVATIVE_FUNCTIONS = (
    "computeABADerivatives",
    "computeRNEADerivatives",
    "computeGeneralizedGravityDerivatives",
    "computeForwardKinematicsDerivatives",
    "computeJointKinematicHessians",
    "computeConstraintDynamicsDerivatives",
    "getPointVelocityDerivatives",
    "getPointClassicAccelerationDerivatives",
    "getFrameKinematicHessian",
)
"""Pinocchio's derivative algorithms and getters (any call is derivative work)."""

FRAME_QUERIES = (
    "position",
    "jacobian",
    "classical_acceleration",
    "velocity_derivative",
    "acceleration_derivatives",
    "hessian",
)
"""The `Kinematics` methods that compute something for one frame."""

PLOTTING_MODULES = ("matplotlib", "plotly", "seaborn", "bokeh", "pyqtgraph", "PIL")
"""Modules a plain ``import contactdiff`` must not load."""


class Footprint(dict):
    """The measurements of `measure_footprint` (a dict: what ``--json`` prints)."""

    def format(self) -> str:
        """The measurements as text (times in ms), one paragraph per measurement present."""
        out = ["== only what a scene needs"]
        d = self.get("derivatives")
        if d:
            out.append(
                "  derivative work in simulate (calls of pinocchio derivative algorithms / "
                "mode solves with derivatives):"
            )
            for run in d["runs"]:
                out.append(
                    f"    {run['scene']:<18} method {run['method']:<6} jacobian={str(run['jacobian']):<5} "
                    f"{run['pinocchio_derivative_calls']:>7d} / {run['derivative_solves']:>6d}   "
                    f"(of {run['dynamics_solves']} mode solves)"
                )
        g = self.get("loading")
        if g:
            out.append(
                f"  loading {g['robot']} (median of {g['repeats']}): load_robot {1e3 * g['load_robot']:.1f} ms "
                f"(geometry objects: {g['geometry_objects_ours']}), example_robot_data.load "
                f"{1e3 * g['example_robot_data']:.1f} ms (geometry objects: visual "
                f"{g['geometry_objects_erd']['visual']}, collision {g['geometry_objects_erd']['collision']}): "
                f"{g['example_robot_data'] / g['load_robot']:.0f}x"
            )
        f = self.get("frames")
        if f:
            out.append(
                f"  {f['scene']}: frames queried {', '.join(sorted(f['queried']))} "
                f"(listed: {', '.join(sorted(f['listed']))}; {f['frames_in_model']} frames in the model)"
            )
            out.append("    per frame: " + ", ".join(f"{k} {v}" for k, v in sorted(f["queries_per_frame"].items())))
            out.append("    efforts evaluated: " + ", ".join(f"{k} {v}" for k, v in f["effort_evaluations"].items()))
        m = self.get("imports")
        if m:
            loaded = [k for k, v in m["plotting_modules_loaded"].items() if v]
            out.append(
                f"  import contactdiff: {1e3 * m['import_time']:.0f} ms in a fresh interpreter; "
                f"plotting modules loaded: {', '.join(loaded) if loaded else 'none'} "
                f"(checked: {', '.join(m['plotting_modules_loaded'])})"
            )
        return "\n".join(out)


@contextmanager
def counting(targets):
    """Count calls of ``(owner, attribute)`` pairs while inside; yields a `Counter` keyed
    by attribute name (with the first argument's value for `Kinematics` frame queries)."""
    counts: Counter = Counter()
    saved = []
    for owner, name in targets:
        original = getattr(owner, name)
        saved.append((owner, name, original))

        def wrapper(*args, _original=original, _name=name, **kwargs):
            counts[_name] += 1
            return _original(*args, **kwargs)

        setattr(owner, name, wrapper)
    try:
        yield counts
    finally:
        for owner, name, original in reversed(saved):
            setattr(owner, name, original)


@contextmanager
def counting_derivative_work():
    """Count pinocchio derivative calls (by name) and `ModeDynamics` solves with and without
    derivatives: keys ``"derivative_solves"`` and ``"dynamics_solves"``."""
    original_solve = ModeDynamics.solve
    with counting([(pin, name) for name in DERIVATIVE_FUNCTIONS if hasattr(pin, name)]) as counts:

        def solve(self, q, v, t, active=(), *, derivatives=False, **options):
            counts["dynamics_solves"] += 1
            if derivatives:
                counts["derivative_solves"] += 1
            return original_solve(self, q, v, t, active, derivatives=derivatives, **options)

        ModeDynamics.solve = solve
        try:
            yield counts
        finally:
            ModeDynamics.solve = original_solve


def derivative_work(scene: Scene, t_final: float, **options) -> dict:
    """Derivative calls of one ``simulate(scene, t_final, **options)`` run."""
    with counting_derivative_work() as counts:
        simulate(scene, t_final, **options)
    pin_calls = sum(counts[name] for name in DERIVATIVE_FUNCTIONS)
    return {
        "scene": scene.name,
        "method": options.get("method", "auto"),
        "jacobian": bool(options.get("jacobian", False)),
        "pinocchio_derivative_calls": pin_calls,
        "derivative_solves": counts["derivative_solves"],
        "dynamics_solves": counts["dynamics_solves"],
        "by_function": {name: counts[name] for name in DERIVATIVE_FUNCTIONS if counts[name]},
    }


def loading(robot: str = "solo12", repeats: int = 5) -> dict:
    """Median time (s) of `load_robot` against ``example_robot_data.load`` (which builds
    the visual and collision models too), alternating the two; geometry objects kept."""
    import example_robot_data

    ours, theirs, loaded = [], [], None
    for _ in range(max(1, repeats)):
        start = time.perf_counter()
        mine = load_robot(robot)
        ours.append(time.perf_counter() - start)
        start = time.perf_counter()
        loaded = example_robot_data.load(robot)
        theirs.append(time.perf_counter() - start)
    assert loaded is not None  # one repeat at least
    geometry = sum(1 for a in ("visual_model", "collision_model") if getattr(mine, a, None) is not None)
    return {
        "robot": robot,
        "repeats": max(1, repeats),
        "load_robot": statistics.median(ours),
        "example_robot_data": statistics.median(theirs),
        "geometry_objects_ours": geometry,
        "geometry_objects_erd": {"visual": loaded.visual_model.ngeoms, "collision": loaded.collision_model.ngeoms},
        "same_dynamics": bool(
            mine.model.nv == loaded.model.nv
            and np.isclose(sum(i.mass for i in mine.model.inertias), sum(i.mass for i in loaded.model.inertias))
        ),
    }


def two_feet_scene() -> Scene:
    """solo12 dropped 5 cm with contacts on two diagonal feet (FL, HR) and one spring
    from the base to the FR foot: two of its four feet can touch."""
    robot = load_robot("solo12")
    base = load_scene("solo12_drop")
    contacts = [c for c in base.contact_specs if c.frame in ("FL_FOOT", "HR_FOOT")]
    spring = Spring("base_link", "FR_FOOT", stiffness=50.0, damping=1.0, rest_length=0.336)  # ~ its length at q0
    return Scene(
        robot, contacts, [spring], gravity=[0, 0, -9.81], q0=base.q0, v0=base.v0, name="solo12 two feet + spring"
    )


def frame_queries(t_final: float = 0.3, jacobian: bool = True) -> dict:
    """Frames queried and efforts evaluated while simulating `two_feet_scene`."""
    scene = two_feet_scene()
    model = scene.model
    per_frame: Counter = Counter()
    saved = [(name, getattr(Kinematics, name)) for name in FRAME_QUERIES]
    for name, original in saved:

        def query(self, fid, *args, _original=original, **kwargs):
            per_frame[model.frames[fid].name] += 1
            return _original(self, fid, *args, **kwargs)

        setattr(Kinematics, name, query)
    effort_calls: Counter = Counter()
    for effort in scene.efforts:
        label = f"{effort.spec.frame_a}-{effort.spec.frame_b} spring"
        for method in ("tau", "derivatives"):
            original = getattr(effort, method)

            def call(*args, _original=original, _label=label, **kwargs):
                effort_calls[_label] += 1
                return _original(*args, **kwargs)

            setattr(effort, method, call)
    try:
        traj = simulate(scene, t_final, jacobian=jacobian)
    finally:
        for name, original in saved:
            setattr(Kinematics, name, original)
    listed = {c.frame for c in scene.contact_specs} | {"base_link", "FR_FOOT"}
    return {
        "scene": scene.name,
        "listed": sorted(listed),
        "queried": sorted(per_frame),
        "queries_per_frame": dict(per_frame),
        "frames_in_model": len(model.frames),
        "effort_evaluations": dict(effort_calls),
        "events": len(traj.events),
        "jacobian": jacobian,
    }


def imports() -> dict:
    """Modules loaded by ``import contactdiff`` in a fresh interpreter, and its time (s)."""
    code = (
        "import sys, time; t = time.perf_counter(); import contactdiff; "
        "print(time.perf_counter() - t); "
        f"print(','.join(m for m in {PLOTTING_MODULES!r} if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split("\n")
    loaded = set(filter(None, out[1].split(",")))
    return {"import_time": float(out[0]), "plotting_modules_loaded": {m: m in loaded for m in PLOTTING_MODULES}}


def measure_footprint(quick: bool = True) -> Footprint:
    """All four measurements (``quick``: fewer load repeats, shorter runs)."""
    runs = []
    for name, t_final in (("planar_trot_soft", 1.8), ("solo12_drop", 0.3 if quick else 1.0)):
        scene = load_scene(name)
        for method in ("auto", "DOP853"):
            for jac in (False, True):
                runs.append(derivative_work(scene, t_final, method=method, jacobian=jac))
    return Footprint(
        derivatives={"runs": runs},
        loading=loading(repeats=3 if quick else 7),
        frames=frame_queries(),
        imports=imports(),
    )


__all__ = [
    "Footprint",
    "measure_footprint",
    "derivative_work",
    "loading",
    "frame_queries",
    "imports",
    "two_feet_scene",
    "counting",
    "counting_derivative_work",
    "DERIVATIVE_FUNCTIONS",
]
