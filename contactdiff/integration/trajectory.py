"""The result of a simulation: segments of smooth flow, events between them, final state.

A `Trajectory` keeps the dense output of every accepted step, so the state can
be evaluated anywhere (`Trajectory.at`, `Trajectory.sample`), and exports to
``.npz`` and JSON. Times are in seconds, states as in the rest of the package
(``q`` of size nq, ``v`` of size nv in the tangent space). Its events, segments,
termination and counters are the records of `contactdiff.integration.run_records`
(re-exported here).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import ContactDiffError, InvalidInputError
from ..model.parameters import parameter_table
from .run_records import EVENT_KINDS, Event, EventKind, NonSmooth, RunStats, Segment, Termination
from .samples import Samples

if TYPE_CHECKING:
    from ..model.scene import Scene


@dataclass(kw_only=True)
class Trajectory:
    """A hybrid trajectory.

    Attributes:
        scene_name: the scene simulated.
        t0, q0, v0: initial time and state.
        t, q, v: final time and state.
        events: the `Event` list in time order.
        segments: the `Segment` list (one per mode visited, in order).
        stats: the run's counters (`RunStats`).
        max_drift: largest constraint violation of an active contact found before
            projection, over the run (m).
        termination: why the run ended (a `Termination`; ``"t_final"`` normally).
        notes: human-readable remarks (Zeno ends, grazing, ...).
        final_nonsmooth: `NonSmooth.FINAL_TIME` with its remark where a contact touches
            at the final time itself, which no event records (empty otherwise).
        jacobian: ``d x(t) / d x0`` (2nv × 2nv, tangent space) if it was asked for.
        parameter_jacobian: ``d x(t) / d p`` (2nv × p, tangent space, per unit of each
            parameter) if parameters were asked for (``simulate(..., parameters=[...])``).
        parameter_names: the names of those parameters, in column order.
        dense: whether the run kept its dense output (``simulate(..., dense=True)``),
            which `at`, `sample` and `save_npz` need.
        samples: the state (and flow Jacobian) at ``simulate(..., sample_times=...)``,
            a `Samples`; None without sample times.
    """

    scene_name: str
    t0: float
    q0: np.ndarray
    v0: np.ndarray
    t: float
    q: np.ndarray
    v: np.ndarray
    events: list[Event]
    segments: list[Segment]
    stats: RunStats
    max_drift: float = 0.0
    termination: Termination = Termination.T_FINAL
    notes: list[str] = field(default_factory=list)
    final_nonsmooth: dict[NonSmooth, str] = field(default_factory=dict)
    jacobian: np.ndarray | None = None
    dense: bool = True
    parameter_jacobian: np.ndarray | None = None
    parameter_names: tuple[str, ...] = ()
    samples: Samples | None = None

    @property
    def differentiable(self) -> bool:
        """True unless some event has only a piecewise-linear derivative, or a contact
        touches at the final time (``final_nonsmooth``)."""
        return not self.final_nonsmooth and all(e.differentiable for e in self.events)

    @property
    def modes(self) -> list[tuple[str, ...]]:
        """Contact mode sequence: active contact names of each segment."""
        return [s.mode for s in self.segments]

    def at(self, t: float, side: str = "right") -> tuple[np.ndarray, np.ndarray]:
        """State ``(q, v)`` at time ``t`` from the dense output.

        Args:
            t: time in [t0, t] (s).
            side: at an event time, ``"right"`` gives the state after the jump,
                ``"left"`` the state before.
        """
        if not self.dense:
            raise InvalidInputError(
                "this run kept no dense output, so its states between events are "
                "gone: simulate(..., dense=True) keeps them (or read traj.events)"
            )
        if side not in ("left", "right"):
            raise InvalidInputError(f"side must be 'left' or 'right', got {side!r}")
        if not (self.t0 <= t <= self.t):
            raise InvalidInputError(f"t must lie in [{self.t0}, {self.t}], got {t!r}")
        candidates = [s for s in self.segments if s.t0 <= t <= s.t1 and s.pieces]
        if not candidates:
            return self.q.copy(), self.v.copy()
        segment = candidates[0] if side == "left" else candidates[-1]
        return segment.at(t)

    def sample(self, times) -> tuple[np.ndarray, np.ndarray]:
        """States at the given times (right limits at events): arrays (n, nq) and (n, nv)."""
        times = np.asarray(times, dtype=float).reshape(-1)
        states = [self.at(float(t)) for t in times]
        return np.array([s[0] for s in states]), np.array([s[1] for s in states])

    def why_not_differentiable(self) -> list[str]:
        """The remarks of the events where the flow is not differentiable, in time order,
        then ``final_nonsmooth``'s."""
        return [remark for e in self.events for remark in e.nonsmooth.values()] + list(self.final_nonsmooth.values())

    def summary(self) -> dict:
        """Final state, events and statistics (what ``--json`` prints, without dense data)."""
        return (
            {
                "scene": self.scene_name,
                "t0": self.t0,
                "t": self.t,
                "q0": self.q0.tolist(),
                "v0": self.v0.tolist(),
                "q": self.q.tolist(),
                "v": self.v.tolist(),
                "events": [e.to_dict() for e in self.events],
                "modes": [list(m) for m in self.modes],
                "stats": self.stats.to_dict(),
                "max_drift": self.max_drift,
                "termination": str(self.termination),
                "notes": list(self.notes),
                "differentiable": self.differentiable,
                "final_nonsmooth": {reason.name.lower(): remark for reason, remark in self.final_nonsmooth.items()},
            }
            | ({"jacobian": self.jacobian.tolist()} if self.jacobian is not None else {})
            | (
                {"parameter_names": list(self.parameter_names), "parameter_jacobian": self.parameter_jacobian.tolist()}
                if self.parameter_jacobian is not None
                else {}
            )
        )

    def format(self, scene: Scene) -> str:
        """The run as text (what ``contactdiff simulate`` prints without ``--json``): the
        events (the first 200), the final state by coordinate name, the counters and
        notes, and the flow and parameter Jacobians' summaries when they were asked for.

        Args:
            scene: the `Scene` simulated (its robot names the coordinates; its parameters'
                values head the parameter Jacobian's rows).
        """
        lines = [
            f"simulation of {self.scene_name} from t = {self.t0:g} to {self.t:g} s",
            f"{len(self.events)} events",
            "",
        ]
        if self.events:
            lines.append(f"  {'t (s)':>18}  {'kind':<9}  {'contacts':<28}  {'simult.':<7}  mode after")
            for e in self.events[:200]:
                lines.append(
                    f"  {e.t:18.12f}  {e.kind:<9}  {', '.join(e.contacts):<28}  "
                    f"{'yes' if e.simultaneous else 'no':<7}  {', '.join(e.mode_after) or '(flight)'}"
                )
            if len(self.events) > 200:
                lines.append(f"  ... {len(self.events) - 200} more (see --json)")
            lines.append("")
        lines.append("final state")
        names = scene.robot.tangent_names()
        for label, x in zip(scene.robot.configuration_names(), self.q):
            lines.append(f"  q {label:<24} {x: .12g}")
        for label, x in zip(names, self.v):
            lines.append(f"  v {label:<24} {x: .12g}")
        lines.append("")
        s = self.stats
        lines.append(
            f"steps {s.steps} (rejected {s.rejected_steps}), dynamics evaluations "
            f"{s.dynamics_evaluations}, largest active-gap drift {self.max_drift:.2e} m"
        )
        if s.steps_by_method:
            lines.append(f"method {s.method}: " + ", ".join(f"{m} {n} steps" for m, n in s.steps_by_method.items()))
        lines += [f"note: {n}" for n in self.notes]
        labels = [f"dq[{n}]" for n in names] + [f"dv[{n}]" for n in names]
        if self.jacobian is not None:
            lines += [""] + self._jacobian_lines(self.jacobian, labels)
        if self.parameter_jacobian is not None:
            lines += [""] + self._parameter_jacobian_lines(self.parameter_jacobian, scene, labels)
        return "\n".join(lines)

    def _parameter_jacobian_lines(self, P: np.ndarray, scene: Scene, labels: list[str]) -> list[str]:
        """Per parameter: its value, the largest entry of its column and where."""
        values = {row["name"]: row["value"] for row in parameter_table(scene)}  # None: a group whose members differ
        lines = [
            f"parameter Jacobian d x({self.t:g}) / d p: {P.shape[0]} x {P.shape[1]}, tangent space, "
            "per unit of each parameter",
            f"  {'parameter':<40} {'value':>12}  {'largest entry':>14}  of",
        ]
        for k, name in enumerate(self.parameter_names):
            i = int(np.argmax(np.abs(P[:, k])))
            value = values[name]
            shown = f"{'(differ)':>12}" if value is None else f"{value:12.6g}"
            lines.append(f"  {name:<40} {shown}  {P[i, k]:14.6g}  {labels[i]}")
        return lines

    def _jacobian_lines(self, J: np.ndarray, labels: list[str]) -> list[str]:
        """Its norm and condition number, its largest entries, each event's verdict."""
        sv = np.linalg.svd(J, compute_uv=False)
        lines = [
            f"flow Jacobian d x({self.t:g}) / d x({self.t0:g}): {J.shape[0]} x {J.shape[1]}, tangent space",
            f"  2-norm {sv[0]:.6g}, condition number {sv[0] / sv[-1] if sv[-1] > 0 else float('inf'):.6g}",
            "  largest entries:",
        ]
        order = np.argsort(-np.abs(J), axis=None)[:6]
        for flat in order:
            i, j = divmod(int(flat), J.shape[1])
            lines.append(f"    d {labels[i]:<28} / d {labels[j]:<28} = {J[i, j]: .6g}")
        lines.append("  events:")
        for e in self.events:
            verdict = "differentiable" if e.differentiable else "NOT differentiable (piecewise-linear derivative)"
            lines.append(f"    t = {e.t:.12f}  {e.kind:<9} {', '.join(e.contacts):<24} {verdict}")
        verdict = (
            "differentiable"
            if self.differentiable
            else "NOT differentiable at some event (see notes)"
            if not self.final_nonsmooth
            else "NOT differentiable: a contact touches at the final time (see notes)"
        )
        lines.append(f"  the trajectory is {verdict}")
        return lines

    def save_json(self, path: str | Path) -> None:
        """Write `summary` as JSON."""
        Path(path).write_text(json.dumps(self.summary(), indent=2))

    def save_npz(self, path: str | Path, n_samples: int = 1000) -> None:
        """Write final state, events and ``n_samples`` states on a uniform time grid."""
        times = np.linspace(self.t0, self.t, int(n_samples))
        qs, vs = self.sample(times)
        np.savez(
            path,
            t=times,
            q=qs,
            v=vs,
            t_final=self.t,
            q_final=self.q,
            v_final=self.v,
            event_t=np.array([e.t for e in self.events]),
            event_kind=np.array([e.kind for e in self.events], dtype=str),
            event_contacts=np.array(["+".join(e.contacts) for e in self.events], dtype=str),
        )

    def to_html(self, path: str | Path, scene: Scene | None = None, **options: Any) -> Path:
        """Write a self-contained HTML page that replays this run in 3-D in a browser,
        with no network: the robot, its closed contacts and a timeline of the events
        (`contactdiff.replay`; needs meshcat, ``pip install 'contactdiff[viz]'``).

        Args:
            path: the ``.html`` file to write.
            scene: the `Scene` simulated; default the scene named ``scene_name``
                (a scene or robot name, or a file path).
            **options: ``fps`` (frames per second of simulated time, default
                `contactdiff.replay_frames.DEFAULT_FPS`; every event time is a frame too),
                ``contact_radius`` (m), ``title``, ``package_dirs`` (folders in which the URDF's
                ``package://`` meshes are found; see `contactdiff.replay.replay_html`).

        Returns:
            The path written.

        Raises:
            MissingExtraError: meshcat is not installed.
            InvalidInputError: the run kept no dense output (``simulate(..., dense=True)``),
                a bad option, or a scene that does not match the run.
        """
        from ..replay import write_html

        if scene is None:
            from ..scenes.scene_file import load_source

            try:
                scene = load_source(self.scene_name)
            except ContactDiffError as exc:
                raise InvalidInputError(
                    f"to_html: scene {self.scene_name!r} cannot be loaded by name ({exc}); "
                    "pass the scene: traj.to_html(path, scene)"
                ) from None
        return write_html(self, scene, path, **options)


__all__ = [
    "EVENT_KINDS",
    "Event",
    "EventKind",
    "NonSmooth",
    "RunStats",
    "Segment",
    "Termination",
    "Trajectory",
]
