"""Flow in a contact mode: accelerations, contact forces and their derivatives.

In mode ``J`` (the set of active contacts) the rows ``A`` of the active contacts
(normal, plus tangents for sticking contacts) are held at zero acceleration:

    M ddq - A^T lam = tau - nle,      A ddq + drift = 0,

with ``M`` the mass matrix (armature included), ``nle`` Coriolis + gravity,
``tau`` the scene's efforts and ``lam`` the row forces (N; normal forces push
when positive). The Delassus matrix ``G = A M^-1 A^T`` is symmetric positive
definite when the rows are independent. Redundant rows (four corners of a face
on a plane, the lateral rows of four sticking feet on planar legs) leave the
forces undetermined; they are the rigid limit of equal compliant supports, the
forces in ``range(A)`` (`contactdiff.dynamics.redundant`: least-norm for a
symmetric ``G``, and the load that decides a sliding face's friction).
Redundancy is decided once per mode, from the singular values of ``A`` at a
configuration of the model where the mode is first used: a Cholesky
factorisation of a singular ``G`` (Pinocchio's, or LAPACK's) does not always
fail, it can return finite forces made of round-off over a pivot of 1e-16
(internal forces of 1e7 N on solo8 folding, and accelerations wrong by 1e-2), a
vector field that no step size resolves.

A mode is a sorted tuple of *contact keys*: key ``i < n`` (``n`` contacts in the
scene) is contact ``i`` with all its rows; key ``n + i`` is sticking contact
``i`` sliding, its normal row only (`BoundContact.sliding_view`).

**Coulomb slip.** A sliding contact with a finite friction coefficient ``μ``
keeps its normal row ``A_n`` as a constraint, and its force acts along
``F = A_n - μ s^T A_T`` (``A_T`` its tangential rows, ``s`` its unit slip
direction in tangent coordinates, `ModeDynamics.slip_direction`): the
friction ``-μ λ_N s`` opposes the slip. The KKT system then has force rows
``F`` and constraint rows ``A`` that differ, and ``G = A M^-1 F^T`` is not
symmetric (LU instead of Cholesky); where ``G`` is singular or its sliding
block has a non-positive diagonal the sliding problem has no or several
solutions (Painlevé's paradox, `contactdiff.dynamics.slip`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal, overload

import numpy as np
import pinocchio as pin

from ..errors import InvalidInputError, check_number
from ..model.contacts import BoundContact
from ..model.kinematics import Kinematics
from ..model.scene import Scene
from .constraint_dynamics import RigidContactMode
from .constraint_dynamics import eligible as rigid_eligible
from .mode_derivatives import kkt_derivatives
from .mode_forces import force_solver
from .mode_solution import ModeDerivatives, ModeSolution
from .redundant import gram_range_basis, range_basis
from .slip import SLIP_SPEED_EPS, SlipRow, slip_direction

__all__ = ["ModeAccelerator", "ModeDerivatives", "ModeDynamics", "ModeSolution"]  # the records' former path


class ModeDynamics:
    """Evaluates the flow of a scene in any contact mode.

    Free flight uses ABA (and its analytic derivatives); a mode of sticking
    point contacts on the ground uses Pinocchio's constraint dynamics
    (`rigid_contacts`); any other mode assembles its rows in Python and solves
    with ``M^-1`` and the Cholesky factor of the Delassus matrix. Uses the
    scene's kinematics cache and ``pinocchio.Data`` of its own; not thread safe
    (one instance per thread, each with its own scene).

    Args:
        scene: the scene.
        slip_speed_floor: m/s, the speed below which a 3-D slip follows its reference
            (`contactdiff.dynamics.slip`; a run passes its ``zeno_speed``).
    """

    def __init__(self, scene: Scene, slip_speed_floor: float = SLIP_SPEED_EPS):
        self.scene = scene
        self.model = scene.model
        self.kin = scene.kinematics
        self.data = self.model.createData()
        self._modes: dict[tuple[int, ...], tuple] = {}
        self.n_contacts = len(scene.contacts)
        self._views: list[BoundContact | None] = [
            *scene.contacts,
            *(c.sliding_view() if c.sticking else None for c in scene.contacts),
        ]
        self.slip_reference: dict[int, np.ndarray] = {}
        """Per slipping contact (scene index), the unit direction (tangent coordinates)
        its slip is continued along: a planar contact's slip sign, a spatial contact's
        direction at its last accepted step (`slip_direction`); set by the hybrid loop."""
        self.slip_speed_floor = slip_speed_floor
        """m/s: a 3-D slip slower than this follows its reference (`contactdiff.dynamics.slip`);
        a run's is its ``zeno_speed``, given at construction."""

    def slip_direction(
        self, index: int, slip_velocity: np.ndarray, jacobian: bool = True
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """Unit slip direction ``s`` of scene contact ``index`` with tangential row
        velocities ``slip_velocity`` (m/s), and ``ds/d(slip_velocity)`` (None where it
        is zero, or not asked for: ``jacobian`` False); see
        `contactdiff.dynamics.slip.slip_direction`."""
        return slip_direction(slip_velocity, self.slip_reference.get(index), self.slip_speed_floor, jacobian)

    # -- contact keys (see the module doc) ----------------------------------------------
    def contact(self, key: int):
        """The bound contact (or sliding view) of a contact key."""
        view = self._views[key]
        if view is None:
            raise InvalidInputError(
                f"contact {self.scene.contacts[key - self.n_contacts].name!r} is not "
                "sticking, so it has no sliding state"
            )
        return view

    def contact_index(self, key: int) -> int:
        """Scene index of the contact of a key."""
        return key - self.n_contacts if key >= self.n_contacts else key

    def sliding_key(self, index: int) -> int:
        """Key of scene contact ``index`` sliding."""
        return index + self.n_contacts

    def is_sliding(self, key: int) -> bool:
        """Whether contact key ``key`` is a sliding key (``n_contacts + i``)."""
        return key >= self.n_contacts

    def contacts_of(self, mode: Sequence[int]) -> tuple[int, ...]:
        """Scene indices of the contacts active in ``mode`` (sticking or sliding)."""
        return tuple(self.contact_index(k) for k in mode)

    def _mode(self, active: tuple[int, ...]):
        """Contacts, row slices and (if eligible) the Pinocchio constraint mode of ``active``."""
        entry = self._modes.get(active)
        if entry is None:
            self._check_mode(active)
            contacts = [self.contact(k) for k in active]
            slices, start = [], 0
            for c in contacts:
                slices.append(slice(start, start + c.n_rows))
                start += c.n_rows
            # redundant rows are a structural property of the mode (the corners of one face):
            # decided once (module doc); Pinocchio's factorisation of a redundant set can succeed
            # on round-off, so a redundant mode takes the compatible-load solve
            redundant = self._redundant(contacts, start)
            rigid = RigidContactMode(self.model, contacts) if rigid_eligible(contacts) and not redundant else None
            slipping = tuple((k, s.start) for k, c, s in zip(active, contacts, slices) if c.slips)
            entry = self._modes[active] = (contacts, tuple(slices), rigid, slipping, redundant)
        return entry

    def _redundant(self, contacts, n_rows: int) -> bool:
        """Whether a mode's rows are dependent (`contactdiff.dynamics.redundant.RANK_TOL`),
        at the kinematics cache's configuration (the scene's initial one before any update)."""
        if n_rows < 2:
            return False
        kin = Kinematics(self.model)
        # the cache's configuration, unless a trial stage left it non-finite (redundancy is
        # structural: any valid configuration decides it)
        q = self.kin.q
        kin.update(self.scene.q0 if q is None or not np.all(np.isfinite(q)) else q, np.zeros(self.model.nv))
        return range_basis(np.vstack([c.rows(kin) for c in contacts])) is not None

    def redundant(self, active: Sequence[int]) -> bool:
        """Whether the rows of mode ``active`` are dependent (their forces chosen by the
        compatible-load principle, `contactdiff.dynamics.redundant`)."""
        return self._mode(tuple(active))[4]

    def accelerator(self, active: Sequence[int]) -> ModeAccelerator:
        """The plain (no derivatives) solve of mode ``active`` as a stepper calls it, its
        lookups done once (see `ModeAccelerator`)."""
        return ModeAccelerator(self, tuple(active))

    def _check_mode(self, active: tuple) -> None:
        """Refuse a mode that is not a tuple of distinct valid contact keys."""
        n = self.n_contacts
        valid = (
            (
                f"keys 0..{n - 1} (contacts {', '.join(self.scene.contact_names)}) and "
                f"n + i = {n}..{2 * n - 1} for sticking contact i sliding"
            )
            if n
            else "none: the scene has no contacts"
        )
        for key in active:
            if isinstance(key, bool) or not isinstance(key, (int, np.integer)) or not 0 <= key < 2 * n:
                raise InvalidInputError(f"mode {active!r}: {key!r} is not a contact key; valid: {valid}")
        indices = [self.contact_index(k) for k in active]
        if len(set(indices)) != len(indices):
            raise InvalidInputError(f"mode {active!r} names a contact twice (sticking and sliding, or repeated)")

    def _check_state(self, q, v, t, tau) -> None:
        """Name the bad argument of a `solve` that failed inside Pinocchio or numpy."""
        model = self.model
        checked = (("q", q, model.nq), ("v", v, model.nv)) + (() if tau is None else (("tau", tau, model.nv),))
        for name, x, size in checked:
            arr = np.asarray(x)
            if arr.shape != (size,) or not np.issubdtype(arr.dtype, np.number):
                raise InvalidInputError(
                    f"ModeDynamics.solve: {name} must be {size} numbers, got shape {arr.shape} ({x!r})"
                )
            if not np.all(np.isfinite(arr)):
                raise InvalidInputError(f"ModeDynamics.solve: {name} must be finite, got {x!r}")
        check_number("ModeDynamics.solve", "t", t)

    @overload
    def solve(
        self,
        q: np.ndarray,
        v: np.ndarray,
        t: float,
        active: Sequence[int] = (),
        *,
        derivatives: Literal[False] = False,
        tau: np.ndarray | None = None,
    ) -> ModeSolution: ...

    @overload
    def solve(
        self,
        q: np.ndarray,
        v: np.ndarray,
        t: float,
        active: Sequence[int] = (),
        *,
        derivatives: Literal[True],
        tau: np.ndarray | None = None,
    ) -> tuple[ModeSolution, ModeDerivatives]: ...

    @overload
    def solve(
        self,
        q: np.ndarray,
        v: np.ndarray,
        t: float,
        active: Sequence[int] = (),
        *,
        derivatives: bool,
        tau: np.ndarray | None = None,
    ) -> ModeSolution | tuple[ModeSolution, ModeDerivatives]: ...

    def solve(
        self,
        q: np.ndarray,
        v: np.ndarray,
        t: float,
        active: Sequence[int] = (),
        *,
        derivatives: bool = False,
        tau: np.ndarray | None = None,
    ) -> ModeSolution | tuple[ModeSolution, ModeDerivatives]:
        """Accelerations and forces in mode ``active`` at ``(q, v)`` (see `_solve`).

        Raises:
            InvalidInputError: ``q``, ``v`` or ``tau`` of the wrong size or not finite,
                or ``active`` not a mode of contact keys (the message lists them).
        """
        try:
            return self._solve(q, v, t, active, derivatives, tau)
        except (ValueError, TypeError, IndexError, RuntimeError) as exc:
            if isinstance(exc, InvalidInputError):
                raise
            # checked only on failure: the hot path pays nothing for it
            self._check_mode(tuple(active))
            self._check_state(q, v, t, tau)
            raise

    def _solve(
        self,
        q: np.ndarray,
        v: np.ndarray,
        t: float,
        active: Sequence[int] = (),
        derivatives: bool = False,
        tau: np.ndarray | None = None,
    ) -> ModeSolution | tuple[ModeSolution, ModeDerivatives]:
        """Accelerations and forces in mode ``active`` at ``(q, v)``.

        Args:
            q: configuration (nq,).
            v: velocity (nv,), tangent space.
            t: time (s), passed to time-dependent efforts.
            active: keys of the active contacts (see the module doc).
            derivatives: also return the `ModeDerivatives`.
            tau: efforts (nv,) to use instead of the scene's at ``t`` (not with
                ``derivatives``).

        Also moves the scene's kinematics cache to ``(q, v)``.
        """
        active = tuple(active)
        kin, model, data = self.kin, self.model, self.data
        kin.update(q, v, derivatives=derivatives)
        if tau is None:
            tau = self.scene.tau(kin, t)
        contacts, slices, rigid, slipping, redundant = self._mode(active)
        if not contacts:  # free flow: ABA, O(n)
            if derivatives:
                ddq_dq, ddq_dv, Minv = pin.computeABADerivatives(model, data, q, v, tau)
                solution = ModeSolution(data.ddq.copy(), np.zeros(0), active, slices)
                dtau_dq, dtau_dv = self.scene.tau_derivatives(kin, t)
                empty = np.zeros((0, model.nv))
                return solution, ModeDerivatives(
                    ddq_dq + Minv @ dtau_dq, ddq_dv + Minv @ dtau_dv, empty, empty, Minv, empty
                )
            return ModeSolution(pin.aba(model, data, q, v, tau), np.zeros(0), active, slices)
        solved = rigid.solve(q, v, tau) if rigid is not None else None
        if solved is not None:
            ddq, forces = solved
            solution = ModeSolution(ddq, forces, active, slices)
            if not derivatives:
                return solution
            dtau_dq, dtau_dv = self.scene.tau_derivatives(kin, t)
            return solution, ModeDerivatives(*rigid.derivatives(dtau_dq, dtau_dv))
        Minv = pin.computeMinverse(model, data, q)  # symmetric copy
        a_free = Minv @ (tau - pin.nonLinearEffects(model, data, q, v))
        A = np.vstack([c.rows(kin) for c in contacts])
        drift = np.concatenate([c.drift(kin) for c in contacts])
        MinvAT = Minv @ A.T
        delassus = A @ MinvAT  # the constraint rows' G: the problem's own without slip
        slips = [SlipRow.at(self, key, row, kin, v, derivatives) for key, row in slipping]
        U = gram_range_basis(delassus) if redundant else None
        if slips:
            F = A.copy()
            for slip in slips:
                F[slip.row] = slip.force_row
            MinvFT = Minv @ F.T
            G = A @ MinvFT
        else:
            MinvFT, G = MinvAT, delassus
        solve = force_solver(self.scene, slips, U, delassus, contacts)
        forces = solve(G, -(drift + A @ a_free))
        solution = ModeSolution(a_free + MinvFT @ forces, forces, active, slices)
        if not derivatives:
            return solution
        return solution, kkt_derivatives(
            self.scene, model, data, kin, q, v, t, solution, contacts, A, Minv, MinvAT, MinvFT, G, slips, solve, U
        )


class ModeAccelerator:
    """``accel(q, v, t) -> ddq`` of one mode, the hot path of an explicit stepper.

    A mode of Pinocchio's 3-D ground contacts calls ``pinocchio.constraintDynamics``
    directly and keeps the raw contact forces of the last call (world axes), turned
    into normal forces only when asked (`normal_forces`): a stepper evaluates a
    dozen stages a step, the guards read the forces at one point. Any other mode,
    and a rigid solve that fails (redundant contacts), goes through
    `ModeDynamics.solve`. Results equal ``ModeDynamics.solve(q, v, t, active)``.
    """

    def __init__(self, dyn: ModeDynamics, active: tuple[int, ...]):
        self.dyn, self.active = dyn, active
        contacts, _, self.rigid, _, _ = dyn._mode(active)
        self._contacts = contacts
        self._kin, self._tau = dyn.kin, dyn.scene.tau
        self._raw: np.ndarray | None = None
        self._solution: ModeSolution | None = None
        if self.rigid is not None:
            # row k picks contact k's normal force out of the stacked world forces
            self._normals = np.zeros((len(contacts), 3 * len(contacts)))
            for k, c in enumerate(contacts):
                self._normals[k, 3 * k : 3 * k + 3] = c.directions[0]

    def __call__(self, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        """Joint accelerations (nv,) in the mode at ``(q, v)`` and time ``t`` (s)."""
        rigid = self.rigid
        if rigid is not None:
            kin = self._kin
            kin.update(q, v)
            ddq = rigid.accelerations(q, v, self._tau(kin, t))
            if ddq is not None:
                self._raw = rigid.data.lambda_c.copy()
                return ddq
        self._raw = None
        self._solution = self.dyn.solve(q, v, t, self.active)
        return self._solution.ddq

    def normal_forces(self) -> np.ndarray:
        """Normal forces (N) of the mode's contacts (order of the mode) at the last call."""
        if self._raw is not None:
            return self._normals @ self._raw
        assert self._solution is not None  # set by __call__ whenever _raw is None
        return self._solution.normal_forces()

    def row_forces(self) -> list[np.ndarray]:
        """Row forces (N) of the mode's contacts (order of the mode) at the last call, as
        `ModeSolution.row_forces`."""
        if self._raw is not None:
            return [c.directions @ self._raw[3 * k : 3 * k + 3] for k, c in enumerate(self._contacts)]
        assert self._solution is not None  # set by __call__ whenever _raw is None
        return self._solution.row_forces()
