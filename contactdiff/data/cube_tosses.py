"""Measured tosses of a real cube, and the cube scene that starts from one.

450 tosses of an acrylic cube (edge 0.1048 m, 0.37 kg) thrown onto a board and
tracked by motion capture at 148 Hz, recorded by the Dynamic Autonomy and
Intelligent Robotics Lab (University of Pennsylvania) for ContactNets (Pfrommer,
Halm, Posa, CoRL 2020) and the simulator study of Acosta, Yang and Posa (RA-L
2022), under the BSD 3-Clause license (``LICENSE_cube_tosses`` beside this file,
which every copy keeps). The package ships 24 of them (`SUBSET`, every 19th
toss, 240 kB); `load_tosses` reads the full set from a path.

A tosses file is a ``.npz`` of arrays ``toss_NNN``, each ``(n, 14)``, one row per
sample: t (s, from the first sample), the centre's x, y, z (m, board frame, z up),
the orientation quaternion qw, qx, qy, qz (cube to board), the centre's linear
velocity (m/s, board frame) and the angular velocity (rad/s, the cube's own
frame). The velocities are backward differences of the poses, median-filtered:
they lag half a sample, so the poses are the measurements.

`cube_scene` is the cube as an object with a Coulomb contact at each of its eight
corners (``cube/±x±y±z``), on a board at height ``ground`` (the contacts'
offset), the eight in group ``cube`` (one μ, e and offset: the parameters
``group:cube:friction``, ``group:cube:restitution``, ``group:cube:offset``);
`Toss.state` gives a sample as the scene's ``(q, v)`` (Pinocchio's free-flyer:
``q = [x y z qx qy qz qw]``, ``v`` linear then angular velocity, both in the
cube's frame).
"""

from __future__ import annotations

import functools
import itertools
import time
from collections import Counter
from dataclasses import dataclass, replace
from importlib import resources
from pathlib import Path

import numpy as np
import pinocchio as pin

from ..errors import InvalidInputError, check_number
from ..integration.hybrid import simulate
from ..integration.trajectory import EVENT_KINDS, NonSmooth
from ..model.contacts import Contact
from ..model.objects import SceneObject, add_objects, empty_robot
from ..model.scene import Scene

SUBSET = "cube_tosses_subset.npz"
"""The tosses shipped with the package (file name in ``contactdiff.data``)."""

COLUMNS = 14
"""Columns of a toss: t, x, y, z, qw, qx, qy, qz, vx, vy, vz, wx, wy, wz."""


@dataclass(frozen=True)
class CubeParameters:
    """The cube's model (SI units).

    Attributes:
        edge: edge length (m).
        mass: kg.
        moment: moment of inertia about each axis through the centre (kg m²); the
            measured cube's 8.1e-4 is above a uniform solid's m edge² / 6 = 6.77e-4.
        friction: Coulomb coefficient of every corner on the board.
        restitution: Newton's coefficient of every corner.
        ground: height of the board's surface (m, board frame): the contacts' offset.
        gravity: m/s², along -z.
    """

    edge: float = 0.1048
    mass: float = 0.37
    moment: float = 8.1e-4
    friction: float = 0.18
    restitution: float = 0.125
    ground: float = 0.0
    gravity: float = 9.81


NOMINAL = CubeParameters()
"""The parameters the data's authors give: a tilt test's μ 0.18, restitution 0.125."""


def cube_scene(parameters: CubeParameters = NOMINAL, **changes) -> Scene:
    """The cube on the board, resting on a face at the origin (`Toss.state` gives a toss's
    start); ``changes`` replace fields of ``parameters`` (``cube_scene(friction=0.3)``).

    Returns:
        A `contactdiff.Scene` whose object is named ``cube``.
    """
    p = replace(parameters, **changes) if changes else parameters
    for name in ("edge", "mass", "moment", "gravity"):
        if not check_number("cube_scene", name, getattr(p, name)) > 0.0:
            raise InvalidInputError(f"cube_scene: {name} must be > 0, got {getattr(p, name)!r}")
    cube = SceneObject(
        "cube",
        shape="box",
        size=(p.edge,) * 3,
        mass=p.mass,
        moments=p.moment,
        position=(0.0, 0.0, p.ground + p.edge / 2),
    )
    corners = [
        "cube/" + "".join(s + axis for s, axis in zip(signs, "xyz")) for signs in itertools.product("+-", repeat=3)
    ]
    contacts = [
        Contact(name, friction=p.friction, restitution=p.restitution, offset=p.ground, group="cube") for name in corners
    ]
    return Scene(add_objects(empty_robot(), [cube]), contacts, gravity=(0.0, 0.0, -p.gravity), name="cube")


@dataclass(frozen=True, eq=False)  # arrays: no element-wise ==
class Toss:
    """One measured toss (module doc for the columns).

    Attributes:
        name: its array's name (``toss_NNN``, the upstream number).
        t: sample times (n,), s from the first sample.
        position: the centre (n, 3), m, board frame.
        quaternion: orientation (n, 4) as ``[qw qx qy qz]``, cube to board.
        velocity: the centre's velocity (n, 3), m/s, board frame.
        omega: angular velocity (n, 3), rad/s, cube frame.
    """

    name: str
    t: np.ndarray
    position: np.ndarray
    quaternion: np.ndarray
    velocity: np.ndarray
    omega: np.ndarray

    @classmethod
    def from_array(cls, name: str, array, where: str = "") -> Toss:
        """A toss from its ``(n, 14)`` array; ``where`` names the file in errors.

        Raises:
            InvalidInputError: not ``(n, 14)`` numbers, fewer than two samples,
                non-finite values, times not increasing, or a quaternion of zero norm.
        """
        label = f"{where}: {name}" if where else name
        a = np.asarray(array)
        if a.ndim != 2 or a.shape[1] != COLUMNS or not np.issubdtype(a.dtype, np.number):
            raise InvalidInputError(f"{label}: a toss is an (n, {COLUMNS}) array of numbers, got shape {a.shape}")
        a = a.astype(float)
        if len(a) < 2:
            raise InvalidInputError(f"{label}: a toss needs at least two samples, got {len(a)}")
        bad = np.argwhere(~np.isfinite(a))
        if len(bad):
            row, col = bad[0]
            raise InvalidInputError(f"{label}: sample {row} column {col} is {a[row, col]} (not finite)")
        steps = np.diff(a[:, 0])
        if np.any(steps <= 0.0):
            k = int(np.argmax(steps <= 0.0))
            raise InvalidInputError(
                f"{label}: times must increase; sample {k + 1} at {a[k + 1, 0]} s follows {a[k, 0]} s"
            )
        norms = np.linalg.norm(a[:, 4:8], axis=1)
        if np.any(norms < 1e-9):
            raise InvalidInputError(f"{label}: sample {int(np.argmin(norms))} has a quaternion of zero norm")
        return cls(name, a[:, 0], a[:, 1:4], a[:, 4:8] / norms[:, None], a[:, 8:11], a[:, 11:14])

    def __len__(self) -> int:
        return len(self.t)

    def configurations(self) -> np.ndarray:
        """The measured poses as the cube scene's ``q`` (n, 7): ``[x y z qx qy qz qw]``."""
        return np.hstack([self.position, self.quaternion[:, 1:], self.quaternion[:, :1]])

    def state(self, k: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """Sample ``k`` as the cube scene's ``(q, v)``: the linear velocity turned into the
        cube's frame (Pinocchio's free-flyer), the angular one as measured."""
        if not -len(self) <= k < len(self):
            raise InvalidInputError(f"{self.name}: sample {k!r} out of range (it has {len(self)})")
        q = self.configurations()[k]
        rotation = pin.Quaternion(q[3:7]).matrix()
        return q, np.r_[rotation.T @ self.velocity[k], self.omega[k]]


def load_tosses(path: str | Path | None = None) -> dict[str, Toss]:
    """The tosses of a ``.npz`` file (module doc), by name in file order; ``None``
    reads the shipped subset.

    Raises:
        InvalidInputError: a missing or unreadable file, one without ``toss_*``
            arrays, or a bad toss (`Toss.from_array`), each naming the file.
    """
    if path is None:
        source = resources.files(__package__).joinpath(SUBSET)
        label = f"the shipped subset ({SUBSET})"
    else:
        source = Path(path)
        label = str(path)
        if not source.is_file():
            raise InvalidInputError(f"tosses file {label!r} does not exist or is not a file")
    try:
        with source.open("rb") as handle, np.load(handle, allow_pickle=False) as archive:
            arrays = {name: archive[name] for name in archive.files}
    except (OSError, ValueError) as exc:
        raise InvalidInputError(f"{label}: not a readable .npz file of tosses ({exc})") from None
    names = [n for n in arrays if n.startswith("toss_")]
    if not names:
        raise InvalidInputError(f"{label}: no arrays named toss_* (found {', '.join(arrays) or 'none'})")
    return {name: Toss.from_array(name, arrays[name], label) for name in names}


@functools.lru_cache(maxsize=4)
def _tosses(path: str | None) -> dict[str, Toss]:
    """`load_tosses`, read once per process (a sweep's worker runs many tosses)."""
    return load_tosses(path)


def run_toss(scene: Scene, point: dict) -> dict:
    """A sweep's job (``contactdiff.data.cube_tosses:run_toss``): the cube ``scene`` run
    from a toss's first sample to its last.

    The point names the toss (``job:toss``) and, optionally, the tosses file
    (``job:tosses``; default the shipped subset) and ``job:sample`` to start from.

    Returns:
        The row's outputs: ``t_end`` and ``t_data`` (s), ``events`` and
        ``events:KIND`` counts, ``not_differentiable`` (events flagged) and
        ``nonsmooth:REASON`` counts (`NonSmooth` names), ``wall`` (s, the run alone),
        ``position_error`` (m, final centre against the last sample).
    """
    toss = _tosses(point.get("job:tosses"))[point["job:toss"]]
    start = int(point.get("job:sample", 0))
    q0, v0 = toss.state(start)
    started = time.perf_counter()
    traj = simulate(scene.with_state(q0, v0), float(toss.t[-1]), t0=float(toss.t[start]))
    wall = time.perf_counter() - started
    kinds = Counter(e.kind for e in traj.events)
    reasons = Counter(reason.name for e in traj.events for reason in e.nonsmooth)
    out = {"t_end": traj.t, "t_data": float(toss.t[-1]), "events": len(traj.events)}
    out |= {f"events:{kind}": kinds.get(kind, 0) for kind in EVENT_KINDS}
    out |= {"not_differentiable": sum(not e.differentiable for e in traj.events)}
    out |= {f"nonsmooth:{reason.name}": reasons.get(reason.name, 0) for reason in NonSmooth}
    out |= {"wall": wall, "position_error": float(np.linalg.norm(traj.q[:3] - toss.position[-1]))}
    return out


__all__ = ["CubeParameters", "NOMINAL", "Toss", "cube_scene", "load_tosses", "run_toss", "SUBSET"]
