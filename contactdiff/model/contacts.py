"""Unilateral contacts: gaps, Jacobian rows, drift and their derivatives.

A contact between frame ``p`` and the ground (or a second frame ``p'``) has the gap

    a(q) = n · (p(q) - p'(q)) - offset        (m, world frame; n unit, world-fixed)

and one constraint row per direction ``d`` it holds (the normal, then for a
sticking contact two tangents): ``A_d = d^T (J_p - J_p')`` with ``J`` the linear
LOCAL_WORLD_ALIGNED Jacobian, and ``drift_d = d^T (J̇_p - J̇_p') v``, so that the
row's acceleration is ``A_d ddq + drift_d``. The first row is the gap's gradient.

**Round contacts.** A contact of radius ``r > 0`` is a sphere of radius ``r``
centred at the frame origin ``p``. Its lowest point along the normal is
``p - r n``, so the gap is ``a(q) = n · (p - p') - r - offset``, and the
material point of the sphere there moves at ``v_p + ω × (-r n) = v_p + r n × ω``
(``ω`` the frame's angular velocity, world axes). Its rows are

    A_d = d^T (J_v - J_p') + r (d × n)^T J_ω  (``J_v``, ``J_ω``: linear and angular
                                               LOCAL_WORLD_ALIGNED Jacobians)

Against a second frame ``p'`` (a sphere touching a robot's finger, or an
object's face) the other body's point is its frame origin: its velocity stands
for that of the touched surface, exactly so when that body does not turn, or
when ``p'`` sits where the sphere touches.

since ``d · (n × ω) = (d × n) · ω``: the normal row has no rotation term (it stays
the gap's gradient), a tangent row holds the rolling point still, so a sticking
round contact rolls without slipping (its tangent rows are not integrable). The
drift is ``d^T a_p + r (d × n)^T α`` with ``a_p`` the classical acceleration of
the origin and ``α`` the angular acceleration, both at zero joint acceleration.
With ``r = 0`` none of these terms is evaluated.
"""

from __future__ import annotations

import copy
import dataclasses
from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from ..errors import InvalidInputError, check_number
from .kinematics import Kinematics
from .robot import Robot


class FrictionLaw(StrEnum):
    """A contact's friction law (`Contact.law`). A `StrEnum`: ``NONE`` and ``STICK`` are
    also the values a contact's ``friction`` is given by name (``"none"``, ``"stick"``),
    and compare equal to those strings."""

    NONE = "none"
    """frictionless: one row (the normal)"""
    STICK = "stick"
    """no slip while active (infinite friction): three rows"""
    COULOMB = "coulomb"
    """Coulomb's law with a finite coefficient ``μ > 0`` (the contact's ``friction`` is
    that number): it sticks inside the cone ``||λ_T|| <= μ λ_N`` and slips on it"""


FRICTION_MODES = (FrictionLaw.NONE, FrictionLaw.STICK)
"""The friction laws a contact's ``friction`` names: ``none``, frictionless, one row;
``stick``, no slip while active, three rows. A number ``μ >= 0`` is Coulomb friction of
that coefficient (``0`` is ``"none"``, ``inf`` is ``"stick"``)."""

_ROW_TOL = 1e-12  # a row whose Jacobian is this small everywhere cannot act (m per unit q)


def _unit_vector(value, *, owner: str) -> tuple[float, float, float]:
    try:
        n = np.asarray(value, dtype=float).reshape(3)
    except (TypeError, ValueError):
        raise InvalidInputError(f"{owner}: normal must be 3 numbers, got {value!r}") from None
    norm = np.linalg.norm(n)
    if not np.all(np.isfinite(n)) or norm < 1e-12:
        raise InvalidInputError(f"{owner}: normal must be a finite non-zero 3-vector, got {value!r}")
    x, y, z = (float(c) for c in n / norm)
    return x, y, z


def _friction(value, owner: str) -> FrictionLaw | float:
    """`FrictionLaw.NONE`, `FrictionLaw.STICK` or a finite ``μ > 0`` (0 and inf map to
    the laws)."""
    if isinstance(value, str):
        if value in FRICTION_MODES:
            return FrictionLaw(value)
    elif not isinstance(value, bool) and isinstance(value, (int, float, np.integer, np.floating)):
        mu = float(value)
        if mu == 0.0:
            return FrictionLaw.NONE
        if mu == np.inf:
            return FrictionLaw.STICK
        if mu > 0.0 and np.isfinite(mu):
            return mu
    raise InvalidInputError(
        f"{owner}: friction must be one of {', '.join(FRICTION_MODES)} or a Coulomb coefficient mu >= 0; got {value!r}"
    )


@dataclass(frozen=True)
class Contact:
    """A unilateral contact, independent of any robot.

    Args:
        frame: name of the contact frame (its origin is the contact point).
        normal: world-fixed normal, normalised on construction.
        offset: gap at which contact closes (m): the plane's position along the normal
            (for a ground contact ``n · p = offset + radius`` on contact).
        restitution: Newton coefficient ``e`` in [0, 1] (0 plastic, 1 elastic).
        friction: ``"none"`` (frictionless), ``"stick"`` (no slip while active, infinite
            friction) or a Coulomb coefficient ``μ >= 0`` (a number; stored as
            `FrictionLaw.NONE` for 0 and `FrictionLaw.STICK` for inf, a name as its
            `FrictionLaw`; the law is `law`): the contact sticks while its
            tangential force stays in the cone ``||λ_T|| <= μ λ_N`` and slips with the
            force ``-μ λ_N s`` along its slip direction ``s`` otherwise.
        against: second frame; ``None`` is the ground (world origin).
        name: contact name, defaults to ``frame``.
        radius: radius (m, >= 0) of a sphere centred at the frame origin (a round
            foot, a ball): the gap is measured to its lowest point along the normal
            and a sticking contact rolls (module doc), on the ground or on the body
            of ``against``. ``None`` (the default) is resolved on the robot
            (`resolved`): the sphere's radius for a ground contact on the centre
            frame of a sphere object (`contactdiff.model.objects`), else 0.
        group: name of a group of contacts that share their coefficients (the eight
            corners of a cube): the scene's parameters ``group:GROUP:restitution``,
            ``group:GROUP:offset`` and ``group:GROUP:friction`` set every member's at
            once (`contactdiff.model.contact_parameters`). ``None``: no group.
    """

    frame: str
    normal: tuple[float, float, float] = (0.0, 0.0, 1.0)
    offset: float = 0.0
    restitution: float = 0.0
    friction: FrictionLaw | str | float = FrictionLaw.NONE
    against: str | None = None
    name: str = None  # type: ignore[assignment]  # None: the frame's name (__post_init__)
    radius: float | None = None
    group: str | None = None

    def __post_init__(self) -> None:
        owner = f"contact {self.name or self.frame!r}"
        if not isinstance(self.frame, str) or not self.frame:
            raise InvalidInputError(f"contact frame must be a frame name, got {self.frame!r}")
        set_ = object.__setattr__  # frozen dataclass: normalise in place once
        set_(self, "name", self.name or self.frame)
        set_(self, "normal", _unit_vector(self.normal, owner=owner))
        set_(self, "offset", check_number(owner, "offset", self.offset))
        e = check_number(owner, "restitution", self.restitution)
        if not 0.0 <= e <= 1.0:
            raise InvalidInputError(f"{owner}: restitution must be in [0, 1], got {e!r}")
        set_(self, "restitution", e)
        set_(self, "friction", _friction(self.friction, owner))
        if self.radius is not None:
            set_(self, "radius", check_number(owner, "radius", self.radius, minimum=0.0))
        if self.group is not None and (not isinstance(self.group, str) or not self.group or ":" in self.group):
            raise InvalidInputError(
                f"{owner}: group must be a non-empty name without ':' (or None), got {self.group!r}"
            )

    def resolved(self, robot: Robot) -> Contact:
        """This contact with its radius set: a given radius is kept; without one, a
        ground contact (no ``against``) on the centre frame of a sphere object of
        ``robot`` gets the sphere's radius (the ball rests on its surface, not on its
        centre), any other contact 0 (a point contact; against a second frame the
        offset holds the distance, as between the centres of two balls)."""
        if self.radius is not None:
            return self
        radius = 0.0
        if self.against is None:
            for obj in robot.objects:
                if obj.name == self.frame and obj.urdf is None and obj.shape == "sphere":
                    radius = obj.radius
        return dataclasses.replace(self, radius=radius)

    @property
    def law(self) -> FrictionLaw:
        """The friction law: `FrictionLaw.COULOMB` for a coefficient, else the named one."""
        return self.friction if isinstance(self.friction, FrictionLaw) else FrictionLaw.COULOMB

    @property
    def sticking(self) -> bool:
        """Whether the contact holds tangential rows while it sticks (``"stick"`` or a
        Coulomb coefficient)."""
        return self.law is not FrictionLaw.NONE

    @property
    def mu(self) -> float:
        """Coulomb coefficient: 0 for ``"none"``, inf for ``"stick"``."""
        law = self.law
        if law is FrictionLaw.COULOMB:
            return float(self.friction)
        return 0.0 if law is FrictionLaw.NONE else np.inf

    @property
    def coulomb(self) -> bool:
        """Whether the friction is Coulomb's with a finite coefficient ``μ > 0``."""
        return self.law is FrictionLaw.COULOMB

    def bind(self, robot: Robot) -> BoundContact:
        """Resolve frame names on ``robot`` and choose the constraint directions."""
        return BoundContact(self, robot)


def tangent_basis(normal) -> np.ndarray:
    """Two unit tangents ``(t1, t2)`` with ``t1 × t2 = n``; ``t1`` is world x projected when possible."""
    n = np.asarray(normal, dtype=float)
    seed = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    t1 = seed - (seed @ n) * n
    t1 /= np.linalg.norm(t1)
    return np.array([t1, np.cross(n, t1)])


class BoundContact:
    """A `Contact` resolved on a robot: frame indices and constraint directions.

    Attributes:
        spec: the `Contact`.
        name: contact name.
        directions: (k, 3) world directions of its rows, normal first; a sticking
            contact keeps only the tangents along which the point can move (a planar
            model has one, a 3-D robot two).
        radius: the sphere's radius (m), 0 for a point contact.
        rolling: (k × 3) angular coefficients ``r (d × n)`` of the rows of a round
            contact (module doc), None when no row has one (``r = 0``, or the normal
            row only).
    """

    def __init__(self, spec: Contact, robot: Robot):
        spec = spec.resolved(robot)
        self.spec, self.name = spec, spec.name
        self.fid = robot.frame_id(spec.frame)
        self.against_fid = robot.frame_id(spec.against) if spec.against is not None else None
        self.offset, self.restitution, self.radius = spec.offset, spec.restitution, spec.radius
        normal = np.array(spec.normal)
        directions = np.array([normal] + (list(tangent_basis(normal)) if spec.sticking else []))
        reach = self._reach(robot, directions)
        if reach[0] < _ROW_TOL:
            raise InvalidInputError(
                f"contact {self.name!r}: frame {spec.frame!r} cannot move along the normal "
                f"{spec.normal} in this model, so the contact can never act"
            )
        self.directions = directions[reach >= _ROW_TOL]
        self.rolling = self._rolling(self.directions)

    def _rolling(self, directions: np.ndarray) -> np.ndarray | None:
        """Angular coefficients ``r (d × n)`` of the rows (k × 3), or None when no row has
        one (a point contact, or a round contact with its normal row only)."""
        if not self.radius or len(directions) < 2:
            return None
        return self.radius * np.cross(directions, directions[0])

    def _reach(self, robot: Robot, directions: np.ndarray) -> np.ndarray:
        """Largest row norm of each direction over a few seeded configurations."""
        kin = Kinematics(robot.model)
        rng = np.random.default_rng(0)
        rolling = self._rolling(directions)
        reach = np.zeros(len(directions))
        for q in [robot.q_ref] + [robot.integrate(robot.q_ref, 0.5 * rng.standard_normal(robot.nv)) for _ in range(3)]:
            kin.update(q, np.zeros(robot.nv))
            rows = directions @ self._point_jacobian(kin)
            if rolling is not None:
                rows = rows + rolling @ kin.angular_jacobian(self.fid)
            reach = np.maximum(reach, np.linalg.norm(rows, axis=1))
        return reach

    sliding = False  # a normal-only view of a sticking contact (see `sliding_view`)
    full: BoundContact | None = None  # the contact of a sliding view, with all its rows

    @property
    def mu(self) -> float:
        """Coulomb coefficient acting on this contact or view: the spec's ``μ`` (inf for a
        sticking contact); 0 for a frictionless contact, a contact without tangential
        rows, and the sliding view of an infinitely sticking one (see `sliding_view`)."""
        if self.n_rows == 1 and not (self.sliding and self.spec.coulomb):
            return 0.0
        return self.spec.mu

    @property
    def holds_cone(self) -> bool:
        """Whether this contact sticks with a finite Coulomb coefficient: its tangential
        force must stay in the cone ``||λ_T|| <= μ λ_N`` (else it slips)."""
        return self.spec.coulomb and self.sticking and self.n_rows > 1

    @property
    def slips(self) -> bool:
        """Whether this is a slipping view with Coulomb friction (force ``-μ λ_N s`` along its
        slip direction ``s``, `contactdiff.dynamics.slip`)."""
        return self.sliding and self.spec.coulomb and self.full is not None and self.full.n_rows > 1

    @property
    def sticking(self) -> bool:
        """Whether this contact sticks: a sticking spec, not its `sliding_view` (normal row only)."""
        return self.spec.sticking and not self.sliding

    def sliding_view(self) -> BoundContact:
        """This contact with its normal row only: a sticking contact that slides.

        At zero normal force Coulomb friction carries no tangential force, so a
        sticking contact whose release would let it sink keeps its normal row and
        drops its tangents (frictionless sliding) until its normal force vanishes.
        A contact with a finite coefficient ``μ`` slips instead: the view keeps the
        normal row as its constraint, and its force acts along ``n - μ s`` (the
        friction ``-μ λ_N s`` opposing the slip velocity ``s``; ``slips`` is True).
        ``full`` is the contact with all its rows.
        """
        view = copy.copy(self)
        view.directions, view.rolling, view.sliding, view.full = self.directions[:1], None, True, self
        return view

    @property
    def n_rows(self) -> int:
        """Number of constraint rows: 1 (normal) plus the tangents it holds."""
        return len(self.directions)

    @property
    def normal(self) -> np.ndarray:
        """Unit normal (3,), world frame: the direction of the first row."""
        return self.directions[0]

    # -- the point difference p - p' and its derivatives ----------------------------
    def _diff(self, get):
        value = get(self.fid)
        if self.against_fid is not None:
            other = get(self.against_fid)
            value = tuple(a - b for a, b in zip(value, other)) if isinstance(value, tuple) else value - other
        return value

    def _point_jacobian(self, kin: Kinematics) -> np.ndarray:
        return self._diff(kin.jacobian)

    # -- values (need kin.update(q, v)) ------------------------------------------------
    def gap(self, kin: Kinematics) -> float:
        """Normal gap ``a(q)`` (m), to the sphere's lowest point when round; negative means
        penetration."""
        p = self._diff(kin.position)
        if self.radius:
            return float(self.normal @ p - self.offset - self.radius)
        return float(self.normal @ p - self.offset)

    def gap_rate(self, kin: Kinematics) -> float:
        """Normal gap rate ``Da(q) v`` (m/s) at the state of ``kin``."""
        return float(self.normal @ self._diff(kin.velocity))

    def rows(self, kin: Kinematics) -> np.ndarray:
        """Constraint rows ``A`` (n_rows × nv); row 0 is ``Da(q)``."""
        A = self.directions @ self._point_jacobian(kin)
        if self.rolling is not None:
            A += self.rolling @ kin.angular_jacobian(self.fid)
        return A

    def drift(self, kin: Kinematics) -> np.ndarray:
        """Row accelerations at zero joint acceleration, ``d^T (J̇_p - J̇_p') v`` (n_rows,),
        plus ``r (d × n)^T α`` when round."""
        drift = self.directions @ self._diff(kin.classical_acceleration)
        if self.rolling is not None:
            drift += self.rolling @ kin.angular_acceleration(self.fid)
        return drift

    # -- derivatives (need kin.update(q, v, derivatives=True)) ----------------------
    def rows_velocity_dq(self, kin: Kinematics) -> np.ndarray:
        """``d(A v)/dq`` at fixed ``v`` (n_rows × nv)."""
        dAv = self.directions @ self._diff(kin.velocity_derivative)
        if self.rolling is not None:
            dAv += self.rolling @ kin.angular_derivatives(self.fid)[0]
        return dAv

    def drift_derivatives(self, kin: Kinematics) -> tuple[np.ndarray, np.ndarray]:
        """``d drift/dq`` and ``d drift/dv`` (each n_rows × nv)."""
        dq, dv = self._diff(kin.acceleration_derivatives)
        dq, dv = self.directions @ dq, self.directions @ dv
        if self.rolling is not None:
            _, alpha_dq, alpha_dv = kin.angular_derivatives(self.fid)
            dq += self.rolling @ alpha_dq
            dv += self.rolling @ alpha_dv
        return dq, dv

    def rows_times_dq(self, kin: Kinematics, x: np.ndarray) -> np.ndarray:
        """``d(A x)/dq`` at fixed ``x`` (n_rows × nv), ``x`` in R^nv (e.g. an acceleration)."""
        H = self._diff(kin.hessian)  # (3, nv, nv)
        dAx = self.directions @ (x @ H)  # x @ H: sum_j x_j H[c, j, k]
        if self.rolling is not None:
            dAx += self.rolling @ (x @ kin.angular_hessian(self.fid))
        return dAx

    def rows_transpose_dq(self, kin: Kinematics, lam: np.ndarray) -> np.ndarray:
        """``d(A^T lam)/dq`` at fixed ``lam`` (nv × nv), ``lam`` one entry per row."""
        H = self._diff(kin.hessian)
        nv = H.shape[1]
        dATlam = ((lam @ self.directions) @ H.reshape(3, nv * nv)).reshape(nv, nv)
        if self.rolling is not None:
            Hw = kin.angular_hessian(self.fid)
            dATlam += ((lam @ self.rolling) @ Hw.reshape(3, nv * nv)).reshape(nv, nv)
        return dATlam
