"""A slip that jams on Painlevé's boundary stops there (`contactdiff.integration.jam`).

References: the closed form of Painlevé's rod (its tip's normal force and slip
deceleration), and physical laws on the ANYmal trot at μ = 0.8, whose left hind foot's
slip turns into a direction of the paradox in its last microseconds (a run that stopped
with `PainleveError` at t = 0.306 s before the jam was modelled): the normal force grows
without bound as the slip stops, and the stop's reset only removes the slip left.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
from helpers import rod_urdf

import contactdiff as cd
from contactdiff.dynamics.mode import ModeDynamics
from contactdiff.errors import PainleveError
from contactdiff.integration.guards import GuardKind
from contactdiff.integration.jam import jammed_slip
from contactdiff.integration.trajectory import EventKind, NonSmooth
from contactdiff.model.contacts import Contact
from contactdiff.ode.step_collapse import COLLAPSE_RATIO

HALF, MASS, MU, THETA = 0.5, 1.0, 1.4, 0.6  # m, kg, -, rad: g > 0 (the slip has a solution)
G0 = 9.81  # m/s²


@pytest.fixture(scope="module")
def rod(tmp_path_factory):
    path = tmp_path_factory.mktemp("jam") / "rod.urdf"
    path.write_text(rod_urdf(HALF, MASS))
    return cd.load_robot(path)


def rod_time_left(theta: float, mu: float) -> float:
    """Time (s) a tip sliding at 1 m/s along +x with ``θ̇ = 0`` needs to stop at its present
    deceleration. With ``g m = 1 + 3 cos²θ - 3 μ sin θ cos θ`` the tip's normal force is
    ``λ = 9.81 / g``; the contact force ``(-μ λ, λ)`` at the tip ``(l cos θ, -l sin θ)`` from
    the centre gives ``ẍ = -μ λ / m`` and ``θ̈ = λ l (μ sin θ - cos θ) / I`` with
    ``I = m l² / 3``; the tip's slip rate ``ẍ - l sin θ θ̈`` (``θ̇ = 0``) is then
    ``-(λ / m) [μ + 3 sin θ (μ sin θ - cos θ)]``."""
    s, c = math.sin(theta), math.cos(theta)
    lam = G0 * MASS / (1.0 + 3.0 * c * c - 3.0 * mu * s * c)
    return 1.0 / ((lam / MASS) * (mu + 3.0 * s * (mu * s - c)))


def test_jam_needs_a_slip_that_ends_within_a_collapsed_step(rod):
    """`jammed_slip` on the rod's sliding tip: its time left is the closed form's; it is a jam
    only where that time is shorter than a collapsed step of the run, only for a contact
    that slips in the mode, and only for an error that names one."""
    q0 = np.array([0.0, HALF * math.sin(THETA), THETA])  # tip on the ground
    v0 = np.array([1.0, 0.0, 0.0])  # the tip slides at 1 m/s along +x
    scene = cd.Scene(rod, [Contact("tip", friction=MU)], gravity=[0, 0, -G0], q0=q0, v0=v0)
    dyn = ModeDynamics(scene)
    sliding = (dyn.sliding_key(0),)
    exc = PainleveError("at the boundary", contact=0)
    expected = rod_time_left(THETA, MU)  # 0.0248 s
    # a run whose typical step makes that time a collapsed step (typical > time / COLLAPSE_RATIO)
    jam = jammed_slip(dyn, 0.0, q0, v0, sliding, 2.0 * expected / COLLAPSE_RATIO, exc)
    assert jam is not None
    assert jam.guard.kind is GuardKind.STOP and jam.guard.contact == sliding[0]
    assert jam.speed == pytest.approx(1.0, rel=1e-14)
    assert jam.time_left == pytest.approx(expected, rel=1e-12)  # a few roundings of the solve
    assert "tip" in jam.remark(scene.contact_names)
    # a run of millisecond steps: 25 ms left is a slip going on, not a jam
    assert jammed_slip(dyn, 0.0, q0, v0, sliding, 1e-3, exc) is None
    assert jammed_slip(dyn, 0.0, q0, v0, sliding, 1e9, PainleveError("several", contact=None)) is None
    assert jammed_slip(dyn, 0.0, q0, np.zeros(3), (0,), 1e9, exc) is None  # the tip sticks in that mode


@pytest.fixture(scope="module")
def anymal_jam():
    scene = cd.load_scene("anymal_trot").with_friction(0.8)
    traj = cd.simulate(scene, 0.32)
    return scene, traj


def test_anymal_trot_passes_the_left_hind_foot_jam(anymal_jam):
    """The trot at μ = 0.8 runs through t = 0.306 s: the left hind foot's slip stops at a jam,
    a stop event flagged `NonSmooth.PAINLEVE_JAM`, after which the foot sticks."""
    scene, traj = anymal_jam
    assert traj.t == 0.32
    jams = [e for e in traj.events if NonSmooth.PAINLEVE_JAM in e.nonsmooth]
    assert len(jams) == 1
    jam = jams[0]
    assert jam.kind is EventKind.STICK and "LH_FOOT" in jam.contacts
    assert "LH_FOOT" in jam.mode_after and "LH_FOOT" not in jam.sliding
    assert 0.30 < jam.t < 0.31  # s
    assert not jam.differentiable and not traj.differentiable


def _slip_velocity(model, data, q, v, frame: str) -> np.ndarray:
    """The foot's tangential velocity (m/s, world x-y)."""
    pin.forwardKinematics(model, data, q, v)
    return pin.getFrameVelocity(model, data, model.getFrameId(frame), pin.LOCAL_WORLD_ALIGNED).linear[:2]


def _normal_force(scene, dyn, segment, t, q, v, contact: str) -> float:
    """The normal force (N) of ``contact`` in ``segment``'s mode at ``(q, v)``."""
    names = scene.contact_names
    mode = tuple(
        sorted(dyn.sliding_key(names.index(c)) if c in segment.sliding else names.index(c) for c in segment.mode)
    )
    index = names.index(contact)
    key = dyn.sliding_key(index) if contact in segment.sliding else index
    return float(dyn.solve(q, v, t, mode).normal_forces()[mode.index(key)])


def test_anymal_jam_is_a_slip_stopped_by_an_unbounded_normal_force(anymal_jam):
    """The jam's physics: from the start of the foot's slip to the jam its normal force grows
    by more than a hundred times, to more than a thousand times the robot's weight
    (``λ = b / g`` with ``g -> 0``); the slip left at the jam is under a hundredth of the slip
    at its start, and the reset removes it (the foot's slip velocity after is zero to
    round-off) M-orthogonally: the kinetic energy does not rise."""
    scene, traj = anymal_jam
    jam = next(e for e in traj.events if NonSmooth.PAINLEVE_JAM in e.nonsmooth)
    end = next(i for i, s in enumerate(traj.segments) if s.t1 == jam.t and s.t1 > s.t0)
    first = end
    while "LH_FOOT" in traj.segments[first - 1].sliding:  # back to the segment the slip started in
        first -= 1
    assert "LH_FOOT" in traj.segments[end].sliding and first < end
    start = [e for e in traj.events if e.t == traj.segments[first].t0][-1]
    dyn = ModeDynamics(scene)
    at_start = _normal_force(scene, dyn, traj.segments[first], start.t, start.q, start.v_plus, "LH_FOOT")
    at_jam = _normal_force(scene, dyn, traj.segments[end], jam.t, jam.q, jam.v_minus, "LH_FOOT")
    model = scene.model
    data = model.createData()
    weight = pin.computeTotalMass(model) * G0  # N
    assert 0.0 < at_start < 10 * weight
    assert at_jam > 1e3 * weight and at_jam > 100 * at_start
    slip_start = np.linalg.norm(_slip_velocity(model, data, start.q, start.v_plus, "LH_FOOT"))
    slip_left = np.linalg.norm(_slip_velocity(model, data, jam.q, jam.v_minus, "LH_FOOT"))
    assert slip_left < 1e-2 * slip_start
    slip_after = np.linalg.norm(_slip_velocity(model, data, jam.q, jam.v_plus, "LH_FOOT"))
    assert slip_after < 1e-12  # m/s: round-off of joint speeds ~ 1
    M = pin.crba(model, data, jam.q)
    M = np.triu(M) + np.triu(M, 1).T
    kinetic = 0.5 * jam.v_minus @ M @ jam.v_minus
    energy_change = 0.5 * jam.v_plus @ M @ jam.v_plus - kinetic
    assert energy_change <= 1e-15 * kinetic * 100  # J: a projection removes energy; 100 eps of round-off
