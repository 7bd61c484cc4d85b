"""Scenes: a robot, its contacts, its efforts, gravity and an initial state.

A scene is built in Python (`Scene`, `Scene.from_robot`) or read from a TOML
file (`contactdiff.scenes.scene_file`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from typing import TypeAlias

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike

from ..errors import InconsistentStateError, InvalidInputError, check_names, check_vector, unknown_name
from .contacts import FRICTION_MODES, BoundContact, Contact
from .efforts import Effort, bind_efforts
from .feet import FootChoice, up_direction
from .kinematics import Kinematics
from .parameters import parameter_names, parameter_values, tau_parameter_derivatives, with_parameters
from .robot import Robot

StateInput: TypeAlias = "ArrayLike | Mapping[str, ArrayLike]"
"""An initial configuration or velocity: a full array (``nq`` or ``nv``), or a mapping
from joint name to value (a number, or a sequence for a multi-coordinate joint)."""

PENETRATION_TOL = 1e-9
"""Largest penetration (m) an initial state may have: a closed contact, not an error."""

UNIT_NORM_TOL = 1e-6
"""How far from 1 the norm of a quaternion or unit complex number of a state may be."""


class Scene:
    """A mechanical system with unilateral contacts, ready to simulate or check.

    Args:
        robot: the `Robot` (its model is copied if gravity changes it).
        contacts: `Contact` specs; their names must be unique.
        efforts: effort specs, each with ``bind(robot)`` (the `Effort` protocol:
            `JointSpring`, `Spring`, `UserEffort`, the trot controller); gravity is
            not one: it is the model's, set by ``gravity``.
        gravity: world gravity (m/s², 3 numbers); ``None`` keeps the model's.
        q0: initial configuration, either a full array (``nq``) or a mapping
            from joint name to value (a number, or a list for multi-coordinate
            joints); unnamed joints keep the robot's reference pose.
        v0: initial velocity, either a full array (``nv``) or a mapping from joint
            name to value, as ``q0``; unnamed joints keep zero velocity.
        name: label for reports.

    Raises:
        InconsistentStateError: the initial state penetrates a contact.
    """

    def __init__(
        self,
        robot: Robot,
        contacts: Sequence[Contact] = (),
        efforts: Sequence = (),
        gravity: ArrayLike | None = None,
        q0: StateInput | None = None,
        v0: StateInput | None = None,
        name: str | None = None,
    ):
        if not isinstance(robot, Robot):
            raise InvalidInputError(f"robot must be a contactdiff Robot (see load_robot), got {robot!r}")
        if gravity is not None:
            robot = robot.copy()
            robot.model.gravity = pin.Motion(check_vector("scene", "gravity", gravity, 3), np.zeros(3))
        self.robot = robot
        self.name = name or robot.name
        for c in contacts:
            if not isinstance(c, Contact):
                raise InvalidInputError(f"contacts must be Contact objects, got {c!r}")
        self.contact_specs = tuple(c.resolved(robot) for c in contacts)  # radii set (`Contact.resolved`)
        self.effort_specs = tuple(efforts)
        names = [c.name for c in self.contact_specs]
        duplicates = sorted({n for n in names if names.count(n) > 1})
        if duplicates:
            raise InvalidInputError(f"contact names must be unique; repeated: {', '.join(duplicates)}")
        _check_one_contact_per_surface(self.contact_specs)
        for e in self.effort_specs:
            if not isinstance(e, Effort):
                raise InvalidInputError(
                    "efforts must be JointSpring, Spring, UserEffort, TrotController or other objects with "
                    f"bind(robot) (the Effort protocol), got {e!r}"
                )
        self.contacts: list[BoundContact] = [c.bind(robot) for c in self.contact_specs]
        self.efforts = bind_efforts(self.effort_specs, robot)
        self._timed_efforts = [e for e in self.efforts if hasattr(e, "next_breakpoint")]
        self.q0 = self._configuration(q0)
        self.v0 = self._velocity(v0)
        self._kinematics: Kinematics | None = None
        self.foot_choice: FootChoice | None = None  # set by from_robot: how its feet were chosen
        self.check_state(self.q0, self.v0)

    # -- basic facts -----------------------------------------------------------------
    @property
    def model(self) -> pin.Model:
        """The robot's ``pinocchio.Model`` (with this scene's gravity)."""
        return self.robot.model

    @property
    def nv(self) -> int:
        """Tangent (velocity) size of the robot."""
        return self.robot.nv

    @property
    def contact_names(self) -> list[str]:
        """Names of the contacts, in scene order (the contact indices)."""
        return [c.name for c in self.contacts]

    def contact_index(self, name: str) -> int:
        """Index of contact ``name``; unknown names raise with the list of contacts."""
        if name not in self.contact_names:
            raise unknown_name("contact", name, self.contact_names)
        return self.contact_names.index(name)

    @property
    def kinematics(self) -> Kinematics:
        """The scene's own kinematics cache (one `pinocchio.Data`, not thread safe)."""
        if self._kinematics is None:
            self._kinematics = Kinematics(self.model)
        return self._kinematics

    # -- evaluation ------------------------------------------------------------------
    def gaps(self, q: np.ndarray) -> np.ndarray:
        """Gaps of all contacts at ``q`` (m), in contact order."""
        kin = self.kinematics
        kin.update(q, np.zeros(self.nv))
        return np.array([c.gap(kin) for c in self.contacts])

    def tau(self, kin: Kinematics, t: float) -> np.ndarray:
        """Sum of the scene's efforts at the state of ``kin`` (gravity excluded); a new
        array, or the single effort's own result (the callers only read it)."""
        if len(self.efforts) == 1:
            return self.efforts[0].tau(kin, t)
        total = np.zeros(self.nv)
        for e in self.efforts:
            total += e.tau(kin, t)
        return total

    def next_breakpoint(self, t: float) -> float:
        """The first time (s) after ``t`` at which an effort's time dependence is not
        smooth (an effort's optional ``next_breakpoint``); ``inf`` if none.

        Raises:
            InvalidInputError: an effort returned a time that is not after ``t``.
        """
        first = math.inf
        for e in self._timed_efforts:
            t_break = e.next_breakpoint(t)
            if not t_break > t:  # also NaN
                raise InvalidInputError(
                    f"effort {e!r}: next_breakpoint({t!r}) returned {t_break!r}, "
                    "not a time after it (inf when no breakpoint is left)"
                )
            first = min(first, t_break)
        return first

    def autonomous_from(self, t: float) -> bool:
        """Whether no effort depends on time after ``t`` (s): each effort says so with its
        optional ``autonomous_from(t)`` (joint springs, springs: always; joint targets: past
        their last knot); an effort without it (a user effort, a controller) depends on time."""
        return all(getattr(e, "autonomous_from", None) is not None and e.autonomous_from(t) for e in self.efforts)

    def tau_derivatives(self, kin: Kinematics, t: float) -> tuple[np.ndarray, np.ndarray]:
        """``d tau/dq`` and ``d tau/dv`` of the efforts (tangent space, nv × nv each)."""
        dq, dv = np.zeros((self.nv, self.nv)), np.zeros((self.nv, self.nv))
        for e in self.efforts:
            a, b = e.derivatives(kin, t)
            dq += a
            dv += b
        return dq, dv

    def tau_time_derivative(self, kin: Kinematics, t: float) -> np.ndarray:
        """``d tau/dt`` at fixed state (nv,): the explicit time rate of the efforts
        (zero for an autonomous scene; see each effort's ``time_derivative``)."""
        total = np.zeros(self.nv)
        for e in self.efforts:
            total += e.time_derivative(kin, t)
        return total

    # -- named parameters (contactdiff.model.parameters) ---------------------------------
    def parameter_names(self) -> list[str]:
        """Names ``kind:target:field`` of every parameter of the scene: gravity, the
        bodies' masses, centres of mass and inertias, joint armatures, contact
        restitutions and offsets, spring, joint-spring, trot-controller and user-effort
        numbers (the naming rules and units are in `contactdiff.model.parameters`)."""
        return parameter_names(self)

    def parameter_values(self, names) -> np.ndarray:
        """Current values of the parameters ``names`` (one name, a sequence, or ``"all"``),
        in their units.

        Raises:
            UnknownNameError: an unknown name (the valid ones are listed).
        """
        return parameter_values(self, names)

    def with_parameters(self, values: Mapping) -> Scene:
        """A new scene with parameters changed (``{name: value}``); this scene, its robot
        and its model are untouched. Values are validated as a scene file's are (see
        `contactdiff.model.parameters.with_parameters`).

        Raises:
            UnknownNameError: an unknown name (the valid ones are listed).
            InvalidInputError: a non-finite or out-of-range value.
            InconsistentStateError: the initial state penetrates a changed contact.
        """
        return with_parameters(self, values)

    def tau_parameter_derivatives(self, kin: Kinematics, t: float, params) -> np.ndarray:
        """``d tau/dp`` (nv × len(params)) of the efforts' sum `tau` at the state of ``kin``
        and time ``t`` (s), per unit of each parameter (`Parameter` objects of this scene
        or names); zero columns for parameters no effort depends on (see
        `contactdiff.model.parameters.tau_parameter_derivatives`)."""
        return tau_parameter_derivatives(self, kin, t, params)

    def check_state(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Validate a state; return its gaps.

        Raises:
            InvalidInputError: wrong size or non-finite entries.
            InconsistentStateError: a gap is below ``-PENETRATION_TOL``.
        """
        q = check_vector("scene", "initial q", q, self.robot.nq, self._labels("q"))
        v = check_vector("scene", "initial v", v, self.nv, self._labels("v"))
        self._check_unit_coordinates(q)
        gaps = self.gaps(q)
        for name, gap in zip(self.contact_names, gaps):
            if gap < -PENETRATION_TOL:
                raise InconsistentStateError(
                    f"initial state penetrates contact {name!r}: gap {gap:.6g} m < 0; "
                    "raise the robot or lower the contact offset"
                )
        return gaps

    def _check_unit_coordinates(self, q: np.ndarray) -> None:
        """Refuse a quaternion (free-flyer, spherical joint) or unit complex number
        (unbounded revolute, planar joint) whose norm is not 1 within `UNIT_NORM_TOL`:
        Pinocchio would turn it into a rotation that is not one, or a zero
        quaternion into no rotation at all."""
        model = self.model
        if self.robot.is_vector_space or pin.isNormalized(model, q, UNIT_NORM_TOL):
            return
        for jid in range(1, model.njoints):
            joint = model.joints[jid]
            if joint.nq == joint.nv:
                continue
            alone = pin.neutral(model)
            alone[joint.idx_q : joint.idx_q + joint.nq] = q[joint.idx_q : joint.idx_q + joint.nq]
            if not pin.isNormalized(model, alone, UNIT_NORM_TOL):
                raise InvalidInputError(
                    f"initial q of joint {model.names[jid]!r} ({joint.shortname()}) holds a quaternion or "
                    f"unit complex number whose norm is not 1 (within {UNIT_NORM_TOL:g}): "
                    f"{q[joint.idx_q : joint.idx_q + joint.nq].tolist()}; a free-flyer is "
                    "[x, y, z, qx, qy, qz, qw] with qx² + qy² + qz² + qw² = 1"
                )

    def _labels(self, kind: str) -> list[str]:
        return self.robot.tangent_names() if kind == "v" else self.robot.configuration_names()

    # -- initial state by joint name ---------------------------------------------------
    def _configuration(self, q0, base: np.ndarray | None = None) -> np.ndarray:
        q = (self.robot.q_ref if base is None else base).copy()
        if q0 is None:
            return q
        if isinstance(q0, Mapping):
            for name, value in q0.items():
                joint = self.model.joints[self.robot.joint_id(name)]
                q[joint.idx_q : joint.idx_q + joint.nq] = _joint_values(name, value, joint.nq, "q")
            if not self.robot.is_vector_space:
                q = pin.normalize(self.model, q)
            return q
        return check_vector("scene", "q0", q0, self.robot.nq, self._labels("q"))

    def _velocity(self, v0, base: np.ndarray | None = None) -> np.ndarray:
        v = np.zeros(self.nv) if base is None else base.copy()
        if v0 is None:
            return v
        if isinstance(v0, Mapping):
            for name, value in v0.items():
                joint = self.model.joints[self.robot.joint_id(name)]
                v[joint.idx_v : joint.idx_v + joint.nv] = _joint_values(name, value, joint.nv, "v")
            return v
        return check_vector("scene", "v0", v0, self.nv, self._labels("v"))

    # -- variants ----------------------------------------------------------------------
    def with_robot(self, robot: Robot) -> Scene:
        """The same scene on another robot model (e.g. one with armature)."""
        return self.rebuilt(robot, self.contact_specs)

    def with_armature(self, armature: float) -> Scene:
        """The same scene with rotor inertia ``armature`` on the robot's actuated joints."""
        return self.with_robot(self.robot.with_armature(armature))

    def with_friction(self, friction, contacts: Sequence[str] | None = None) -> Scene:
        """The same scene with the ``friction`` of the named ``contacts`` (default every
        contact) replaced: a Coulomb coefficient μ >= 0, ``"stick"`` or ``"none"``, as
        `Contact` takes it.

        Raises:
            UnknownNameError: a name that is not a contact (the contacts are listed).
        """
        if contacts is None:
            chosen = set(self.contact_names)
        else:
            chosen = set(check_names("with_friction", "contacts", contacts))
            for name in chosen:
                self.contact_index(name)  # an unknown name raises, listing the contacts
        specs = [
            dataclasses.replace(spec, friction=friction) if spec.name in chosen else spec for spec in self.contact_specs
        ]
        return self.rebuilt(self.robot, specs)

    def rebuilt(self, robot: Robot, contacts: Sequence[Contact], efforts: Sequence | None = None) -> Scene:
        """This scene on another robot, with other contacts or other efforts (None keeps
        this scene's), every spec bound again; ``robot`` already carries the scene's
        gravity. The initial state, name and foot choice are this scene's.

        Raises:
            InconsistentStateError: the initial state penetrates one of ``contacts``.
        """
        scene = Scene(
            robot, contacts, self.effort_specs if efforts is None else efforts, None, self.q0, self.v0, self.name
        )
        scene.foot_choice = self.foot_choice
        return scene

    def with_state(self, q0: StateInput | None = None, v0: StateInput | None = None) -> Scene:
        """The same scene from another initial state: full arrays, or joint-name
        mappings that change only the named joints of this scene's state."""
        scene = Scene.__new__(Scene)
        scene.__dict__.update(self.__dict__)
        scene._kinematics = None
        scene.q0 = self.q0 if q0 is None else scene._configuration(q0, self.q0)
        scene.v0 = self.v0 if v0 is None else scene._velocity(v0, self.v0)
        scene.check_state(scene.q0, scene.v0)
        return scene

    @classmethod
    def from_robot(
        cls, robot: Robot, restitution: float = 0.0, friction: str = "stick", name: str | None = None
    ) -> Scene:
        """A robot standing on the ground: one contact per foot (``robot.feet``, see
        `contactdiff.model.feet`), normal along the vertical ``-g / |g|`` and offset so the
        reference pose touches the ground. A robot without feet gets no contacts; feet the
        model gives as spheres (``robot.foot_choice.radii``, an MJCF's) are round contacts."""
        up = up_direction(robot.model)
        kin = Kinematics(robot.model)
        kin.update(robot.q_ref, np.zeros(robot.nv))
        radii = robot.foot_choice.radii if robot.foot_choice is not None else {}
        contacts = [
            Contact(
                foot,
                normal=tuple(up),
                radius=radii.get(foot, 0.0),
                offset=float(up @ kin.position(robot.frame_id(foot))) - radii.get(foot, 0.0),
                restitution=restitution,
                friction=friction,
            )
            for foot in robot.feet
        ]
        scene = cls(robot, contacts, name=name or robot.name)
        scene.foot_choice = robot.foot_choice
        return scene


_SAME_NORMAL_TOL = 1e-9  # unit normals closer than this are one direction (a copied entry, not a corner)


def _check_one_contact_per_surface(contacts: Sequence[Contact]) -> None:
    """Refuse two contacts of one frame against one body (the ground or the same frame)
    along one normal: their gaps differ by a constant only (the offsets and radii), so
    one surface would be two constraints whose rows are equal, closing in an order set
    by round-off. Contacts of a frame along different normals (a floor and a wall), or
    against different frames, are different surfaces and allowed. A contact of ``p``
    against ``p'`` along ``n`` is the one of ``p'`` against ``p`` along ``-n``."""
    seen: list[tuple[str, str | None, np.ndarray, Contact]] = []
    for c in contacts:
        n = np.array(c.normal)
        for frame, against, normal, first in seen:
            same = ((c.frame, c.against) == (frame, against) and np.linalg.norm(n - normal) < _SAME_NORMAL_TOL) or (
                c.against is not None
                and (c.against, c.frame) == (frame, against)
                and np.linalg.norm(n + normal) < _SAME_NORMAL_TOL
            )
            if same:
                body = "the ground" if against is None else f"frame {against!r}"
                turned = "" if c.frame == frame else " (the second written the other way round)"
                raise InvalidInputError(
                    f"contacts {first.name!r} and {c.name!r} are both frame {frame!r} against {body} along the "
                    f"normal {first.normal}{turned}: one surface, whose two gaps differ by a constant only "
                    f"(offsets {first.offset:g} and {c.offset:g} m, radii {first.radius:g} and {c.radius:g} m), so "
                    "they would close in an order set by round-off; keep one contact there (with the offset, "
                    "radius, restitution and friction you mean), or give them different normals (a floor and a "
                    "wall) or different 'against' frames"
                )
        seen.append((c.frame, c.against, n, c))


def _joint_values(joint: str, value, size: int, kind: str) -> np.ndarray:
    try:
        x = np.array(value, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise InvalidInputError(f"initial {kind} of joint {joint!r} must be numeric, got {value!r}") from None
    if x.shape != (size,):
        raise InvalidInputError(f"initial {kind} of joint {joint!r} needs {size} value(s), got {value!r}")
    if not np.all(np.isfinite(x)):
        raise InvalidInputError(f"initial {kind} of joint {joint!r} must be finite, got {value!r}")
    return x


__all__ = ["Scene", "PENETRATION_TOL", "UNIT_NORM_TOL", "FRICTION_MODES"]
