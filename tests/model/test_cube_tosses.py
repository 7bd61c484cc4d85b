"""The measured cube tosses: the shipped subset, the reader's checks, the cube scene."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import contactdiff as cd
from contactdiff.data.cube_tosses import SUBSET

SHARED_TOSSES = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "cube_tosses" / "tosses.npz"


def test_the_shipped_subset_loads_with_its_license():
    tosses = cd.load_tosses()
    assert len(tosses) == 24 and all(name.startswith("toss_") for name in tosses)
    folder = resources.files("contactdiff.data")
    assert "BSD 3-Clause" in folder.joinpath("LICENSE_cube_tosses").read_text()
    assert len(folder.joinpath(SUBSET).read_bytes()) < 1_000_000
    for toss in tosses.values():
        assert len(toss) >= 2 and np.all(np.diff(toss.t) > 0.0)
        np.testing.assert_allclose(np.linalg.norm(toss.quaternion, axis=1), 1.0, rtol=1e-12)


@pytest.mark.skipif(
    not SHARED_TOSSES.is_file(), reason="the full set of tosses (shared data) is not beside the repository"
)
def test_the_full_set_loads():
    tosses = cd.load_tosses(SHARED_TOSSES)
    assert len(tosses) == 450
    subset = cd.load_tosses()
    for name, toss in subset.items():  # the subset is a byte-for-byte copy of those tosses
        np.testing.assert_array_equal(toss.position, tosses[name].position)


def test_a_sample_as_the_scene_state():
    """``q`` is Pinocchio's ``[x y z qx qy qz qw]``; ``v`` has the linear velocity in the
    cube's frame, so turning it back with the measured orientation gives the board-frame
    velocity of the data; the angular velocity is the data's (already in the cube frame)."""
    toss = cd.load_tosses()["toss_000"]
    q, v = toss.state(3)
    np.testing.assert_allclose(q[:3], toss.position[3])
    w, x, y, z = toss.quaternion[3]
    np.testing.assert_allclose(q[3:], [x, y, z, w])
    rotation = pin.Quaternion(q[3:]).matrix()
    np.testing.assert_allclose(rotation @ v[:3], toss.velocity[3], atol=1e-15)
    np.testing.assert_allclose(v[3:], toss.omega[3])
    with pytest.raises(cd.InvalidInputError, match="out of range"):
        toss.state(len(toss))


def _write(tmp_path, **arrays):
    path = tmp_path / "bad.npz"
    np.savez(path, **arrays)
    return path


def _good(n=5):
    a = np.zeros((n, 14))
    a[:, 0] = np.arange(n) / 148
    a[:, 4] = 1.0
    return a


@pytest.mark.parametrize(
    "change, message",
    [
        (lambda a: a[:, :13], r"\(n, 14\) array"),
        (lambda a: a[:1], "at least two samples"),
        (lambda a: np.where(np.arange(14) == 2, np.nan, a), "not finite"),
        (lambda a: a[[0, 2, 1, 3, 4]], "times must increase"),
        (lambda a: np.where(np.arange(14) >= 4, 0.0, a), "quaternion of zero norm"),
    ],
)
def test_bad_tosses_are_named_with_the_file(tmp_path, change, message):
    path = _write(tmp_path, toss_001=change(_good()))
    with pytest.raises(cd.InvalidInputError, match=message) as info:
        cd.load_tosses(path)
    assert "bad.npz" in str(info.value) and "toss_001" in str(info.value)


def test_bad_files(tmp_path):
    with pytest.raises(cd.InvalidInputError, match="does not exist"):
        cd.load_tosses(tmp_path / "none.npz")
    text = tmp_path / "text.npz"
    text.write_text("not an archive")
    with pytest.raises(cd.InvalidInputError, match="not a readable .npz"):
        cd.load_tosses(text)
    with pytest.raises(cd.InvalidInputError, match="no arrays named toss_"):
        cd.load_tosses(_write(tmp_path, other=_good()))


def test_cube_scene_holds_the_nominal_cube():
    """Mass 0.37 kg, moments 8.1e-4 kg m² about each axis, eight Coulomb corners at
    ±edge/2 with μ 0.18 and e 0.125; resting on a face its centre is edge/2 above the
    board (at ``ground``)."""
    scene = cd.cube_scene(ground=0.001)
    inertia = scene.model.inertias[1]
    assert inertia.mass == pytest.approx(0.37)
    np.testing.assert_allclose(inertia.inertia, 8.1e-4 * np.eye(3))
    assert len(scene.contacts) == 8
    assert {c.spec.mu for c in scene.contacts} == {0.18}
    assert {c.restitution for c in scene.contacts} == {0.125}
    assert scene.q0[2] == pytest.approx(0.001 + 0.1048 / 2)
    with pytest.raises(cd.InvalidInputError, match="mass must be > 0"):
        cd.cube_scene(mass=0.0)


def test_object_moments_are_checked():
    with pytest.raises(cd.InvalidInputError, match="not those of a body"):
        cd.SceneObject("b", shape="box", size=(1, 1, 1), mass=1.0, moments=(1.0, 1.0, 3.0))
    with pytest.raises(cd.InvalidInputError, match="must be > 0"):
        cd.SceneObject("b", shape="box", size=(1, 1, 1), mass=1.0, moments=-1.0)
    box = cd.SceneObject("b", shape="box", size=(1, 1, 1), mass=1.0, moments=(0.2, 0.3, 0.4))
    np.testing.assert_allclose(box.inertia().inertia, np.diag([0.2, 0.3, 0.4]))


@pytest.mark.skipif(
    not SHARED_TOSSES.is_file(), reason="the full set of tosses (shared data) is not beside the repository"
)
@pytest.mark.parametrize("name, mu, e", [("toss_066", 0.5, 0.0), ("toss_170", 0.5, 0.3)])
def test_a_landing_order_whose_slip_vanishes_is_flagged_not_fatal(name, mu, e):
    """Regression: a hypothetical landing order of a two-corner touchdown leaves a corner sliding
    with zero slip (its impulse on its cone's edge), whose slip direction has no derivative;
    the reset's Jacobian divided by the zero slip speed and LinAlgError stopped the run. Now
    the order is unresolved, the event flagged, and the toss runs to its end."""
    toss = cd.load_tosses(SHARED_TOSSES)[name]
    traj = cd.simulate(cd.cube_scene(friction=mu, restitution=e).with_state(*toss.state(0)), toss.t[-1])
    assert traj.t == toss.t[-1]
    vanishing = [n for n in traj.notes if "slides with a slip of" in n and "stick/slip threshold" in n]
    assert vanishing
    assert any(not ev.differentiable for ev in traj.events)


@pytest.mark.skipif(
    not SHARED_TOSSES.is_file(), reason="the full set of tosses (shared data) is not beside the repository"
)
def test_a_corner_an_impact_leaves_open_slides_on_and_the_jacobian_run_finishes():
    """Regression (toss 16, nominal): the Zeno impact that ends a two-corner cascade on a
    sliding edge leaves the edge's corner -x+y-z open (no impulse, zero normal speed) while
    it slips at 0.66 m/s. Its key after the impact was read from the impact's scene index,
    not from its sliding key before, so it kept a sticking key: the face slid 0.11 s with that
    corner at constant slip, until a cone crossing and a stop at the same instant removed the
    slip without an impulse, and the run with the flow Jacobian stopped (StepCollapseError at
    0.3979 s) on the slip from rest that followed. Now every contact that sticks after an
    event is at rest there (its slip below the slip-speed floor ``zeno_speed`` = 1e-6 m/s:
    a sticking contact's slip is held to round-off, ~1e-12 m/s here), and the run finishes
    with and without the Jacobian."""
    toss = cd.load_tosses(SHARED_TOSSES)["toss_016"]
    scene = cd.cube_scene().with_state(*toss.state(0))
    kin = scene.kinematics
    for jacobian in (False, True):
        traj = cd.simulate(scene, toss.t[-1], t0=toss.t[0], jacobian=jacobian)
        assert traj.t == toss.t[-1]
        for event in traj.events:
            kin.update(event.q, event.v_plus)
            for name in set(event.mode_after) - set(event.sliding):
                slip = scene.contacts[scene.contact_names.index(name)].rows(kin)[1:] @ event.v_plus
                assert np.linalg.norm(slip) <= 1e-6, (event.t, event.kind, name, slip)


def test_a_toss_whose_flow_jacobian_column_dwarfs_an_entry_runs_to_its_end():
    """Regression (toss 530 of the shipped subset, nominal): after a Zeno sequence the flow
    Jacobian's column of the initial height reaches ~2.5e5, and at t ≈ 0.7898 s an edge slips
    from rest into a sliding field whose Jacobian reaches ~1e6 1/s (its slip ~1e-6 m/s). The
    error of that column's entry for ω_x, ~1e-7, was measured against ``atol`` = 1e-10 alone:
    4e-16 of its column, below the round-off of the products that form it, so the steps shrank
    to 6e-8 s and the run with the Jacobian stopped with StepBudgetError at 0.790 s (without
    the Jacobian it finished). Each entry's scale now has the floor ``RTOL_FLOOR`` (100 eps)
    times its column's largest entry (`contactdiff.ode.variational`), and the run ends at the
    last sample with the Jacobian, with the events of the run without it."""
    toss = cd.load_tosses()["toss_530"]
    scene = cd.cube_scene().with_state(*toss.state(0))
    plain = cd.simulate(scene, toss.t[-1], t0=toss.t[0])
    traj = cd.simulate(scene, toss.t[-1], t0=toss.t[0], jacobian=True)
    assert traj.t == plain.t == toss.t[-1]
    assert [(e.kind, e.contacts) for e in traj.events] == [(e.kind, e.contacts) for e in plain.events]
    assert np.all(np.isfinite(traj.jacobian))


def test_an_impacts_open_corner_at_rest_is_held_not_slid():
    """A corner the frictional impact leaves open (no impulse, zero normal speed after)
    that slid before but whose slip is now at rest within the integration's noise is held
    like the law's own creeping slips (below ``CREEP_FACTOR`` slip-speed floors, 10 x
    ``zeno_speed`` = 1e-5 m/s): it keeps its sticking key and Coulomb's law on its forces
    decides after the impact, not a sliding key whose friction ``μ λ_N`` acts along a stale
    direction. Here the cube lies on its face and moves along +x at u = 2e-6 m/s, every
    bottom corner's slip; friction would stop that in u / (μ g) = 1.1 µs (μ = 0.18), below
    any step of the run. So every corner keeps its sticking key and is held, and holding
    the four corners' rows (`held_velocity`) leaves the cube at rest (up to round-off of
    the M-weighted projection, 1e-16 of the unit-scale velocities)."""
    from types import SimpleNamespace

    from contactdiff.dynamics.frictional_impact import ContactState
    from contactdiff.integration.event_resets import CREEP_FACTOR
    from contactdiff.integration.projection import held_velocity

    half = cd.CubeParameters().edge / 2
    q = np.r_[0.0, 0.0, half, 0.0, 0.0, 0.0, 1.0]
    v = np.r_[2e-6, 0.0, 0.0, 0.0, 0.0, 0.0]
    scene = cd.cube_scene().with_state(q, v)
    loop = cd.HybridLoop(scene, 0.0, 1.0)
    dyn, names = loop.dyn, scene.contact_names
    assert dyn.slip_speed_floor < 2e-6 < CREEP_FACTOR * dyn.slip_speed_floor  # between the floor and the creep
    bottom = sorted(i for i, n in enumerate(names) if n.endswith("-z"))
    stale = names.index("cube/+x-y-z")
    dyn.slip_reference[stale] = np.array([-1.0, 0.0])
    keys_before = [dyn.sliding_key(i) if i == stale else i for i in bottom]
    impact = SimpleNamespace(
        contacts=tuple(bottom),
        v_plus=v,
        normal_speeds_before=np.zeros(4),
        normal_speeds_after=np.zeros(4),
        states=tuple(ContactState.OPEN if i == stale else ContactState.SLIDE for i in bottom),
        slide_directions=tuple(np.zeros(2) if i == stale else np.array([1.0, 0.0]) for i in bottom),
    )
    keys, creeping = loop._friction_keys(q, impact, keys_before)
    assert keys == bottom and sorted(creeping) == bottom
    np.testing.assert_allclose(held_velocity(dyn, q, v, creeping), 0.0, atol=1e-16)


@pytest.mark.skipif(
    not SHARED_TOSSES.is_file(), reason="the full set of tosses (shared data) is not beside the repository"
)
def test_an_edge_at_rest_sticks_where_its_sticking_forces_are_inside_the_cones():
    """Regression (toss 446, μ = 0.5, e = 0.3): a Zeno impact ends a cascade with the cube
    at rest on its edge -y-z (both corners' slips below 1e-5 m/s, ``CREEP_FACTOR`` slip-speed
    floors) and nearly balanced on it: each corner carries about half the weight, m g / 2 =
    1.8 N, and the edge's sticking forces need about 1 % of their cones. Coulomb's law then
    sticks both. The corner the impact left open got a sliding key with no slip of its own;
    its friction μ m g / 2 had to be held by the other corner, exactly its own cone's edge,
    and the two alternated between slip and stop (118 slip events in 0.1 s at slips of
    1e-5 m/s, 11 s of wall time). Checked at every event whose contacts all end at rest:
    where sticking them all puts every force strictly inside its cone (by 1 % of μ λ_N, far
    above the threshold tolerance 1e-9), none slides."""
    from contactdiff.integration.event_resets import CREEP_FACTOR

    mu = 0.5
    toss = cd.load_tosses(SHARED_TOSSES)["toss_446"]
    scene = cd.cube_scene(friction=mu, restitution=0.3).with_state(*toss.state(0))
    traj = cd.simulate(scene, toss.t[-1], t0=toss.t[0])
    assert traj.t == toss.t[-1]
    loop = cd.HybridLoop(scene, toss.t[0], toss.t[-1])
    dyn, kin, names = loop.dyn, scene.kinematics, scene.contact_names
    checked = 0
    for event in traj.events:
        active = tuple(sorted(names.index(n) for n in event.mode_after))
        kin.update(event.q, event.v_plus)
        slips = [np.linalg.norm(scene.contacts[i].rows(kin)[1:] @ event.v_plus) for i in active]
        if not active or max(slips) > CREEP_FACTOR * dyn.slip_speed_floor:
            continue
        sol = dyn.solve(event.q, event.v_plus, event.t, active)
        margins = [(mu * f[0] - np.linalg.norm(f[1:])) / (mu * f[0]) for f in sol.row_forces()]
        if min(margins) > 0.01:
            checked += 1
            assert event.sliding == (), (event.t, event.kind, event.sliding, margins)
    assert checked
