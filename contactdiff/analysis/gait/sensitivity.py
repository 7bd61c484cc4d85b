"""How a periodic gait moves with the model's parameters: its fixed point, its stride
time and its Floquet multipliers.

**Fixed point** (implicit-function theorem). `find_periodic_gait` solves
``r(s, p) = Bᵀ (P(x* ⊕ B s, p) ⊖ (x* ⊕ B s)) = 0`` in the section coordinates ``s``
(`contactdiff.analysis.gait.stride` has the map, the section and the clock phase).
With ``J`` the stride's (extended) Jacobian and ``J_p = ∂x'/∂p`` its parameter
Jacobian (`Stride.extended_parameter_jacobian`), both exact,

    (Bᵀ J B - I) ds/dp = -Bᵀ J_p,        dx*/dp = B ds/dp,

solved in the least-squares sense (a family of orbits, multiplier 1, gives the
derivative of the nearest member).

**Stride time** ``T = t' - t0``: ``dT/dp = (∂t'/∂x - e_τ) dx*/dp + ∂t'/∂p`` (the row
``e_τ`` of the phase only on a clock-driven scene).

**Multipliers** (eigenvalue perturbation). A simple eigenvalue ``λ`` of ``J`` with
right and left eigenvectors ``v``, ``w`` moves by ``dλ = wᴴ dJ v / (wᴴ v)``; the
multipliers are the eigenvalues of ``J`` off the section's trivial 0 and the
neutral moves' 1 (the same numbers whatever section coordinates are used), so
``J`` itself is differentiated. Its total derivative along the fixed point,
``dJ/dp = ∂J/∂p + ∂J/∂x dx*/dp``, needs second derivatives of the flow; it is
taken here as the central difference of the exact Jacobians of the gaits
re-converged at ``p ± h`` (Newton from ``x* ± h dx*/dp``, already within
``O(h²)``), so ``dλ/dp`` has an error of about ``h² |d³λ/dp³| / 6`` plus the
Jacobians' own error over ``2h`` (the map's resolution: ~1e-9 on the trots). On
the clock-driven shaker of the tests the first is ``84 h²`` (measured: 8.4e-5,
8.4e-7, 8.4e-9 at relative steps 1e-3, 1e-4, 1e-5), hence the default
``h = 1e-4 |p|``: about 1e-6, and 1e-9 / 2e-4 = 5e-6 from a trot's resolution. A multiplier that is
not simple (another eigenvalue of ``J`` within `REPEATED_TOL` of it, e.g. the
several exact zeros of plastic impacts) has no derivative: that is an error
naming it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
import scipy.linalg

from ...errors import InvalidInputError, check_number
from ...model.scene import Scene
from .periodic import PeriodicGait, find_periodic_gait
from .section import onto_section, section_basis
from .stride import stride_map
from .stride_result import Stride

REPEATED_TOL = 1e-6
"""Relative distance (to ``max(1, |λ|)``) below which two eigenvalues of the stride
Jacobian count as one repeated eigenvalue, which has no derivative."""
DEFAULT_STEP = 1e-4
"""Relative step ``h / max(|p|, 1e-3)`` of the multipliers' central differences (module doc)."""


@dataclass(kw_only=True)
class GaitSensitivity:
    """Derivatives of a periodic gait with respect to scene parameters (module doc).

    Attributes:
        parameter_names: the parameters, in column order.
        values: their values (each in its own unit).
        fixed_point: ``dx*/dp`` ((2nv [+1]) × p): tangent space at the gait's start,
            with the clock phase (s) as the last row on a clock-driven scene; its
            component along the neutral moves is not defined and is zero.
        stride_time: ``dT/dp`` (p,), s per unit of each parameter.
        multipliers: the multipliers differentiated (complex).
        multiplier_derivatives: ``dλ/dp`` (k × p, complex).
        steps: the central differences' step of each parameter (its unit).
        stride: the stride at the gait's start, with its parameter Jacobian.
    """

    parameter_names: tuple[str, ...]
    values: np.ndarray
    fixed_point: np.ndarray
    stride_time: np.ndarray
    multipliers: np.ndarray
    multiplier_derivatives: np.ndarray
    steps: np.ndarray
    stride: Stride

    def modulus_gradient(self, k: int = 0) -> np.ndarray:
        """``d|λ_k|/dp`` (p,) of the k-th multiplier differentiated: ``Re(conj(λ) dλ) / |λ|``."""
        lam = self.multipliers[k]
        if lam == 0:
            raise InvalidInputError(f"multiplier {k} is 0: its modulus has no derivative")
        return np.real(np.conj(lam) * self.multiplier_derivatives[k]) / abs(lam)

    def to_dict(self) -> dict:
        """JSON-ready data (complex numbers as [real, imag])."""

        def cplx(a):
            return np.stack([np.real(a), np.imag(a)], axis=-1).tolist()

        return {
            "parameter_names": list(self.parameter_names),
            "values": self.values.tolist(),
            "fixed_point": self.fixed_point.tolist(),
            "stride_time": self.stride_time.tolist(),
            "multipliers": cplx(self.multipliers),
            "multiplier_derivatives": cplx(self.multiplier_derivatives),
            "modulus_gradient": [self.modulus_gradient(k).tolist() for k in range(len(self.multipliers))],
            "steps": self.steps.tolist(),
        }

    def format(self) -> str:
        """A table: per parameter, its value, dT/dp and d|λ|/dp of each multiplier differentiated."""
        head = "  ".join(f"d|λ{k}|/dp" for k in range(len(self.multipliers)))
        lines = [f"{'parameter':<36} {'value':>12} {'dT/dp (s)':>12}  {head}"]
        grads = [self.modulus_gradient(k) for k in range(len(self.multipliers))]
        for j, name in enumerate(self.parameter_names):
            cells = "  ".join(f"{g[j]:9.4g}" for g in grads)
            lines.append(f"{name:<36} {self.values[j]:12.6g} {self.stride_time[j]:12.5g}  {cells}")
        lines.append("multipliers: " + ", ".join(f"{m:.6g} (|λ| {abs(m):.6g})" for m in self.multipliers))
        return "\n".join(lines)


def _simple_eigenpair(J: np.ndarray, lam: complex, k: int):
    """Right and left eigenvectors of the eigenvalue of ``J`` nearest ``lam``; an error
    if it is not simple or not there."""
    values, left, right = scipy.linalg.eig(J, left=True, right=True)
    m = int(np.argmin(np.abs(values - lam)))
    scale = max(1.0, abs(lam))
    if abs(values[m] - lam) > 1e-6 * scale:
        raise InvalidInputError(
            f"multiplier {k} ({lam:.6g}) is not an eigenvalue of the stride Jacobian "
            f"(nearest {values[m]:.6g}): is the gait converged?"
        )
    others = np.delete(values, m)
    if others.size and np.min(np.abs(others - values[m])) <= REPEATED_TOL * scale:
        near = others[int(np.argmin(np.abs(others - values[m])))]
        raise InvalidInputError(
            f"multiplier {k} ({lam:.6g}) is a repeated eigenvalue of the stride Jacobian "
            f"(another at {near:.6g}): it has no derivative; choose simple ones with which="
        )
    return right[:, m], left[:, m]


def gait_sensitivity(
    scene: Scene,
    gait: PeriodicGait,
    parameters: Sequence[str],
    *,
    which: Sequence[int] = (0,),
    step: float = DEFAULT_STEP,
    newton: int = 4,
    tol: float = 1e-10,
    **stride_options,
) -> GaitSensitivity:
    """Derivatives of ``gait`` (a converged `find_periodic_gait` result on ``scene``) with
    respect to ``parameters``: fixed point, stride time and the multipliers ``which``
    (indices into ``gait.multipliers``, by decreasing modulus; default the largest).

    Args:
        scene: the scene the gait was found on.
        gait: the `PeriodicGait`.
        parameters: scene parameter names (`Scene.parameter_names`).
        which: multipliers to differentiate (each must be a simple eigenvalue); ``()``
            skips them and the re-converged gaits they need.
        step: relative step of the multipliers' central differences (module doc).
        newton: Newton iterations of each re-converged gait.
        tol: residual tolerance of the re-converged gaits.
        **stride_options: the options the gait was found with (``rtol``, ``atol``,
            ``method``, ``t_max``, ``min_stride``, ``min_flight``, ``period``, ...),
            passed to `stride_map` and `find_periodic_gait`.

    Raises:
        InvalidInputError: a gait that did not converge, unknown parameters (listing
            the valid ones), a multiplier index out of range or a repeated multiplier.
    """
    if not isinstance(gait, PeriodicGait):
        raise InvalidInputError(f"gait must be a PeriodicGait (find_periodic_gait), got {gait!r}")
    if not gait.converged:
        raise InvalidInputError(
            "gait_sensitivity: the gait did not converge (residual "
            f"{gait.residuals[-1]:.3g}); its derivatives are those of no fixed point"
        )
    names = [parameters] if isinstance(parameters, str) else list(parameters)
    values = scene.parameter_values(names)
    step = check_number("gait_sensitivity", "step", step, minimum=1e-12)
    which = tuple(int(k) for k in which)
    for k in which:
        if not 0 <= k < len(gait.multipliers):
            raise InvalidInputError(
                f"gait_sensitivity: which = {k} is not a multiplier index; valid: 0..{len(gait.multipliers) - 1}"
            )
    clock = gait.stride.period
    sim = dict(stride_options, period=False if clock is None else clock)
    stride = stride_map(scene, gait.foot, gait.q, gait.v, gait.t, parameters=names, **sim)
    B = section_basis(scene, gait.foot, stride.q0, gait.neutral, clock)
    J, Jp = stride.extended_jacobian(), stride.extended_parameter_jacobian()
    ds = -np.linalg.lstsq(B.T @ J @ B - np.eye(B.shape[1]), B.T @ Jp, rcond=None)[0]
    dx = B @ ds
    n = 2 * scene.nv
    if clock is None:
        dT = stride.time_gradient @ dx + stride.parameter_time_gradient
    else:  # t' - t0 on (x, τ): t' moves by its row of J, t0 by the phase
        row = J[n] - np.eye(n + 1)[n]
        dT = row @ dx + stride.parameter_time_gradient
    lams = gait.multipliers[list(which)]
    dlam = np.zeros((len(which), len(names)), dtype=complex)
    steps = np.array([step * max(abs(v), 1e-3) for v in values])
    if which:
        pairs = [_simple_eigenpair(J, lam, k) for lam, k in zip(lams, which)]
        for j, (name, value, h) in enumerate(zip(names, values, steps)):
            dJ = (
                _reconverged_jacobian(scene, gait, name, value, h, dx[:, j], newton, tol, sim)
                - _reconverged_jacobian(scene, gait, name, value, -h, dx[:, j], newton, tol, sim)
            ) / (2 * h)
            for i, (v, w) in enumerate(pairs):
                dlam[i, j] = (w.conj() @ dJ @ v) / (w.conj() @ v)
    return GaitSensitivity(
        parameter_names=tuple(names),
        values=values,
        fixed_point=dx,
        stride_time=dT,
        multipliers=lams,
        multiplier_derivatives=dlam,
        steps=steps,
        stride=stride,
    )


def _reconverged_jacobian(scene, gait, name, value, h, direction, newton, tol, sim) -> np.ndarray:
    """The extended stride Jacobian of the gait re-converged with ``name`` at ``value + h``,
    Newton started from ``x* + h dx*/dp``."""
    moved = scene.with_parameters({name: value + h})
    nv = scene.nv
    q = onto_section(moved, gait.foot, pin.integrate(scene.model, gait.q, h * direction[:nv]))
    v = gait.v + h * direction[nv : 2 * nv]
    t = gait.t + (h * direction[2 * nv] if gait.stride.period is not None else 0.0)
    again = find_periodic_gait(moved, gait.foot, q, v, t, iterations=newton, tol=tol, neutral=gait.neutral, **sim)
    if not again.converged:
        raise InvalidInputError(
            f"gait_sensitivity: the gait did not re-converge with {name} = {value + h:.9g} "
            f"(residual {again.residuals[-1]:.3g}); try a smaller step"
        )
    return again.stride.extended_jacobian()


__all__ = ["GaitSensitivity", "gait_sensitivity", "REPEATED_TOL", "DEFAULT_STEP"]
