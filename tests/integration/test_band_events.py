"""Events while a slip from rest still follows its onset's reference (the band below 2ε,
`contactdiff.integration.band`), with the flow Jacobian and a parameter's derivative.

A slip from rest follows the reference ``r`` its onset set (``θ`` its angle) until it is
faster than 2ε, and the flow Jacobian carries ``θ`` as a parameter born at the onset
(test_slip_onset). An event in the band:

* a touchdown reads no force and its impact law reads the velocities only: the term the
  flow Jacobian carried up to it is the whole dependence (the code before this said, in a
  note, that the reference was held from there: it was not needed);
* a cone crossing of another contact reads the forces, which move with ``θ`` through the
  slip's friction: its time moves by ``-h_θ w / rate`` (``h_θ`` the cone margin's
  derivative at a fixed state, ``w = ∂θ/∂`` the onset's row), and the flow after it by
  ``(F+ - F-) h_θ w / rate``; the slip that goes on in the band keeps its term;
* a stop of the band's own slip is not formed: a note says so.

Central differences as in test_slip_onset (``EPS``, ``FD_RTOL``: two runs each within
~1e-10 of their flows, over 2 ``EPS``, and a 2x margin).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from scipy.linalg import null_space
from test_slip_onset import (
    EPS,
    FD_RTOL,
    MASS,
    OPTS,
    B,
    G,
    _directions,
    _events,
    _fd,
    _mass_fd,
    corner_scene,
)

import contactdiff as cd
from contactdiff.integration.band import BandEvents, guard_reference_rates
from contactdiff.integration.guards import Guard, GuardKind
from contactdiff.model.objects import SceneObject, add_objects, empty_robot

EDGE = ("cube/-x+y-z", "cube/-x-y-z")
# a cone crossing is located to the forces' integration error over the margin's rate,
# ~1e-11 s (test_slip_onset's EVENT_ATOL); over 2 EPS that is 1e-6 s per unit of a column:
# 1e-5 keeps a 10x margin (the code before this missed the yaw column's by 6e-2 s/rad)
TIME_ATOL = 1e-5


def edge_scene(mu: float, pitch: float = -0.3, side: float = 0.3, efforts=()):
    """The cube of `test_slip_onset.corner_scene` (μ = ``mu``) at rest on its bottom edge
    -x (corners ``-x±y-z``), pitched by ``pitch`` rad about y about that edge, under gravity
    tilted by ``side`` rad towards +y, with ``efforts``."""
    cube = SceneObject("cube", shape="box", size=(2 * B,) * 3, mass=MASS, position=(0.0, 0.0, B))
    corners = [f"cube/{sx}x{sy}y-z" for sx in "+-" for sy in "+-"]
    scene = cd.Scene(
        add_objects(empty_robot(), [cube]),
        [cd.Contact(n, friction=mu) for n in corners],
        list(efforts),
        gravity=(0.0, G * np.sin(side), -G * np.cos(side)),
    )
    rotation = pin.rpy.rpyToMatrix(0.0, pitch, 0.0)
    centre = -rotation @ np.array([-B, 0.0, -B])
    return scene.with_state(np.r_[centre, pin.Quaternion(rotation).coeffs()], np.zeros(6))


def _without_the_band_terms(monkeypatch):
    """The code before the band's events were formed: every onset's term ends at an event in
    the band, with a note (until ``monkeypatch.undo()``)."""
    monkeypatch.setattr(BandEvents, "_band_guard", lambda self, *args: False)


def _yawed(scene, angle: float) -> np.ndarray:
    """``scene.q0`` turned by ``angle`` (rad) about the world's vertical through the origin
    (the edge stays on the ground)."""
    turn = pin.rpy.rpyToMatrix(0.0, 0.0, angle)
    q = scene.q0.copy()
    q[:3] = turn @ q[:3]
    q[3:7] = pin.Quaternion(turn @ pin.Quaternion(q[3:7]).matrix()).coeffs()
    return q


def _yaw_direction(scene) -> np.ndarray:
    """The tangent (2nv,) of `_yawed` at 0: the free flyer's local velocity of a turn about
    the world's z through the origin, ``(Rᵀ (ẑ × p), Rᵀ ẑ)``."""
    rotation = pin.Quaternion(scene.q0[3:7]).matrix()
    z = np.array([0.0, 0.0, 1.0])
    return np.r_[rotation.T @ np.cross(z, scene.q0[:3]), rotation.T @ z, np.zeros(6)]


def test_a_touchdown_inside_the_band_is_exact_without_a_note():
    """The corner of `corner_scene` slips from rest (t ≈ 0.0122 s) and, with ε = 0.2 m/s, is
    still slower than 2ε when the next corner lands (t ≈ 0.052 s): the landing's guard is a gap
    and the impact law reads velocities, so the flow Jacobian at 0.054 s matches central
    differences of free runs along `_directions` (measured 2e-8 of the columns) and no note
    says the reference is held (the code before this left one)."""
    scene = corner_scene()
    traj = cd.simulate(scene, 0.054, jacobian=True, zeno_speed=0.2, **OPTS)
    assert [e.kind for e in traj.events] == ["slip", "touchdown"]
    assert not any("reference direction" in n for n in traj.notes), traj.notes
    for d in _directions(scene):
        runs = [
            cd.simulate(scene.with_state(scene.q0, scene.v0 + s * EPS * d), 0.054, zeno_speed=0.2, **OPTS)
            for s in (1.0, -1.0)
        ]
        assert all(_events(r) == _events(traj) for r in runs)
        fd = _fd(scene, runs)
        assert np.abs(traj.jacobian[:, scene.nv :] @ d - fd).max() <= FD_RTOL * np.abs(fd).max()


@pytest.fixture(scope="module")
def crossing():
    """The edge scene with μ = 0.55 and ε = 1e-3 m/s: ``-x-y-z`` slips from rest at the start
    (its reference set there) and ``-x+y-z`` sticks until its cone margin reaches zero at
    t ≈ 0.027 s, while the first slip is still below 2ε (test below)."""
    scene = edge_scene(0.55)
    options = dict(zeno_speed=1e-3, **OPTS)
    traj = cd.simulate(scene, 0.035, jacobian=True, parameters=["body:cube:mass"], **options)
    return scene, options, traj


def test_a_cone_crossing_inside_the_band_moves_with_the_reference(crossing, monkeypatch):
    """A stick → slip event of ``-x+y-z`` while ``-x-y-z`` slips from rest in the band: the
    cone margin ``μ λ_N - |λ_T|`` reads the forces, which move with ``θ``. At 0.035 s the flow
    Jacobian along the yaw of the start (the edge stays on the ground, the slip's reference
    turns with it) and along the roll about the edge (the null space of the edge's rows: its
    corners stay at rest), and the mass derivative, against central differences of free runs
    (``FD_RTOL``); the event's time gradient along the yaw and in the mass against central
    differences of the event times (``TIME_ATOL``). The code before this ended the term at the
    crossing with a note and missed the yaw column by 5.2e-2 and the mass derivative by
    3.6e-2 of their sizes (measured). Asserted here: without the crossing's ``h_θ`` and the
    term after it (`_without_the_band_terms`, the later slip's chain to the first kept) they
    miss by more than 4 ``FD_RTOL`` (measured 1.2e-2 and 8.6e-3)."""
    scene, options, traj = crossing
    kinds = [("slip", (EDGE[0],))]
    assert _events(traj) == kinds and traj.segments[0].sliding == (EDGE[1],)
    assert not any("reference direction" in n for n in traj.notes), traj.notes
    _without_the_band_terms(monkeypatch)
    held = cd.simulate(scene, 0.035, jacobian=True, parameters=["body:cube:mass"], **options)
    monkeypatch.undo()
    assert any("reference direction" in n for n in held.notes)
    event = traj.events[0]
    yaw = _yaw_direction(scene)
    runs = [cd.simulate(scene.with_state(_yawed(scene, s * EPS), scene.v0), 0.035, **options) for s in (1.0, -1.0)]
    assert all(_events(r) == kinds for r in runs)
    fd = _fd(scene, runs)
    scale = np.abs(fd).max()
    assert np.abs(traj.jacobian @ yaw - fd).max() <= FD_RTOL * scale
    assert np.abs(held.jacobian @ yaw - fd).max() > 4 * FD_RTOL * scale
    t_fd = (runs[0].events[0].t - runs[1].events[0].t) / (2 * EPS)
    assert abs(event.time_gradient @ yaw - t_fd) <= TIME_ATOL
    kin = scene.kinematics
    kin.update(scene.q0, scene.v0)
    rows = np.vstack([scene.contacts[scene.contact_names.index(n)].rows(kin) for n in EDGE])
    (roll,) = null_space(rows).T
    runs = [cd.simulate(scene.with_state(scene.q0, s * EPS * roll), 0.035, **options) for s in (1.0, -1.0)]
    assert all(_events(r) == kinds for r in runs)
    fd = _fd(scene, runs)
    assert np.abs(traj.jacobian[:, scene.nv :] @ roll - fd).max() <= FD_RTOL * np.abs(fd).max()
    fd, runs = _mass_fd(scene, 0.035, **options)
    assert all(_events(r) == kinds for r in runs)
    scale = np.abs(fd).max()
    assert np.abs(traj.parameter_jacobian[:, 0] - fd).max() <= FD_RTOL * scale
    assert np.abs(held.parameter_jacobian[:, 0] - fd).max() > 4 * FD_RTOL * scale
    t_fd = (runs[0].events[0].t - runs[1].events[0].t) / (2 * EPS * MASS)
    assert abs(event.parameter_time_gradient[0] - t_fd) <= TIME_ATOL


def test_a_stop_of_the_band_slip_itself_ends_the_term_with_a_note():
    """With μ = 0.7 only ``-x-y-z`` slips from rest, and its own slip's stop guard fires while
    it is still below 2ε (t ≈ 0.059 s): that guard's dependence on the reference is not formed
    (`contactdiff.integration.band`), and a note says the reference is held from there."""
    traj = cd.simulate(edge_scene(0.7), 0.06, jacobian=True, zeno_speed=1e-3, **OPTS)
    assert _events(traj) == [("slip", (EDGE[1],))]
    assert any(EDGE[1] in n and "holds the reference direction" in n for n in traj.notes), traj.notes


@pytest.mark.parametrize("kind, corner", [("force", 0), ("force", 1), ("cone", 0)])
def test_a_guards_reference_rate_matches_central_differences(crossing, kind, corner):
    """``h_θ`` of a guard that reads the forces (`guard_reference_rates`), at the state just
    before the crossing of the test above, where ``-x-y-z`` slips in the band: the normal force
    of either edge corner and the cone margin of the sticking one, against central differences
    of the guard's value over a turn of the slip's reference by ±δ at that fixed state. δ = 1e-6
    rad: the forces (~1 N) are solved to ~1e-14 relative, so the differences are good to
    ~1e-8 N/rad, and their truncation δ² |h'''| ~ 1e-12: 1e-7 (N/rad) of the rate's size keeps
    a 10x margin."""
    scene, options, traj = crossing
    event = traj.events[0]
    loop = cd.HybridLoop(scene, 0.0, 1.0, options=cd.SimulateOptions(zeno_speed=options["zeno_speed"]))
    dyn, names = loop.dyn, scene.contact_names
    sticking, slipping = (names.index(n) for n in EDGE)
    mode = tuple(sorted((sticking, dyn.sliding_key(slipping))))
    q, v, t = event.q, event.v_minus, event.t
    dyn.kin.update(q, v)
    u_T = dyn.contact(dyn.sliding_key(slipping)).full.rows(dyn.kin)[1:] @ v
    assert np.linalg.norm(u_T) < 2 * options["zeno_speed"]  # in the band: s depends on r
    key = [sticking, dyn.sliding_key(slipping)][corner]
    guard = Guard(GuardKind.FORCE if kind == "force" else GuardKind.CONE, key)
    r = np.array([np.cos(0.4), np.sin(0.4)])  # any reference: h_θ is a derivative at a fixed state

    def value(angle):
        c, s = np.cos(angle), np.sin(angle)
        dyn.slip_reference[slipping] = np.array([c * r[0] - s * r[1], s * r[0] + c * r[1]])
        sol = dyn.solve(q, v, t, mode)
        f = sol.forces[sol.row_slices[mode.index(key)]]
        return f[0] if kind == "force" else dyn.contact(key).spec.mu * f[0] - np.linalg.norm(f[1:])

    delta = 1e-6
    fd = (value(delta) - value(-delta)) / (2 * delta)
    dyn.slip_reference[slipping] = r
    _, rates = guard_reference_rates(dyn, t, q, v, mode, guard, {slipping: None})
    assert abs(rates[slipping] - fd) <= 1e-7 * max(1.0, abs(fd)), (rates, fd)
    assert abs(fd) > 1e-3  # the guard does move with the reference


ROLL_RATE = 10.0  # N m/s: the torque ramp of `lifting_scene`


def lifting_scene():
    """The edge scene (pitch -0.3 rad, gravity tilted by 0.3 rad towards +y) with μ = 0.8 and a
    torque about the body's -x growing as ``ROLL_RATE t`` (no dependence on the state: its
    Jacobians are zero): it rolls the cube towards +y, unloading ``-x-y-z``. That corner
    slips from rest (its cone margin reaches zero at t ≈ 7.2e-4 s) and its normal force
    reaches zero at t ≈ 5.9e-3 s, a lift-off while its slip is still below 2ε for ε = 0.05
    m/s (test below)."""
    torque = np.array([0.0, 0.0, 0.0, -ROLL_RATE, 0.0, 0.0])
    effort = cd.UserEffort(
        lambda q, v, t: t * torque,
        lambda q, v, t: (np.zeros((6, 6)), np.zeros((6, 6))),
        name="roll",
        time_derivative=lambda q, v, t: torque,
    )
    return edge_scene(0.8, efforts=[effort])


LIFTING = dict(zeno_speed=0.05, **OPTS)
LIFTING_T = 0.008  # s: after the lift-off, before anything else
LIFTING_KINDS = [("slip", (EDGE[1],)), ("lift-off", (EDGE[1],))]


class _StopAtTheSecondEvent(cd.HybridLoop):
    """A run that ends just after its second event, keeping the flow Jacobian just before it."""

    def on_event(self, event, mode_before, phi_before):
        self.phi_before = phi_before
        return len(self.events) == 2


def test_the_recorded_blocks_rebuild_the_flow_jacobian_through_a_band_event():
    """The lift-off of `lifting_scene` (a guard reading the forces, in the band), in a run
    stopped just after it, so that its flow Jacobian is the one just after the event: the
    flow Jacobian just before it (``phi_before``) carried through the event's recorded blocks,
    ``Ξ Φ- + reference_jump`` and ``Ξ Φ-_p + Ξ_p + parameter_reference_jump`` (`Event`), is
    the run's flow Jacobian and mass derivative, to the round-off of the products (entries
    O(1)-O(10), 1e-12 of the largest). The band's term ``(F+ - F-) h_θ w / rate`` is recorded
    and vanishes here: at a lift-off the field is continuous (the normal force that reaches
    zero is the contact's only force through ``μ λ_N``), as at a cone crossing (the slip's
    friction equals the sticking force) and a bear (the held contact's load is zero), so the
    saltation alone carries the flow Jacobian through, to the event's location error (1e-9 of
    the Jacobian's size, ~1e3 times the sizes measured, 1e-31)."""
    scene = lifting_scene()
    opts = cd.SimulateOptions(jacobian=True, parameters=("body:cube:mass",), **LIFTING)
    loop = _StopAtTheSecondEvent(scene, 0.0, LIFTING_T, options=opts)
    traj = loop.run()
    assert _events(traj) == LIFTING_KINDS
    event = traj.events[1]
    assert event.reference_jump is not None and event.parameter_reference_jump is not None
    n = 2 * scene.nv
    phi = loop.phi_before
    state = event.saltation @ phi[:, :n] + event.reference_jump
    mass = event.saltation @ phi[:, n:] + event.parameter_saltation + event.parameter_reference_jump
    scale = np.abs(traj.jacobian).max()
    assert np.abs(state - traj.jacobian).max() <= 1e-12 * scale
    assert np.abs(event.reference_jump).max() <= 1e-9 * scale
    scale = np.abs(traj.parameter_jacobian).max()
    assert np.abs(mass - traj.parameter_jacobian).max() <= 1e-12 * scale
    assert np.abs(event.parameter_reference_jump).max() <= 1e-9 * scale
    record = event.to_dict()
    assert np.array_equal(record["reference_jump"], event.reference_jump)
    assert np.array_equal(record["parameter_reference_jump"], event.parameter_reference_jump)


def test_a_liftoff_inside_the_band_matches_central_differences():
    """The lift-off of `lifting_scene` while the lifting corner's own slip from rest is in the
    band (its guard, the normal force, reads the slip's friction through ``θ``): at
    ``LIFTING_T`` the flow Jacobian along the yaw of the start and the roll about the edge
    (as in the cone crossing's test) and the mass derivative match central differences of free
    runs (``FD_RTOL``), and the lift-off's time gradient along the yaw and in the mass matches
    the differences of the event times (``TIME_ATOL``: located to ~1e-11 s, over 2 ``EPS``).
    Measured: 1.7e-10 and 9.2e-10 of the columns, 1.6e-13 s and 7.9e-14 s/kg. The lift-off's own
    ``h_θ`` is small here (a run that ends the band's term at the lift-off, with a note, differs
    from this one in the 7th digit of the time gradient): the test checks the lift-off in the
    band, not that term's size."""
    scene = lifting_scene()
    traj = cd.simulate(scene, LIFTING_T, jacobian=True, parameters=["body:cube:mass"], **LIFTING)
    assert _events(traj) == LIFTING_KINDS
    assert not traj.notes, traj.notes
    event = traj.events[1]
    yaw = _yaw_direction(scene)
    runs = [cd.simulate(scene.with_state(_yawed(scene, s * EPS), scene.v0), LIFTING_T, **LIFTING) for s in (1.0, -1.0)]
    assert all(_events(r) == LIFTING_KINDS for r in runs)
    fd = _fd(scene, runs)
    assert np.abs(traj.jacobian @ yaw - fd).max() <= FD_RTOL * np.abs(fd).max()
    t_fd = (runs[0].events[1].t - runs[1].events[1].t) / (2 * EPS)
    assert abs(event.time_gradient @ yaw - t_fd) <= TIME_ATOL
    kin = scene.kinematics
    kin.update(scene.q0, scene.v0)
    rows = np.vstack([scene.contacts[scene.contact_names.index(n)].rows(kin) for n in EDGE])
    (roll,) = null_space(rows).T
    runs = [cd.simulate(scene.with_state(scene.q0, s * EPS * roll), LIFTING_T, **LIFTING) for s in (1.0, -1.0)]
    assert all(_events(r) == LIFTING_KINDS for r in runs)
    fd = _fd(scene, runs)
    assert np.abs(traj.jacobian[:, scene.nv :] @ roll - fd).max() <= FD_RTOL * np.abs(fd).max()
    fd, runs = _mass_fd(scene, LIFTING_T, **LIFTING)
    assert all(_events(r) == LIFTING_KINDS for r in runs)
    assert np.abs(traj.parameter_jacobian[:, 0] - fd).max() <= FD_RTOL * np.abs(fd).max()
    t_fd = (runs[0].events[1].t - runs[1].events[1].t) / (2 * EPS * MASS)
    assert abs(event.parameter_time_gradient[0] - t_fd) <= TIME_ATOL
