"""Configuration spaces of the steppers: vector spaces and Pinocchio's Lie groups.

A configuration is a Pinocchio ``q`` (size ``nq``; a Lie-group element when the
model has a free-flyer, spherical, planar or continuous joint) with velocity
``v`` (size ``nv``, each joint's local frame), ``dq/dt = v`` in Pinocchio's sense.
Lie groups are handled by Runge–Kutta–Munthe-Kaas in a chart re-centred at the
start of every step: ``q = q_n ⊕ xi`` with ``xi(t_n) = 0`` and
``dxi/dt = Jr(xi)^-1 v`` (exact dexpinv), so every Runge–Kutta method keeps its
order; ``q_{n+1} = q_n ⊕ xi_{n+1}``. On vector spaces the chart is the identity.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from ..errors import InvalidInputError


@runtime_checkable
class LieGroup(Protocol):
    """Configuration space seen by the steppers (all vectors in Pinocchio's tangent convention).

    Attributes:
        nq: configuration size.
        nv: tangent (velocity) size.
        is_vector_space: True when ``nq == nv`` and ``⊕`` is ``+``; the
            steppers then never call the methods below.
    """

    nq: int
    nv: int
    is_vector_space: bool

    def integrate(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """``q ⊕ dq`` (``pin.integrate``)."""

    def difference(self, q0: np.ndarray, q1: np.ndarray) -> np.ndarray:
        """``dq`` with ``q0 ⊕ dq = q1`` (``pin.difference``)."""

    def chart_velocity(self, q0: np.ndarray, xi: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``dxi/dt = Jr(xi)^-1 v`` in the chart ``q = q0 ⊕ xi``, ``Jr = dIntegrate(q0, xi, ARG1)``."""

    def tangent_velocity(self, q0: np.ndarray, xi: np.ndarray, xi_dot: np.ndarray) -> np.ndarray:
        """``Jr(xi) xi_dot``: the velocity ``v`` of ``q0 ⊕ xi(t)`` (inverse of `chart_velocity`)."""

    def velocity_jacobian_q(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """d(δq')/dδq of ``q' = v`` linearised in the tangent space (nv x nv); ``-ad(v)`` per joint."""

    def magnitude(self, q: np.ndarray) -> np.ndarray:
        """Per tangent component, the size of ``q`` that ``rtol`` is relative to (nv,)."""


class VectorSpace:
    """R^n with ``⊕ = +`` (plain ODEs, tests, fixed-base robots with bounded joints).

    Args:
        n: dimension (``nq = nv = n``).
    """

    is_vector_space = True

    def __init__(self, n: int) -> None:
        n = int(n)
        if n < 1:
            raise InvalidInputError(f"VectorSpace dimension n must be >= 1, got {n}")
        self.nq = self.nv = n

    def integrate(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """``q + dq``."""
        return q + dq

    def difference(self, q0: np.ndarray, q1: np.ndarray) -> np.ndarray:
        """``q1 - q0``."""
        return q1 - q0

    def chart_velocity(self, q0: np.ndarray, xi: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``v`` itself (a copy): ``Jr = I``."""
        return np.array(v, dtype=float)

    def tangent_velocity(self, q0: np.ndarray, xi: np.ndarray, xi_dot: np.ndarray) -> np.ndarray:
        """``xi_dot`` itself (a copy): ``Jr = I``."""
        return np.array(xi_dot, dtype=float)

    def velocity_jacobian_q(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Zero (n × n): on a vector space ``q' = v`` does not depend on ``q``."""
        return np.zeros((self.nv, self.nv))

    def magnitude(self, q: np.ndarray) -> np.ndarray:
        """``|q|`` per component (n,): what ``rtol`` is relative to."""
        return np.abs(q)

    def __repr__(self) -> str:
        return f"VectorSpace({self.nv})"


# Lie-group joints the chart handles, by pinocchio shortname.
_SE3 = ("JointModelFreeFlyer",)
_SO3 = ("JointModelSpherical",)
_SE2 = ("JointModelPlanar",)
_SO2 = ("JointModelRUBX", "JointModelRUBY", "JointModelRUBZ", "JointModelRevoluteUnboundedUnaligned")


class PinocchioGroup:
    """The configuration Lie group of a Pinocchio model.

    Joints with ``nq == nv`` are Euclidean. Supported Lie-group joints:
    free-flyer (SE(3)), spherical (SO(3)), planar (SE(2)) and continuous
    revolute (SO(2), ``nq = 2, nv = 1``). ``dIntegrate(ARG1)`` is block
    diagonal per joint, so the chart only inverts the non-identity blocks: in
    closed form for SE(3)/SO(3) (``Jr^-1 = Jlog(exp(xi))``, cheaper than a
    6x6 solve) and with a small solve for SE(2); SO(2) is abelian (block 1).

    Args:
        model: the ``pinocchio.Model``.

    Raises:
        InvalidInputError: a joint with ``nq != nv`` of an unsupported type.
    """

    def __init__(self, model) -> None:
        import pinocchio as pin

        self._pin = pin
        self.model = model
        self.nq, self.nv = int(model.nq), int(model.nv)
        eq: list[int] = []
        ev: list[int] = []
        self._blocks: list[tuple[str, int, int, int]] = []  # (kind, idx_q, idx_v, nv_j)
        for j in range(1, model.njoints):
            jm = model.joints[j]
            iq, iv, nqj, nvj = jm.idx_q, jm.idx_v, jm.nq, jm.nv
            if nqj == nvj:
                eq.extend(range(iq, iq + nqj))
                ev.extend(range(iv, iv + nvj))
                continue
            name = jm.shortname()
            if name in _SE3:
                kind = "se3"
            elif name in _SO3:
                kind = "so3"
            elif name in _SE2:
                kind = "se2"
            elif name in _SO2:
                kind = "so2"
            else:
                supported = ", ".join(_SE3 + _SO3 + _SE2 + _SO2)
                raise InvalidInputError(
                    f"joint {model.names[j]!r} of type {name} (nq={nqj}, nv={nvj}) is not supported by "
                    f"PinocchioGroup; supported non-Euclidean joints: {supported}"
                )
            self._blocks.append((kind, iq, iv, nvj))
        self._eq = np.array(eq, dtype=int)
        self._ev = np.array(ev, dtype=int)
        self.is_vector_space = self.nq == self.nv and not self._blocks
        # SO(2) blocks are identity in dIntegrate and have ad = 0.
        self._chart_blocks = [b for b in self._blocks if b[0] != "so2"]

    def integrate(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """``q ⊕ dq = pin.integrate(model, q, dq)`` (nq,)."""
        return self._pin.integrate(self.model, q, dq)

    def difference(self, q0: np.ndarray, q1: np.ndarray) -> np.ndarray:
        """``dq`` (nv,) with ``q0 ⊕ dq = q1`` (``pin.difference``)."""
        return self._pin.difference(self.model, q0, q1)

    def chart_velocity(self, q0: np.ndarray, xi: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``dxi/dt = Jr(xi)^-1 v`` (nv,) in the chart ``q = q0 ⊕ xi``: in closed form on SE(3)/SO(3)
        blocks, by a small solve on SE(2) blocks, ``v`` itself elsewhere."""
        pin = self._pin
        out = np.array(v, dtype=float)
        D = None
        for kind, _, iv, n in self._chart_blocks:
            s = slice(iv, iv + n)
            if kind == "se3":
                out[s] = pin.Jlog6(pin.exp6(xi[s])) @ v[s]
            elif kind == "so3":
                out[s] = pin.Jlog3(pin.exp3(xi[s])) @ v[s]
            else:  # se2: no closed form exposed by pinocchio
                if D is None:
                    D = pin.dIntegrate(self.model, q0, xi, pin.ARG1)
                out[s] = np.linalg.solve(D[s, s], v[s])
        return out

    def tangent_velocity(self, q0: np.ndarray, xi: np.ndarray, xi_dot: np.ndarray) -> np.ndarray:
        """``Jr(xi) xi_dot`` (nv,): the velocity ``v`` of ``q0 ⊕ xi(t)`` (inverse of `chart_velocity`)."""
        pin = self._pin
        out = np.array(xi_dot, dtype=float)
        D = None
        for kind, _, iv, n in self._chart_blocks:
            s = slice(iv, iv + n)
            if kind == "se3":
                out[s] = pin.Jexp6(xi[s]) @ xi_dot[s]
            elif kind == "so3":
                out[s] = pin.Jexp3(xi[s]) @ xi_dot[s]
            else:
                if D is None:
                    D = pin.dIntegrate(self.model, q0, xi, pin.ARG1)
                out[s] = D[s, s] @ xi_dot[s]
        return out

    def velocity_jacobian_q(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """d(δq')/dδq of ``q' = v`` linearised in the tangent space (nv × nv): ``-ad(v)`` on each
        SE(3), SO(3) and SE(2) block, zero elsewhere."""
        G = np.zeros((self.nv, self.nv))
        for kind, _, iv, n in self._chart_blocks:
            s = slice(iv, iv + n)
            if kind == "se3":  # -ad(v) on (linear, angular), checked by FD of dIntegrate(ARG0)
                G[s, s] = -self._pin.Motion(v[s]).action
            elif kind == "so3":
                G[s, s] = -self._pin.skew(v[s])
            else:  # se2, v = (vx, vy, w): -ad(v)
                vx, vy, w = v[iv], v[iv + 1], v[iv + 2]
                G[s, s] = -np.array([[0.0, -w, vy], [w, 0.0, -vx], [0.0, 0.0, 0.0]])
        return G

    def magnitude(self, q: np.ndarray) -> np.ndarray:
        """Per tangent component, the size of ``q`` that ``rtol`` is relative to (nv,)."""
        # Euclidean coordinates: |q_i|; translations of SE(3)/SE(2) joints: the
        # position's norm; rotation coordinates have no natural size (atol only).
        m = np.zeros(self.nv)
        m[self._ev] = np.abs(q[self._eq])
        for kind, iq, iv, _ in self._blocks:
            if kind == "se3":
                m[iv : iv + 3] = np.linalg.norm(q[iq : iq + 3])
            elif kind == "se2":
                m[iv : iv + 2] = np.linalg.norm(q[iq : iq + 2])
        return m

    def __repr__(self) -> str:
        return f"PinocchioGroup(nq={self.nq}, nv={self.nv}, is_vector_space={self.is_vector_space})"


def _as_group(group) -> LieGroup:
    """Accept a group object or a ``pinocchio.Model``."""
    if hasattr(group, "nq") and hasattr(group, "nv") and hasattr(group, "is_vector_space"):
        if not group.is_vector_space:
            missing = [
                m
                for m in (
                    "integrate",
                    "difference",
                    "chart_velocity",
                    "tangent_velocity",
                    "velocity_jacobian_q",
                    "magnitude",
                )
                if not callable(getattr(group, m, None))
            ]
            if missing:
                raise InvalidInputError(f"group {group!r} lacks the methods: {', '.join(missing)}")
        return group
    if hasattr(group, "njoints") and hasattr(group, "joints"):
        return PinocchioGroup(group)
    raise InvalidInputError(
        f"group must be a LieGroup (VectorSpace, PinocchioGroup) or a pinocchio.Model, got {type(group).__name__}"
    )
