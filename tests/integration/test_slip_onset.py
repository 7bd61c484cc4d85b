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
depends on the state (and the parameters) at the onset. The flow Jacobian carries that
term, ``∂x/∂r ∂r/∂x0`` (`contactdiff.integration.mode_field.ModeField`: every column of
the variational equation is forced with ``∂f/∂θ ∂θ/∂x0`` while the slip is in the band,
``θ`` the angle of ``r``), so it is the derivative of free runs, each onset taking its
own reference: checked against central differences of such runs. Without the term (the
code before it was carried) the Jacobian missed it by 4.5e-4 of a column at the default
floor ε = 1e-6 m/s and 2.2e-3 at ε = 1e-5 (from a cone crossing the slip grows as
``|u_T| ≈ c (t - t_s)²``, below 2ε for ``τ = (2ε/c)^½``), and the mass derivative by
1.1e-4: 23x, 110x and 5.5x the tolerance of the differences (``FD_RTOL``).

The other slips from rest, whose references Coulomb's law sets as it settles a mode: at
the start (a spring-held point mass; a cube on its edge whose second corner leaves its
cone once the first slips, its reference then moving with the first one's angle), after
an impact, and after the start's impact. Events inside the band: test_band_events.
"""

from __future__ import annotations

import coulomb_models
import numpy as np
import pinocchio as pin
import pytest
from scipy.linalg import null_space
from test_anisotropic_stop import ANISO_URDF

import contactdiff as cd
from contactdiff.integration import event_resets, friction_events, hybrid_loop
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
# margin; the reference term the Jacobian omitted before is 5x-110x above it (module doc).
EPS, FD_RTOL = 1e-5, 2e-5


def corner_scene():
    """The cube on its corner ``-x+y-z`` (module doc), at rest at that corner."""
    cube = SceneObject("cube", shape="box", size=(2 * B,) * 3, mass=MASS, position=(0.0, 0.0, B))
    corners = [f"cube/{sx}x{sy}y-z" for sx in "+-" for sy in "+-"]
    side = 0.2  # rad: gravity tilted towards +y
    scene = cd.Scene(
        add_objects(empty_robot(), [cube]),
        [cd.Contact(n, friction=MU) for n in corners],
        gravity=(0.0, G * np.sin(side), -G * np.cos(side)),
    )
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


def _runs(scene, states, **options):
    """Plain runs to T from the ``(q, v)`` in ``states``."""
    return [cd.simulate(scene.with_state(q, v), T, **{**OPTS, **options}) for q, v in states]


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


def _mass_fd(scene, t_final, **options):
    """Central differences (step ``EPS`` of the mass) of the state at ``t_final`` in the cube's
    mass ``body:cube:mass`` (tangent space), and the two runs."""
    h = EPS * MASS
    runs = [
        cd.simulate(scene.with_parameters({"body:cube:mass": MASS + s * h}), t_final, **options) for s in (1.0, -1.0)
    ]
    return np.r_[pin.difference(scene.model, runs[1].q, runs[0].q), runs[0].v - runs[1].v] / (2 * h), runs


def _without_the_onset_term(monkeypatch):
    """Make the runs carry no onset term (the flow Jacobian before it was carried) until
    ``monkeypatch.undo()``."""
    monkeypatch.setattr(FrictionEvents, "_onset_columns", lambda self, *args: None)


def _misses(scene, traj, floor):
    """Largest difference between ``traj``'s flow Jacobian and central differences of free runs
    along each of `_directions`, relative to the differences' largest entry."""
    q, v = scene.q0, scene.v0
    out = []
    for d in _directions(scene):
        runs = _runs(scene, [(q, v + EPS * d), (q, v - EPS * d)], zeno_speed=floor)
        assert all(_events(r) == _events(traj) for r in runs)
        fd = _fd(scene, runs)
        out.append(np.abs(traj.jacobian[:, scene.nv :] @ d - fd).max() / np.abs(fd).max())
    return np.array(out)


@pytest.mark.parametrize("floor", [1e-6, 1e-5])
def test_flow_jacobian_through_the_onset_matches_free_runs(floor, monkeypatch):
    """The velocity columns along the perturbations that keep the corner at rest (each onset
    takes its own reference): within ``FD_RTOL`` of central differences of free runs. The
    term is there: without it the Jacobian misses by more than 4 ``FD_RTOL`` along one of
    them (module doc: 23x and 110x measured)."""
    scene = corner_scene()
    traj = cd.simulate(scene, T, jacobian=True, zeno_speed=floor, **OPTS)
    misses = _misses(scene, traj, floor)
    assert misses.max() <= FD_RTOL, misses
    _without_the_onset_term(monkeypatch)
    held = cd.simulate(scene, T, jacobian=True, zeno_speed=floor, **OPTS)
    monkeypatch.undo()
    assert np.abs(held.jacobian - traj.jacobian).max() > 4 * FD_RTOL * np.abs(traj.jacobian).max()
    assert _misses(scene, held, floor).max() > 4 * FD_RTOL


def test_mass_derivative_through_the_onset_matches_free_runs(onset, monkeypatch):
    """``body:cube:mass`` with the moments of inertia fixed: the ratio of the corner's
    translational to rotational inverse mass changes, and with it the onset, its reference
    (the sticking force's direction) and the slip. Free runs: within ``FD_RTOL`` of central
    differences; without the onset term it missed by 1.1e-4 (module doc), asserted above
    2 ``FD_RTOL``."""
    scene, _, traj = onset
    fd, runs = _mass_fd(scene, T, **OPTS)
    assert all(_events(r) == _events(traj) for r in runs)
    exact = traj.parameter_jacobian[:, 0]
    assert np.abs(exact - fd).max() <= FD_RTOL * np.abs(fd).max(), np.abs(exact - fd).max()
    _without_the_onset_term(monkeypatch)
    held = cd.simulate(scene, T, parameters=["body:cube:mass"], **OPTS)
    monkeypatch.undo()
    assert np.abs(held.parameter_jacobian[:, 0] - fd).max() > 2 * FD_RTOL * np.abs(fd).max()


def test_a_start_at_rest_outside_the_cone_carries_its_reference_term(tmp_path_factory, monkeypatch):
    """A slip from rest at the start (Coulomb's law settled at t0, no event): the anisotropic point
    mass of ``test_anisotropic_stop`` (``M = diag(3, 2, 2)`` kg on sliders x, y, z, μ = 0.5) held
    by a spring ``f = -k (x, y)`` (k = 100 N/m) at rest at (0.12, 0.1) m: the spring's pull,
    15.6 N, exceeds ``μ m g`` = 9.81 N, so it slips from rest along ``r = -λ_T/|λ_T|``, the
    pull's direction, a function of q0, and grows along ``W r`` (W = diag(1/3, 1/2)). With
    ε = 1e-3 m/s the band lasts long enough for the term to be ~1e-4 of a column. Columns along
    x0 and y0 against central differences (`coulomb_models`: rtol = atol = 1e-12, step 1e-6,
    ``FD_RTOL`` = 1e-5 of the Jacobian's scale); without the term they miss by more than
    4 ``FD_RTOL`` (measured 6.3e-5 and 8.7e-5 of the columns)."""
    robot = coulomb_models.load(tmp_path_factory, "aniso", ANISO_URDF)
    k = 100.0  # N/m
    spring = cd.UserEffort(
        lambda q, v, t: np.array([-k * q[0], -k * q[1], 0.0]),
        lambda q, v, t: (np.diag([-k, -k, 0.0]), np.zeros((3, 3))),
        name="spring",
        time_derivative=lambda q, v, t: np.zeros(3),
    )
    scene = cd.Scene(
        robot,
        [cd.Contact("block", friction=coulomb_models.MU)],
        [spring],
        gravity=[0, 0, -coulomb_models.G],
        q0=np.array([0.12, 0.1, 0.0]),
        v0=np.zeros(3),
    )
    options = dict(zeno_speed=1e-3, **coulomb_models.TOL)
    step, rtol = coulomb_models.EPS, coulomb_models.FD_RTOL
    t_final = 0.3  # s: before its first stop (~0.5 s)
    traj = cd.simulate(scene, t_final, jacobian=True, **options)
    assert traj.events == [] and traj.segments[0].sliding == ("block",)
    _without_the_onset_term(monkeypatch)
    held = cd.simulate(scene, t_final, jacobian=True, **options)
    monkeypatch.undo()
    for d in np.eye(6)[:2]:
        runs = [
            cd.simulate(scene.with_state(robot.integrate(scene.q0, s * step * d[:3]), scene.v0), t_final, **options)
            for s in (1.0, -1.0)
        ]
        assert all(r.events == [] for r in runs)
        fd = np.r_[robot.difference(runs[1].q, runs[0].q), runs[0].v - runs[1].v] / (2 * step)
        scale = max(1.0, np.abs(fd).max())
        assert np.abs(traj.jacobian @ d - fd).max() <= rtol * scale
        assert np.abs(held.jacobian @ d - fd).max() > 4 * rtol * scale


def test_a_start_whose_second_corner_slips_once_the_first_does(monkeypatch):
    """Two slips from rest at the start, the second set by the first (a later round of
    `settle_friction`): the cube (as `corner_scene`, μ = 0.5) at rest on its edge -x, -z (corners
    ``-x±y-z``), pitched by -0.3 rad about y about that edge, under gravity tilted by 0.3 rad
    towards +y. Corner ``-x-y-z`` leaves its cone first; slipping, its friction is ``μ λ_N``
    along its reference, and the loads it leaves push ``-x+y-z`` out of its cone too, so that
    corner's reference depends on the first one's angle as well as on the state and the mass.
    With ε = 1e-3 m/s (a long band) the mass derivative at 5 ms against central differences
    (tolerance ``FD_RTOL``, module doc); without the second reference's dependence on the first
    (the chain term) it misses by 9.8e-4, without any onset term by 5.7e-3 (measured), asserted
    above 4 ``FD_RTOL``."""
    cube = SceneObject("cube", shape="box", size=(2 * B,) * 3, mass=MASS, position=(0.0, 0.0, B))
    corners = [f"cube/{sx}x{sy}y-z" for sx in "+-" for sy in "+-"]
    side = 0.3  # rad
    scene = cd.Scene(
        add_objects(empty_robot(), [cube]),
        [cd.Contact(n, friction=0.5) for n in corners],
        gravity=(0.0, G * np.sin(side), -G * np.cos(side)),
    )
    rotation = pin.rpy.rpyToMatrix(0.0, -0.3, 0.0)
    scene = scene.with_state(np.r_[-rotation @ np.array([-B, 0.0, -B]), pin.Quaternion(rotation).coeffs()], np.zeros(6))
    options = dict(zeno_speed=1e-3, **OPTS)
    t_final = 0.005  # s: no event before
    rounds = []
    settle = hybrid_loop.settle_friction

    def spy(dyn, q, v, t, mode, from_rest=None):
        out = settle(dyn, q, v, t, mode, from_rest)
        rounds.extend(from_rest or [])
        return out

    monkeypatch.setattr(hybrid_loop, "settle_friction", spy)
    traj = cd.simulate(scene, t_final, parameters=["body:cube:mass"], **options)
    monkeypatch.undo()
    names = scene.contact_names
    assert [names[i] for i, _ in rounds] == ["cube/-x-y-z", "cube/-x+y-z"] and rounds[0][1] != rounds[1][1]
    assert traj.events == [] and traj.segments[0].sliding == ("cube/-x+y-z", "cube/-x-y-z")
    fd, runs = _mass_fd(scene, t_final, **options)
    assert all(r.events == [] for r in runs)
    scale = np.abs(fd).max()
    assert np.abs(traj.parameter_jacobian[:, 0] - fd).max() <= FD_RTOL * scale
    monkeypatch.setattr(friction_events, "reference_turn", lambda *args: None)  # no chain term
    unchained = cd.simulate(scene, t_final, parameters=["body:cube:mass"], **options)
    _without_the_onset_term(monkeypatch)
    held = cd.simulate(scene, t_final, parameters=["body:cube:mass"], **options)
    monkeypatch.undo()
    for run in (unchained, held):
        assert np.abs(run.parameter_jacobian[:, 0] - fd).max() > 4 * FD_RTOL * scale


def _landing_scene():
    """The cube of `corner_scene` with μ = 0.3 and restitution 0, at rest 2 mm above its corner
    ``-x+y-z``, under gravity tilted by 0.2 rad towards +y (the next two tests)."""
    cube = SceneObject("cube", shape="box", size=(2 * B,) * 3, mass=MASS, position=(0.0, 0.0, B))
    corners = [f"cube/{sx}x{sy}y-z" for sx in "+-" for sy in "+-"]
    side = 0.2  # rad
    scene = cd.Scene(
        add_objects(empty_robot(), [cube]),
        [cd.Contact(n, friction=0.3, restitution=0.0) for n in corners],
        gravity=(0.0, G * np.sin(side), -G * np.cos(side)),
    )
    rotation = pin.rpy.rpyToMatrix(-0.02, -0.6, 0.0)
    centre = -rotation @ np.array([-B, B, -B]) + np.array([0.0, 0.0, 0.002])
    return scene.with_state(np.r_[centre, pin.Quaternion(rotation).coeffs()], np.zeros(6))


def test_a_corner_that_slips_from_rest_after_its_landing(monkeypatch):
    """A slip from rest that Coulomb's law settles after an impact: the cube (as `corner_scene`,
    μ = 0.3, restitution 0) dropped from 2 mm above its corner ``-x+y-z``, at rest, under gravity
    tilted by 0.2 rad towards +y. That corner lands and slides (t ≈ 0.0204 s); then ``-x-y-z``
    lands (t ≈ 0.0283 s), the impact stops its slip, and its sticking force there leaves the cone:
    it slips from rest along that force's direction, a function of the state after the impact
    (its reset Jacobian, the landing's time). With ε = 1e-3 m/s (a long band), at 31 ms, the
    velocity columns along v_x0 and ω_z0 and the mass derivative against central differences
    (tolerance ``FD_RTOL``, module doc); without the onset term the mass derivative misses by
    1.65e-4 (measured), asserted above 4 ``FD_RTOL``."""
    scene = _landing_scene()
    options = dict(zeno_speed=1e-3, **OPTS)
    t_final = 0.031  # s
    rounds = []
    settle = friction_events.settle_friction

    def spy(dyn, q, v, t, mode, from_rest=None):
        out = settle(dyn, q, v, t, mode, from_rest)
        rounds.extend((t, i) for i, _ in from_rest or [])
        return out

    monkeypatch.setattr(event_resets, "settle_friction", spy)
    traj = cd.simulate(scene, t_final, jacobian=True, parameters=["body:cube:mass"], **options)
    monkeypatch.undo()
    kinds = _events(traj)
    assert kinds == [("touchdown", ("cube/-x+y-z",)), ("touchdown", ("cube/-x-y-z",))]
    assert [(t, scene.contact_names[i]) for t, i in rounds] == [(traj.events[1].t, "cube/-x-y-z")]
    assert traj.events[1].sliding == ("cube/-x+y-z", "cube/-x-y-z")
    for k in (6, 11):  # v_x0 and ω_z0: the cube starts in the air, any perturbation is admissible
        d = np.eye(2 * scene.nv)[k]
        runs = [
            cd.simulate(scene.with_state(scene.q0, scene.v0 + s * EPS * d[scene.nv :]), t_final, **options)
            for s in (1.0, -1.0)
        ]
        assert all(_events(r) == kinds for r in runs)
        fd = _fd(scene, runs)
        assert np.abs(traj.jacobian @ d - fd).max() <= FD_RTOL * np.abs(fd).max()
    fd, runs = _mass_fd(scene, t_final, **options)
    assert all(_events(r) == kinds for r in runs)
    scale = np.abs(fd).max()
    assert np.abs(traj.parameter_jacobian[:, 0] - fd).max() <= FD_RTOL * scale
    _without_the_onset_term(monkeypatch)
    held = cd.simulate(scene, t_final, parameters=["body:cube:mass"], **options)
    monkeypatch.undo()
    assert np.abs(held.parameter_jacobian[:, 0] - fd).max() > 4 * FD_RTOL * scale


def test_a_start_on_a_landing_whose_corner_slips_from_rest_after_it(monkeypatch):
    """The start's impact (no guard, its reset alone) followed by a slip from rest: the previous
    test's run started at its second landing (the state just before it, from the run itself),
    where ``-x+y-z`` slides and ``-x-y-z`` closes at t0. Velocity columns along the directions
    that keep ``-x+y-z`` on the ground (the null space of its normal row: a perturbation off it
    would start it leaving) and the mass derivative at 3 ms against central differences
    (tolerance ``FD_RTOL``, module doc); without the onset term the mass derivative misses by
    1.48e-4 (measured), asserted above 4 ``FD_RTOL``."""
    options = dict(zeno_speed=1e-3, **OPTS)
    landing = _landing_scene()
    second = cd.simulate(landing, 0.031, **options).events[1]
    scene = landing.with_state(second.q, second.v_minus)
    t_final = 0.003  # s
    traj = cd.simulate(scene, t_final, jacobian=True, parameters=["body:cube:mass"], **options)
    kinds = [("touchdown", ("cube/-x+y-z", "cube/-x-y-z"))]
    assert _events(traj) == kinds and traj.events[0].t == 0.0
    assert traj.events[0].sliding == ("cube/-x+y-z", "cube/-x-y-z")
    kin = scene.kinematics
    kin.update(scene.q0, scene.v0)
    for d in null_space(scene.contacts[scene.contact_names.index("cube/-x+y-z")].rows(kin)[:1]).T:
        runs = [
            cd.simulate(scene.with_state(scene.q0, scene.v0 + s * EPS * d), t_final, **options) for s in (1.0, -1.0)
        ]
        assert all(_events(r) == kinds for r in runs)
        fd = _fd(scene, runs)
        assert np.abs(traj.jacobian[:, scene.nv :] @ d - fd).max() <= FD_RTOL * np.abs(fd).max()
    fd, runs = _mass_fd(scene, t_final, **options)
    assert all(_events(r) == kinds for r in runs)
    scale = np.abs(fd).max()
    assert np.abs(traj.parameter_jacobian[:, 0] - fd).max() <= FD_RTOL * scale
    _without_the_onset_term(monkeypatch)
    held = cd.simulate(scene, t_final, parameters=["body:cube:mass"], **options)
    monkeypatch.undo()
    assert np.abs(held.parameter_jacobian[:, 0] - fd).max() > 4 * FD_RTOL * scale
