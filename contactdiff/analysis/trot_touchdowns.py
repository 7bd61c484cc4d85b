"""Diagonal touchdown states of a quadruped: where its trot lands a diagonal pair.

The states at which the decoupling checker and the order gap are measured on a
real robot (scripts/quadruped_decoupling_table.py): the diagonal touchdowns of
the robot's simulated trot (`contactdiff.control.trot_scenes`; `trot_touchdowns`),
the partner foot's gap closed along its own leg where it lands a few
milliseconds later, or one trot-like touchdown built from the standing pose
(`contactdiff.analysis.order_gap.diagonal_touchdown`). Lengths in m, speeds in
m/s, times in s; states in Pinocchio's configuration and tangent spaces.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from ..control.trot_scenes import trot_parameters, trot_scene
from ..errors import ContactDiffError, InvalidInputError
from ..integration.hybrid import simulate
from ..model.robot_files import load_robot
from ..model.scene import Scene
from .order_gap import diagonal_pairs, diagonal_touchdown

STATE_SOURCES = ("trot", "standing")
# Simulated strides of the trot, from rest (`contactdiff.control.trot_scenes`); the first touchdown of the
# run (about 60 ms in) counts like any other.
TROT_STRIDES = 2
# m: a pair counts as landing together if the partner foot is at most this far above the
# ground when the first one lands (under a third of the smallest step height, solo12's
# 3.5 cm); closing it turns the partner's leg joints by a few degrees at most.
TROT_MAX_PARTNER_GAP = 0.01
# m/s: slower landings are the micro re-contacts that follow an impact, not a foot's touchdown
# (the trots' feet land at tenths of a metre per second).
TROT_MIN_SPEED = 0.02
CLOSE_TOL = 1e-13  # m: partner gap left after closing it along its leg


class TouchdownState(NamedTuple):
    """A diagonal touchdown: both feet of ``pair`` closed and approaching.

    q (nq,), v (nv,): configuration and velocity just before (tangent space);
    pair: contact indices of the landing feet; mode: contact indices already
    active (the other pair's stance feet); t: time (s) at which the efforts are
    evaluated (the trot controller is clock-driven); partner_gap: how far (m) the
    partner foot was above the ground before its gap was closed (0 when it
    landed at the same event, or for the standing-pose state).
    """

    q: np.ndarray
    v: np.ndarray
    pair: tuple[int, int]
    mode: tuple[int, ...]
    t: float = 0.0
    partner_gap: float = 0.0


def _stderr(message: str) -> None:
    print(message, file=sys.stderr)


def touchdown_states(
    name: str, source: str = "trot", note: Callable[[str], None] = _stderr
) -> tuple[Scene, list[TouchdownState], str]:
    """Scene, diagonal touchdown states (`TouchdownState`) and a label, for robot ``name``.

    ``source="trot"`` (default): the diagonal touchdown events of the simulated
    trot of `contactdiff.control.trot_scenes` (see `trot_touchdowns`), falling back to the
    standing pose (with a ``note``, by default a line on stderr) when its
    simulation fails or it has no clean diagonal touchdown. ``source="standing"``:
    a trot-like touchdown built from the standing pose
    (`contactdiff.analysis.order_gap.diagonal_touchdown`), on `Scene.from_robot` (no efforts).
    """
    if source not in STATE_SOURCES:
        raise InvalidInputError(f"unknown state source {source!r}; valid: {', '.join(STATE_SOURCES)}")
    if source == "trot":
        try:
            scene, states = trot_touchdowns(name)
            if states:
                return scene, states, "trot touchdowns (contactdiff.control.trot_scenes)"
            reason = "no diagonal touchdown in the simulated strides"
        except (ContactDiffError, ValueError, np.linalg.LinAlgError) as exc:
            reason = f"{type(exc).__name__}: {exc}"
        note(f"note: {name}: trot not used ({reason}); standing-pose touchdown instead")
    scene = Scene.from_robot(load_robot(name))
    q, v, pair = diagonal_touchdown(scene)
    return scene, [TouchdownState(q, v, pair, ())], "standing-pose diagonal touchdown"


def trot_touchdowns(name: str, strides: float = TROT_STRIDES) -> tuple[Scene, list[TouchdownState]]:
    """Diagonal touchdowns of the simulated trot of ``name`` over ``strides`` periods.

    The simulated trot does not land a diagonal pair at one instant: one foot
    lands first (the controller's ``lag`` and the mechanics), the other a few to
    tens of milliseconds later. At each touchdown event in which a foot of a
    diagonal pair lands while neither foot of that pair is active:

    * the event's state, if the partner lands at the same event;
    * else, if the partner is above the ground by at most TROT_MAX_PARTNER_GAP
      and approaching, the event's state with the partner's gap closed along its
      own leg (Gauss-Newton on its leg joints, to CLOSE_TOL; base, velocity and
      the other legs unchanged): both feet touch, as at the simultaneous landing
      whose order gap is measured, at a state within that distance of the
      trot's.

    Both feet must approach faster than TROT_MIN_SPEED (slower landings are the
    micro re-contacts that follow an impact). ``mode`` is the stance of the
    other pair at that instant; a state in which one of its feet slides (normal
    row only) is skipped, since `order_gap` takes sticking modes. ``t`` is the
    event time: the controller's torques depend on it.

    Returns:
        ``(scene, [TouchdownState, ...])`` in time order.
    """
    scene = trot_scene(name)
    traj = simulate(scene, strides * trot_parameters(name)["period"])
    index = scene.contact_index
    kin = scene.kinematics
    sliding = set(traj.segments[0].sliding) if traj.segments else set()
    states = []
    for event in traj.events:
        sliding_before, sliding = sliding, set(event.sliding)
        if event.kind != "touchdown" or sliding_before & set(event.mode_before):
            continue
        fired = {index(c) for c in event.contacts}
        before = {index(c) for c in event.mode_before}
        for pair in diagonal_pairs(scene):
            if not fired & set(pair) or before & set(pair):
                continue
            q, partner_gap, closed = event.q.copy(), 0.0, True
            for partner in set(pair) - fired:
                kin.update(q, np.zeros(scene.nv))
                partner_gap = scene.contacts[partner].gap(kin)
                moved = _close_gap(scene, q, partner)
                if moved is None:
                    closed = False
                    break
                q = moved
            if not closed:
                continue
            kin.update(q, event.v_minus)
            if all(scene.contacts[k].rows(kin)[0] @ event.v_minus < -TROT_MIN_SPEED for k in pair):
                states.append(
                    TouchdownState(
                        q,
                        event.v_minus.copy(),
                        pair,
                        tuple(sorted(before - set(pair))),
                        float(event.t),
                        float(partner_gap),
                    )
                )
    return scene, states


def _close_gap(scene: Scene, q: np.ndarray, contact: int) -> np.ndarray | None:
    """``q`` with contact's gap closed by its own leg joints, or None if it is too far."""
    kin, c = scene.kinematics, scene.contacts[contact]
    zero = np.zeros(scene.nv)
    kin.update(q, zero)
    if not 0 <= c.gap(kin) <= TROT_MAX_PARTNER_GAP:
        return None
    joint = scene.model.frames[c.fid].parentJoint
    cols = [
        k
        for j in scene.model.supports[joint]
        if j > 1
        for k in range(scene.model.joints[j].idx_v, scene.model.joints[j].idx_v + scene.model.joints[j].nv)
    ]
    for _ in range(50):
        kin.update(q, zero)
        gap = c.gap(kin)
        if abs(gap) <= CLOSE_TOL:
            return q
        row = c.rows(kin)[0][cols]
        step = np.zeros(scene.nv)
        step[cols] = -gap * row / (row @ row)
        q = scene.robot.integrate(q, step)
    return None
