"""MuJoCo's own dynamics of an MJCF model, in Pinocchio's coordinates (tests and benchmarks only).

MuJoCo cannot compile a model whose mesh files are missing (Menagerie's XML without
its meshes): `stripped_copy` writes a copy without mesh assets, mesh geoms and
texture files. That leaves the dynamics unchanged when every body with a mesh
geom has an explicit ``<inertial>`` (the loader refuses other models when their
meshes are missing; with the meshes there, compile the file as given).
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin

from contactdiff.model.mjcf import mujoco_velocity_map
from contactdiff.model.mjcf_xml import read_document, resolve


def stripped_copy(path: Path, folder: Path) -> Path:
    """``path`` with its classes written inline (`contactdiff.model.mjcf_xml.resolve`, which
    MuJoCo reads as the original: tested) and without mesh assets, mesh geoms, skins,
    height-field files and texture files, written into ``folder`` (same file name)."""
    from xml.etree.ElementTree import tostring

    root = resolve(read_document(Path(path)))  # classes inline: a class's mesh geoms are seen as such
    for parent in list(root.iter()):
        for child in list(parent):
            drop = (
                (child.tag in ("mesh", "skin") and parent.tag == "asset")
                or (child.tag == "geom" and (child.get("mesh") or child.get("type") == "mesh"))
                or (child.tag in ("texture", "hfield") and child.get("file"))
            )
            if drop:
                parent.remove(child)
            elif child.tag == "material":
                child.attrib.pop("texture", None)
    for default in root.iter("default"):  # a class that makes geoms meshes would need a mesh
        for geom in default.findall("geom"):
            if geom.get("type") == "mesh" or geom.get("mesh"):
                geom.attrib.pop("type", None)
                geom.attrib.pop("mesh", None)
    out = Path(folder) / Path(path).name
    out.write_bytes(tostring(root))
    return out


class MujocoReference:
    """MuJoCo's mass matrix and bias forces for a Pinocchio model of the same file.

    Joints are matched by name (a free-flyer with MuJoCo's free joint); MuJoCo
    quaternions ``(w, x, y, z)`` become Pinocchio's ``(x, y, z, w)``; velocities go
    through `contactdiff.model.mjcf.mujoco_velocity_map`.
    """

    def __init__(self, model: pin.Model, path: Path):
        self.pin = model
        self.mj = mujoco.MjModel.from_xml_path(str(path))
        self.data = mujoco.MjData(self.mj)
        self.slots = []  # (idx_q, nq, qposadr, idx_v, nv, dofadr)
        free = [j for j in range(self.mj.njnt) if self.mj.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE]
        for jid in range(1, model.njoints):
            joint = model.joints[jid]
            if joint.shortname() == "JointModelFreeFlyer":
                mj = free.pop(0)
            else:
                mj = mujoco.mj_name2id(self.mj, mujoco.mjtObj.mjOBJ_JOINT, model.names[jid])
                assert mj >= 0, f"joint {model.names[jid]} not in MuJoCo's model"
            self.slots.append(
                (joint.idx_q, joint.nq, self.mj.jnt_qposadr[mj], joint.idx_v, joint.nv, self.mj.jnt_dofadr[mj])
            )
        assert self.mj.nv == model.nv and self.mj.nq == model.nq

    def qpos(self, q: np.ndarray) -> np.ndarray:
        """MuJoCo's configuration of Pinocchio's ``q``."""
        qpos = np.zeros(self.mj.nq)
        for iq, nq, adr, _, _, _ in self.slots:
            part = q[iq : iq + nq]
            if nq == 7:
                part = np.concatenate([part[:3], [part[6]], part[3:6]])
            elif nq == 4:
                part = np.concatenate([[part[3]], part[:3]])
            qpos[adr : adr + nq] = part
        return qpos

    def permutation(self) -> np.ndarray:
        """``perm[i]``: MuJoCo's dof of Pinocchio's tangent coordinate ``i``."""
        perm = np.zeros(self.pin.nv, dtype=int)
        for _, _, _, iv, nv, adr in self.slots:
            perm[iv : iv + nv] = np.arange(adr, adr + nv)
        return perm

    def dynamics(self, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(M, b)`` in Pinocchio's coordinates: ``M = T^T M_mj T``, ``b = T^T (b_mj + M_mj Ṫ v)``."""
        T, Tdot_v = mujoco_velocity_map(self.pin, q, v)
        perm = self.permutation()
        qvel = np.zeros(self.mj.nv)
        qvel[perm] = T @ v
        self.data.qpos[:] = self.qpos(q)
        self.data.qvel[:] = qvel
        mujoco.mj_forward(self.mj, self.data)
        full = np.zeros((self.mj.nv, self.mj.nv))
        mujoco.mj_fullM(self.mj, self.data, full)
        M = full[np.ix_(perm, perm)]
        b = self.data.qfrc_bias[perm]
        return T.T @ M @ T, T.T @ (b + M @ Tdot_v)


def random_states(model: pin.Model, count: int, seed: int = 0):
    """``count`` random ``(q, v)``: joints uniform in their limits (clipped to ±3), a random base
    orientation within ±1 m, velocities uniform in ±2."""
    rng = np.random.default_rng(seed)
    lower = np.clip(model.lowerPositionLimit, -3, 3)
    upper = np.clip(model.upperPositionLimit, -3, 3)
    for _ in range(count):
        q = pin.neutral(model)
        for jid in range(1, model.njoints):
            joint = model.joints[jid]
            i, n = joint.idx_q, joint.nq
            if n in (4, 7):  # free-flyer or ball: random unit quaternion (and position)
                quat = rng.normal(size=4)
                q[i + n - 4 : i + n] = quat / np.linalg.norm(quat)
                q[i : i + n - 4] = rng.uniform(-1, 1, n - 4)
            else:
                q[i : i + n] = rng.uniform(lower[i : i + n], upper[i : i + n])
        yield q, rng.uniform(-2, 2, model.nv)
