"""Long horizons: the outcome of a run does not depend on how far it is asked to go.

A run that comes to rest must stay at rest, with the same events, whether ``t_final``
is 100 s or 1e9 s. Regression: free flight under constant gravity is a polynomial,
which DOP853 integrates exactly (zero error estimate), so its steps grew tenfold each
time up to ``t_final``; a ball's last bounces (1e-6 m/s, flights of 2e-6 s) then fell
inside steps thousands of seconds long whose end lay 1e7 m below the ground, the
grazing band (10 rtol |q|) taken there was a metre wide, and the ball sank through the
ground and came back at 1.58 m/s (t_final = 5000) or bounced forever (1e4, 1e9).
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
from helpers import LEG_URDF

import contactdiff as cd
from contactdiff.dynamics.impacts import choose_mode
from contactdiff.dynamics.mode import ModeDynamics
from contactdiff.integration.rest import RestCheck
from contactdiff.model.robot_files import load_robot

E = 0.8  # the ball's restitution (robots/ball.toml; h = 1 m, g = 1 m/s²)
ZENO_SPEED = 1e-6  # SimulateOptions.zeno_speed's default (m/s)


def _ball_closed_form():
    """Impacts of robots/ball.toml up to the Zeno rule: ``(times, speeds)``.

    Dropped from h = 1 under g = 1 it lands at t_0 = sqrt(2h/g) = sqrt(2) with speed
    u_0 = sqrt(2 g h) = sqrt(2); each bounce leaves at e u_k and lands again after a
    flight of 2 e u_k / g at u_{k+1} = e u_k. The Zeno rule ends the sequence at the
    first impact slower than zeno_speed: k = ceil(ln(zeno / sqrt 2) / ln e) = 64
    (sqrt 2 · 0.8^63 = 1.1e-6, sqrt 2 · 0.8^64 = 8.9e-7), so 65 events, the last of
    kind "zeno", all before the Zeno time sqrt 2 (1 + 2e / (1 - e)) = 9 sqrt 2 = 12.728 s.
    """
    n = math.ceil(math.log(ZENO_SPEED / math.sqrt(2.0)) / math.log(E)) + 1
    speeds = [math.sqrt(2.0) * E**k for k in range(n)]
    times = [math.sqrt(2.0)]
    for u in speeds[:-1]:
        times.append(times[-1] + 2.0 * E * u)
    return times, speeds


@pytest.mark.parametrize("t_final", [100.0, 5000.0, 1e4, 1e9])
def test_ball_rests_whatever_the_final_time(t_final):
    """The ball of robots/ball.toml bounces 65 times (closed form above) and rests on the
    ground at every final time; its energy never exceeds the initial g h = 1 J/kg.

    Tolerances: event times and speeds carry the integration error of rtol = 1e-8
    accumulated over 65 events (a few 1e-8 relative); 1e-6 s and 1e-7 m/s leave a wide
    margin. Energy: the speed at an impact is sqrt(2) (1 + O(1e-8)), so 1/2 v² <= 1 + 1e-7.
    At rest the contact is held on its manifold (project_tol = atol = 1e-10 m)."""
    times, speeds = _ball_closed_form()
    assert len(times) == 65
    traj = cd.simulate(cd.load_scene("ball"), t_final)
    assert traj.termination is cd.Termination.T_FINAL
    assert len(traj.events) == len(times)
    assert [e.kind for e in traj.events] == ["bounce"] * 64 + ["zeno"]
    for event, t_k, u_k in zip(traj.events, times, speeds):
        assert event.t == pytest.approx(t_k, abs=1e-6)
        assert -event.v_minus[0] == pytest.approx(u_k, abs=1e-7)
        for v in (event.v_minus[0], event.v_plus[0]):
            assert 0.5 * v * v + event.q[0] <= 1.0 + 1e-7
    assert traj.t == t_final
    assert abs(traj.q[0]) <= 1e-10 and traj.v[0] == 0.0
    assert traj.modes[-1] == ("ball",)
    # the rest costs a few steps, not steps in proportion to t_final
    assert traj.stats.steps <= 200


def _energy(scene, q, v) -> float:
    """Kinetic + gravity + joint-spring energy (J) of ``scene`` at ``(q, v)``."""
    model, data = scene.model, scene.model.createData()
    energy = pin.computeKineticEnergy(model, data, q, v) + pin.computePotentialEnergy(model, data, q)
    for effort in scene.efforts:
        energy += 0.5 * float(np.sum(effort.stiffness * (q[effort.iq] - effort.rest) ** 2))
    return energy


@pytest.fixture(scope="module")
def crept_solo():
    """solo12_drop run for 100 s with the rest check off: dropped 5 cm, it lands on its four
    sticking feet and its joint dampers remove the motion (test_hybrid.test_solo12_drop);
    the stepper then creeps on in steps of ~10 s, bounded by round-off (contactdiff's
    integration/rest.py)."""
    scene = cd.load_scene("solo12_drop")
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(RestCheck, "settle", lambda *args: False)
        return scene, cd.simulate(scene, 100.0)


@pytest.mark.parametrize("t_final", [1e4, 1e9])
def test_resting_quadruped_over_a_long_horizon(crept_solo, t_final):
    """solo12_drop to t_final = 1e4 s and 1e9 s: the same landing, then it stands where the
    run without the rest check crept to, on its four feet, and the run ends in the same
    steps whatever t_final.

    Regression: once at rest, the contact forces' round-off (~1e-13 m/s² along the held
    directions, where the field is a double integrator) bounds Radau's steps at ~10 s
    (Newton's iterates move by h² times it); 1e4 s took 1,217 steps and 1e9 s ran out of
    its 200,000 steps at 1.7e6 s. The run now sees it rests (integration/rest.py) and
    steps to t_final in one step of its linearised flow.

    Tolerances: the pose is held on the contact manifold to project_tol = atol = 1e-10 m and
    the crept run's drift between projections is of that size; 1e-8 m and 1e-8 rad leave a
    margin of 100. Velocities: the rest's linear flow ends at the equilibrium (v -> 0) to
    its round-off, far below the crept run's noise (1e-12 m/s); 1e-9 m/s as before. The
    contact forces carry the weight: at rest the momentum is constant, so the normal
    forces sum to m g, to the accelerations' size (below 1e-6 m/s², 1e-7 relative).
    Energy: the landing is plastic and the joints are damped, so the energy (kinetic,
    gravity, springs) at every event and at the end is at most the start's."""
    scene, crept = crept_solo
    traj = cd.simulate(scene, t_final)
    assert traj.termination is cd.Termination.T_FINAL and traj.t == t_final
    assert [(e.t, e.kind) for e in traj.events] == [(e.t, e.kind) for e in crept.events]
    assert set(traj.modes[-1]) == set(scene.contact_names)
    assert any(note.startswith("at rest from t = ") for note in traj.notes)
    np.testing.assert_allclose(traj.q, crept.q, atol=1e-8)
    assert np.max(np.abs(traj.v)) <= 1e-9
    assert np.max(np.abs(scene.gaps(traj.q))) <= 1e-8
    dyn = ModeDynamics(scene)
    mode = choose_mode(dyn, traj.q, traj.v, traj.t, list(range(len(scene.contacts))))
    solution = dyn.solve(traj.q, traj.v, traj.t, mode)
    weight = pin.computeTotalMass(scene.model) * 9.81
    assert np.max(np.abs(solution.ddq)) <= 1e-6
    assert float(np.sum(solution.normal_forces())) == pytest.approx(weight, rel=1e-7)
    e0 = _energy(scene, scene.q0, scene.v0)
    for event in traj.events:
        assert _energy(scene, event.q, event.v_minus) <= e0 and _energy(scene, event.q, event.v_plus) <= e0
    assert _energy(scene, traj.q, traj.v) <= e0
    # the steps to rest, then one: the same count whatever t_final, far below the crept run's
    assert traj.stats.steps == cd.simulate(scene, 10.0).stats.steps < crept.stats.steps


def _leg_scene(tmp_path):
    """The planar leg of tests/helpers.py (slider 0.5 kg free in x, body 0.5 kg on it free in
    z, leg 0.2 kg on a hip about y, its centre of mass l = 0.25 m below the hip), with no
    contact: x has a damper only (c = 1.2 N s/m), z a spring-damper (100 N/m, 10 N s/m,
    rest 1 m), the hip a spring-damper (5 N m/rad, 0.5 N m s/rad, rest 0). Started at
    z = 1, hip 0.3 rad, moving at x' = 0.1 m/s, z' = 0.5 m/s."""
    path = tmp_path / "leg.urdf"
    path.write_text(LEG_URDF)
    springs = [
        cd.JointSpring("body_x", 0.0, LEG_C, 0.0),
        cd.JointSpring("body_z", 100.0, 10.0, 1.0),
        cd.JointSpring("hip", 5.0, 0.5, 0.0),
    ]
    scene = cd.Scene(load_robot(path), efforts=springs)
    return scene.with_state({"body_z": 1.0, "hip": 0.3}, {"body_x": 0.1, "body_z": 0.5})


LEG_C = 1.2  # N s/m, the leg's x damper
LEG_MASS, LEG_LEG, LEG_L = 1.2, 0.2, 0.25  # kg moving in x, kg of the leg, m hip to its centre of mass


@pytest.mark.parametrize("t_final", [40.0, 1e9])
def test_rest_flow_jacobian_against_closed_forms(tmp_path, t_final):
    """The leg of `_leg_scene` comes to rest (slowest decay c / M = 1 /s, at rest within
    ~25 s) and is stepped to t_final in one step; its state and flow Jacobian are those of
    the rest whatever t_final.

    Closed forms. Only the x damper acts on the x momentum p = M x' + m_leg d(x_leg)/dt
    (the springs are internal or vertical), so dp/dt = -c x' and, with everything at rest
    at the end, x(inf) = x0 + p0 / c. The hip hangs its leg's centre at (-l sin θ, -l cos θ)
    from the hip (rotation about y), so p0 = M x0' - m_leg l cos θ0 θ0'. Hence
    d x(inf)/d x0 = 1, d x(inf)/d x0' = M / c = 1, d x(inf)/d θ0' = -m_leg l cos θ0 / c,
    d x(inf)/d θ0 = -m_leg l sin θ0 θ0' / c = 0 (θ0' = 0). The body hangs on its spring:
    z(inf) = rest - (0.5 + 0.2) g / k, d z(inf)/d rest = 1, and the hip at θ = 0. Every
    other entry decays to 0 (exp(-1 s⁻¹ · 15 s) ~ 3e-7 at 40 s, times the state's scale
    of the perturbation: the 1e-6 below).

    Tolerances: the run's global error at rtol = 1e-8 over a few oscillations, ~1e-8
    relative; the rest leaves at most 0.1 of one step's tolerance; 1e-6 covers both."""
    scene = _leg_scene(tmp_path)
    traj = cd.simulate(scene, t_final, jacobian=True, parameters=["joint_spring:body_z:rest"])
    assert traj.t == t_final and traj.termination is cd.Termination.T_FINAL
    assert any(note.startswith("at rest from t = ") for note in traj.notes)
    assert traj.stats.steps < 500
    theta0 = 0.3
    p0 = LEG_MASS * 0.1  # theta0' = 0
    np.testing.assert_allclose(traj.q, [0.0 + p0 / LEG_C, 1.0 - 0.7 * 9.81 / 100.0, 0.0], atol=1e-6)
    np.testing.assert_allclose(traj.v, 0.0, atol=1e-6)
    expected = np.zeros((6, 6))
    expected[0, 0] = 1.0
    expected[0, 3] = LEG_MASS / LEG_C
    expected[0, 5] = -LEG_LEG * LEG_L * math.cos(theta0) / LEG_C
    np.testing.assert_allclose(traj.jacobian, expected, atol=1e-6)
    np.testing.assert_allclose(traj.parameter_jacobian[:, 0], [0.0, 1.0, 0.0, 0.0, 0.0, 0.0], atol=1e-6)


def test_rest_goes_on_across_sample_times(tmp_path):
    """The leg of `_leg_scene` at rest from ~23 s, sampled every 10 s to 1e4 s: the rest
    steps from sample to sample (a few steps per sample, not steps bounded by round-off),
    every sample after the rest holds the resting state, and the final state and flow
    Jacobians are those of the unsampled run, which steps to t_final in one step.

    Chained steps of the linearised flow of one equilibrium ``exp(J a) exp(J b)`` equal
    ``exp(J (a + b))`` (the same ``J`` to the equilibrium's round-off, ~1e-16 of the
    state): 1e-9 leaves room for the expm's own round-off over 1e3 samples."""
    scene = _leg_scene(tmp_path)
    times = np.arange(10.0, 1e4, 10.0)
    plain = cd.simulate(scene, 1e4, jacobian=True, parameters=["joint_spring:body_z:rest"])
    sampled = cd.simulate(scene, 1e4, jacobian=True, parameters=["joint_spring:body_z:rest"], sample_times=times)
    assert sampled.stats.steps < plain.stats.steps + 3 * len(times)
    notes = [note for note in sampled.notes if note.startswith("at rest from t = ")]
    assert len(notes) == 1 and "one to each sample time" in notes[0]
    np.testing.assert_allclose(sampled.q, plain.q, atol=1e-9)
    np.testing.assert_allclose(sampled.jacobian, plain.jacobian, atol=1e-9)
    np.testing.assert_allclose(sampled.parameter_jacobian, plain.parameter_jacobian, atol=1e-9)
    resting = sampled.samples.t >= 30.0
    np.testing.assert_allclose(
        sampled.samples.q[resting], np.broadcast_to(plain.q, sampled.samples.q[resting].shape), atol=1e-9
    )
    np.testing.assert_allclose(sampled.samples.jacobian[-1], plain.jacobian, atol=1e-9)


def test_rest_flow_jacobian_against_finite_differences(tmp_path):
    """The leg of `_leg_scene` to t_final = 40 s (at rest from ~23 s): the flow Jacobian's
    columns of the hip's angle and rate, and the parameter column, against central
    differences of runs from perturbed starts (each comes to rest on its own).

    Step 1e-3: x(inf) is linear in the initial velocities and z(inf) in the spring's rest
    (closed forms above), and the other entries decay, so the truncation error is below
    the runs' own error (~1e-8 of the state, 1e-5 once divided by the step); 1e-4."""
    scene = _leg_scene(tmp_path)
    traj = cd.simulate(scene, 40.0, jacobian=True, parameters=["joint_spring:body_z:rest"])
    eps = 1e-3

    def final(q0=None, v0=None, rest=1.0):
        run = cd.simulate(scene.with_parameters({"joint_spring:body_z:rest": rest}), 40.0, q0, v0)
        return np.concatenate((run.q, run.v))

    q0, v0 = scene.q0, scene.v0
    columns = {2: (lambda e: final(q0=q0 + e * np.eye(3)[2])), 5: (lambda e: final(v0=v0 + e * np.eye(3)[2]))}
    for k, run in columns.items():
        fd = (run(eps) - run(-eps)) / (2 * eps)
        np.testing.assert_allclose(traj.jacobian[:, k], fd, atol=1e-4)
    fd = (final(rest=1.0 + eps) - final(rest=1.0 - eps)) / (2 * eps)
    np.testing.assert_allclose(traj.parameter_jacobian[:, 0], fd, atol=1e-4)


def test_which_scenes_are_autonomous():
    """The rest check needs a scene whose efforts no longer depend on time: joint springs
    always (solo12_drop), no effort at all (the ball), joint targets only past their last
    knot (panda_lift's arm at 0.9 s, its fingers at 0.35 s), a user effort never (its
    function takes t)."""
    assert cd.load_scene("solo12_drop").autonomous_from(0.0)
    assert cd.load_scene("ball").autonomous_from(0.0)
    panda = cd.load_scene("panda_lift")
    assert not panda.autonomous_from(0.5) and not panda.autonomous_from(0.9 - 1e-9)
    assert panda.autonomous_from(0.9) and panda.autonomous_from(1e9)
    ball = cd.load_scene("ball")
    pushed = cd.Scene(ball.robot, efforts=[cd.UserEffort(lambda q, v, t: np.zeros(ball.nv))])
    assert not pushed.autonomous_from(1e9)
