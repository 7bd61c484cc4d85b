"""Robot models: a Pinocchio model with its frames, joints, feet and Lie-group helpers.

Where robots come from (URDF and MJCF files, the project's ``robots/`` folder,
example-robot-data names) is `contactdiff.model.robot_files` (`load_robot`).

Configurations follow Pinocchio: ``q`` has ``nq`` entries (a free-flyer base is
``[x y z qx qy qz qw]``, world frame), velocities and every perturbation live
in the tangent space of size ``nv``, and ``q ⊕ dq = pin.integrate(model, q, dq)``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin

from ..errors import InvalidInputError, ModelLoadError, unknown_name
from .feet import FootChoice, FootRule


@dataclass
class Robot:
    """A Pinocchio model with the facts contactdiff needs about it.


    Attributes:
        model: the ``pinocchio.Model`` (its ``gravity`` and ``armature`` are used as set).
        name: short name (file stem or example-robot-data name).
        urdf: path of the URDF file the model came from ("" if built in code).
        floating_base: whether the root joint is a free-flyer.
        q_ref: reference configuration (SRDF "standing" pose if known, else neutral).
        feet: foot frame names (chosen automatically or by hand, see `contactdiff.model.feet`),
            may be empty.
        actuated: names of the joints that carry a motor (armature is added to these).
        foot_choice: how the feet were chosen (`FootChoice`), for reports.
        objects: the free objects appended to the model (`contactdiff.model.objects`),
            their joints after the robot's.
    """

    model: pin.Model
    name: str
    urdf: str = ""
    floating_base: bool = False
    q_ref: np.ndarray = None  # type: ignore[assignment]  # None: the standing pose or neutral (__post_init__)
    feet: tuple[str, ...] = ()
    actuated: tuple[str, ...] = ()
    foot_choice: FootChoice | None = None
    objects: tuple = ()
    _data: pin.Data | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        if self.q_ref is None:
            self.q_ref = pin.neutral(self.model)
        self.q_ref = np.array(self.q_ref, dtype=float)
        if self.foot_choice is None:
            self.foot_choice = FootChoice(tuple(self.feet), FootRule.GIVEN)

    # -- sizes and scratch data ---------------------------------------------------
    @property
    def nq(self) -> int:
        """Configuration size (a free-flyer counts 7: position and quaternion)."""
        return self.model.nq

    @property
    def nv(self) -> int:
        """Tangent (velocity) size (a free-flyer counts 6)."""
        return self.model.nv

    @property
    def data(self) -> pin.Data:
        """A scratch ``pinocchio.Data`` owned by this robot (not thread safe)."""
        if self._data is None:
            self._data = self.model.createData()
        return self._data

    def new_data(self) -> pin.Data:
        """A fresh ``pinocchio.Data`` (for APIs that must not share buffers)."""
        return self.model.createData()

    # -- Lie group -----------------------------------------------------------------
    def integrate(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """Return ``q ⊕ dq`` (``dq`` in the tangent space, local frame for a free-flyer)."""
        return pin.integrate(self.model, q, dq)

    def difference(self, q0: np.ndarray, q1: np.ndarray) -> np.ndarray:
        """Return ``dq`` with ``q0 ⊕ dq = q1``."""
        return pin.difference(self.model, q0, q1)

    @property
    def is_vector_space(self) -> bool:
        """True if ``q ⊕ dq = q + dq``: no joint has more coordinates than velocities
        (quaternions and unbounded revolutes do), so ``nq == nv`` says it all."""
        return self.model.nq == self.model.nv

    # -- names -----------------------------------------------------------------------
    @property
    def frame_names(self) -> list[str]:
        """Names of the model's frames, in frame-index order."""
        return [f.name for f in self.model.frames]

    @property
    def joint_names(self) -> list[str]:
        """Names of the model's joints, universe excluded."""
        return list(self.model.names)[1:]

    def frame_id(self, name: str) -> int:
        """Index of frame ``name``; unknown names raise with the list of frames."""
        if not isinstance(name, str) or not self.model.existFrame(name):
            raise unknown_name(f"frame of robot {self.name!r}", name, self.frame_names)
        return self.model.getFrameId(name)

    def joint_id(self, name: str) -> int:
        """Index of joint ``name``; unknown names raise with the list of joints."""
        if not isinstance(name, str) or not self.model.existJointName(name):
            raise unknown_name(f"joint of robot {self.name!r}", name, self.joint_names)
        return self.model.getJointId(name)

    def scalar_joint(self, name: str) -> tuple[int, int]:
        """Return ``(idx_q, idx_v)`` of a one-coordinate joint (revolute or prismatic)."""
        joint = self.model.joints[self.joint_id(name)]
        if joint.nq != 1 or joint.nv != 1:
            raise InvalidInputError(
                f"joint {name!r} has nq={joint.nq}, nv={joint.nv}; only one-coordinate "
                "(revolute or prismatic) joints can be set by a single number"
            )
        return joint.idx_q, joint.idx_v

    def configuration_names(self) -> list[str]:
        """One label per configuration coordinate (``joint`` or ``joint[k]``)."""
        labels = []
        for jid in range(1, self.model.njoints):
            name, nq = self.model.names[jid], self.model.joints[jid].nq
            labels += [name] if nq == 1 else [f"{name}[{k}]" for k in range(nq)]
        return labels

    def tangent_names(self) -> list[str]:
        """One label per tangent coordinate (``joint`` or ``joint[k]`` for multi-dof joints)."""
        return _tangent_names(self.model)

    # -- variants --------------------------------------------------------------------
    def copy(self) -> Robot:
        """A copy whose model can be changed (gravity, armature) without touching this one."""
        return Robot(
            pin.Model(self.model),
            self.name,
            self.urdf,
            self.floating_base,
            self.q_ref.copy(),
            self.feet,
            self.actuated,
            self.foot_choice,
            self.objects,
        )

    def with_armature(self, armature: float) -> Robot:
        """A copy with reflected rotor inertia ``armature`` (kg m² or kg) on every actuated joint."""
        armature = float(armature)
        if not np.isfinite(armature) or armature < 0:
            raise InvalidInputError(f"armature must be finite and >= 0, got {armature!r}")
        robot = self.copy()
        values = np.array(robot.model.armature)
        for name in self.actuated:
            j = robot.model.joints[robot.model.getJointId(name)]
            values[j.idx_v : j.idx_v + j.nv] += armature
        robot.model.armature = values
        return robot


def _check_inertias(model: pin.Model, path: Path, kind: str = "URDF") -> None:
    """Refuse negative or non-finite masses and inertias: they make M indefinite."""
    for jid in range(1, model.njoints):
        inertia = model.inertias[jid]
        values = np.concatenate([[inertia.mass], inertia.lever, inertia.inertia.ravel()])
        if not np.all(np.isfinite(values)) or inertia.mass < 0:
            raise ModelLoadError(
                f"{kind} {str(path)!r}: body of joint {model.names[jid]!r} has mass {inertia.mass!r} "
                "and inertia entries that must be finite with mass >= 0"
            )
        if np.min(np.linalg.eigvalsh(inertia.inertia)) < -1e-12 * max(1.0, np.abs(inertia.inertia).max()):
            raise ModelLoadError(
                f"{kind} {str(path)!r}: rotational inertia of joint {model.names[jid]!r} is not "
                f"positive semidefinite: {inertia.inertia.tolist()}"
            )


def _check_mass_matrix(model: pin.Model, q: np.ndarray, path: Path, kind: str = "URDF") -> None:
    """Refuse a model whose mass matrix is singular (a coordinate moves no mass)."""
    M = pin.crba(model, model.createData(), q)
    try:
        np.linalg.cholesky(M)
    except np.linalg.LinAlgError:
        massless = [n for n, m in zip(_tangent_names(model), np.diag(M)) if not m > 0]
        raise ModelLoadError(
            f"{kind} {str(path)!r}: the mass matrix is singular at the reference pose"
            + (f"; coordinates moving no mass: {', '.join(massless)}" if massless else "")
            + " (check the <inertial> elements"
            + ("; a mass that failed to parse is dropped)" if kind == "URDF" else ")")
        ) from None


def _tangent_names(model: pin.Model) -> list[str]:
    labels = []
    for jid in range(1, model.njoints):
        name, nv = model.names[jid], model.joints[jid].nv
        labels += [name] if nv == 1 else [f"{name}[{k}]" for k in range(nv)]
    return labels
