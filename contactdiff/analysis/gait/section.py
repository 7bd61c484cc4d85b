"""The section of a stride map and the moves it is taken modulo: the scene's clock,
the neutral moves (translations along the ground, turning about the vertical),
the section's coordinates, and the Floquet multipliers in them.

The mathematics is in `contactdiff.analysis.gait.stride`'s module docstring.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from ...dynamics.mode import ModeDynamics
from ...errors import InvalidInputError, check_number
from ...integration.sensitivity import gap_gradient
from ...integration.trajectory import EventKind
from ...model.scene import Scene

NEUTRAL_NAMES = ("x", "y", "yaw")
"""Neutral moves: world translations along x and y, rotation about the vertical (free-flyer)."""

MIN_FLIGHT_SHARE = 0.05
"""Default ``min_flight`` of a clock-driven scene, as a share of its clock period."""

SECTION_TOL = 1e-9
"""Largest gap (m) of the foot at a state given as a point of the section; it is then closed exactly."""

RESOLUTION_TIGHTENING = 10.0
"""`find_periodic_gait` measures the map's resolution against the same stride at
``rtol`` and ``atol`` divided by this (a tenfold tightening at least halves the
integration error: DOP853's shrinks about 7.7 times, 10^(8/9))."""

_SYMMETRY_TOL = 1e-9  # relative change of gaps and accelerations under a neutral move that counts as none
_IMPACT_KINDS = (EventKind.TOUCHDOWN, EventKind.BOUNCE)


def _positive_duration(owner: str, name: str, value) -> float:
    x = check_number(owner, name, value, minimum=0.0)
    if x <= 0:
        raise InvalidInputError(f"{owner}: {name} must be > 0 s, got {value!r}")
    return x


# ----------------------------------------------------------------------------------
# the clock, neutral moves, the section
# ----------------------------------------------------------------------------------
def scene_period(scene: Scene) -> float | None:
    """Clock period (s) of the scene's clock-driven efforts (those with a ``period``
    attribute), or None if it has none. Different periods are an error."""
    periods = {float(e.period) for e in scene.effort_specs if getattr(e, "period", None) is not None}
    if len(periods) > 1:
        raise InvalidInputError(
            f"scene {scene.name!r} has efforts with different clock periods {sorted(periods)}; pass period= explicitly"
        )
    return periods.pop() if periods else None


def _resolve_period(scene: Scene, period) -> float | None:
    if period is None:
        return scene_period(scene)
    if period is False:
        return None
    value = check_number("stride map", "period", period, minimum=0.0)
    if value <= 0:
        raise InvalidInputError(f"stride map: period must be > 0 s, got {period!r}")
    return value


def _joint_jacobian_stack(scene: Scene, q: np.ndarray) -> np.ndarray:
    """Joint Jacobians (LOCAL_WORLD_ALIGNED: world axes at each joint origin), stacked, 6 rows per joint."""
    model, data = scene.model, scene.robot.new_data()
    pin.computeJointJacobians(model, data, q)
    return np.vstack(
        [
            pin.getJointJacobian(model, data, j, pin.LOCAL_WORLD_ALIGNED).reshape(6, model.nv)
            for j in range(1, model.njoints)
        ]
    )


def _neutral_vector(scene: Scene, q: np.ndarray, name: str) -> np.ndarray | None:
    """Tangent vector (nv,) of the neutral move ``name`` at ``q``, or None if the
    joints cannot realise it (every joint origin moving by it, no joint turning)."""
    nv = scene.nv
    if name == "yaw":
        if not scene.robot.floating_base:
            return None
        R = pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix()
        d = np.zeros(nv)
        d[3:6] = R.T @ np.array([0.0, 0.0, 1.0])  # base frame: rotation about the world vertical
        return d
    axis = {"x": 0, "y": 1}[name]
    jac = _joint_jacobian_stack(scene, q)
    target = np.zeros(jac.shape[0])
    target[axis::6] = 1.0
    d, *_ = np.linalg.lstsq(jac, target, rcond=None)
    return d if np.linalg.norm(jac @ d - target) <= 1e-9 * math.sqrt(target.size) else None


def _is_symmetry(scene: Scene, q: np.ndarray, v: np.ndarray, t: float, direction: np.ndarray) -> bool:
    """The gaps and the free-flight accelerations are unchanged by a finite move along ``direction``."""
    dyn = ModeDynamics(scene)
    moved = pin.integrate(scene.model, q, 0.3 * direction)
    g0, g1 = scene.gaps(q), scene.gaps(moved)
    a0, a1 = dyn.solve(q, v, t, ()).ddq, dyn.solve(moved, v, t, ()).ddq
    scale = 1.0 + max(np.abs(g0).max(initial=0.0), np.abs(a0).max(initial=0.0))
    return max(np.abs(g1 - g0).max(initial=0.0), np.abs(a1 - a0).max(initial=0.0)) <= _SYMMETRY_TOL * scale


def available_neutral(
    scene: Scene, q: np.ndarray | None = None, v: np.ndarray | None = None, t: float = 0.0
) -> tuple[str, ...]:
    """Neutral moves of `NEUTRAL_NAMES` the scene admits at ``(q, v, t)`` (default
    its initial state): realisable by the joints and leaving gaps and dynamics unchanged."""
    q = scene.q0 if q is None else np.asarray(q, dtype=float)
    v = scene.v0 if v is None else np.asarray(v, dtype=float)
    out = []
    for name in NEUTRAL_NAMES:
        d = _neutral_vector(scene, q, name)
        if d is not None and _is_symmetry(scene, q, v, t, d):
            out.append(name)
    return tuple(out)


def _check_neutral(scene: Scene, neutral, q, v, t) -> tuple[str, ...]:
    if neutral is None:
        return available_neutral(scene, q, v, t)
    if isinstance(neutral, str):
        neutral = [n for n in neutral.replace(",", " ").split() if n]
    names = tuple(neutral)
    for name in names:
        if name not in NEUTRAL_NAMES:
            raise InvalidInputError(f"unknown neutral move {name!r}; valid: {', '.join(NEUTRAL_NAMES)}")
    valid = available_neutral(scene, q, v, t)
    bad = [n for n in names if n not in valid]
    if bad:
        raise InvalidInputError(
            f"scene {scene.name!r} does not admit the neutral move(s) {', '.join(bad)} "
            f"(not realisable by its joints, or not a symmetry); valid here: "
            f"{', '.join(valid) or '(none)'}"
        )
    return names


def neutral_directions(scene: Scene, q: np.ndarray, neutral: Sequence[str]) -> np.ndarray:
    """Tangent vectors (2nv × k) of the neutral moves at ``q`` (velocity part zero)."""
    cols = []
    for name in neutral:
        d = _neutral_vector(scene, q, name)
        if d is None:
            raise InvalidInputError(f"neutral move {name!r} is not realisable by the joints of {scene.name!r}")
        cols.append(np.concatenate([d, np.zeros(scene.nv)]))
    return np.array(cols).T.reshape(2 * scene.nv, len(cols))


def section_basis(
    scene: Scene, foot: str, q: np.ndarray, neutral: Sequence[str] = (), period: float | None = None
) -> np.ndarray:
    """Orthonormal section coordinates at ``q``: a basis (n × m) of the tangent
    vectors with ``Dh δx = 0`` (along the foot's guard) orthogonal to the neutral
    moves; with a clock (``period``) one more row and column for the phase τ.
    ``n = 2nv (+1)``, ``m = 2nv - 1 - len(neutral) (+1)``."""
    i = scene.contact_index(foot)
    Dh = gap_gradient(ModeDynamics(scene), q, i)
    constraints = np.vstack([Dh[None, :], neutral_directions(scene, q, neutral).T])
    # null space of the constraints: right singular vectors beyond their rank
    _, s, vt = np.linalg.svd(constraints)
    rank = int(np.sum(s > 1e-10 * max(s[0], 1.0)))
    B = vt[rank:].T
    if period is None:
        return B
    n, m = B.shape
    out = np.zeros((n + 1, m + 1))
    out[:n, :m] = B
    out[n, m] = 1.0
    return out


def _sorted_eigenvalues(A: np.ndarray) -> np.ndarray:
    lam = np.linalg.eigvals(A) if A.size else np.zeros(0, dtype=complex)
    return lam[np.lexsort((-lam.imag, -np.abs(lam)))].astype(complex)


def _foot_index(scene: Scene, foot: str) -> int:
    if not isinstance(scene, Scene):
        raise InvalidInputError(f"scene must be a Scene (see load_scene), got {scene!r}")
    return scene.contact_index(foot)


def onto_section(scene: Scene, foot: str, q: np.ndarray, tol: float = 1e-15) -> np.ndarray:
    """``q`` moved onto ``a_foot(q) = 0`` by Gauss–Newton along the gap gradient (tangent space)."""
    i = _foot_index(scene, foot)
    kin, contact, zero = scene.kinematics, scene.contacts[i], np.zeros(scene.nv)
    q = np.array(q, dtype=float)
    for _ in range(20):
        kin.update(q, zero)
        gap = contact.gap(kin)
        if abs(gap) <= tol:
            break
        row = contact.rows(kin)[0]
        if not row @ row > 0:
            raise InvalidInputError(f"the gap of {foot!r} does not depend on q here: no section to move onto")
        q = pin.integrate(scene.model, q, -row * gap / float(row @ row))
    return q


def _yaw(q: np.ndarray) -> float:
    R = pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix()
    return math.atan2(R[1, 0], R[0, 0])


def align(scene: Scene, q: np.ndarray, q_ref: np.ndarray, neutral: Sequence[str]) -> tuple[np.ndarray, dict]:
    """``q`` moved by the neutral moves so that its base yaw and centre-of-mass x, y
    match ``q_ref``'s (only the moves in ``neutral``); also returns the move undone
    (``{"x": m, "y": m, "yaw": rad}``, the part of ``q`` beyond ``q_ref``)."""
    model, data = scene.model, scene.robot.new_data()
    q = np.array(q, dtype=float)
    moved = {}
    if "yaw" in neutral:
        dpsi = math.atan2(math.sin(_yaw(q) - _yaw(q_ref)), math.cos(_yaw(q) - _yaw(q_ref)))
        d = _neutral_vector(scene, q, "yaw")
        assert d is not None  # neutral holds available moves only (_check_neutral)
        q = pin.integrate(model, q, -dpsi * d)
        moved["yaw"] = dpsi
    com, com_ref = pin.centerOfMass(model, data, q).copy(), pin.centerOfMass(model, data, q_ref).copy()
    for name, axis in (("x", 0), ("y", 1)):
        if name in neutral:
            shift = float(com[axis] - com_ref[axis])
            d = _neutral_vector(scene, q, name)
            assert d is not None  # neutral holds available moves only (_check_neutral)
            q = pin.integrate(model, q, -shift * d)
            moved[name] = shift
    return q, moved
