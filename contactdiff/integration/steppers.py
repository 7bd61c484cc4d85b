"""Error-controlled one-step integrators with dense output (mechanical systems).

The state is a Pinocchio configuration ``q`` (size ``nq``; a Lie-group element
when the model has a free-flyer, spherical, planar or continuous joint) and a
velocity ``v`` (size ``nv``) driven by ``dv/dt = accel(t, q, v)`` and
``dq/dt = v`` in Pinocchio's sense, ``q(t + dt) = q(t) ⊕ dt·v + O(dt²)``.

Lie groups are handled by Runge–Kutta–Munthe-Kaas in a chart re-centred at the
start of every step: ``q = q_n ⊕ xi`` with ``xi(t_n) = 0`` and
``dxi/dt = Jr(xi)^-1 v`` (exact dexpinv), so every Runge–Kutta method keeps its
order; ``q_{n+1} = q_n ⊕ xi_{n+1}``. On vector spaces the chart is the identity
and the steppers integrate ``y = (q, v)`` directly without any chart call.

A stepper is driven one accepted step at a time by the hybrid loop::

    st = make_stepper("DOP853", accel, PinocchioGroup(model), t0, q0, v0,
                      rtol=1e-10, atol=1e-12)
    st.step()                       # one accepted step [st.t_old, st.t]
    dense = st.dense()              # (q, v) = dense(t) on that interval
    st.truncate(t_event)            # keep the step only up to an event
    st.restart(t_event, q_plus, v_plus, phi=Xi @ st.phi)   # after a jump

Units and frames: time in the model's unit (s); ``q`` and ``v`` in Pinocchio's
units and frames (m, rad, quaternion components; m/s and rad/s in each joint's
local frame). The flow Jacobian ``phi`` (``2nv x m``) maps perturbations at the
initial point to tangent perturbations ``(δq, δv)`` at the current point,
``q ⊕ δq`` (Pinocchio's convention, DESIGN.md §2); by default its local error
is controlled together with the state's (``variational_error_control``).
Integration runs forward in time only.

Callbacks receive arrays that this module never modifies afterwards, so they
may keep references to them (e.g. for caching).
"""

from __future__ import annotations

import math
from typing import Callable, Protocol, runtime_checkable

import numpy as np
from scipy.integrate._ivp import dop853_coefficients as _dop
from scipy.integrate._ivp.rk import RK45 as _SciRK45
from scipy.linalg.lapack import dgetrf, dgetrs, zgetrf, zgetrs

from contactdiff.errors import IntegrationError, InvalidInputError

__all__ = [
    "METHODS",
    "AccelFn",
    "JacFn",
    "LieGroup",
    "VectorSpace",
    "PinocchioGroup",
    "DenseOutput",
    "Stepper",
    "ExplicitRK",
    "RK45",
    "DOP853",
    "Radau",
    "make_stepper",
]

AccelFn = Callable[[float, np.ndarray, np.ndarray], np.ndarray]
"""``accel(t, q, v) -> dv/dt`` (nv,), in the joints' local frames."""
JacFn = Callable[[float, np.ndarray, np.ndarray], "tuple[np.ndarray, np.ndarray]"]
"""``jac(t, q, v) -> (J_q, J_v)``: d accel / d q (tangent, ``q ⊕ δq``) and d accel / d v, nv x nv each."""

_EPS = np.finfo(float).eps
_SAFETY = 0.9
_MIN_FACTOR = 0.2  # largest allowed step decrease after a rejection
_MAX_FACTOR = 10.0  # largest allowed step increase


# --------------------------------------------------------------------------
# Lie groups
# --------------------------------------------------------------------------


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
        return q + dq

    def difference(self, q0: np.ndarray, q1: np.ndarray) -> np.ndarray:
        return q1 - q0

    def chart_velocity(self, q0: np.ndarray, xi: np.ndarray, v: np.ndarray) -> np.ndarray:
        return np.array(v, dtype=float)

    def tangent_velocity(self, q0: np.ndarray, xi: np.ndarray, xi_dot: np.ndarray) -> np.ndarray:
        return np.array(xi_dot, dtype=float)

    def velocity_jacobian_q(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        return np.zeros((self.nv, self.nv))

    def magnitude(self, q: np.ndarray) -> np.ndarray:
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
        return self._pin.integrate(self.model, q, dq)

    def difference(self, q0: np.ndarray, q1: np.ndarray) -> np.ndarray:
        return self._pin.difference(self.model, q0, q1)

    def chart_velocity(self, q0: np.ndarray, xi: np.ndarray, v: np.ndarray) -> np.ndarray:
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
                for m in ("integrate", "difference", "chart_velocity", "tangent_velocity",
                          "velocity_jacobian_q", "magnitude")
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


# --------------------------------------------------------------------------
# Dense output
# --------------------------------------------------------------------------


class DenseOutput:
    """Interpolant of one accepted step on ``[t_old, t]``.

    Stores ``y(x) = y_old + sum_k coef[k-1] x^k`` with ``x = (t - t_old)/h`` in
    the step's chart (``y = (xi, v)``, or ``(q, v)`` on a vector space). It owns
    its data, so it stays valid after further steps.

    Attributes:
        t_old: start of the step (s).
        t: end of the valid interval (s); lowered by `Stepper.truncate`.
    """

    __slots__ = ("t_old", "t", "h", "_y_old", "_coef", "_pow", "_group", "_q_base", "_nv")

    def __init__(self, t_old, t, h, y_old, coef, group, q_base, nv):
        self.t_old, self.t, self.h = t_old, t, h
        self._y_old, self._coef = y_old, coef
        self._pow = np.arange(1, coef.shape[0] + 1, dtype=float)
        self._group, self._q_base, self._nv = group, q_base, nv  # group None: vector space

    def _y(self, t):
        x = (np.asarray(t, dtype=float) - self.t_old) / self.h
        if x.ndim == 0:
            return self._y_old + (x**self._pow) @ self._coef
        return self._y_old + (x[:, None] ** self._pow) @ self._coef

    def _dy(self, t):
        x = (np.asarray(t, dtype=float) - self.t_old) / self.h
        p = self._pow
        if x.ndim == 0:
            return (p * x ** (p - 1)) @ self._coef / self.h
        return (p * x[:, None] ** (p - 1)) @ self._coef / self.h

    def __call__(self, t):
        """State at ``t``.

        Args:
            t: time (s), scalar or 1-D array (k,), normally in ``[t_old, t]``.

        Returns:
            ``(q, v)``: (nq,), (nv,) for scalar ``t``; (k, nq), (k, nv) for an array.
        """
        y = self._y(t)
        nv = self._nv
        if self._group is None:
            return y[..., :nv], y[..., nv:]
        if y.ndim == 1:
            return self._group.integrate(self._q_base, y[:nv]), y[nv:]
        q = np.array([self._group.integrate(self._q_base, yi[:nv]) for yi in y])
        return q, y[:, nv:]

    def derivative(self, t):
        """Time derivative of the interpolant at scalar ``t``.

        Returns:
            ``(qdot, vdot)``: ``qdot`` (nv,) is the velocity of the dense curve
            ``q(t)`` in Pinocchio's tangent convention (equals the interpolated
            ``v`` up to the integration error); ``vdot`` (nv,) its acceleration.
        """
        dy = self._dy(t)
        nv = self._nv
        if self._group is None:
            return dy[:nv], dy[nv:]
        xi = self._y(t)[:nv]
        return self._group.tangent_velocity(self._q_base, xi, dy[:nv]), dy[nv:]


class LazyDenseOutput(DenseOutput):
    """A `DenseOutput` whose coefficients are computed on first use.

    DOP853's interpolant needs three extra vector-field evaluations; a caller
    that keeps every step's interpolant but reads few of them (the hybrid loop
    reads one only where a guard may cross) skips that work for the others.
    ``build()`` returns the coefficients from a snapshot of the step.
    """

    __slots__ = ("_build",)

    def __init__(self, t_old, t, h, y_old, build, group, q_base, nv):
        self.t_old, self.t, self.h = t_old, t, h
        self._y_old, self._coef, self._pow, self._build = y_old, None, None, build
        self._group, self._q_base, self._nv = group, q_base, nv

    def _ready(self) -> None:
        if self._coef is None:
            self._coef = self._build()
            self._pow = np.arange(1, self._coef.shape[0] + 1, dtype=float)
            self._build = None

    def _y(self, t):
        self._ready()
        return DenseOutput._y(self, t)

    def _dy(self, t):
        self._ready()
        return DenseOutput._dy(self, t)


# --------------------------------------------------------------------------
# Input validation helpers
# --------------------------------------------------------------------------


def _scalar(name: str, x, *, allow_inf: bool = False) -> float:
    try:
        val = float(x)
    except (TypeError, ValueError):
        raise InvalidInputError(f"{name} must be a real number, got {x!r}") from None
    if math.isnan(val) or (math.isinf(val) and not allow_inf):
        raise InvalidInputError(f"{name} must be finite, got {x!r}")
    return val


def _vector(name: str, x, n: int) -> np.ndarray:
    try:
        arr = np.array(x, dtype=float)
    except (TypeError, ValueError):
        raise InvalidInputError(f"{name} must be a real vector of length {n}, got {x!r}") from None
    if arr.shape != (n,):
        raise InvalidInputError(f"{name} must have shape ({n},), got shape {arr.shape}")
    if not np.isfinite(arr).all():
        bad = np.flatnonzero(~np.isfinite(arr))
        raise InvalidInputError(f"{name} must be finite; entries {bad.tolist()} are {arr[bad].tolist()}")
    return arr


def _combine(weights: np.ndarray, stack: np.ndarray) -> np.ndarray:
    """``sum_s weights[s] stack[s]`` for a stack of matrices, as one matrix-vector
    product (``np.tensordot``'s Python-level reshaping costs more at these sizes)."""
    return (weights @ stack.reshape(len(weights), -1)).reshape(stack.shape[1:])


def _rms(x: np.ndarray) -> float:
    return math.sqrt(float(np.vdot(x, x)) / x.size)


def _rms_cols(x: np.ndarray) -> float:
    """Largest RMS over the rows of a column of ``x`` (n x m); inf if not finite."""
    err = math.sqrt(float(np.max(np.einsum("ij,ij->j", x, x))) / x.shape[0])
    return err if math.isfinite(err) else math.inf


# --------------------------------------------------------------------------
# Base stepper
# --------------------------------------------------------------------------


class Stepper:
    """One-step integrator with error control and dense output (base class).

    Args:
        accel: ``accel(t, q, v) -> dv/dt`` (nv,).
        group: configuration space (`VectorSpace`, `PinocchioGroup`) or a
            ``pinocchio.Model``.
        t0: initial time (s).
        q0: initial configuration (nq,).
        v0: initial velocity (nv,).
        rtol: relative tolerance (>= 100 eps).
        atol: absolute tolerance, scalar or (2nv,) for ``(δq, δv)``, > 0.
            The error of a step is the RMS norm of the local error in
            ``(xi, v)`` divided by ``atol + rtol * |y|`` (scipy's norm).
        jac: ``jac(t, q, v) -> (J_q, J_v)``; needed for ``variational``; for
            `Radau` a forward-difference Jacobian is used when omitted.
        first_step: initial step (s); None selects it (Hairer's heuristic).
        max_step: largest step (s).
        t_bound: steps never go beyond this time (s).
        variational: initial flow Jacobian ``phi`` (2nv x m) to propagate with
            the same steps, or None.
        variational_error_control: with ``variational``, also control the
            local error of ``phi`` ("full error control", as CVODES'
            ``errconS``): every attempted step computes the stage increments
            of ``phi``, forms the method's embedded error estimate for them and
            is accepted only if both the state's and ``phi``'s error norms are
            <= 1; the step size is chosen from the larger. Without it the steps
            are chosen for the state alone, which can be far too long for
            ``phi`` when the state is easy but its linearisation is not (a
            spring at its rest length along the trajectory, free motion on a
            Lie group). It never changes how ``phi`` is propagated (on vector
            spaces ``phi`` stays the exact derivative of the discrete flow),
            only which steps are accepted.
        variational_atol: absolute tolerance of ``phi``, scalar or (2nv,) per
            row; None uses ``atol`` per row. Each column of ``phi`` is the
            response ``(δq, δv)`` to a unit initial perturbation, so its rows
            carry the state's units and the state's ``atol`` is the natural
            absolute floor (CVODES' default ``atolS = atol / pbar`` with
            ``pbar = 1``). The error of ``phi`` is the RMS over the rows of
            each column of its local error divided by
            ``variational_atol + rtol * |phi|`` (entrywise), maximised over
            the columns (CVODES' norm for a set of sensitivities).

    Attributes:
        t, q, v, phi: current time, state and flow Jacobian (phi None if off).
        t_old, q_old, v_old, phi_old: the same at the start of the last step.
        n_steps, n_rejected, n_accel, n_jac: accepted steps, rejected step
            attempts, calls of ``accel`` and Jacobian evaluations.
    """

    method: str = ""
    error_order: int = 0  # error ~ h^(error_order + 1); for the first-step heuristic

    def __init__(
        self,
        accel: AccelFn,
        group,
        t0: float,
        q0,
        v0,
        *,
        rtol: float = 1e-6,
        atol=1e-9,
        jac: JacFn | None = None,
        first_step: float | None = None,
        max_step: float = np.inf,
        t_bound: float = np.inf,
        variational=None,
        variational_error_control: bool = True,
        variational_atol=None,
    ) -> None:
        if not callable(accel):
            raise InvalidInputError(f"accel must be callable accel(t, q, v), got {accel!r}")
        if jac is not None and not callable(jac):
            raise InvalidInputError(f"jac must be callable jac(t, q, v) -> (J_q, J_v) or None, got {jac!r}")
        self.group = _as_group(group)
        self.nq, self.nv = int(self.group.nq), int(self.group.nv)
        if self.nv < 1:
            raise InvalidInputError(f"group must have nv >= 1, got nv={self.nv}")
        self.n = 2 * self.nv
        self._vs = bool(self.group.is_vector_space)
        self.accel, self.jac = accel, jac

        t0 = _scalar("t0", t0)
        self.q = _vector("q0", q0, self.nq)
        self.v = _vector("v0", v0, self.nv)
        rtol = _scalar("rtol", rtol)
        if rtol < 100 * _EPS:
            raise InvalidInputError(f"rtol must be >= 100*eps = {100 * _EPS:.3g}, got {rtol!r}")
        self.rtol = rtol
        atol_arr = np.array(atol, dtype=float)
        if atol_arr.shape not in ((), (self.n,)):
            raise InvalidInputError(f"atol must be a scalar or have shape ({self.n},), got shape {atol_arr.shape}")
        if not (np.isfinite(atol_arr).all() and (atol_arr > 0).all()):
            raise InvalidInputError(f"atol must be positive and finite, got {atol!r}")
        self.atol = float(atol_arr) if atol_arr.ndim == 0 else atol_arr
        self.max_step = _scalar("max_step", max_step, allow_inf=True)
        if not self.max_step > 0:
            raise InvalidInputError(f"max_step must be > 0, got {max_step!r}")
        self.t_bound = _scalar("t_bound", t_bound, allow_inf=True)
        if self.t_bound < t0:
            raise InvalidInputError(f"t_bound must be >= t0 = {t0!r} (forward integration only), got {t_bound!r}")
        self.variational_error_control = bool(variational_error_control)
        if variational_atol is None:
            self._atol_phi = self.atol if atol_arr.ndim == 0 else self.atol[:, None]
        else:
            va = np.array(variational_atol, dtype=float)
            if va.shape not in ((), (self.n,)):
                raise InvalidInputError(
                    f"variational_atol must be a scalar or have shape ({self.n},), got shape {va.shape}")
            if not (np.isfinite(va).all() and (va > 0).all()):
                raise InvalidInputError(f"variational_atol must be positive and finite, got {variational_atol!r}")
            self._atol_phi = float(va) if va.ndim == 0 else va[:, None]
        self.t = t0
        self.phi = None if variational is None else self._check_phi(variational)

        self.n_steps = self.n_rejected = self.n_accel = self.n_jac = 0
        self.t_old = self.q_old = self.v_old = self.phi_old = None
        self._y = self._point_y(self.q, self.v)
        self._f = self._point_f(self.t, self.q, self.v)
        self._setup()
        if first_step is None:
            self.h_abs = self._initial_step()
        else:
            self.h_abs = _scalar("first_step", first_step)
            if self.h_abs <= 0:
                raise InvalidInputError(f"first_step must be > 0, got {first_step!r}")

    # -- public API ---------------------------------------------------------

    @property
    def h_next(self) -> float:
        """Size of the next step to try (s)."""
        return min(self.h_abs, self.max_step)

    def step(self) -> None:
        """Take one accepted step (retrying internally after rejections).

        Raises:
            IntegrationError: step-size underflow, Newton failure, ``t`` already
                at ``t_bound``, or non-finite ``accel``/``jac`` output.
        """
        raise NotImplementedError

    def dense(self, lazy: bool = False) -> DenseOutput:
        """Interpolant of the last step on ``[t_old, t]``; with ``lazy`` any extra
        vector-field evaluations it needs are deferred until it is first read."""
        raise NotImplementedError

    def truncate(self, t: float) -> None:
        """Keep the last step only up to ``t`` (an event time).

        The state becomes the dense output at ``t`` exactly (so a guard located
        on the dense output is zero at the new state). With a flow Jacobian,
        the step is re-taken with ``h = t - t_old`` from the step's start and
        the variational equation is propagated over it; its state differs from
        the dense value by the local error only (O(tol)), which is negligible
        for the Jacobian.

        Args:
            t: time in ``[t_old, t]`` of the last step (s).
        """
        if self.t_old is None:
            raise InvalidInputError("truncate() needs a step taken since the last (re)start")
        t = _scalar("t", t)
        if not self.t_old <= t <= self.t:
            raise InvalidInputError(f"truncate time t={t!r} is outside the last step [{self.t_old!r}, {self.t!r}]")
        if t == self.t:
            return
        dense = self.dense()
        if t == self.t_old:
            q, v = self.q_old, self.v_old
        else:
            q, v = dense(t)
            q, v = np.array(q), np.array(v)
        if self.phi is not None:
            self.phi = self.phi_old if t == self.t_old else self._redo_variational(t - self.t_old)
        dense.t = t
        self.t, self.q, self.v = t, q, v
        self._y = self._point_y(q, v)
        self._f = self._point_f(t, q, v)
        self._after_truncate()

    def restart(self, t: float, q, v, phi=None, *, accel: AccelFn | None = None, jac: JacFn | None = None,
                t_bound: float | None = None) -> None:
        """Start again from a new state (after a jump or a mode change).

        The step-size estimate is kept; Jacobian, LU factors and the dense
        output of the previous step are dropped.

        Args:
            t: time (s).
            q: configuration (nq,).
            v: velocity (nv,).
            phi: new flow Jacobian (2nv x m), e.g. ``Xi @ stepper.phi``; None
                keeps the current one (an identity jump).
            accel: new vector field (mode change); None keeps the current one.
            jac: new Jacobian callback; None keeps the current one.
            t_bound: new bound (s); None keeps the current one.
        """
        if accel is not None:
            if not callable(accel):
                raise InvalidInputError(f"accel must be callable accel(t, q, v), got {accel!r}")
            self.accel = accel
        if jac is not None:
            if not callable(jac):
                raise InvalidInputError(f"jac must be callable jac(t, q, v) -> (J_q, J_v), got {jac!r}")
            self.jac = jac
        t = _scalar("t", t)
        q = _vector("q", q, self.nq)
        v = _vector("v", v, self.nv)
        if t_bound is not None:
            self.t_bound = _scalar("t_bound", t_bound, allow_inf=True)
        if self.t_bound < t:
            raise InvalidInputError(f"t_bound = {self.t_bound!r} is before the restart time t = {t!r}")
        if phi is not None:
            self.phi = self._check_phi(phi)
        self.t, self.q, self.v = t, q, v
        self.t_old = self.q_old = self.v_old = self.phi_old = None
        self._y = self._point_y(q, v)
        self._f = self._point_f(t, q, v)
        self._after_restart()

    # -- hooks for subclasses -------------------------------------------------

    def _setup(self) -> None:
        pass

    def _after_truncate(self) -> None:
        pass

    def _after_restart(self) -> None:
        pass

    def _redo_variational(self, h: float) -> np.ndarray:
        raise NotImplementedError

    # -- shared machinery -----------------------------------------------------

    def _check_phi(self, phi) -> np.ndarray:
        if self.jac is None:
            raise InvalidInputError("a flow Jacobian (variational/phi) needs jac(t, q, v) -> (J_q, J_v)")
        arr = np.array(phi, dtype=float)
        if arr.ndim != 2 or arr.shape[0] != self.n:
            raise InvalidInputError(f"phi must have shape ({self.n}, m), got shape {arr.shape}")
        if not np.isfinite(arr).all():
            raise InvalidInputError("phi must be finite")
        return arr

    def _point_y(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``y`` of a point in its own chart: ``(q, v)`` or ``(0, v)``."""
        if self._vs:
            return np.concatenate((q, v))
        y = np.zeros(self.n)
        y[self.nv :] = v
        return y

    def _point_f(self, t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``dy/dt = (v, accel)`` at a point in its own chart (validates ``accel``)."""
        a = self.accel(t, q, v)
        self.n_accel += 1
        a = np.asarray(a, dtype=float)
        if a.shape != (self.nv,):
            raise InvalidInputError(f"accel must return shape ({self.nv},), got shape {a.shape}")
        if not np.isfinite(a).all():
            raise IntegrationError(f"accel returned non-finite values at t={float(t)!r}: {a.tolist()}")
        return np.concatenate((v, a))

    def _mag(self, y: np.ndarray, q: np.ndarray | None) -> np.ndarray:
        """Sizes that ``rtol`` is relative to, per component of ``y``."""
        if self._vs:
            return np.abs(y)
        return np.concatenate((self.group.magnitude(q), np.abs(y[self.nv :])))

    def _eval_into(self, t: float, y: np.ndarray, out: np.ndarray, qc, accel=None) -> np.ndarray:
        """Write ``F(t, y)`` in the chart at ``qc`` (None: vector space) into ``out``; return the stage ``q``.

        ``accel`` overrides the current vector field (a lazy interpolant evaluates
        the field of the step it belongs to)."""
        nv = self.nv
        v = y[nv:]
        if qc is None:
            q = y[:nv]
            out[:nv] = v
        else:
            xi = y[:nv]
            q = self.group.integrate(qc, xi)
            out[:nv] = self.group.chart_velocity(qc, xi, v)
        out[nv:] = (self.accel if accel is None else accel)(t, q, v)
        self.n_accel += 1
        return q

    def _nonfinite_stage(self, t: float, y: np.ndarray, fa: np.ndarray) -> None:
        """Raise if ``accel`` returned non-finite values for a finite state."""
        if not np.isfinite(fa).all() and np.isfinite(y).all():
            raise IntegrationError(
                f"accel returned non-finite values at t={float(t)!r} (v={y[self.nv:].tolist()}); "
                "the vector field must be finite at every finite state"
            )

    def _call_jac(self, t: float, q: np.ndarray, v: np.ndarray):
        """``(J_q, J_v)`` from the user's callback, or forward differences if none."""
        self.n_jac += 1
        if self.jac is None:
            return self._fd_jac(t, q, v)
        Jq, Jv = self.jac(t, q, v)
        Jq = np.asarray(Jq, dtype=float)
        Jv = np.asarray(Jv, dtype=float)
        shape = (self.nv, self.nv)
        if Jq.shape != shape or Jv.shape != shape:
            raise InvalidInputError(f"jac must return two {shape} arrays, got shapes {Jq.shape} and {Jv.shape}")
        if not math.isfinite(Jq.sum() + Jv.sum()):  # one reduction; a sum is NaN/inf iff an entry is (or overflows)
            raise IntegrationError(f"jac returned non-finite values at t={float(t)!r}")
        return Jq, Jv

    def _fd_jac(self, t: float, q: np.ndarray, v: np.ndarray):
        """Forward differences in the tangent space (only for Radau's Newton matrix)."""
        nv = self.nv
        a0 = np.asarray(self.accel(t, q, v), dtype=float)
        Jq, Jv = np.empty((nv, nv)), np.empty((nv, nv))
        mq = np.abs(q[:nv]) if self._vs else self.group.magnitude(q)
        for k in range(nv):
            e = math.sqrt(_EPS) * max(1.0, mq[k])
            dq = np.zeros(nv)
            dq[k] = e
            qk = q + dq if self._vs else self.group.integrate(q, dq)
            Jq[:, k] = (np.asarray(self.accel(t, qk, v), dtype=float) - a0) / e
            e = math.sqrt(_EPS) * max(1.0, abs(v[k]))
            vk = v.copy()
            vk[k] += e
            Jv[:, k] = (np.asarray(self.accel(t, q, vk), dtype=float) - a0) / e
        self.n_accel += 1 + 2 * nv
        return Jq, Jv

    def _df(self, t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Full tangent-space Jacobian ``[[G, I], [J_q, J_v]]`` (2nv x 2nv) of the flow."""
        nv = self.nv
        Jq, Jv = self._call_jac(t, q, v)
        A = np.zeros((self.n, self.n))
        A[:nv, nv:] = np.eye(nv)
        if not self._vs:
            A[:nv, :nv] = self.group.velocity_jacobian_q(q, v)
        A[nv:, :nv] = Jq
        A[nv:, nv:] = Jv
        return A

    def _stage_df(self, t: float, q: np.ndarray, v: np.ndarray):
        """``(J_q, J_v, G)`` of the tangent-space field at a point; ``G = -ad(v)`` (None on vector spaces)."""
        Jq, Jv = self._call_jac(t, q, v)
        return Jq, Jv, None if self._vs else self.group.velocity_jacobian_q(q, v)

    def _df_apply(self, df, P: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """``[[G, I], [J_q, J_v]] @ P`` for ``df = (J_q, J_v, G)``, into ``out`` if given."""
        Jq, Jv, G = df
        nv = self.nv
        if out is None:
            out = np.empty(P.shape)
        top, bot = P[:nv], P[nv:]
        out[:nv] = bot
        if G is not None:
            out[:nv] += G @ top
        out[nv:] = Jq @ top + Jv @ bot
        return out

    def _phi_scale(self, P0: np.ndarray, P1: np.ndarray) -> np.ndarray:
        """Entrywise ``variational_atol + rtol * max(|phi_n|, |phi_n+1|)``."""
        return self._atol_phi + self.rtol * np.maximum(np.abs(P0), np.abs(P1))

    def _initial_step(self) -> float:
        """Hairer–Nørsett–Wanner's starting step (as scipy's ``select_initial_step``)."""
        interval = self.t_bound - self.t
        if interval == 0.0:
            return min(1.0, self.max_step)  # nothing to integrate; any positive value
        y0, f0 = self._y, self._f
        scale = self.atol + self.rtol * self._mag(y0, self.q)
        d0 = _rms(self._mag(y0, self.q) / scale)
        d1 = _rms(f0 / scale)
        h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
        h0 = min(h0, interval)
        y1 = y0 + h0 * f0
        f1 = np.empty(self.n)
        self._eval_into(self.t + h0, y1, f1, None if self._vs else self.q)
        self._nonfinite_stage(self.t + h0, y1, f1[self.nv :])
        d2 = _rms((f1 - f0) / scale) / h0
        if d1 <= 1e-15 and d2 <= 1e-15:
            h1 = max(1e-6, h0 * 1e-3)
        else:
            h1 = (0.01 / max(d1, d2)) ** (1.0 / (self.error_order + 1))
        return min(100 * h0, h1, interval, self.max_step)

    def _begin_step(self) -> tuple[float, float]:
        """Check that a step is possible; return (min_step, first h to try)."""
        t = self.t
        if t >= self.t_bound:
            raise IntegrationError(f"cannot step: t = {t!r} is already at t_bound = {self.t_bound!r}")
        min_step = 10.0 * abs(np.nextafter(t, np.inf) - t)
        return min_step, max(min(self.h_abs, self.max_step), min_step)

    def _underflow(self, h_abs: float, min_step: float) -> IntegrationError:
        return IntegrationError(
            f"{self.method}: step size underflow at t={float(self.t)!r}: h={h_abs:.3g} < {min_step:.3g} "
            f"(rtol={self.rtol:g}); the vector field may be singular or non-smooth here"
        )

    def _accept_state(self, t_new: float, y_new: np.ndarray, q_new: np.ndarray, a_new: np.ndarray) -> None:
        """Move the current point to the end of the accepted step."""
        self.t_old, self.q_old, self.v_old, self.phi_old = self.t, self.q, self.v, self.phi
        self.t = t_new
        nv = self.nv
        if self._vs:
            self._y = y_new
            self.q, self.v = y_new[:nv], y_new[nv:]
        else:
            self.q, self.v = q_new, y_new[nv:]
            self._y = self._point_y(q_new, self.v)
        self._f = np.concatenate((self.v, a_new))
        self.n_steps += 1


# --------------------------------------------------------------------------
# Explicit Runge–Kutta
# --------------------------------------------------------------------------


class ExplicitRK(Stepper):
    """Explicit embedded Runge–Kutta pair with FSAL (base of `RK45`, `DOP853`).

    The flow Jacobian is propagated by applying the same Runge–Kutta stages to
    the variational equation, ``K_i = DF(x_i) (phi_n + h sum_j a_ij K_j)`` with
    ``DF`` at each stage's state (for vector spaces this is the exact
    derivative of the discrete step).

    With ``variational_error_control`` these stage increments are computed in
    every attempt whose state error passes (a rejection on the state alone
    costs no Jacobian), and the pair's embedded error formula is applied to
    them. ``DF`` at the step's start is evaluated once per step (not once per
    attempt); when the error formula weights the FSAL stage (RK45) its
    ``DF(x_{n+1})`` is reused as the next step's first stage.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    n_stages: int
    n_rows: int  # rows of the stage buffer (stages + FSAL + dense-output extras)

    def _setup(self) -> None:
        self._K = np.empty((self.n_rows, self.n))
        self._dense_cache: DenseOutput | None = None
        self._f_old = self._y_old = self._qc_old = self._y_end = None
        self._h_last = 0.0
        self._KP: np.ndarray | None = None  # stage increments of phi, (n_stages + 1, n, m)
        self._df_start = None  # DF at the current point (t, y), when known
        # stages the error formula uses: the FSAL stage only if it has a nonzero weight
        self._n_err = self.n_stages + int(any(e[self.n_stages] != 0 for e in self._error_weights()))

    def _error_weights(self) -> tuple[np.ndarray, ...]:
        return (self.E,)

    def _stages(self, t: float, y: np.ndarray, h: float, qc):
        """Stages of one attempt; ``K[n_stages]`` is ``F(t + h, y_new)`` (FSAL)."""
        K, C, ns, nv = self._K, self.C, self.n_stages, self.nv
        hA = h * self.A
        ys = [y]
        if qc is None:  # vector-space fast path, inlined (this loop dominates the cost)
            accel = self.accel
            qs = [y[:nv]]
            for s in range(1, ns):
                ys_s = y + hA[s, :s].dot(K[:s])
                v = ys_s[nv:]
                K[s, :nv] = v
                K[s, nv:] = accel(t + C[s] * h, ys_s[:nv], v)
                ys.append(ys_s)
                qs.append(ys_s[:nv])
            self.n_accel += ns - 1
        else:
            qs = [qc]
            for s in range(1, ns):
                ys_s = y + hA[s, :s].dot(K[:s])
                qs.append(self._eval_into(t + C[s] * h, ys_s, K[s], qc))
                ys.append(ys_s)
        y_new = y + (h * self.B).dot(K[:ns])
        q_new = self._eval_into(t + h, y_new, K[ns], qc)
        return y_new, q_new, ys, qs

    def _error_norm(self, h: float, K: np.ndarray, scale: np.ndarray) -> float:
        return _rms(h * (self.E @ K[: self.n_stages + 1]) / scale)

    def _phi_error_norm(self, h: float, KP: np.ndarray, scale: np.ndarray) -> float:
        """`_error_norm` applied to each column of phi's stage increments (max over columns)."""
        ne = self._n_err
        return _rms_cols(_combine(h * self.E[:ne], KP[:ne]) / scale)

    def _controlled_variational(self, t, h, ys, qs, t_new, y_new, q_new):
        """phi_{n+1} of an attempt and its error norm; the end point's DF, if evaluated, is kept."""
        P0, nv, ns = self.phi, self.nv, self.n_stages
        KP = self._KP
        if KP is None or KP.shape[2] != P0.shape[1]:
            KP = self._KP = np.empty((ns + 1, self.n, P0.shape[1]))
        if self._df_start is None:
            self._df_start = self._stage_df(t, qs[0], ys[0][nv:])
        phi_new = self._variational(t, h, ys, qs, P0, KP, self._df_start)
        df_end = None
        if self._n_err > ns:
            df_end = self._stage_df(t_new, q_new, y_new[nv:])
            self._df_apply(df_end, phi_new, KP[ns])
        err = self._phi_error_norm(h, KP, self._phi_scale(P0, phi_new))
        return phi_new, err, df_end

    def step(self) -> None:
        min_step, h_abs = self._begin_step()
        t, y = self.t, self._y
        qc = None if self._vs else self.q
        nv, ns, K = self.nv, self.n_stages, self._K
        K[0] = self._f
        mag_n = self._mag(y, qc)
        exponent = -1.0 / (self.error_order + 1)
        control = self.phi is not None and self.variational_error_control
        phi_new = df_end = None
        rejected = False
        while True:
            if h_abs < min_step:
                raise self._underflow(h_abs, min_step)
            t_new = min(t + h_abs, self.t_bound)
            h = t_new - t
            y_new, q_new, ys, qs = self._stages(t, y, h, qc)
            scale = self.atol + self.rtol * np.maximum(mag_n, self._mag(y_new, q_new))
            err = self._error_norm(h, K, scale)
            if not math.isfinite(err):
                for s in range(1, ns + 1):  # name the culprit if accel itself returned inf/nan
                    self._nonfinite_stage(t + self.C[s] * h if s < ns else t_new,
                                          ys[s] if s < ns else y_new, K[s, nv:])
                err = math.inf  # overflow of a too-large step: reject it
            if control and err < 1.0:
                phi_new, err_phi, df_end = self._controlled_variational(t, h, ys, qs, t_new, y_new, q_new)
                err = max(err, err_phi)
            if err < 1.0:
                factor = _MAX_FACTOR if err == 0 else min(_MAX_FACTOR, _SAFETY * err**exponent)
                if rejected:
                    factor = min(1.0, factor)
                h_abs = h * factor
                break
            h_abs = h * max(_MIN_FACTOR, _SAFETY * err**exponent if math.isfinite(err) else 0.0)
            rejected = True
            self.n_rejected += 1

        if self.phi is not None and not control:
            phi_new = self._variational(t, h, ys, qs, self.phi)
        self._df_start = df_end  # DF at the new point if the error formula needed it, else unknown
        # Kept for dense output and truncate(): the step's start, its chart and its end in that chart.
        self._y_old, self._f_old, self._qc_old, self._h_last, self._y_end = y, self._f, qc, h, y_new
        self._dense_cache = None
        self._accept_state(t_new, y_new, q_new, K[ns, nv:].copy())
        self.phi = phi_new
        self.h_abs = h_abs

    def _variational(self, t: float, h: float, ys, qs, P0: np.ndarray, KP: np.ndarray | None = None,
                     df0=None) -> np.ndarray:
        """phi_{n+1}; the stage increments go to ``KP[:n_stages]``; ``df0``: DF at the first stage if known."""
        nv, ns = self.nv, self.n_stages
        hA, hB, C = h * self.A, h * self.B, self.C
        if KP is None:
            KP = np.empty((ns, self.n, P0.shape[1]))
        for s in range(ns):
            Ps = P0 + _combine(hA[s, :s], KP[:s]) if s else P0
            df = df0 if s == 0 and df0 is not None else self._stage_df(t + C[s] * h, qs[s], ys[s][nv:])
            self._df_apply(df, Ps, KP[s])
        return P0 + _combine(hB, KP[:ns])

    def _redo_variational(self, h: float) -> np.ndarray:
        self._K[0] = self._f_old
        _, _, ys, qs = self._stages(self.t_old, self._y_old, h, self._qc_old)
        return self._variational(self.t_old, h, ys, qs, self.phi_old)

    def dense(self, lazy: bool = False) -> DenseOutput:
        """Interpolant of the last step; ``lazy`` defers its extra work to first use."""
        if self.t_old is None:
            raise InvalidInputError("dense() needs a step taken since the last (re)start")
        if self._dense_cache is not None:
            return self._dense_cache
        group = None if self._vs else self.group
        if not lazy:
            self._dense_cache = DenseOutput(self.t_old, self.t, self._h_last, self._y_old,
                                            self._dense_coef(), group, self._qc_old, self.nv)
            return self._dense_cache
        step = (self._K.copy(), self._h_last, self._y_old, self._y_end.copy(), self._qc_old,
                self.t_old, self.accel)
        return LazyDenseOutput(self.t_old, self.t, self._h_last, self._y_old,
                               lambda: self._coef_from(*step), group, self._qc_old, self.nv)

    def _dense_coef(self) -> np.ndarray:
        """Monomial coefficients (degree x n) of the last step's interpolant, x in [0, 1]."""
        return self._coef_from(self._K, self._h_last, self._y_old, self._y_end, self._qc_old,
                               self.t_old, None)

    def _coef_from(self, K, h, y_old, y_end, qc, t_old, accel) -> np.ndarray:
        """Interpolant coefficients from a step's stages ``K`` (extra rows may be written)."""
        raise NotImplementedError

    def _after_truncate(self) -> None:
        self._df_start = None

    def _after_restart(self) -> None:
        self._dense_cache = None
        self._df_start = None


class RK45(ExplicitRK):
    """Dormand–Prince 5(4) with FSAL and its quartic dense output (scipy's coefficients)."""

    method = "RK45"
    error_order = 4
    n_stages = 6
    n_rows = 7

    A, B, C, E, P = _SciRK45.A, _SciRK45.B, _SciRK45.C, _SciRK45.E, _SciRK45.P

    def _coef_from(self, K, h, y_old, y_end, qc, t_old, accel) -> np.ndarray:
        return h * (self.P.T @ K)


class DOP853(ExplicitRK):
    """Dormand–Prince 8(5,3) with FSAL and its 7th-order dense output.

    Coefficients are scipy's (``scipy/integrate/_ivp/dop853_coefficients.py``);
    the error estimate combines the 5th- and 3rd-order embedded formulas as in
    Hairer's DOP853. The three extra stages of the dense output are only
    evaluated when `dense` is called.
    """

    method = "DOP853"
    error_order = 7
    n_stages = _dop.N_STAGES
    n_rows = _dop.N_STAGES_EXTENDED
    A = _dop.A[: _dop.N_STAGES, : _dop.N_STAGES]
    A_FULL = _dop.A
    B = _dop.B
    C = _dop.C
    E3 = _dop.E3
    E5 = _dop.E5
    D = _dop.D

    def _error_weights(self) -> tuple[np.ndarray, ...]:
        return (self.E5, self.E3)

    def _error_norm(self, h: float, K: np.ndarray, scale: np.ndarray) -> float:
        Ks = K[: self.n_stages + 1]
        err5 = (self.E5 @ Ks) / scale
        err3 = (self.E3 @ Ks) / scale
        e5 = float(err5 @ err5)
        e3 = float(err3 @ err3)
        if e5 == 0.0 and e3 == 0.0:
            return 0.0
        return abs(h) * e5 / math.sqrt((e5 + 0.01 * e3) * self.n)

    def _phi_error_norm(self, h: float, KP: np.ndarray, scale: np.ndarray) -> float:
        """Hairer's 5(3) combination per column of phi (RMS over its rows), max over columns."""
        ne = self._n_err
        err5 = _combine(self.E5[:ne], KP[:ne]) / scale
        err3 = _combine(self.E3[:ne], KP[:ne]) / scale
        e5 = np.einsum("ij,ij->j", err5, err5)
        den = (e5 + 0.01 * np.einsum("ij,ij->j", err3, err3)) * self.n
        if not np.isfinite(den).all():
            return math.inf
        pos = den > 0.0
        if not pos.any():
            return 0.0
        return abs(h) * float(np.max(e5[pos] / np.sqrt(den[pos])))

    def _coef_from(self, K, h, y_old, y_end, qc, t_old, accel) -> np.ndarray:
        A, C = self.A_FULL, self.C
        for s in range(self.n_stages + 1, self.n_rows):
            ys = y_old + (h * A[s, :s]) @ K[:s]
            self._eval_into(t_old + C[s] * h, ys, K[s], qc, accel)
            self._nonfinite_stage(t_old + C[s] * h, ys, K[s, self.nv :])
        f_old, f_new = K[0], K[self.n_stages]
        dy = y_end - y_old
        F = [dy, h * f_old - dy, 2 * dy - h * (f_new + f_old), *(h * (self.D @ K))]
        # Expand y_old + x(F0 + (1-x)(F1 + x(F2 + (1-x)(F3 + ...)))) into monomials of x.
        c = np.zeros((len(F) + 1, self.n))
        for i, f in enumerate(reversed(F)):
            c[0] += f
            if i % 2 == 0:
                c[1:] = c[:-1].copy()
                c[0] = 0.0
            else:
                c[1:] = c[1:] - c[:-1]
        return c[1:]


# --------------------------------------------------------------------------
# Radau IIA (order 5)
# --------------------------------------------------------------------------

_S6 = 6**0.5
_RC = np.array([(4 - _S6) / 10, (4 + _S6) / 10, 1.0])
_RA = np.array([
    [(88 - 7 * _S6) / 360, (296 - 169 * _S6) / 1800, (-2 + 3 * _S6) / 225],
    [(296 + 169 * _S6) / 1800, (88 + 7 * _S6) / 360, (-2 - 3 * _S6) / 225],
    [(16 - _S6) / 36, (16 + _S6) / 36, 1 / 9],
])
_RE = np.array([-13 - 7 * _S6, -13 + 7 * _S6, -1]) / 3
# A^-1 = T diag(mu_real, mu_complex pair) T^-1 decouples the Newton systems.
_MU_REAL = 3 + 3 ** (2 / 3) - 3 ** (1 / 3)
_MU_COMPLEX = 3 + 0.5 * (3 ** (1 / 3) - 3 ** (2 / 3)) - 0.5j * (3 ** (5 / 6) + 3 ** (7 / 6))
_RT = np.array([
    [0.09443876248897524, -0.14125529502095421, 0.03002919410514742],
    [0.25021312296533332, 0.20412935229379994, -0.38294211275726192],
    [1, 1, 0],
])
_RTI = np.array([
    [4.17871859155190428, 0.32768282076106237, 0.52337644549944951],
    [-4.17871859155190428, -0.32768282076106237, 0.47662355450055044],
    [0.50287263494578682, -2.57192694985560522, 0.59603920482822492],
])
_RTI_REAL = _RTI[0]
_RTI_COMPLEX = _RTI[1] + 1j * _RTI[2]
# Collocation polynomial in monomials: Z^T P gives y(x) - y_old for x = 1..3 powers.
_RP = np.array([
    [13 / 3 + 7 * _S6 / 3, -23 / 3 - 22 * _S6 / 3, 10 / 3 + 5 * _S6],
    [13 / 3 - 7 * _S6 / 3, -23 / 3 + 22 * _S6 / 3, 10 / 3 - 5 * _S6],
    [1 / 3, -8 / 3, 10 / 3],
])
_NEWTON_MAXITER = 6


def _predict_factor(h_abs, h_abs_old, err, err_old) -> float:
    """Gustafsson's predictive step-size controller (Hairer–Wanner II, IV.8)."""
    if err_old is None or h_abs_old is None or err == 0:
        mult = 1.0
    else:
        mult = h_abs / h_abs_old * (err_old / err) ** 0.25
    return min(1.0, mult) * err**-0.25 if err > 0 else math.inf


class Radau(Stepper):
    """Radau IIA, 3 stages, order 5, for stiff systems (after scipy's ``radau.py``).

    Simplified Newton iterations on the collocation system with the
    transformation to one real and one complex linear system. The Newton
    matrix uses the approximate Jacobian ``[[0, I], [J_q, J_v]]`` of the chart
    field (it neglects d(dxi/dt)/dxi = O(|v|), which only slows Newton
    slightly), so the 2nv systems reduce to nv x nv Schur complements
    ``alpha^2 I - alpha J_v - J_q``. LU factors are reused while ``h`` and the
    Jacobian are unchanged (the controller keeps ``h`` when it would grow by
    less than 20%). Error estimate (3rd order), controller and dense output
    (the cubic collocation polynomial) as in scipy.

    The flow Jacobian differentiates the stage equations:
    ``(I - h (A ⊗ I) diag(DF_j)) dY = 1 ⊗ phi_n``, ``phi_{n+1} = dY_3``, with
    ``DF_j`` at the converged stages (a dense solve of size 6nv).

    That is Radau IIA applied to the linear ODE ``phi' = DF(t) phi`` (``DF``
    sampled at the stages), so with ``variational_error_control`` its own
    embedded estimator applies unchanged to the stage increments
    ``dZ_i = dY_i - phi_n``: ``err_phi = (gamma/h I - J)^-1 (DF_n phi_n +
    sum_i e_i dZ_i / h)``, with the state's LU factors, its filtered variant
    after a rejection, and ``DF_n`` the exact Jacobian at the step's start
    (the previous step's last stage, so no extra evaluation). It is what the
    state's estimator gives for the augmented system ``(y, phi)`` with the
    block-diagonal Newton matrix; ``J`` only filters the estimate, the
    cancellation to ``O(h^4)`` is in the bracket. The 6nv solve and the three
    stage Jacobians are then done per attempt (only for attempts whose state
    error passes) instead of per accepted step.

    Attributes:
        n_lu: number of LU factorisations (pairs).
    """

    method = "Radau"
    error_order = 3

    def _setup(self) -> None:
        self.n_lu = 0
        self.newton_tol = max(10 * _EPS / self.rtol, min(0.03, self.rtol**0.5))
        self._J = self._call_jac(self.t, self.q, self.v)
        self._current_jac = True
        self._lu = None  # (h, J, lu_real, piv_real, lu_complex, piv_complex)
        self._sol: DenseOutput | None = None
        self._h_abs_old = self._err_old = None
        self._y_old = self._qc_old = self._Z = None
        self._df_start = None  # (J_q, J_v, G) at the current point, when known

    # -- linear algebra on (alpha I - [[0, I], [J_q, J_v]]) --------------------

    def _factor(self, h: float, J) -> None:
        Jq, Jv = J
        eye = np.eye(self.nv)
        ar, ac = _MU_REAL / h, _MU_COMPLEX / h
        lur, pivr, info_r = dgetrf(ar * ar * eye - ar * Jv - Jq)
        luc, pivc, info_c = zgetrf(ac * ac * eye - ac * Jv - Jq)
        self.n_lu += 1
        singular = info_r != 0 or info_c != 0
        self._lu = (h, J, lur, pivr, luc, pivc, singular)

    def _solve(self, r: np.ndarray, real: bool) -> np.ndarray:
        """Solve ``(alpha I - J) x = r`` via the Schur complement on the velocity block."""
        h, (Jq, _), lur, pivr, luc, pivc, _ = self._lu
        nv = self.nv
        r1, r2 = r[:nv], r[nv:]
        if real and r.ndim == 2:  # phi's error estimate: one column at a time, because
            # OpenBLAS threads getrs with several right-hand sides, which costs ~0.1 ms a
            # call on small busy machines (10x the whole step in tests)
            alpha = _MU_REAL / h
            b = alpha * r2 + Jq @ r1
            w = np.empty_like(b)
            for j in range(b.shape[1]):
                w[:, j] = dgetrs(lur, pivr, b[:, j])[0]
        elif real:
            alpha = _MU_REAL / h
            w, _ = dgetrs(lur, pivr, alpha * r2 + Jq @ r1)
        else:
            alpha = _MU_COMPLEX / h
            w, _ = zgetrs(luc, pivc, alpha * r2 + Jq @ r1)
        x = np.empty(r.shape, dtype=w.dtype)
        x[:nv] = (r1 + w) / alpha
        x[nv:] = w
        return x

    def _ensure_lu(self, h: float) -> None:
        if self._lu is None or self._lu[0] != h or self._lu[1] is not self._J:
            self._factor(h, self._J)

    # -- Newton on the collocation system ----------------------------------------

    def _newton(self, t: float, y: np.ndarray, h: float, Z0: np.ndarray, scale: np.ndarray, qc):
        if self._lu[6]:
            return False, 1, Z0, None
        nv = self.nv
        Mr, Mc = _MU_REAL / h, _MU_COMPLEX / h
        W = _RTI @ Z0
        Z = Z0
        F = np.empty((3, self.n))
        ch = h * _RC
        dW = np.empty_like(W)
        dW_norm_old = rate = None
        converged = False
        k = 0
        for k in range(_NEWTON_MAXITER):
            for i in range(3):
                self._eval_into(t + ch[i], y + Z[i], F[i], qc)
            if not np.isfinite(F).all():
                for i in range(3):
                    self._nonfinite_stage(t + ch[i], y + Z[i], F[i, nv:])
                break
            f_real = _RTI_REAL @ F - Mr * W[0]
            f_complex = _RTI_COMPLEX @ F - Mc * (W[1] + 1j * W[2])
            dW[0] = self._solve(f_real, True)
            dWc = self._solve(f_complex, False)
            dW[1], dW[2] = dWc.real, dWc.imag
            dW_norm = _rms(dW / scale)
            if dW_norm_old is not None:
                rate = dW_norm / dW_norm_old
            # stop when diverging or when the predicted final error cannot reach newton_tol
            if rate is not None and (
                rate >= 1 or rate ** (_NEWTON_MAXITER - k) / (1 - rate) * dW_norm > self.newton_tol
            ):
                break
            W += dW
            Z = _RT @ W
            if dW_norm == 0 or (rate is not None and rate / (1 - rate) * dW_norm < self.newton_tol):
                converged = True
                break
            dW_norm_old = dW_norm
        return converged, k + 1, Z, rate

    def _predict(self, t: float, h: float, y: np.ndarray, qc) -> np.ndarray:
        """Newton starting guess from the previous step's collocation polynomial."""
        sol = self._sol
        if sol is None:
            return np.zeros((3, self.n))
        ts = t + h * _RC
        if qc is None:
            return sol._y(ts) - y
        Z0 = np.empty((3, self.n))
        qs, vs = sol(ts)
        for i in range(3):  # the old polynomial lives in the previous chart
            Z0[i, : self.nv] = self.group.difference(qc, qs[i])
        Z0[:, self.nv :] = vs - y[self.nv :]
        return Z0

    def step(self) -> None:
        min_step, _ = self._begin_step()
        t, y, f = self.t, self._y, self._f
        qc = None if self._vs else self.q
        nv = self.nv
        if self.h_abs > self.max_step:
            h_abs, h_abs_old, err_old = self.max_step, None, None
        elif self.h_abs < min_step:
            h_abs, h_abs_old, err_old = min_step, None, None
        else:
            h_abs, h_abs_old, err_old = self.h_abs, self._h_abs_old, self._err_old
        mag_n = self._mag(y, qc)
        scale_newton = self.atol + self.rtol * mag_n
        control = self.phi is not None and self.variational_error_control
        phi_new = J_end = df_end = None
        rejected = False
        while True:
            if h_abs < min_step:
                raise self._underflow(h_abs, min_step)
            t_new = min(t + h_abs, self.t_bound)
            h = t_new - t
            h_abs = h
            Z0 = self._predict(t, h, y, qc)
            while True:
                self._ensure_lu(h)
                converged, n_iter, Z, rate = self._newton(t, y, h, Z0, scale_newton, qc)
                if converged or self._current_jac:
                    break
                self._J = self._call_jac(t, self.q, self.v)
                self._current_jac = True
            if not converged:
                h_abs *= 0.5
                self.n_rejected += 1
                continue
            y_new = y + Z[2]
            q_new = y_new[:nv] if qc is None else self.group.integrate(qc, y_new[:nv])
            ZE = (_RE @ Z) / h
            err_vec = self._solve(f + ZE, True)
            scale = self.atol + self.rtol * np.maximum(mag_n, self._mag(y_new, q_new))
            err = _rms(err_vec / scale)
            safety = 0.9 * (2 * _NEWTON_MAXITER + 1) / (2 * _NEWTON_MAXITER + n_iter)
            if rejected and err > 1:  # Hairer's filtered estimate, more reliable after a rejection
                fe = np.empty(self.n)
                ye = y + err_vec
                self._eval_into(t, ye, fe, qc)
                if np.isfinite(fe).all():
                    err = _rms(self._solve(fe + ZE, True) / scale)
            if not math.isfinite(err):
                err = math.inf
            if control and err <= 1:
                phi_new, df_end, err_phi = self._controlled_variational(t, h, y, Z, qc, rejected)
                J_end = df_end[:2]
                err = max(err, err_phi)
            if err > 1:
                factor = _predict_factor(h_abs, h_abs_old, err, err_old)
                h_abs *= max(_MIN_FACTOR, safety * factor if math.isfinite(err) else 0.0)
                rejected = True
                self.n_rejected += 1
                continue
            break

        recompute_jac = n_iter > 2 and rate is not None and rate > 1e-3
        factor = min(_MAX_FACTOR, safety * _predict_factor(h_abs, h_abs_old, err, err_old))
        if not recompute_jac and factor < 1.2:
            factor = 1.0  # keep h so that the LU factors stay valid

        # Final state and derivative at t_new (the last Newton evaluation was not at the converged Z).
        a_new = np.asarray(self.accel(t_new, q_new, y_new[nv:]), dtype=float)
        self.n_accel += 1
        self._nonfinite_stage(t_new, y_new, a_new)
        if self.phi is not None and not control:
            phi_new, J_end = self._variational(t, h, y, Z, qc, self.phi)
        # the last stage is the new point: its DF starts phi's next error estimate
        self._df_start = df_end if control else None
        if recompute_jac:
            self._J = J_end if J_end is not None else self._call_jac(t_new, q_new, y_new[nv:])
            self._current_jac = True
        else:
            self._current_jac = False

        self._y_old, self._qc_old, self._Z = y, qc, Z
        self._h_abs_old, self._err_old = h_abs, err
        self._accept_state(t_new, y_new, q_new, a_new)
        self.phi = phi_new
        self.h_abs = h_abs * factor
        self._sol = DenseOutput(t, t_new, h, y, _RP.T @ Z, None if self._vs else self.group, qc, nv)

    def _variational_stages(self, t: float, h: float, y: np.ndarray, Z: np.ndarray, qc, P0: np.ndarray):
        """Differentiate the stage equations; return (dY (3, n, m), (J_q, J_v, G) at the last stage)."""
        nv, n = self.nv, self.n
        M = np.eye(3 * n)
        DF = np.zeros((n, n))
        DF[:nv, nv:] = np.eye(nv)
        df = None
        for j in range(3):
            Yj = y + Z[j]
            qj = Yj[:nv] if qc is None else self.group.integrate(qc, Yj[:nv])
            df = self._stage_df(t + _RC[j] * h, qj, Yj[nv:])
            if df[2] is not None:
                DF[:nv, :nv] = df[2]
            DF[nv:, :nv], DF[nv:, nv:] = df[0], df[1]
            for i in range(3):
                M[i * n : (i + 1) * n, j * n : (j + 1) * n] -= (h * _RA[i, j]) * DF
        dY = np.linalg.solve(M, np.tile(P0, (3, 1)))
        return dY.reshape(3, n, P0.shape[1]), df

    def _variational(self, t: float, h: float, y: np.ndarray, Z: np.ndarray, qc, P0: np.ndarray):
        """Return (phi_{n+1}, (J_q, J_v) at the last stage)."""
        dY, df = self._variational_stages(t, h, y, Z, qc, P0)
        return dY[2], df[:2]

    def _controlled_variational(self, t: float, h: float, y: np.ndarray, Z: np.ndarray, qc, rejected: bool):
        """phi_{n+1} of an attempt, (J_q, J_v) at its end and phi's error norm (Radau's estimator)."""
        P0 = self.phi
        dY, df_end = self._variational_stages(t, h, y, Z, qc, P0)
        phi_new = dY[2]
        if self._df_start is None:
            self._df_start = self._stage_df(t, self.q, self.v)
        df_n = self._df_start
        ZE = np.tensordot(_RE / h, dY - P0, axes=1)
        err_vec = self._solve(self._df_apply(df_n, P0) + ZE, True)
        scale = self._phi_scale(P0, phi_new)
        err = _rms_cols(err_vec / scale)
        if rejected and err > 1:  # linearisation of the state's filtered estimate
            err = _rms_cols(self._solve(self._df_apply(df_n, P0 + err_vec) + ZE, True) / scale)
        return phi_new, df_end, err

    def _redo_variational(self, h: float) -> np.ndarray:
        t, y, qc = self.t_old, self._y_old, self._qc_old
        scale = self.atol + self.rtol * self._mag(y, qc)
        Z0 = self._sol._y(t + h * _RC) - y  # same chart: an excellent guess
        for attempt in range(2):
            self._ensure_lu(h)
            converged, _, Z, _ = self._newton(t, y, h, Z0, scale, qc)
            if converged:
                break
            q_old = y[: self.nv] if qc is None else qc
            self._J = self._call_jac(t, q_old, y[self.nv :])
        else:
            raise IntegrationError(
                f"Radau: Newton failed when re-taking the step from t={float(t)!r} with h={float(h)!r}"
            )
        return self._variational(t, h, y, Z, qc, self.phi_old)[0]

    def dense(self, lazy: bool = False) -> DenseOutput:
        # the collocation polynomial costs nothing extra: lazy changes nothing
        if self.t_old is None or self._sol is None:
            raise InvalidInputError("dense() needs a step taken since the last (re)start")
        return self._sol

    def _after_truncate(self) -> None:
        self._df_start = None

    def _after_restart(self) -> None:
        self._df_start = None
        self._sol = None
        self._h_abs_old = self._err_old = None
        self._J = self._call_jac(self.t, self.q, self.v)
        self._current_jac = True
        self._lu = None


# --------------------------------------------------------------------------
# Factory
# --------------------------------------------------------------------------

_CLASSES: dict[str, type[Stepper]] = {"DOP853": DOP853, "RK45": RK45, "Radau": Radau}
METHODS: tuple[str, ...] = tuple(_CLASSES)
"""Valid ``method`` names for `make_stepper`."""


def make_stepper(method: str, accel: AccelFn, group, t0: float, q0, v0, **options) -> Stepper:
    """Create a stepper by name.

    Args:
        method: one of `METHODS` (case-insensitive): ``"DOP853"`` (explicit,
            default choice), ``"RK45"`` (explicit, loose tolerances),
            ``"Radau"`` (implicit, stiff springs).
        accel, group, t0, q0, v0, options: see `Stepper`.

    Raises:
        InvalidInputError: unknown method (the message lists the valid ones) or bad input.
    """
    by_lower = {m.lower(): c for m, c in _CLASSES.items()}
    cls = by_lower.get(str(method).lower())
    if cls is None:
        raise InvalidInputError(f"unknown integration method {method!r}; valid: {', '.join(METHODS)}")
    return cls(accel, group, t0, q0, v0, **options)
