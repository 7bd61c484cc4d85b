"""Dense output of one accepted step: the interpolant the hybrid loop locates events on."""

from __future__ import annotations

import numpy as np


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
