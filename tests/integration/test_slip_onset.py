"""A 3-D slip that starts from rest at an angle to its reference direction, with the
flow Jacobian and a parameter's derivative.

The scene: a uniform cube (half edge b = 0.05 m, m = 0.4 kg, μ = 1) standing on one
bottom corner, turned by 0.6 rad about y and 0.02 rad about x so that only that corner
touches, turning about y at -11 rad/s, under gravity tilted by 0.2 rad towards +y. The
corner sticks until its sticking force leaves the cone (t ≈ 0.0122 s) and then slips
from zero speed. Its reference direction is the sticking force's, ``r = -λ_T/|λ_T|``,
but the slip grows along ``W r`` (W the corner's tangential inverse mass, not a
multiple of the identity for a point off the centre's vertical): 55° apart here. Below
the noise floor ε (``zeno_speed``) the slip follows ``r``, between ε and 2ε it turns to
its own direction (`contactdiff.dynamics.slip`). With the flow Jacobian that turn
collapsed the steps (`StepCollapseError`) before the turn was C^∞ and the reference was
held through it.

The derivative. The run's flow depends on ``r`` while the slip is below 2ε, and ``r``
depends on the state at the onset; the flow Jacobian holds ``r`` fixed (the onset's
saltation matrix is I), so it is the derivative of the runs whose onset takes the
nominal run's ``r``: checked against central differences of such runs. Against free
runs it misses ``∂x/∂r ∂r/∂x0``, a term that lasts only while the slip is below 2ε:
from a cone crossing the slip grows as ``|u_T| ≈ c (t - t_s)²``, below 2ε for
``τ = (2ε/c)^½``, so the term shrinks with the floor (checked).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from scipy.linalg import null_space

import contactdiff as cd
from contactdiff.integration.friction_events import FrictionEvents
from contactdiff.model.objects import SceneObject, add_objects, empty_robot

G, B, MASS, MU = 9.81, 0.05, 0.4, 1.0
CORNER = "cube/-x+y-z"
T = 0.03  # s: after the onset (~0.0122 s); nothing else happens before 0.04 s
OPTS = dict(rtol=1e-10, atol=1e-12)
# Event times: a cone crossing is located to the forces' integration error (~1e-10 N
# relative to O(1) N) over the margin's rate (O(10) N/s): ~1e-11 s; 1e-8 s is the
# face-friction tests' margin for rtol 1e-10.
EVENT_ATOL = 1e-8  # s
# Central differences with ε = 1e-5 (m/s; and 1e-5 |m| for the mass): two runs each
# within ~1e-10 |x| (|x| ~ 1) of their flows differ by at most 2e-10, over 2ε: 1e-5 of a
# column of size ~1; truncation ε² |x'''| ~ 1e-10. 2e-5 of the column's size keeps a 2x
# margin; the omitted reference term (free runs) is 4x-20x above it here.
EPS, FD_RTOL = 1e-5, 2e-5


def corner_scene():
    """The cube on its corner ``-x+y-z`` (module doc), at rest at that corner."""
    cube = SceneObject("cube", shape="box", size=(2 * B,) * 3, mass=MASS, position=(0.0, 0.0, B))
    corners = [f"cube/{sx}x{sy}y-z" for sx in "+-" for sy in "+-"]
    side = 0.2  # rad: gravity tilted towards +y
    scene = cd.Scene(add_objects(empty_robot(), [cube]), [cd.Contact(n, friction=MU) for n in corners],
                     gravity=(0.0, G * np.sin(side), -G * np.cos(side)))
    rotation = pin.rpy.rpyToMatrix(-0.02, -0.6, 0.0)
    centre = -rotation @ np.array([-B, B, -B])  # the corner at the origin
    omega = np.array([0.0, 11.0, 0.0])  # rad/s, world: turning about y through the corner
    v = np.r_[rotation.T @ np.cross(omega, centre), rotation.T @ omega]
    return scene.with_state(np.r_[centre, pin.Quaternion(rotation).coeffs()], v)


def _events(traj):
    return [(e.kind, e.contacts) for e in traj.events]


@pytest.fixture(scope="module")
def onset():
    scene = corner_scene()
    plain = cd.simulate(scene, T, **OPTS)
    traj = cd.simulate(scene, T, jacobian=True, parameters=["body:cube:mass"], **OPTS)
    return scene, plain, traj


def test_the_corner_slips_from_rest_off_its_reference_and_the_jacobian_run_finishes(onset):
    scene, plain, traj = onset
    assert _events(plain) == _events(traj) == [("slip", (CORNER,))]
    assert traj.events[0].t == pytest.approx(plain.events[0].t, abs=EVENT_ATOL)
    assert traj.t == T and traj.differentiable
    kin = scene.kinematics
    contact = scene.contacts[scene.contact_names.index(CORNER)]
    e = traj.events[0]
    kin.update(e.q, e.v_plus)
    assert np.linalg.norm(contact.rows(kin)[1:] @ e.v_plus) < 1e-9  # m/s: it starts from rest
    kin.update(traj.q, traj.v)
    u = contact.rows(kin)[1:] @ traj.v
    assert np.linalg.norm(u) > 1e-3  # m/s at T: it slips on, far above the band


def _hold_reference(monkeypatch, scene, reference):
    """Make every run's slip onset take ``reference`` as the corner's reference direction
    (the Jacobian's assumption, module doc) until ``monkeypatch.undo()``."""
    index = scene.contact_names.index(CORNER)
    original = FrictionEvents._friction_event

    def held(self, *args, **kwargs):
        out = original(self, *args, **kwargs)
        if index in self.dyn.slip_reference:
            self.dyn.slip_reference[index] = reference.copy()
        return out

    monkeypatch.setattr(FrictionEvents, "_friction_event", held)


def _runs(scene, states, **options):
    """Plain runs to T from the ``(q, v)`` in ``states``."""
    return [cd.simulate(scene.with_state(q, v), T, **{**OPTS, **options}) for q, v in states]


def _reference_of(scene, traj):
    """The slip's reference at its onset in ``traj``: the sticking force's direction there."""
    e = traj.events[0]
    mode = tuple(scene.contact_names.index(n) for n in e.mode_before)
    dyn = cd.ModeDynamics(scene)
    f = dict(zip(mode, dyn.solve(e.q, e.v_minus, e.t, mode).row_forces()))[scene.contact_names.index(CORNER)]
    return -f[1:] / np.linalg.norm(f[1:])


def _directions(scene):
    """Velocity perturbations that keep the corner on the ground and at rest (the null space
    of its three rows): the perturbed starts need no projection."""
    kin = scene.kinematics
    kin.update(scene.q0, scene.v0)
    rows = scene.contacts[scene.contact_names.index(CORNER)].rows(kin)
    assert np.abs(rows @ scene.v0).max() < 1e-12
    return null_space(rows).T


def _fd(scene, runs):
    plus, minus = runs
    return np.r_[pin.difference(scene.model, minus.q, plus.q), plus.v - minus.v] / (2 * EPS)


def test_flow_jacobian_through_the_onset_matches_finite_differences_at_the_same_reference(onset, monkeypatch):
    scene, _, traj = onset
    reference = _reference_of(scene, traj)
    q, v = scene.q0, scene.v0
    for d in _directions(scene):
        _hold_reference(monkeypatch, scene, reference)
        runs = _runs(scene, [(q, v + EPS * d), (q, v - EPS * d)])
        monkeypatch.undo()
        assert all(_events(r) == _events(traj) for r in runs)
        fd, exact = _fd(scene, runs), traj.jacobian[:, scene.nv:] @ d
        assert np.abs(exact - fd).max() <= FD_RTOL * np.abs(fd).max(), np.abs(exact - fd).max()


def test_mass_derivative_through_the_onset_matches_finite_differences(onset, monkeypatch):
    """``body:cube:mass`` with the moments of inertia fixed: the ratio of the corner's
    translational to rotational inverse mass changes, and with it the onset and the slip."""
    scene, _, traj = onset
    reference = _reference_of(scene, traj)
    h = EPS * MASS
    _hold_reference(monkeypatch, scene, reference)
    runs = [cd.simulate(scene.with_parameters({"body:cube:mass": MASS + s * h}), T, **OPTS) for s in (1.0, -1.0)]
    monkeypatch.undo()
    assert all(_events(r) == _events(traj) for r in runs)
    fd = np.r_[pin.difference(scene.model, runs[1].q, runs[0].q), runs[0].v - runs[1].v] / (2 * h)
    exact = traj.parameter_jacobian[:, 0]
    assert np.abs(exact - fd).max() <= FD_RTOL * np.abs(fd).max(), np.abs(exact - fd).max()


def test_the_reference_term_the_jacobian_omits_shrinks_with_the_floor():
    """Against free runs (each onset takes its own reference) the Jacobian misses the
    reference's term, which lasts while the slip is below 2ε: τ = (2ε/c)^½ (module doc), so
    a floor 10x lower shrinks it by about 10^½ ≈ 3.2; asserted: by more than 2 (the slip's
    growth is not exactly quadratic over τ). It is the whole disagreement: at the same
    reference the differences agree (the test above)."""
    scene = corner_scene()
    d = _directions(scene)[0]
    q, v = scene.q0, scene.v0
    misses = []
    for floor in (1e-5, 1e-6):
        traj = cd.simulate(scene, T, jacobian=True, zeno_speed=floor, **OPTS)
        runs = _runs(scene, [(q, v + EPS * d), (q, v - EPS * d)], zeno_speed=floor)
        assert all(_events(r) == _events(traj) for r in runs)
        fd = _fd(scene, runs)
        misses.append(np.abs(traj.jacobian[:, scene.nv:] @ d - fd).max() / np.abs(fd).max())
    assert misses[1] < misses[0] / 2.0, misses
    assert misses[1] > FD_RTOL  # the term is there, above the differences' noise
