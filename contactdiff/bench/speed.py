"""The loop's speed: quadruped trots against real time and against Pinocchio's own calls.

`run_speed` times ``simulate(scene, t_final)`` on the trots (median of
``repeats`` runs, in this process) and prints, each measured in the same run:

* **real time**: wall time over simulated time (1 or less: faster than the robot);
* **steps**: rejected over accepted steps (a healthy DOP853 run rejects a few
  per cent; a schedule whose kinks are stepped across rejects about as many as
  it accepts, see `contactdiff.model.efforts` on breakpoints);
* **loop overhead**: wall time per dynamics evaluation inside ``simulate``
  (everything the run does, divided by its evaluations) over Pinocchio's own
  call for the mode evaluated: ``pinocchio.constraintDynamics`` with the mode's
  contacts (3-D, as the trot's sticking feet are), ``pinocchio.aba`` in flight,
  each timed from Python at the run's final state (median of many calls) and
  averaged over the run's modes weighted by the time spent in each;
* optionally **memory**: the peak resident memory of a child process that runs
  a long trot keeping its events only (``dense=False``), against the same
  process's memory before the run.
"""

from __future__ import annotations

import json
import statistics
import subprocess
import sys
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass

import numpy as np
import pinocchio as pin

from ..dynamics.constraint_dynamics import RigidContactMode
from ..errors import InvalidInputError, check_count, check_number
from ..integration.hybrid import simulate
from ..scenes.scene_file import load_scene

TROTS = ("solo12_trot", "anymal_trot")
CALLS = 2000  # Pinocchio calls per timing of its own cost


@dataclass
class TrotSpeed:
    """One trot's timing (s), counts, and ratios (see the module doc)."""

    scene: str
    t_final: float
    wall: float
    events: int
    steps: int
    rejected_steps: int
    evaluations: int
    per_evaluation: float
    pinocchio: float
    constraint_dynamics: float
    aba: float

    @property
    def real_time_ratio(self) -> float:
        """Wall time over simulated time."""
        return self.wall / self.t_final

    @property
    def rejected_ratio(self) -> float:
        """Rejected over accepted steps."""
        return self.rejected_steps / max(self.steps, 1)

    @property
    def overhead_ratio(self) -> float:
        """Wall time per evaluation over Pinocchio's own call for the modes evaluated."""
        return self.per_evaluation / self.pinocchio

    def to_dict(self) -> dict:
        """The fields and the three ratios (what ``--json`` prints)."""
        return asdict(self) | {
            "real_time_ratio": self.real_time_ratio,
            "rejected_ratio": self.rejected_ratio,
            "overhead_ratio": self.overhead_ratio,
        }


@dataclass
class MemoryPeak:
    """Peak resident memory (MB) of a child process running a trot with events only, and
    its resident memory after loading the scene, before the run."""

    scene: str
    t_final: float
    before_mb: float
    peak_mb: float
    wall: float
    events: int

    def to_dict(self) -> dict:
        """The fields (what ``--json`` prints)."""
        return asdict(self)


@dataclass
class SpeedReport:
    """The rows of `run_speed`."""

    trots: list[TrotSpeed]
    memory: MemoryPeak | None = None

    def to_dict(self) -> dict:
        """The rows (what ``--json`` prints)."""
        return {
            "trots": [t.to_dict() for t in self.trots],
            "memory": None if self.memory is None else self.memory.to_dict(),
        }

    def format(self) -> str:
        """The rows as a table, with a line on what each column means."""
        lines = [
            "scene          sim s  wall s  wall/sim  events  steps  rejected  evals   us/eval  "
            "pin us  us/eval / pin  (cD all feet us, aba us)"
        ]
        for r in self.trots:
            lines.append(
                f"{r.scene:<14} {r.t_final:5.2f}  {r.wall:6.2f}  {r.real_time_ratio:8.2f}  "
                f"{r.events:6d}  {r.steps:5d}  {r.rejected_ratio:7.1%}  {r.evaluations:6d}  "
                f"{1e6 * r.per_evaluation:7.1f}  {1e6 * r.pinocchio:6.1f}  {r.overhead_ratio:13.2f}  "
                f"({1e6 * r.constraint_dynamics:.1f}, {1e6 * r.aba:.1f})"
            )
        lines.append(
            "wall/sim <= 1: faster than real time; rejected: over accepted steps; pin: Pinocchio's own "
            "call for the modes evaluated (constraintDynamics with the mode's feet, aba in flight), "
            "weighted by the time in each, timed in this process"
        )
        if self.memory is not None:
            m = self.memory
            lines.append(
                f"memory: {m.scene} for {m.t_final:g} s with events only (dense=False): peak "
                f"{m.peak_mb:.0f} MB, {m.before_mb:.0f} MB before the run ({m.events} events, "
                f"{m.wall:.1f} s wall)"
            )
        return "\n".join(lines)


def _median_call(fn, calls: int) -> float:
    """Median over 5 batches of the time of one call (s)."""
    times = []
    for _ in range(5):
        start = time.perf_counter()
        for _ in range(calls):
            fn()
        times.append((time.perf_counter() - start) / calls)
    return statistics.median(times)


class _PinocchioCosts:
    """Pinocchio's own call for a mode, by the names of its contacts, at one state:
    ``constraintDynamics`` with their 3-D constraints (those the integrator's sticking
    feet use, `RigidContactMode`), ``aba`` with none; each a median single call from
    Python (s), measured once per mode."""

    def __init__(self, scene, q, v):
        self.scene, self.q, self.v = scene, q, v
        self._by_name = {c.name: c for c in scene.contacts}
        self._cost: dict[tuple[str, ...], float] = {}

    def __call__(self, mode: tuple[str, ...]) -> float:
        if mode not in self._cost:
            model, q, v = self.scene.model, self.q, self.v
            tau = np.zeros(model.nv)
            if mode:
                m = RigidContactMode(model, [self._by_name[n] for n in mode])
                settings = pin.ProximalSettings(1e-12, 0.0, 1)  # exact: one factorisation

                def call():
                    return pin.constraintDynamics(model, m.data, q, v, tau, m.models, m.datas, settings)
            else:
                data = model.createData()

                def call():
                    return pin.aba(model, data, q, v, tau)

            self._cost[mode] = _median_call(call, CALLS)
        return self._cost[mode]

    def weighted(self, traj) -> float:
        """The cost of the run's modes, weighted by the time spent in each (s)."""
        time_in: dict[tuple[str, ...], float] = {}
        for seg in traj.segments:
            time_in[seg.mode] = time_in.get(seg.mode, 0.0) + (seg.t1 - seg.t0)
        return sum(share * self(mode) for mode, share in time_in.items()) / sum(time_in.values())


def trot_speed(name: str, t_final: float = 3.0, repeats: int = 3) -> TrotSpeed:
    """Time ``simulate(load_scene(name), t_final)`` (median of ``repeats``) and
    Pinocchio's own calls at the state the run ends in."""
    scene = load_scene(name)
    walls, traj = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        traj = simulate(scene, t_final)
        walls.append(time.perf_counter() - start)
    wall = statistics.median(walls)
    assert traj is not None  # repeats >= 1
    s = traj.stats
    costs = _PinocchioCosts(scene, traj.q, traj.v)
    return TrotSpeed(
        scene=name,
        t_final=t_final,
        wall=wall,
        events=len(traj.events),
        steps=s.steps,
        rejected_steps=s.rejected_steps,
        evaluations=s.dynamics_evaluations,
        per_evaluation=wall / s.dynamics_evaluations,
        pinocchio=costs.weighted(traj),
        constraint_dynamics=costs(tuple(scene.contact_names)),
        aba=costs(()),
    )


_CHILD = """
import json, resource, sys, time
import contactdiff as cd
scene = cd.load_scene(sys.argv[1])
try:  # resident memory now (Linux); elsewhere the peak so far
    before = next(int(line.split()[1]) for line in open("/proc/self/status") if line.startswith("VmRSS:"))
except (OSError, StopIteration):
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
start = time.perf_counter()
traj = cd.simulate(scene, float(sys.argv[2]), dense=False)
wall = time.perf_counter() - start
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(json.dumps(dict(before=before / 1024, peak=peak / 1024, wall=wall, events=len(traj.events))))
"""


def memory_peak(name: str = "solo12_trot", t_final: float = 60.0) -> MemoryPeak:
    """Peak resident memory of a fresh process that loads ``name`` and simulates it for
    ``t_final`` s keeping events only (Linux reports ``ru_maxrss`` in kB)."""
    out = subprocess.run(
        [sys.executable, "-c", _CHILD, name, repr(float(t_final))], capture_output=True, text=True, check=True
    )
    row = json.loads(out.stdout.strip().splitlines()[-1])
    return MemoryPeak(
        scene=name,
        t_final=t_final,
        before_mb=row["before"],
        peak_mb=row["peak"],
        wall=row["wall"],
        events=row["events"],
    )


def run_speed(
    scenes: Sequence[str] | None = None, t_final: float = 3.0, repeats: int = 3, memory_seconds: float | None = None
) -> SpeedReport:
    """The speed report (module doc).

    Args:
        scenes: trot scenes (names of the project's ``robots/``), default `TROTS`.
        t_final: simulated time of each timed run (s), > 0.
        repeats: timed runs per scene (median kept), >= 1.
        memory_seconds: if given, also the peak memory of a solo12 trot this long (s)
            keeping events only, in a child process.
    """
    t_final = check_number("bench --speed", "t_final", t_final)
    if t_final <= 0:
        raise InvalidInputError(f"bench --speed: t_final must be > 0 s, got {t_final!r}")
    repeats = check_count("bench --speed", "repeats", repeats, minimum=1)
    rows = [trot_speed(name, t_final, repeats) for name in (scenes or TROTS)]
    memory = None
    if memory_seconds is not None:
        memory = memory_peak(
            "solo12_trot", check_number("bench --speed", "memory_seconds", memory_seconds, minimum=1e-3)
        )
    return SpeedReport(rows, memory)
