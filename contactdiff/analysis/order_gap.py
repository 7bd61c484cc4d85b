"""The order gap: how much a simultaneous touchdown depends on which foot lands first.

Two contacts ``i`` and ``j`` close at the same configuration ``q`` with both
feet approaching. A perturbation that makes ``i`` land an instant earlier than
``j`` and one that makes ``j`` land earlier lead, in the limit, to the two
*one-sided outcomes*:

* order ``(i, j)``: the impact of ``i`` alone at ``(q, v-)``, then, at the same
  ``q``, the impact of ``j`` with ``i`` in whatever mode the first impact left it
  (``j`` does not land if the first impact already sends it away);
* order ``(j, i)``: the same with the roles swapped.

The *simultaneous outcome* is the impact with both closed at once. The paper's
theorem says that for limbs decoupled through the body all three coincide and
so do the saltation matrices of the two orders; on a coupled robot they differ,
and the flow is only piecewise differentiable (a B-derivative) there. The
numbers of `OrderGap` measure by how much.

Norms (all dimensionless, defined at the event configuration ``q``):

* ``outcome``: ``‖v_ij - v_ji‖_M / ‖v_sim - v-‖_M``, with the kinetic-energy
  norm ``‖x‖_M = sqrt(x^T M(q) x)`` (coordinate-free: it does not mix metres and
  radians) and ``v_sim`` the simultaneous outcome: the two orders' difference as
  a fraction of the velocity jump the impact makes.
* ``outcome_vs_simultaneous``: ``max over orders ‖v_order - v_sim‖_M / ‖v_sim - v-‖_M``.
* ``saltation``: ``max|Ξ_ij - Ξ_ji| / max(1, max|Ξ_ij|, max|Ξ_ji|)`` (entry-wise
  max norm, the convention of `sensitivity.ORDER_TOL`; the entries mix units,
  so it is a size, not a physical quantity).
* ``saltation_spread``: the same relative max norm over the two orders and the
  paper's ``DR_K + Σ_k S_k`` (`sensitivity.SimultaneousSaltation.spread`).

With ``horizon`` given, each outcome is also carried forward by `simulate` for
``horizon`` seconds, and ``later`` is the M(q)-norm of the difference of the two
orders' velocities then, relative to the same impact jump. With ``jacobian``
too, ``later_saltation`` compares the two one-sided derivatives ``Φ Ξ_order`` of
the state at ``t + horizon`` (same relative max norm as ``saltation``): the
size of the non-differentiability as seen a little later, where the flow after
the event (springs, efforts) has acted on it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike

from ..dynamics.impacts import resolve_impact
from ..dynamics.mode import ModeDynamics
from ..errors import InvalidInputError, check_number
from ..integration.sensitivity import ORDER_TOL, simultaneous_saltation, touchdown
from ..model.scene import Scene

GAP_TOL = 1e-9
"""Largest |gap| (m) at which a contact counts as closed for an order gap."""


@dataclass
class OrderGap:
    """The two one-sided outcomes of a simultaneous touchdown and how far apart they are.

    Attributes:
        contacts: the two contact names, in the order given.
        t: event time (s).
        q: event configuration (nq,).
        v_minus: velocity just before (nv,).
        v_simultaneous: velocity after the impact with both closed at once (nv,).
        v_after: velocity after each order, keyed by the order (first, second) of
            contact names (nv,) each.
        mode_after: contacts active after each order (names; a sliding one marked "(sliding)").
        saltation_orders: saltation matrix of each order (2nv × 2nv, tangent space).
        saltation_paper: the paper's ``DR_K + Σ_k S_k`` (2nv × 2nv); None when a contact's
            single landing has no solution (`SimultaneousSaltation.unresolved`).
        impact_jump: ``‖v_sim - v-‖_M`` (sqrt(kg) m/s for a metric in kg; the scale
            of the relative numbers).
        outcome, outcome_vs_simultaneous, saltation, saltation_spread: the
            relative gaps defined in the module docstring.
        outcome_abs: ``‖v_ij - v_ji‖_M`` (same units as ``impact_jump``).
        outcome_max: ``max|v_ij - v_ji|`` entry-wise (m/s or rad/s).
        horizon: time (s) the outcomes were carried forward (None: not simulated).
        q_later, v_later: state of each order (and of ``"simultaneous"``) at
            ``t + horizon``.
        later: relative velocity gap at ``t + horizon`` (None without horizon).
        jacobian_later: per order, ``Φ Ξ_order``: the one-sided derivative of the
            state at ``t + horizon`` with respect to the state just before the event
            (``Φ`` the flow Jacobian after the event; with ``jacobian=True``).
        later_saltation: ``max|Φ_ij Ξ_ij - Φ_ji Ξ_ji| / max(1, max|Φ_ij Ξ_ij|, max|Φ_ji Ξ_ji|)``:
            how far apart the two one-sided derivatives are at ``t + horizon``
            (None unless computed).
    """

    contacts: tuple[str, str]
    t: float
    q: np.ndarray
    v_minus: np.ndarray
    v_simultaneous: np.ndarray
    v_after: dict
    mode_after: dict
    saltation_orders: dict
    saltation_paper: np.ndarray | None
    impact_jump: float
    outcome: float
    outcome_vs_simultaneous: float
    outcome_abs: float
    outcome_max: float
    saltation: float
    saltation_spread: float
    horizon: float | None = None
    q_later: dict = field(default_factory=dict)
    v_later: dict = field(default_factory=dict)
    later: float | None = None
    jacobian_later: dict = field(default_factory=dict)
    later_saltation: float | None = None

    def later_saltation_on(self, coordinates: Sequence[int]) -> float:
        """``later_saltation`` restricted to the rows of some tangent ``coordinates``
        (their position and velocity rows), e.g. the base's six: how far apart the
        one-sided derivatives of that part of the state are at ``t + horizon``."""
        if not self.jacobian_later:
            raise InvalidInputError("later_saltation_on needs order_gap(..., horizon=..., jacobian=True)")
        nv = len(self.v_minus)
        coords = [int(k) for k in coordinates]
        if not coords or min(coords) < 0 or max(coords) >= nv:
            raise InvalidInputError(f"coordinates must be tangent indices in [0, {nv}), got {coordinates!r}")
        rows = coords + [nv + k for k in coords]
        Pa, Pb = (P[rows] for P in self.jacobian_later.values())
        return _relative_gap(Pa, Pb)

    def differentiable(self, tol: float = ORDER_TOL) -> bool:
        """Whether the two orders agree (outcome and saltation) within ``tol``."""
        return self.outcome <= tol and self.saltation_spread <= tol

    def to_dict(self, matrices: bool = False) -> dict:
        """JSON-ready summary (the matrices only if asked)."""

        def key(order):
            return "->".join(order)

        d = {
            "contacts": list(self.contacts),
            "t": self.t,
            "q": self.q.tolist(),
            "v_minus": self.v_minus.tolist(),
            "v_simultaneous": self.v_simultaneous.tolist(),
            "v_after": {key(k): v.tolist() for k, v in self.v_after.items()},
            "mode_after": {key(k): list(m) for k, m in self.mode_after.items()},
            "impact_jump": self.impact_jump,
            "outcome": self.outcome,
            "outcome_vs_simultaneous": self.outcome_vs_simultaneous,
            "outcome_abs": self.outcome_abs,
            "outcome_max": self.outcome_max,
            "saltation": self.saltation,
            "saltation_spread": self.saltation_spread,
            "horizon": self.horizon,
            "later": self.later,
            "later_saltation": self.later_saltation,
        }
        if self.horizon is not None:
            d["v_later"] = {(k if isinstance(k, str) else key(k)): v.tolist() for k, v in self.v_later.items()}
        if matrices:
            d["saltation_orders"] = {key(k): m.tolist() for k, m in self.saltation_orders.items()}
            d["saltation_paper"] = None if self.saltation_paper is None else self.saltation_paper.tolist()
        return d


def _index(scene: Scene, contact) -> int:
    if isinstance(contact, str):
        return scene.contact_index(contact)
    try:
        k = int(contact)
    except (TypeError, ValueError):
        raise InvalidInputError(f"order_gap: a contact must be a name or an index, got {contact!r}") from None
    if not 0 <= k < len(scene.contacts):
        raise InvalidInputError(
            f"order_gap: contact index {k} out of range; the scene has {len(scene.contacts)} contacts: "
            + ", ".join(scene.contact_names)
        )
    return k


def order_gap(
    scene: Scene,
    q: ArrayLike,
    v_minus: ArrayLike,
    contacts: Sequence = (0, 1),
    *,
    mode: Sequence = (),
    t: float = 0.0,
    horizon: float | None = None,
    jacobian: bool = False,
    simulate_options: dict | None = None,
) -> OrderGap:
    """Order gap of the simultaneous touchdown of two contacts at ``(q, v-)``.

    Args:
        scene: the scene.
        q: configuration (nq,) at which both contacts are closed (|gap| <= `GAP_TOL`).
        v_minus: velocity just before (nv,); both contacts must approach (``A_n v- < 0``).
        contacts: the two contacts (names or indices).
        mode: contacts already active before the event (names or indices).
        t: event time (s), for time-dependent efforts.
        horizon: if given (s, > 0), also simulate each outcome this long.
        jacobian: with ``horizon``, also carry each order's saltation matrix
            forward with the flow Jacobian and measure ``later_saltation``.
        simulate_options: keyword arguments for `simulate` (tolerances, method).

    Returns:
        An `OrderGap` (norms in the module docstring).

    Raises:
        InvalidInputError: wrong sizes, non-finite values, a contact not closed or
            not approaching, the same contact twice, or a contact both in ``mode``
            and landing.
    """
    if not isinstance(scene, Scene):
        raise InvalidInputError(f"order_gap: scene must be a Scene, got {scene!r}")
    q = np.array(q, dtype=float)
    v_minus = np.array(v_minus, dtype=float)
    if q.shape != (scene.robot.nq,) or v_minus.shape != (scene.nv,):
        raise InvalidInputError(
            f"order_gap: q must have shape ({scene.robot.nq},) and v_minus ({scene.nv},); "
            f"got {q.shape} and {v_minus.shape}"
        )
    if not (np.all(np.isfinite(q)) and np.all(np.isfinite(v_minus))):
        raise InvalidInputError(f"order_gap: q and v_minus must be finite, got q={q}, v_minus={v_minus}")
    t = check_number("order_gap", "t", t)
    if horizon is not None:
        horizon = check_number("order_gap", "horizon", horizon)
        if not horizon > 0:
            raise InvalidInputError(f"order_gap: horizon must be > 0 s, got {horizon!r}")
    if len(contacts) != 2:
        raise InvalidInputError(f"order_gap: contacts must be two contacts, got {contacts!r}")
    i, j = (_index(scene, c) for c in contacts)
    if i == j:
        raise InvalidInputError(f"order_gap: the two contacts must differ, got {scene.contact_names[i]!r} twice")
    before = tuple(sorted(_index(scene, c) for c in mode))
    if i in before or j in before:
        raise InvalidInputError(f"order_gap: a landing contact cannot already be active; mode {list(mode)!r}")
    names = scene.contact_names
    dyn = ModeDynamics(scene)
    kin = dyn.kin
    kin.update(q, v_minus)
    for k in (i, j):
        c = scene.contacts[k]
        gap, speed = c.gap(kin), float(c.rows(kin)[0] @ v_minus)
        if abs(gap) > GAP_TOL:
            raise InvalidInputError(
                f"order_gap: contact {names[k]!r} is not closed at q: gap {gap:.3g} m (|gap| must be <= {GAP_TOL:g})"
            )
        if not speed < 0.0:
            raise InvalidInputError(
                f"order_gap: contact {names[k]!r} does not approach: normal velocity {speed:.3g} m/s (must be < 0)"
            )

    # the two one-sided outcomes: sequential impacts at the same configuration
    v_after, mode_after = {}, {}
    for order in ((i, j), (j, i)):
        v, current = v_minus, before
        for _, step in landings(dyn, t, q, v_minus, before, order):
            v, current = step.v_plus, step.mode_after
        v_after[order], mode_after[order] = v, current
    whole = resolve_impact(dyn, q, v_minus, sorted(set(before) | {i, j}))
    v_sim = whole.v_plus
    sal = simultaneous_saltation(dyn, t, q, v_minus, before, (i, j))

    M = pin.crba(scene.model, scene.robot.new_data(), q)

    def m_norm(x):
        return float(np.sqrt(max(x @ M @ x, 0.0)))

    jump = m_norm(v_sim - v_minus)
    scale = jump if jump > 0 else 1.0
    dv = v_after[(i, j)] - v_after[(j, i)]
    Xa, Xb = sal.orders[(i, j)], sal.orders[(j, i)]

    def named(order):
        return tuple(names[k] for k in order)

    result = OrderGap(
        contacts=(names[i], names[j]),
        t=t,
        q=q,
        v_minus=v_minus,
        v_simultaneous=v_sim,
        v_after={named(o): v for o, v in v_after.items()},
        mode_after={named(o): tuple(_key_name(names, k) for k in m) for o, m in mode_after.items()},
        saltation_orders={named(o): X for o, X in sal.orders.items()},
        saltation_paper=sal.paper,
        impact_jump=jump,
        outcome=m_norm(dv) / scale,
        outcome_vs_simultaneous=max(m_norm(v - v_sim) for v in v_after.values()) / scale,
        outcome_abs=m_norm(dv),
        outcome_max=float(np.max(np.abs(dv))),
        saltation=_relative_gap(Xa, Xb),
        saltation_spread=sal.spread,
    )
    if horizon is not None:
        _carry_forward(scene, result, horizon, bool(jacobian), dict(simulate_options or {}), m_norm, scale)
    return result


def landings(
    dyn: ModeDynamics, t: float, q: np.ndarray, v_minus: np.ndarray, mode: tuple[int, ...], order: Sequence[int]
):
    """The impacts of one landing order at ``q``: for each contact of ``order`` that still
    approaches after the earlier ones (one sent away does not land), ``(v before, its
    `touchdown`)``, each on the mode and velocity the earlier impacts left."""
    v, current = v_minus, mode
    for k in order:
        dyn.kin.update(q, v)
        if dyn.contact(k).rows(dyn.kin)[0] @ v >= 0.0:
            continue
        step = touchdown(dyn, t, q, v, current, [k], guard=k)
        yield v, step
        v, current = step.v_plus, step.mode_after


def _carry_forward(
    scene: Scene, result: OrderGap, horizon: float, jacobian: bool, options: dict, m_norm, scale
) -> None:
    """Simulate each outcome ``horizon`` seconds from the event (the simulator picks
    the mode from the closed contacts and the post-impact velocity)."""
    from ..integration.hybrid import simulate  # the integrator imports much; only needed here

    options = {"rtol": 1e-10, "atol": 1e-12, **options}
    starts = dict(result.v_after)
    starts["simultaneous"] = result.v_simultaneous
    for key, v in starts.items():
        with_jacobian = jacobian and key != "simultaneous"
        traj = simulate(scene, result.t + horizon, q0=result.q, v0=v, t0=result.t, jacobian=with_jacobian, **options)
        result.q_later[key], result.v_later[key] = traj.q.copy(), traj.v.copy()
        if with_jacobian:
            result.jacobian_later[key] = traj.jacobian @ result.saltation_orders[key]
    orders = list(result.v_after)
    a, b = (result.v_later[k] for k in orders)
    result.horizon, result.later = horizon, m_norm(a - b) / scale
    if jacobian:
        result.later_saltation = _relative_gap(*(result.jacobian_later[k] for k in orders))


def _relative_gap(A: np.ndarray, B: np.ndarray) -> float:
    """``max|A - B| / max(1, max|A|, max|B|)``: the order-gap size of two matrices."""
    return float(np.max(np.abs(A - B))) / max(1.0, float(np.max(np.abs(A))), float(np.max(np.abs(B))))


# -- a diagonal touchdown from the standing pose ----------------------------------------
def diagonal_pairs(scene: Scene) -> tuple[tuple[int, int], tuple[int, int]]:
    """The two diagonal pairs of a quadruped scene's four contacts:
    ``(front-left, hind-right)`` and ``(front-right, hind-left)``, from the contact
    points in the base frame at the reference pose (x forward, y left)."""
    if len(scene.contacts) != 4:
        raise InvalidInputError(
            f"diagonal pairs need four contacts, scene {scene.name!r} has "
            f"{len(scene.contacts)}: {', '.join(scene.contact_names)}"
        )
    model, robot = scene.model, scene.robot
    data = model.createData()
    pin.framesForwardKinematics(model, data, robot.q_ref)
    base = data.oMi[1] if robot.floating_base else pin.SE3.Identity()
    local = [base.actInv(data.oMf[c.fid]).translation for c in scene.contacts]
    front = [k for k in range(4) if local[k][0] > 0]
    left = [k for k in range(4) if local[k][1] > 0]
    if len(front) != 2 or len(left) != 2:
        raise InvalidInputError(
            f"cannot tell front/hind and left/right feet of scene {scene.name!r} from "
            f"their base-frame positions {[p.round(3).tolist() for p in local]}"
        )
    fl = next(k for k in front if k in left)
    fr = next(k for k in front if k not in left)
    hl = next(k for k in left if k not in front)
    hr = next(k for k in range(4) if k not in front and k not in left)
    return (fl, hr), (fr, hl)


def _leg_coordinates(scene: Scene, contact: int) -> list[int]:
    """Tangent indices of the joints carrying a contact frame, the free-flyer excluded."""
    model = scene.model
    coords = []
    for jid in model.supports[model.frames[scene.contacts[contact].fid].parentJoint]:
        j = model.joints[jid]
        if jid == 0 or (scene.robot.floating_base and jid == 1):
            continue
        coords += list(range(j.idx_v, j.idx_v + j.nv))
    return coords


def diagonal_touchdown(
    scene: Scene, *, down_speed: float = 0.2, forward_speed: float = 0.4, lift: float = 0.03
) -> tuple[np.ndarray, np.ndarray, tuple[int, int]]:
    """A trot-like touchdown of the front-left/hind-right pair, built from the standing pose.

    The base keeps the reference pose and moves forward at ``forward_speed`` and
    down at ``down_speed`` (m/s, world frame). The landing feet are at their
    standing positions (gaps 0) and, through their leg joint velocities, move
    straight down at ``down_speed`` with no horizontal speed (ground-speed
    matching, as a trotting leg retracts before touchdown). The other pair is
    lifted by ``lift`` (m, inverse kinematics on its leg joints) and its joints
    are still. Needs a scene whose reference pose closes all four contacts, such
    as `Scene.from_robot`.

    Returns:
        ``(q, v, (front_left, hind_right))``: configuration, velocity just before,
        and the contact indices of the landing pair.
    """
    down_speed = check_number("diagonal_touchdown", "down_speed", down_speed, minimum=0.0)
    forward_speed = check_number("diagonal_touchdown", "forward_speed", forward_speed)
    lift = check_number("diagonal_touchdown", "lift", lift, minimum=0.0)
    if down_speed <= 0:
        raise InvalidInputError(f"diagonal_touchdown: down_speed must be > 0 m/s, got {down_speed!r}")
    landing, swinging = diagonal_pairs(scene)
    robot, kin = scene.robot, scene.kinematics
    q = robot.q_ref.copy()
    zero = np.zeros(scene.nv)
    for k in swinging:  # Gauss-Newton on the leg's joints: the foot up by `lift`, x and y kept
        kin.update(q, zero)
        target = kin.position(scene.contacts[k].fid) + np.array([0.0, 0.0, lift])
        cols = _leg_coordinates(scene, k)
        for _ in range(50):
            kin.update(q, zero)
            error = target - kin.position(scene.contacts[k].fid)
            if np.max(np.abs(error)) < 1e-12:
                break
            step = np.zeros(scene.nv)
            step[cols] = np.linalg.lstsq(kin.jacobian(scene.contacts[k].fid)[:, cols], error, rcond=None)[0]
            q = robot.integrate(q, step)
        else:
            raise InvalidInputError(f"diagonal_touchdown: cannot lift foot {scene.contact_names[k]!r} by {lift} m")
    v = np.zeros(scene.nv)
    kin.update(q, zero)
    if robot.floating_base:  # free-flyer velocity is in the base frame
        R = pin.Quaternion(q[3:7]).normalized().matrix()
        v[:3] = R.T @ np.array([forward_speed, 0.0, -down_speed])
    else:
        raise InvalidInputError(f"diagonal_touchdown needs a free-flyer robot; {robot.name!r} has a fixed base")
    for k in landing:
        cols = _leg_coordinates(scene, k)
        J = kin.jacobian(scene.contacts[k].fid)
        wanted = np.array([0.0, 0.0, -down_speed]) - J @ v
        v[cols] = np.linalg.lstsq(J[:, cols], wanted, rcond=None)[0]
    return q, v, landing


def _key_name(names, key: int) -> str:
    """Name of a contact key (`contactdiff.dynamics.mode`): a sliding contact is marked."""
    n = len(names)
    return names[key] if key < n else f"{names[key - n]} (sliding)"
