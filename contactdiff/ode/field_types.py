"""The types of a stepper's callbacks: the vector field and its Jacobians.

A stepper integrates ``dv/dt = accel(t, q, v)``, ``dq/dt = v`` (Pinocchio's sense);
``q`` is a configuration (nq,), ``v`` a velocity (nv,) in the joints' local frames,
``t`` the time (s). The callbacks receive arrays the stepper never modifies afterwards.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

AccelFn = Callable[[float, np.ndarray, np.ndarray], np.ndarray]
"""``accel(t, q, v) -> dv/dt`` (nv,), in the joints' local frames."""
JacFn = Callable[[float, np.ndarray, np.ndarray], "tuple[np.ndarray, np.ndarray]"]
"""``jac(t, q, v) -> (J_q, J_v)``: d accel / d q (tangent, ``q ⊕ δq``) and d accel / d v, nv x nv each."""
ParameterJacFn = Callable[[float, np.ndarray, np.ndarray], np.ndarray]
"""``parameter_jac(t, q, v) -> J_p``: d accel / d p (nv x p) at fixed state, for p parameters."""
