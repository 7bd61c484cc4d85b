"""A held corner at rest that would slide in its enlarged set: its reference's angle
carried in the flow Jacobian.

The scene: the measured cube (`contactdiff.cube_scene`, μ = 1.5, e = 0) at rest on its
face under a push fixed in the cube's frame, ``F(t) = (F0 - k t) m g (cos a, sin a, 0)``
at the centre (F0 = 0.8, k = 1 /s, a = 0.6 rad), and a couple about the vertical
``τ0 + c t²`` (τ0 = 0.05 N m, c = 18 N m/s²). At t = 0 the trailing corner -x-y-z would
pull (the push's pitch moment unloads it past zero: its compatible load on four corners
is ``m g / 4 - F (|cos a| + |sin a|) / 4`` below ``0`` for F0 = 0.8): it is released,
held at zero gap by the three others, which stick and fix the cube. In the enlarged set
(the face with it) its sticking force pulls, so Coulomb's law makes it bear sliding, from
rest, along ``r = -λ_T/|λ_T|`` of that force (`contactdiff.integration.held`). That ``r``
is a function of the state and the parameters at the mode's start, carried as an
onset's angle ``θ`` (`HeldEvents._held_onsets`): ``w = ∂θ/∂(x0, p)``.

Closed forms. The push and the couple turn with the cube, gravity is vertical and the
ground is the plane z = 0, so the scene is symmetric under a turn ψ about the world's
vertical: the run from the start turned by ψ is the nominal run turned by ψ. Hence
``∂θ/∂ψ = 1`` (``r`` is in the world's tangent axes), and the flow Jacobian's yaw column
at T is the derivative of the turned final state, ``d/dψ (R_z(ψ) M(T))`` at ψ = 0 (in the
free flyer's tangent space; the body-frame velocity does not change). The push's size
``F0`` moves ``r`` at fixed state: checked against central differences of the
reference set at perturbed starts.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from helpers import spy_salted

import contactdiff as cd
from contactdiff.integration.held import HeldEvents

P = cd.CubeParameters()
B, MASS, G = P.edge / 2, P.mass, P.gravity
MU, ANGLE, RATE, GROWTH = 1.5, 0.6, 1.0, 18.0
F0, TAU0 = 0.8, 0.05
CORNER = "cube/-x-y-z"
PUSH_DIRECTION = np.array([np.cos(ANGLE), np.sin(ANGLE), 0.0])


def _push(q, v, t, F0, tau0):
    return np.r_[(F0 - RATE * t) * MASS * G * PUSH_DIRECTION, 0.0, 0.0, tau0 + GROWTH * t * t]


def _push_rate(q, v, t, F0, tau0):
    return np.r_[-RATE * MASS * G * PUSH_DIRECTION, 0.0, 0.0, 2.0 * GROWTH * t]


def pushed_cube():
    """The cube at rest on its face with the push and couple of the module doc."""
    base = cd.cube_scene(friction=MU, restitution=0.0)
    effort = cd.UserEffort(_push, name="push", time_derivative=_push_rate, parameters={"F0": F0, "tau0": TAU0})
    scene = cd.Scene(base.robot, base.contact_specs, efforts=[effort])
    return scene.with_state(np.r_[0.0, 0.0, B, 0.0, 0.0, 0.0, 1.0], np.zeros(6))


def _start(scene, **options):
    """The loop's start (its mode, the field that watches the held corner): the loop, and
    the angle (rad) of the held corner's reference in the world's tangent axes."""
    loop = cd.HybridLoop(scene, 0.0, 0.1, options=cd.SimulateOptions(**options))
    q, v = scene.q0.copy(), scene.v0.copy()
    mode, v = loop.initial_mode(q, v)
    loop._field(mode, True, 0.0, q, v)
    r = loop.dyn.slip_reference[scene.contact_names.index(CORNER)]
    return loop, float(np.arctan2(r[1], r[0]))


def test_the_held_corners_reference_angle_has_its_derivatives():
    """``w`` of the held corner at the start: 1 along the yaw (the symmetry, module doc),
    0 along the horizontal position, and ``∂θ/∂F0`` against central differences of the
    angle the start sets. The angle is a smooth function of the forces (solved to
    round-off, ~1e-15 relative): central differences with step 1e-6 carry ~1e-15/1e-6 =
    1e-9 of round-off and ~1e-12 of truncation, so 1e-7 absolute (rad per unit) is a 100x
    margin; without the term ``w`` is absent."""
    scene = pushed_cube()
    loop, theta = _start(scene, jacobian=True, parameters=["effort:push:F0"])
    index = scene.contact_names.index(CORNER)
    w = loop.onsets[index]
    assert w.shape == (13,)
    assert w[5] == pytest.approx(1.0, abs=1e-9)  # yaw: the symmetry (round-off of the solves)
    np.testing.assert_allclose(w[[0, 1, 2, 6, 7, 8, 9, 10, 11]], 0.0, atol=1e-9)
    eps = 1e-6
    angles = [_start(scene.with_parameters({"effort:push:F0": F0 + s * eps}))[1] for s in (1.0, -1.0)]
    fd = (angles[0] - angles[1]) / (2 * eps)
    assert abs(fd) > 0.1  # rad per unit of F0: the push's size moves the reference
    assert w[12] == pytest.approx(fd, abs=1e-7)
    # yaw by differences too (the start turned: the reference turns with it)
    angles = [
        _start(scene.with_state(pin.integrate(scene.model, scene.q0, s * eps * np.eye(6)[5])))[1] for s in (1.0, -1.0)
    ]
    assert (angles[0] - angles[1]) / (2 * eps) == pytest.approx(w[5], abs=1e-7)


def _turned_column(scene, traj) -> np.ndarray:
    """The flow Jacobian's yaw column by the symmetry (module doc): central difference of the
    final state turned by ±ε about the world's vertical (exact turns: truncation ε² ~ 1e-12)."""
    eps = 1e-6
    turned = []
    for s in (1.0, -1.0):
        M = pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, s * eps), np.zeros(3)) * pin.XYZQUATToSE3(traj.q)
        turned.append(pin.SE3ToXYZQUAT(M))
    return np.r_[pin.difference(scene.model, turned[1], turned[0]), np.zeros(6)] / (2 * eps)


@pytest.mark.slow
def test_flow_jacobian_through_the_held_corners_bearing_turns_with_the_cube(monkeypatch):
    """The run to T = 0.15 s: the corner is released at t = 0, a side corner leaves its cone
    (its slip from rest, at zero speed: the cube is held), the held corner bears sliding at
    0.081 s with the reference set at t = 0, and the two others leave their cones: the face
    spins from 0.109 s with the held corner's slip in the band. The yaw column of the flow
    Jacobian against the symmetry's (module doc): the run's error at rtol 1e-10 on a column
    of size 1, with its events located to ~1e-12 s, is ~1e-10; 1e-9 keeps a 10x margin.
    Without the held corner's term the column misses by 1.4e-8 (measured), 14x that."""
    scene = pushed_cube()
    T, options = 0.15, dict(rtol=1e-10, atol=1e-12, max_step=2e-3)  # steps short enough to see the cones' crossings
    traj = cd.simulate(scene, T, jacobian=True, **options)
    kinds = [(e.kind, e.contacts) for e in traj.events]
    assert kinds[0] == ("lift-off", (CORNER,)) and ("bear", (CORNER,)) in kinds and traj.differentiable
    reference = _turned_column(scene, traj)
    assert np.abs(traj.jacobian[:, 5] - reference).max() <= 1e-9
    monkeypatch.setattr(HeldEvents, "_held_onsets", lambda self, *args, **kwargs: None)
    held = cd.simulate(scene, T, jacobian=True, **options)
    assert np.abs(held.jacobian[:, 5] - reference).max() > 1e-9


def test_held_contacts_returns_the_references_it_sets():
    """`held_contacts` in the mode the corner's lift-off at t = 0 leaves (the slow run's
    first event: the three other bottom corners sticking, the corner at zero gap and at
    rest) returns the held corner with the slip references it set on the dynamics: each
    entry the very array now in ``dyn.slip_reference``, of unit norm, and the held
    corner's the direction Coulomb's law gives it in the enlarged set,
    ``r = -λ_T / |λ_T|`` of its sticking force when the face and it all stick (the corner
    is at rest: the first round of `settle_friction`). That force comes from the same
    deterministic solve, so 1e-12 only allows for the norm's rounding."""
    from contactdiff.integration.held import enlarged, held_contacts

    scene = pushed_cube()
    loop = cd.HybridLoop(scene, 0.0, 0.1, options=cd.SimulateOptions())
    q, v, dyn = scene.q0.copy(), scene.v0.copy(), loop.dyn
    index = scene.contact_names.index(CORNER)
    mode = tuple(scene.contact_names.index(f"cube/{c}-z") for c in ("+x+y", "+x-y", "-x+y"))
    gaps, rates = loop.gaps_and_rates(q, v)
    tol = max(loop.gap_tol, loop.options.resolved_project_tol)
    held, references = held_contacts(dyn, q, v, 0.0, mode, gaps, rates, tol, loop.options.grazing_speed)
    assert set(held) == {index} and index in references
    for k, r in references.items():
        assert dyn.slip_reference[k] is r
        assert np.linalg.norm(r) == pytest.approx(1.0, abs=1e-15)
    sticking = enlarged(mode, index)
    f = dyn.solve(q, v, 0.0, sticking).row_forces()[sticking.index(index)]
    assert f[0] < 0.0  # it would pull: the reason it bears sliding
    np.testing.assert_allclose(references[index], -f[1:] / np.linalg.norm(f[1:]), atol=1e-12)


def test_the_events_saltation_product_is_formed_once(monkeypatch):
    """At the corner's lift-off (t = 0) and the side corner's slip (0.062 s) the mode after
    holds the corner at rest: its onset (`HeldEvents._held_onsets`) and the stepper's restart
    (`EventJacobians.after`) both read ``Ξ φ`` of the event: read twice, formed once
    (`EventJacobians.salted`)."""
    reads, formed = spy_salted(monkeypatch)
    onsets, held_onsets = [], HeldEvents._held_onsets

    def onset_spy(self, t, q, v, mode, found, start):
        onsets.append(len(self.events))
        return held_onsets(self, t, q, v, mode, found, start)

    monkeypatch.setattr(HeldEvents, "_held_onsets", onset_spy)
    traj = cd.simulate(pushed_cube(), 0.065, jacobian=True, rtol=1e-10, atol=1e-12, max_step=2e-3)
    assert [(e.kind, e.contacts) for e in traj.events] == [("lift-off", (CORNER,)), ("slip", ("cube/+x-y-z",))]
    assert onsets == [1, 2]  # after each of the two events
    for event in traj.events:
        assert reads[id(event)] == 2 and formed[id(event)] == 1
