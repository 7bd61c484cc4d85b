"""Measured trajectories of a scene: sample times, configurations, optionally velocities
and per-sample weights (`Observations`), and the columns that name them.

A measurement is a table with one row per sample and one column per measured
coordinate (docs/observations.md gives the format; `contactdiff.fit.observation_files`
reads and writes it as CSV or ``.npz``). The columns of a scene, for each joint ``J``
(its Pinocchio joint name):

* a free body (free-flyer joint): ``J:x J:y J:z`` the position of the joint frame's origin
  (m, in the world frame), ``J:qw J:qx J:qy J:qz`` the unit quaternion (Hamilton, scalar
  first) of the rotation from the body's frame to the world frame; velocities, optional,
  ``J:vx J:vy J:vz`` of that origin (m/s, world frame) and ``J:wx J:wy J:wz`` the angular
  velocity (rad/s, body frame), as motion capture gives them;
* a ball joint (spherical): ``J:qw J:qx J:qy J:qz`` (child to parent), ``J:wx J:wy J:wz``
  (rad/s, child frame);
* a 1-dof joint (revolute, prismatic, or an unbounded revolute): ``J`` (rad or m),
  ``J:v`` (rad/s or m/s);

and ``t`` (s, required, strictly increasing) and ``weight`` (optional, >= 0, default 1).
A joint is measured or not as a whole: all its configuration columns or none
(velocity columns need the configuration's); joints without columns are unmeasured
(`Observations.mask`) and hold the scene's initial configuration.

Quaternions: each is divided by its norm. A norm within `QUATERNION_TOLERANCE` of 1
(rounding in a file, a tracker's drift) is normalised silently; a norm farther from 1
is refused with its row (a column swapped, a scale applied: the data are not what the
names say), and so is a norm below `ZERO_NORM`.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum
from pathlib import Path

import numpy as np

from ..errors import InvalidInputError, ObservationFileError
from .column_files import write_columns

QUATERNION_TOLERANCE = 0.1
"""A quaternion whose norm differs from 1 by at most this is normalised; farther, refused."""
ZERO_NORM = 1e-9
"""A quaternion with a norm below this has no direction: refused."""
TIME = "t"
WEIGHT = "weight"


class JointKind(Enum):
    """How a joint's configuration is written in an observation file."""

    FREE = "free body: position and quaternion"
    SPHERICAL = "ball joint: quaternion"
    SCALAR = "1-dof joint: its coordinate"
    ANGLE = "unbounded revolute joint: its angle (the scene holds cos, sin)"


@dataclass(frozen=True)
class JointColumns:
    """The columns of one joint of a scene (module doc).

    Attributes:
        name: the joint's name; kind: its `JointKind`.
        idx_q, idx_v: its first index in the scene's ``q`` (nq) and ``v`` (nv).
        configuration, velocity: its column names, in the order of the module doc.
    """

    name: str
    kind: JointKind
    idx_q: int
    idx_v: int
    configuration: tuple[str, ...]
    velocity: tuple[str, ...]

    @property
    def nv(self) -> int:
        """The joint's velocity coordinates."""
        return {JointKind.FREE: 6, JointKind.SPHERICAL: 3}.get(self.kind, 1)


def joint_columns(scene) -> list[JointColumns]:
    """The observable joints of ``scene`` with their column names; joints of other kinds
    (planar, translation, composite) have no columns."""
    model = scene.model
    out = []
    for j in range(1, model.njoints):
        joint, name = model.joints[j], model.names[j]
        short = joint.shortname()
        if joint.nq == 7 and joint.nv == 6 and "FreeFlyer" in short:
            kind = JointKind.FREE
            config = tuple(f"{name}:{c}" for c in ("x", "y", "z", "qw", "qx", "qy", "qz"))
            velocity = tuple(f"{name}:{c}" for c in ("vx", "vy", "vz", "wx", "wy", "wz"))
        elif joint.nq == 4 and joint.nv == 3 and "Spherical" in short:
            kind = JointKind.SPHERICAL
            config = tuple(f"{name}:{c}" for c in ("qw", "qx", "qy", "qz"))
            velocity = tuple(f"{name}:{c}" for c in ("wx", "wy", "wz"))
        elif joint.nv == 1 and joint.nq in (1, 2):
            kind = JointKind.SCALAR if joint.nq == 1 else JointKind.ANGLE
            config, velocity = (name,), (f"{name}:v",)
        else:
            continue
        out.append(JointColumns(name, kind, joint.idx_q, joint.idx_v, config, velocity))
    return out


def valid_columns(scene) -> list[str]:
    """Every column name an observation file of ``scene`` may hold, in the module doc's order."""
    names = [TIME, WEIGHT]
    for joint in joint_columns(scene):
        names += [*joint.configuration, *joint.velocity]
    return names


@dataclass(kw_only=True, eq=False)  # arrays: no element-wise ==
class Observations:
    """A measured trajectory of a scene (module doc for the file's columns).

    Attributes:
        t: sample times (k,), s, strictly increasing, k >= 2.
        q: configurations (k, nq) in the scene's convention (Pinocchio's: a free body's
            ``[x y z qx qy qz qw]``), quaternions of unit norm; unmeasured joints hold the
            scene's initial configuration.
        mask: (nv,) bool, the tangent coordinates of ``q`` that were measured (a free
            body's 6: position then rotation).
        weights: (k,) >= 0, each sample's weight (1 where the file has none).
        v: velocities (k, nv) in the scene's convention (a free body's linear velocity in
            its own frame, as Pinocchio's), 0 where unmeasured; None if none measured.
        v_mask: (nv,) bool, the measured velocity coordinates; None with ``v``.
        joints: names of the measured joints.
        scene_name: the scene's name; source: the file (or what else) they came from.
    """

    t: np.ndarray
    q: np.ndarray
    mask: np.ndarray
    weights: np.ndarray
    v: np.ndarray | None = None
    v_mask: np.ndarray | None = None
    joints: tuple[str, ...] = ()
    scene_name: str = ""
    source: str = ""

    def __len__(self) -> int:
        return len(self.t)

    @classmethod
    def from_states(
        cls, scene, t, q, v=None, *, weights=None, joints=None, source: str = "observations"
    ) -> Observations:
        """Observations of ``scene`` from states in its convention (e.g. a simulated
        trajectory's samples), checked as a file's would be.

        Args:
            scene: the `Scene`.
            t: times (k,), s.
            q: configurations (k, nq).
            v: velocities (k, nv) or None.
            weights: (k,) or None (all 1).
            joints: names of the joints observed (default every observable joint).
            source: how to name these observations in errors.

        Raises:
            ObservationFileError: as `from_columns`; InvalidInputError: arrays of the wrong shape.
        """
        by_name = {j.name: j for j in joint_columns(scene)}
        names = list(by_name) if joints is None else list(joints)
        unknown = [n for n in names if n not in by_name]
        if unknown:
            raise InvalidInputError(
                f"{source}: unknown joint(s) {', '.join(unknown)}; observable: {', '.join(by_name)}"
            )
        t = np.asarray(t, dtype=float)
        q = np.asarray(q, dtype=float)
        if t.ndim != 1 or q.shape != (len(t), scene.model.nq):
            raise InvalidInputError(
                f"{source}: t must be (k,) and q (k, {scene.model.nq}), got shapes {t.shape} and {q.shape}"
            )
        if v is not None and np.shape(v) != (len(t), scene.nv):
            raise InvalidInputError(f"{source}: v must be ({len(t)}, {scene.nv}), got shape {np.shape(v)}")
        columns = {TIME: t} | ({} if weights is None else {WEIGHT: np.asarray(weights, dtype=float)})
        for name in names:
            columns |= state_columns(by_name[name], q, None if v is None else np.asarray(v, dtype=float))
        return from_columns(columns, scene, source)

    def columns(self, scene) -> dict[str, np.ndarray]:
        """The measured columns by name (module doc): what a file of these observations holds."""
        out = {TIME: self.t}
        if np.any(self.weights != 1.0):
            out[WEIGHT] = self.weights
        for joint in joint_columns(scene):
            if joint.name in self.joints:
                measured_v = self.v is not None and self.v_mask is not None and bool(self.v_mask[joint.idx_v])
                out |= state_columns(joint, self.q, self.v if measured_v else None)
        return out

    def save(self, path: str | Path, scene) -> Path:
        """Write these observations as CSV or ``.npz`` (by the suffix of ``path``)."""
        return write_columns(self.columns(scene), path)


# -- quaternion algebra (scalar first, [w x y z]) -------------------------------------
def _rotate(quat: np.ndarray, vec: np.ndarray, inverse: bool = False) -> np.ndarray:
    """Rotate the rows of ``vec`` (k, 3) by the unit quaternions (k, 4) ``[w x y z]`` (or by
    their inverses): ``v + 2 w (u × v) + 2 u × (u × v)``."""
    w, u = quat[:, :1], quat[:, 1:] * (-1.0 if inverse else 1.0)
    c = np.cross(u, vec)
    return vec + 2.0 * w * c + 2.0 * np.cross(u, c)


def state_columns(joint: JointColumns, q: np.ndarray, v: np.ndarray | None) -> dict[str, np.ndarray]:
    """One joint's columns (module doc) from states ``q`` (k, nq) and ``v`` (k, nv) or None."""
    a, b = joint.idx_q, joint.idx_v
    if joint.kind in (JointKind.FREE, JointKind.SPHERICAL):
        o = 3 if joint.kind is JointKind.FREE else 0
        quat = np.column_stack([q[:, a + o + 3], q[:, a + o : a + o + 3]])  # [w x y z]
        values = ([q[:, a + i] for i in range(3)] if o else []) + [quat[:, i] for i in range(4)]
        if v is not None:
            linear = [_rotate(quat, v[:, b : b + 3])] if o else []  # local -> world
            values += [c for block in [*linear, v[:, b + o : b + o + 3]] for c in block.T]
    else:
        angle = q[:, a] if joint.kind is JointKind.SCALAR else np.arctan2(q[:, a + 1], q[:, a])
        values = [angle] + ([v[:, b]] if v is not None else [])
    names = joint.configuration + (joint.velocity if v is not None else ())
    return dict(zip(names, values))


# -- columns -> Observations ----------------------------------------------------------
def _row(k: int, lines) -> str:
    return f"row {k}" + (f" (line {lines[k]})" if lines is not None else "")


def from_columns(columns: dict, scene, source: str, lines=None) -> Observations:
    """`Observations` of ``scene`` from a table's columns, checked.

    Args:
        columns: column name -> values (k,), in the file's order.
        scene: the `Scene` observed.
        source: the file (named in every error).
        lines: the file line of each row (CSV), named in errors; None: rows only.

    Raises:
        ObservationFileError: an unknown or missing column, columns of different lengths,
            fewer than two samples, a value that is not finite, times not increasing,
            a negative weight, a quaternion of zero norm or far from unit norm (module doc).
    """

    def fail(message: str) -> ObservationFileError:
        return ObservationFileError(f"{source}: {message}")

    valid = valid_columns(scene)
    unknown = [name for name in columns if name not in valid]
    if unknown:
        raise fail(f"unknown column(s) {', '.join(map(repr, unknown))}; valid: {', '.join(valid)}")
    if TIME not in columns:
        raise fail(f"missing column 't' (sample times, s); valid: {', '.join(valid)}")
    arrays = {}
    for name, values in columns.items():
        a = np.asarray(values)
        if a.ndim != 1 or not (np.issubdtype(a.dtype, np.number) or a.dtype == bool):
            raise fail(f"column {name!r} must be one number per sample, got shape {a.shape} of {a.dtype}")
        arrays[name] = a.astype(float)
    lengths = {name: len(a) for name, a in arrays.items()}
    if len(set(lengths.values())) > 1:
        raise fail(f"columns of different lengths: {', '.join(f'{n} {k}' for n, k in lengths.items())}")
    k = lengths[TIME]
    if k < 2:
        raise fail(f"a trajectory needs at least two samples, got {k}")
    table = np.column_stack(list(arrays.values()))
    bad = np.argwhere(~np.isfinite(table))
    if len(bad):
        row, col = bad[0]
        raise fail(f"{_row(row, lines)}, column {list(arrays)[col]!r}: {table[row, col]} is not a finite number")
    t = arrays[TIME]
    back = np.flatnonzero(np.diff(t) <= 0.0)
    if back.size:
        r = back[0] + 1
        raise fail(
            f"times must increase: {_row(r, lines)} has t = {float(t[r])!r} s, not after {float(t[r - 1])!r} s "
            f"of row {r - 1}"
        )
    weights = arrays.get(WEIGHT, np.ones(k))
    if np.any(weights < 0.0):
        r = int(np.argmax(weights < 0.0))
        raise fail(f"{_row(r, lines)}: weight {float(weights[r])!r} is negative (weights are >= 0)")
    if not np.any(weights > 0.0):
        raise fail("every weight is 0: nothing is measured")

    q = np.tile(scene.q0, (k, 1))
    nv = scene.nv
    mask, v_mask, v = np.zeros(nv, bool), np.zeros(nv, bool), np.zeros((k, nv))
    joints = []
    for joint in joint_columns(scene):
        given = [c for c in joint.configuration if c in arrays]
        given_v = [c for c in joint.velocity if c in arrays]
        if not given and not given_v:
            continue
        for names, present in ((joint.configuration, given), (joint.velocity, given_v)):
            # a joint is measured as a whole; its velocity only with its configuration
            if present and len(present) < len(names) or (present is given_v and not given):
                missing = [c for c in (names if given else joint.configuration) if c not in arrays]
                raise fail(
                    f"missing column(s) {', '.join(map(repr, missing))} of joint {joint.name!r} "
                    f"({joint.kind.value}; its columns: {', '.join(joint.configuration + joint.velocity)})"
                )
        _fill(joint, arrays, q, v if given_v else None, fail, lines)
        joints.append(joint.name)
        mask[joint.idx_v : joint.idx_v + joint.nv] = True
        if given_v:
            v_mask[joint.idx_v : joint.idx_v + joint.nv] = True
    if not joints:
        raise fail(f"no configuration column; valid: {', '.join(valid)}")
    return Observations(
        t=t,
        q=q,
        mask=mask,
        weights=weights,
        v=v if v_mask.any() else None,
        v_mask=v_mask if v_mask.any() else None,
        joints=tuple(joints),
        scene_name=scene.name,
        source=source,
    )


def _fill(joint: JointColumns, arrays, q, v, fail, lines) -> None:
    """Write one joint's columns into ``q`` (k, nq) and ``v`` (k, nv; None: not measured)."""
    a, b = joint.idx_q, joint.idx_v
    col = [arrays[c] for c in joint.configuration]
    if joint.kind in (JointKind.SCALAR, JointKind.ANGLE):
        if joint.kind is JointKind.SCALAR:
            q[:, a] = col[0]
        else:
            q[:, a], q[:, a + 1] = np.cos(col[0]), np.sin(col[0])
        if v is not None:
            v[:, b] = arrays[joint.velocity[0]]
        return
    o = 3 if joint.kind is JointKind.FREE else 0
    quat = np.column_stack(col[o : o + 4])  # [w x y z]
    norms = np.linalg.norm(quat, axis=1)
    if np.any(norms < ZERO_NORM):
        r = int(np.argmax(norms < ZERO_NORM))
        raise fail(f"{_row(r, lines)}: the quaternion of joint {joint.name!r} has zero norm")
    off = np.abs(norms - 1.0) > QUATERNION_TOLERANCE
    if np.any(off):
        r = int(np.argmax(off))
        raise fail(
            f"{_row(r, lines)}: the quaternion of joint {joint.name!r} has norm {norms[r]:.6g}, "
            f"not 1 within {QUATERNION_TOLERANCE:g} (columns {', '.join(joint.configuration[o:])}, "
            "scalar first)"
        )
    quat = quat / norms[:, None]
    if o:
        q[:, a : a + 3] = np.column_stack(col[:3])
    q[:, a + o : a + o + 3], q[:, a + o + 3] = quat[:, 1:], quat[:, 0]
    if v is not None:
        w = np.column_stack([arrays[c] for c in joint.velocity])
        if o:
            v[:, b : b + 3] = _rotate(quat, w[:, :3], inverse=True)  # world -> the body's frame
        v[:, b + o : b + o + 3] = w[:, o:]


def toss_observations(toss, scene=None, *, velocities: bool = True) -> Observations:
    """A measured cube toss (`contactdiff.data.cube_tosses.Toss`) as `Observations` of
    ``scene`` (default `contactdiff.data.cube_tosses.cube_scene`'s cube): its poses, and
    with ``velocities`` its velocities (backward differences of the poses, half a sample
    late: the poses are the measurements).

    Raises:
        InvalidInputError: the scene has no free body (the cube's joint is its first free-flyer).
    """
    if scene is None:
        from ..data.cube_tosses import cube_scene

        scene = cube_scene()
    free = [j for j in joint_columns(scene) if j.kind is JointKind.FREE]
    if not free:
        raise InvalidInputError(f"toss_observations: scene {scene.name!r} has no free body to observe the cube as")
    joint = free[0]
    values = [*toss.position.T, *toss.quaternion.T] + ([*toss.velocity.T, *toss.omega.T] if velocities else [])
    names = joint.configuration + (joint.velocity if velocities else ())
    return from_columns({TIME: toss.t} | dict(zip(names, values)), scene, f"toss {toss.name}")
