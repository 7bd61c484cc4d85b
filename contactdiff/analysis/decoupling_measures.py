"""The decoupling check's measures at one scene (part of
`contactdiff.analysis.decoupling`, whose notes define them): the limbs'
coordinates, poses with two contacts closed, each pair's normalised inverse-mass
coupling, and the limb assumptions' terms (mass-matrix blocks, gaps, efforts)."""

from __future__ import annotations

import itertools

import numpy as np
import pinocchio as pin

from ..model.scene import Scene
from .decoupling_report import PairCoupling, Term

_FD_STEP = 1e-5  # central differences of analytic first derivatives: error ~1e-10 relative


_PROJECTION_TOL = 1e-12  # m, gap after projection onto a_i = a_j = 0


class Checker:
    """The measurements of one check; coordinates are tangent (velocity) indices."""

    def __init__(self, scene: Scene, rng: np.random.Generator, spread: float, groups):
        self.scene, self.rng, self.spread = scene, rng, float(spread)
        self.model, self.robot = scene.model, scene.robot
        self.data = self.model.createData()
        self.kin = scene.kinematics
        # one limb per group of contacts (`decoupling._limb_groups`): its chains' coordinates, no other limb's
        index = {name: i for i, name in enumerate(scene.contact_names)}
        self.members = [[index[n] for n in members] for _, members in groups]
        self.limb_names = [limb for limb, _ in groups]
        self.limb_of = {i: g for g, members in enumerate(self.members) for i in members}
        supports = [set().union(*(self._support(scene.contacts[i]) for i in members)) for members in self.members]
        self.limbs = [s - set().union(*(o for k, o in enumerate(supports) if k != i)) for i, s in enumerate(supports)]
        self.body = set(range(self.model.nv)) - set().union(*self.limbs)
        self.v_joint = {}  # tangent index -> joint id
        for jid in range(1, self.model.njoints):
            j = self.model.joints[jid]
            for k in range(j.idx_v, j.idx_v + j.nv):
                self.v_joint[k] = jid

    def joints_of(self, coords: set[int]) -> list[int]:
        """The joints (Pinocchio indices, sorted) that move the tangent coordinates ``coords``."""
        return sorted({self.v_joint[k] for k in coords})

    def _support(self, contact) -> set[int]:
        """Tangent coordinates on the kinematic chain(s) of a contact's frame(s)."""
        coords: set[int] = set()
        for fid in (contact.fid, contact.against_fid):
            if fid is None:
                continue
            for jid in self.model.supports[self.model.frames[fid].parentJoint]:
                if jid == 0:
                    continue
                j = self.model.joints[jid]
                coords.update(range(j.idx_v, j.idx_v + j.nv))
        return coords

    # -- poses -------------------------------------------------------------------------
    def _random_pose(self) -> np.ndarray:
        dq = self.rng.uniform(-self.spread, self.spread, self.model.nv)
        return self.robot.integrate(self.scene.q0, dq)

    def _project(self, q: np.ndarray, idx: list[int]) -> np.ndarray | None:
        """Gauss–Newton (minimum-norm steps) onto the closed set of contacts ``idx``."""
        zero = np.zeros(self.model.nv)
        for _ in range(50):
            self.kin.update(q, zero)
            gaps = np.array([self.scene.contacts[i].gap(self.kin) for i in idx])
            if np.max(np.abs(gaps)) <= _PROJECTION_TOL:
                return q
            A = np.vstack([self.scene.contacts[i].rows(self.kin)[:1] for i in idx])
            q = self.robot.integrate(q, -np.linalg.lstsq(A, gaps, rcond=None)[0])
        return None

    def _poses(self, idx: list[int], samples: int) -> list[np.ndarray]:
        poses = [self._project(self.scene.q0.copy(), idx)]
        poses += [self._project(self._random_pose(), idx) for _ in range(samples)]
        return [q for q in poses if q is not None]

    # -- orthogonality -------------------------------------------------------------------
    def _coupling(self, q: np.ndarray, i: int, j: int) -> float:
        self.kin.update(q, np.zeros(self.model.nv))
        A = np.vstack([self.scene.contacts[k].rows(self.kin)[:1] for k in (i, j)])
        Minv = pin.computeMinverse(self.model, self.data, q)
        G = A @ Minv @ A.T
        return float(abs(G[0, 1]) / np.sqrt(G[0, 0] * G[1, 1]))

    def pair_coupling(self, i: int, j: int, samples: int, poses=None) -> PairCoupling:
        """Coupling over projected reference and random poses, or at ``poses`` as given."""
        poses = self._poses([i, j], samples) if poses is None else poses
        values = [self._coupling(q, i, j) for q in poses]
        names = self.scene.contact_names
        ref = values[0] if poses and poses[0] is not None else float("nan")
        return PairCoupling((names[i], names[j]), ref, float(np.max(values)), float(np.median(values)), len(values))

    # -- limb assumption -----------------------------------------------------------------
    def _effort_jacobian(self, q: np.ndarray, v: np.ndarray, t: float = 0.0) -> np.ndarray:
        """``[d f/dq, d f/dv]`` of ``f = tau - nle`` at time ``t`` (s) (nv × 2nv)."""
        self.kin.update(q, v, derivatives=True)
        dtau_dq, dtau_dv = self.scene.tau_derivatives(self.kin, t)
        dn_dq, dn_dv, _ = pin.computeRNEADerivatives(self.model, self.data, q, v, np.zeros(self.model.nv))
        return np.hstack([dtau_dq - dn_dq, dtau_dv - dn_dv])

    def assumption_terms(self, samples: int, states=None) -> list[Term]:
        """Terms over projected poses with random velocities at t = 0, or at ``states``
        ((q, v, t) triples)."""
        nv, names = self.model.nv, self.scene.contact_names
        if states is None:
            all_closed = list(range(len(self.scene.contacts)))
            poses = self._poses(all_closed, samples) or [self.scene.q0]
            states = [(q, self.rng.uniform(-self.spread, self.spread, nv), 0.0) for q in poses]
        limb_names = self.limb_names
        blocks = [("body", self.body)] + [(f"limb {n}", limb) for n, limb in zip(limb_names, self.limbs)]
        owners = [()] + [tuple(names[i] for i in members) for members in self.members]
        # largest relative size of each term over the poses, keyed by block/limb indices
        mass: dict[tuple[int, int], float] = {}  # by pair of limbs
        dep: dict[int, float] = {}
        effort: dict[int, float] = {}
        additive: dict[tuple[int, int], float] = {}  # by pair of limbs
        gap = np.zeros(len(names))
        for q, v, t in states:
            M = pin.crba(self.model, self.data, q)
            diag = np.sqrt(np.abs(np.diag(M)))
            scale = np.where(diag > 0, diag, 1.0)
            Mn = M / np.outer(scale, scale)
            for ia, ib in itertools.combinations(range(len(blocks)), 2):
                ca, cb = sorted(blocks[ia][1]), sorted(blocks[ib][1])
                if ca and cb:
                    key = (ia, ib)
                    mass[key] = max(mass.get(key, 0.0), float(np.max(np.abs(Mn[np.ix_(ca, cb)]))))
            # block j of M may depend only on coordinates of block j
            dM = self._mass_derivative(q)
            for ib, (_, coords) in enumerate(blocks):
                c = sorted(coords)
                others = [k for k in range(nv) if k not in coords]
                if c and others:
                    value = np.max(np.abs(dM[np.ix_(c, c, others)])) / max(np.max(np.abs(M[np.ix_(c, c)])), 1e-300)
                    dep[ib] = max(dep.get(ib, 0.0), float(value))
            # each gap depends on its limb only
            self.kin.update(q, np.zeros(nv))
            for i, contact in enumerate(self.scene.contacts):
                row = contact.rows(self.kin)[0]
                outside = [k for k in range(nv) if k not in self.limbs[self.limb_of[i]]]
                if outside:
                    gap[i] = max(gap[i], float(np.max(np.abs(row[outside])) / max(np.max(np.abs(row)), 1e-300)))
            # efforts
            Df = self._effort_jacobian(q, v, t)
            fscale = max(float(np.max(np.abs(Df))), 1.0)
            for i, limb in enumerate(self.limbs):
                other = sorted(set().union(*(other_limb for k, other_limb in enumerate(self.limbs) if k != i)))
                if limb and other:
                    cols = other + [nv + k for k in other]
                    value = float(np.max(np.abs(Df[np.ix_(sorted(limb), cols)]))) / fscale
                    effort[i] = max(effort.get(i, 0.0), value)
            body = sorted(self.body)
            if body:
                for i, j in itertools.combinations(range(len(self.limbs)), 2):
                    if not (self.limbs[i] and self.limbs[j]):  # a contact of the body alone (an object
                        continue  # on the ground): no mixed derivative
                    value = self._mixed_body_derivative(q, v, t, body, self.limbs[i], self.limbs[j]) / fscale
                    additive[(i, j)] = max(additive.get((i, j), 0.0), value)
        terms = []
        for (ia, ib), value in mass.items():
            terms.append(
                Term("mass matrix", f"block {blocks[ia][0]} / {blocks[ib][0]}", value, owners[ia] + owners[ib])
            )
        for ib, value in dep.items():
            terms.append(Term("mass matrix", f"block {blocks[ib][0]} depends on other coordinates", value, owners[ib]))
        for i, value in enumerate(gap):
            terms.append(Term("gap", f"{names[i]} depends on coordinates outside its limb", float(value), (names[i],)))
        for i, value in effort.items():
            terms.append(Term("limb effort", f"limb {limb_names[i]} depends on other limbs", value, owners[i + 1]))
        for (i, j), value in additive.items():
            terms.append(
                Term(
                    "body effort",
                    f"not additive in limbs {limb_names[i]} and {limb_names[j]}",
                    value,
                    owners[i + 1] + owners[j + 1],
                )
            )
        return terms

    def _mass_derivative(self, q: np.ndarray) -> np.ndarray:
        """``dM[a, b, k] = d M_ab / d q_k`` by central differences of ``crba``."""
        nv = self.model.nv
        dM = np.empty((nv, nv, nv))
        for k in range(nv):
            e = np.zeros(nv)
            e[k] = _FD_STEP
            dM[:, :, k] = (
                pin.crba(self.model, self.data, self.robot.integrate(q, e))
                - pin.crba(self.model, self.data, self.robot.integrate(q, -e))
            ) / (2 * _FD_STEP)
        return dM

    def _mixed_body_derivative(self, q, v, t, body, limb_i, limb_j) -> float:
        """Largest ``|d² f_body / dx_i dx_j|`` over coordinates ``x_i`` of limb i and
        ``x_j`` of limb j (positions and velocities): central differences in ``x_j``
        of the analytic first derivatives in ``x_i``."""
        nv = self.model.nv
        cols = sorted(limb_i) + [nv + k for k in sorted(limb_i)]
        worst = 0.0
        for k in sorted(limb_j):
            e = np.zeros(nv)
            e[k] = _FD_STEP
            for (q_plus, v_plus), (q_minus, v_minus) in (
                ((self.robot.integrate(q, e), v), (self.robot.integrate(q, -e), v)),
                ((q, v + e), (q, v - e)),
            ):
                diff = self._effort_jacobian(q_plus, v_plus, t) - self._effort_jacobian(q_minus, v_minus, t)
                worst = max(worst, float(np.max(np.abs(diff[np.ix_(body, cols)]))) / (2 * _FD_STEP))
        return worst
