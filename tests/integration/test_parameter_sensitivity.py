"""Derivatives of trajectories with respect to model parameters, through every event.

References, never the code's own output:

* **Closed forms.** A harmonic oscillator ``q'' = -k q`` (the stepper's forced
  variational equation); the bouncing ball (g = 1, height 1, e = 0.8): after one
  bounce at ``t1 = sqrt(2)`` with speed ``u = sqrt(2)``, ``z = e u s - s²/2`` and
  ``v = e u - s`` (``s = T - t1``), so ``∂z/∂e = u s``, ``∂v/∂e = u``; after the
  second bounce at ``t2 = t1 + 2 e u`` (``∂t2/∂e = 2u``), ``v = e² u - (T - t2)``,
  so ``∂v/∂e = 2 e u + 2 u`` and ``∂z/∂e = 2 e u (T - t2) + 2 u ((T - t2) - e² u)``;
  a body's mass where only gravity acts on it alone has derivative exactly 0.
* **Central finite differences through `Scene.with_parameters`** on the manifold
  (``pin.difference``), with the step ``h = 1e-5 |p|`` (1e-5 where p = 0) at rtol
  1e-12, atol 1e-13, as the state Jacobian's tests (test_sensitivity.py): the FD's
  truncation is ~h² (1e-10 relative) and its noise, the runs' integration errors
  (about 1e-11 |x| each after a few events) over 2h. A column is compared to
  1e-6 of its own size plus that noise, ``1e-11 max(1, |x|) / h``, so a column
  whose true value is near zero is held to the noise it can be measured to.
  The perturbed runs must keep the nominal event sequence.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pinocchio as pin
import pytest
from test_sensitivity import _solo_tilted  # the tilted solo12 drop: feet land one at a time

import contactdiff as cd
from contactdiff.errors import InvalidInputError
from contactdiff.integration.hybrid import simulate
from contactdiff.ode.factory import VectorSpace, make_stepper

TOL = dict(rtol=1e-12, atol=1e-13)
REL_STEP = 1e-5
# a parameter whose response is small against the state's size needs a larger step to
# rise above the runs' noise: solo12's knee spring (|dx/dk| = 0.07 per N m/rad) differs
# from the Jacobian by 1.5e-4 at h = 1e-5 |k| (noise), 5e-8 at 1e-4 and 2.7e-8 at 1e-3
# (rtol 1e-12, measured), so it takes 1e-3 |k|, whose truncation is ~1e-6 relative
REL_STEPS = {"joint_spring:FR_KFE:stiffness": 1e-3}
JAC_RTOL = 1e-6
NOISE = 1e-11  # integration error of one run, relative to max(1, |x|), after a few events


# ----------------------------------------------------------------------------------
# the stepper's forced variational equation
# ----------------------------------------------------------------------------------
@pytest.mark.parametrize("method", ["DOP853", "RK45", "Radau"])
def test_forced_variational_equation_matches_the_oscillator_closed_form(method):
    """q'' = -k q from q0 = 1, v0 = 0: q = cos(w t), w = sqrt(k); the last column of phi
    is (∂q/∂k, ∂v/∂k) = (-t sin(w t) / (2w), -(sin(w t) + w t cos(w t)) / (2w))."""
    k, T = 2.0, 3.0
    st = make_stepper(
        method,
        lambda t, q, v: -k * q,
        VectorSpace(1),
        0.0,
        [1.0],
        [0.0],
        rtol=1e-11,
        atol=1e-13,
        jac=lambda t, q, v: (np.array([[-k]]), np.array([[0.0]])),
        parameter_jac=lambda t, q, v: np.array([[-q[0]]]),
        variational=np.eye(2, 3),
    )
    while st.t < T:
        st.t_bound = T
        st.step()
    w = math.sqrt(k)
    dq = -T * math.sin(w * T) / (2 * w)
    dv = -(math.sin(w * T) + w * T * math.cos(w * T)) / (2 * w)
    # local error 1e-11 relative over ~100 steps: the sensitivity is good to ~1e-8 (Radau's
    # third-order error estimate at this tolerance: ~1e-7)
    tol = 1e-6 if method == "Radau" else 1e-8
    assert st.phi[:, 2] == pytest.approx([dq, dv], abs=tol)
    # the state columns are the unforced oscillator's: [[cos, sin/w], [-w sin, cos]]
    expected = np.array([[math.cos(w * T), math.sin(w * T) / w], [-w * math.sin(w * T), math.cos(w * T)]])
    assert np.abs(st.phi[:, :2] - expected).max() <= tol


def test_parameter_jacobian_of_the_wrong_shape_is_named():
    st = make_stepper(
        "DOP853",
        lambda t, q, v: -q,
        VectorSpace(1),
        0.0,
        [1.0],
        [0.0],
        jac=lambda t, q, v: (np.array([[-1.0]]), np.array([[0.0]])),
        parameter_jac=lambda t, q, v: np.zeros((2, 1)),
        variational=np.eye(2, 3),
    )
    with pytest.raises(InvalidInputError, match="parameter_jac"):
        st.step()


# ----------------------------------------------------------------------------------
# the bouncing ball: closed forms
# ----------------------------------------------------------------------------------
E = 0.8
U = math.sqrt(2.0)
T1 = math.sqrt(2.0)
T2 = T1 + 2 * E * U


def _ball(T, parameters):
    return simulate(cd.load_scene("ball"), T, jacobian=True, parameters=parameters, **TOL)


def test_ball_restitution_after_one_bounce():
    T = 2.5
    traj = _ball(T, ["contact:ball:restitution"])
    assert [e.kind for e in traj.events] == ["bounce"]
    s = T - T1
    assert traj.parameter_jacobian[:, 0] == pytest.approx([U * s, U], abs=1e-9)
    assert traj.parameter_names == ("contact:ball:restitution",)
    # the bounce happens where the ball is: its time does not depend on e
    assert traj.events[0].parameter_time_gradient == pytest.approx([0.0], abs=1e-12)


def test_ball_restitution_after_two_bounces_moves_the_second_bounce():
    T = 5.2
    traj = _ball(T, ["contact:ball:restitution"])
    assert [e.kind for e in traj.events] == ["bounce", "bounce"]
    r = T - T2
    dv = 2 * E * U + 2 * U
    dz = 2 * E * U * r + 2 * U * (r - E**2 * U)
    assert traj.parameter_jacobian[:, 0] == pytest.approx([dz, dv], abs=1e-9)
    assert traj.events[1].parameter_time_gradient == pytest.approx([2 * U], abs=1e-9)
    assert traj.events[1].t == pytest.approx(T2, abs=1e-10)


def test_ball_mass_has_exactly_zero_derivative():
    """Only gravity acts on the ball, and the impact law does not see the mass of a single body."""
    traj = _ball(5.2, ["body:ball:mass"])
    assert np.abs(traj.parameter_jacobian).max() <= 1e-12


# ----------------------------------------------------------------------------------
# finite differences through with_parameters
# ----------------------------------------------------------------------------------
def _bar() -> cd.Scene:
    base = cd.trot_touchdown("rigid", 0.05)
    contacts = [cd.Contact(c.frame, restitution=0.5) for c in base.contact_specs]
    return cd.Scene(base.robot, contacts, base.effort_specs, None, base.q0, base.v0, name="bar")


def _ball_on_spring() -> cd.Scene:
    """The ball with a user effort: a spring-damper pulling it to z = r with parameters
    (k, c, r), its Jacobian by hand and its parameter Jacobian left to central differences."""

    def force(q, v, t, k, c, r):
        return np.array([-k * (q[0] - r) - c * v[0]])

    def jacobian(q, v, t, k, c, r):
        return np.array([[-k]]), np.array([[-c]])

    spring = cd.UserEffort(force, jacobian, name="tether", parameters={"k": 0.5, "c": 0.1, "r": 0.6})
    ball = cd.load_scene("ball")
    return cd.Scene(ball.robot, ball.contact_specs, [spring], None, ball.q0, ball.v0, name="ball-tether")


def _soft_stick() -> cd.Scene:
    base = cd.trot_touchdown("soft", 0.05)
    contacts = [cd.Contact(c.frame, friction="stick") for c in base.contact_specs]
    return cd.Scene(base.robot, contacts, base.effort_specs, None, base.q0, base.v0, name="soft-stick")


def _pick(scene, *patterns):
    """The first parameter name of the scene matching each (prefix, suffix) pattern, of a
    body with mass where it is a body's (a planar model's massless links carry its joints)."""
    names = scene.parameter_names()
    out = []
    for prefix, suffix in patterns:
        match = [n for n in names if n.startswith(prefix) and n.endswith(suffix)]
        match = [
            n
            for n in match
            if not n.startswith("body:") or scene.parameter_values([n.rsplit(":", 1)[0] + ":mass"])[0] > 0
        ]
        assert match, (prefix, suffix, names)
        out.append(match[0])
    return out


T0 = {"solo12_trot": 0.08}  # the trot's runs start after its landing cascade (bounces 1e-4 s apart)


@functools.lru_cache(maxsize=None)
def _trot_stance() -> cd.Scene:
    """solo12_trot at t = 0.08 s, all four feet down (the state reached from its start)."""
    scene = cd.load_scene("solo12_trot")
    run = simulate(scene, T0["solo12_trot"], **TOL)
    return scene.with_state(run.q, run.v)


# scene builder, final time, expected events (kind, contacts), parameter patterns
CASES = {
    "ball": (
        lambda: cd.load_scene("ball"),
        5.2,
        [("bounce", {"ball"}), ("bounce", {"ball"})],
        [("scene:", "gravity_z"), ("contact:", "offset"), ("contact:", "restitution")],
    ),
    # simultaneous touchdown and simultaneous lift-off, springs
    "two_limb": (
        lambda: cd.load_scene("two_limb"),
        2.0,
        [("touchdown", {"left_foot", "right_foot"}), ("lift-off", {"left_foot", "right_foot"})],
        [("spring:", "stiffness"), ("spring:", "rest_length"), ("body:", "mass"), ("contact:left_foot", "offset")],
    ),
    # a user effort's own parameters (its parameter Jacobian by central differences)
    "ball_tether": (
        _ball_on_spring,
        4.0,
        [("bounce", {"ball"}), ("bounce", {"ball"})],
        [("effort:tether", "k"), ("effort:tether", "c"), ("effort:tether", "r")],
    ),
    # separate touchdowns and lift-offs (force guards), inertias and centres of mass
    "soft_pitch0.05": (
        lambda: cd.trot_touchdown("soft", 0.05),
        1.8,
        [
            ("touchdown", {"rear_foot"}),
            ("touchdown", {"front_foot"}),
            ("lift-off", {"front_foot"}),
            ("lift-off", {"rear_foot"}),
        ],
        [
            ("body:", "mass"),
            ("body:", "com_x"),
            ("body:", "iyy"),
            ("spring:", "damping"),
            ("contact:front_foot", "offset"),
            ("scene:", "gravity_x"),
        ],
    ),
    # rigid bar bouncing on both feet: restitution and inertia through the impact law
    "bar": (
        _bar,
        1.5,
        [("bounce", {"rear_foot"}), ("bounce", {"front_foot"})],
        [
            ("contact:rear_foot", "restitution"),
            ("contact:front_foot", "restitution"),
            ("body:", "mass"),
            ("body:", "iyy"),
            ("body:", "com_z"),
            ("joint:body_pitch", "armature"),
        ],
    ),
    # sticking feet: lift-offs with tangential force left
    "soft_stick": (
        _soft_stick,
        1.8,
        [
            ("touchdown", {"rear_foot"}),
            ("touchdown", {"front_foot"}),
            ("lift-off", {"front_foot"}),
            ("lift-off", {"rear_foot"}),
        ],
        [("body:", "mass"), ("spring:", "stiffness")],
    ),
    # free-flyer, sticking plastic feet, three touchdowns (the state study's tighter tolerance)
    "solo12_tilted": (
        _solo_tilted,
        0.112,
        [("touchdown", {"FR_FOOT"}), ("touchdown", {"FL_FOOT"}), ("touchdown", {"FR_FOOT"})],
        [
            ("body:base_link", "mass"),
            ("body:FL_LOWER_LEG", "com_x"),
            ("body:FR_UPPER_LEG", "ixx"),
            ("scene:", "gravity_z"),
            ("contact:FL_FOOT", "offset"),
            ("joint_spring:FR_KFE", "stiffness"),
        ],
    ),
    # the controlled trot: the controller's gains, and the base's mass and gravity, which
    # its feed-forward also holds; slips (a sticking foot's release that would sink) and
    # lift-offs
    "solo12_trot": (
        _trot_stance,
        0.2,
        [("slip", {"FL_FOOT"}), ("lift-off", {"FL_FOOT"}), ("slip", {"HR_FOOT"}), ("lift-off", {"HR_FOOT"})],
        [("trot:", "kp"), ("trot:", "kd"), ("body:base_link", "mass"), ("scene:", "gravity_z")],
    ),
}
OPTIONS = {"solo12_tilted": dict(rtol=1e-13, atol=1e-14)}
# parameters at the bound of their range (zero damping, armature) are moved inside it, so
# that the central difference stays valid (a damping small enough to keep the event
# sequence: 0.5 swaps the lift-offs). Armature is studied on the bar, not on solo12's
# knee: there 1e-5 kg m² doubles the light shank's inertia and the perturbed runs'
# integration error, measured, puts the FD's noise at 1e-4 relative for h = 1e-5 |p|
# (2.8e-7 at h = 1e-4 |p|, which is where the Jacobian agrees)
NOMINAL = {"soft_pitch0.05": {"spring:rear_hip-rear_foot:damping": 0.05}, "bar": {"joint:body_pitch:armature": 0.1}}


def _sequence(traj):
    return [(e.kind, set(e.contacts)) for e in traj.events]


@functools.lru_cache(maxsize=None)
def _study(name):
    build, T, events, patterns = CASES[name]
    scene = build()
    if name in NOMINAL:
        scene = scene.with_parameters(NOMINAL[name])
    options = {**TOL, **OPTIONS.get(name, {})}
    names = _pick(scene, *patterns)
    options["t0"] = T0.get(name, 0.0)
    traj = simulate(scene, T, jacobian=True, parameters=names, **options)
    values = scene.parameter_values(names)
    model = scene.model
    fd, steps, sequences = [], [], []
    for name_k, value in zip(names, values):
        h = REL_STEPS.get(name_k, REL_STEP) * (abs(value) if value != 0 else 1.0)
        runs = [simulate(scene.with_parameters({name_k: value + sign * h}), T, **options) for sign in (1, -1)]
        sequences += [_sequence(r) for r in runs]
        plus, minus = runs
        fd.append(np.concatenate([pin.difference(model, minus.q, plus.q), plus.v - minus.v]) / (2 * h))
        steps.append(h)
    return scene, names, traj, np.array(fd).T, np.array(steps), sequences


@pytest.mark.parametrize("name", list(CASES))
def test_parameter_jacobian_matches_finite_differences(name):
    scene, names, traj, fd, steps, sequences = _study(name)
    events = CASES[name][2]
    assert _sequence(traj) == events
    assert traj.differentiable, traj.notes
    if not any(len(contacts) > 1 for _, contacts in events):
        assert all(s == events for s in sequences), ("a perturbation changed the event sequence", sequences)
    # else: a perturbation splits a simultaneous event of the decoupled two_limb in one
    # order or the other, and the paper's theorem (the flow stays C¹ there, which
    # `differentiable` checks through the orders' saltation matrices) is what makes the
    # central difference valid across the split
    J = traj.parameter_jacobian
    assert J.shape == (2 * scene.nv, len(names))
    size = max(1.0, float(np.abs(np.concatenate([traj.q, traj.v])).max()))
    for k, name_k in enumerate(names):
        allowed = JAC_RTOL * np.abs(fd[:, k]).max() + NOISE * size / steps[k]
        err = np.abs(J[:, k] - fd[:, k]).max()
        assert err <= allowed, (name_k, err, allowed, J[:, k], fd[:, k])


def test_parameters_leave_the_state_jacobian_as_it_was():
    """Adding parameter columns changes the error control's columns, not the state Jacobian
    beyond the tolerance it is computed to."""
    scene, names, traj, *_ = _study("soft_pitch0.05")
    plain = simulate(scene, CASES["soft_pitch0.05"][1], jacobian=True, **TOL)
    assert np.abs(traj.jacobian - plain.jacobian).max() <= 1e-8 * np.abs(plain.jacobian).max()


def test_event_time_gradient_with_respect_to_an_offset():
    """The ball lands where its gap z - offset is 0: raising the offset by h makes it land
    earlier, t1 = sqrt(2 (1 - r)), so dt1/dr = -1 / sqrt(2) at r = 0."""
    traj = _ball(2.5, ["contact:ball:offset"])
    assert traj.events[0].parameter_time_gradient == pytest.approx([-1 / math.sqrt(2.0)], abs=1e-9)


def test_unknown_parameter_names_list_the_valid_ones():
    with pytest.raises(InvalidInputError, match="body:ball:mass"):
        simulate(cd.load_scene("ball"), 1.0, jacobian=True, parameters=["body:ball:weight"])


@pytest.mark.parametrize("name", ["bar", "soft_pitch0.05"])
def test_parameters_alone_give_the_same_columns_without_the_state_jacobian(name):
    """Without ``jacobian`` only the parameter columns are propagated: the same
    derivatives, to the error control's tolerance (the steps differ)."""
    scene, names, traj, *_ = _study(name)
    alone = simulate(scene, CASES[name][1], parameters=names, **TOL)
    assert alone.jacobian is None and alone.events[0].time_gradient is None
    J = traj.parameter_jacobian
    assert np.abs(alone.parameter_jacobian - J).max() <= 1e-8 * np.abs(J).max()
    assert alone.events[-1].parameter_time_gradient == pytest.approx(
        traj.events[-1].parameter_time_gradient, rel=1e-8, abs=1e-12
    )


def test_radau_gives_the_same_parameter_jacobian():
    """The implicit stepper propagates the forced variational equation through its stage
    equations (parameters' forcing on the right-hand side): the same columns as DOP853's,
    which the finite differences above check, to the error control's tolerance (rtol 1e-12
    on both, Radau's third-order estimate: ~1e-8 relative). With the parameters' columns
    alone its steps in flight grow to 0.75 s, and re-taking the one an event cuts needs the
    halved re-take (`Radau._retake`): Newton fails on it whole."""
    scene, names, traj, *_ = _study("soft_pitch0.05")
    radau = simulate(scene, CASES["soft_pitch0.05"][1], parameters=names, method="Radau", **TOL)
    assert _sequence(radau) == _sequence(traj)
    J = traj.parameter_jacobian
    assert np.abs(radau.parameter_jacobian - J).max() <= 1e-6 * np.abs(J).max()
