"""`SimulateOptions.jacobian_error`: which local errors choose the steps of a run that carries
the flow Jacobian. Under ``"state"`` the steps are chosen from the state's error alone, so the
run's steps, events and state are the plain run's bit for bit, and the Jacobian, propagated over
those steps, still matches central differences through an impact, a slip that stops with a
turning direction and a sphere's slip that ends in rolling (models, closed forms and tolerances:
`coulomb_models`, ``test_anisotropic_stop``, ``test_coulomb_impacts``).
"""

from __future__ import annotations

import numpy as np
import pytest
from coulomb_models import FD_RTOL, MU, TOL, G, central_differences, event_kinds, load, unit
from helpers import assert_fd
from test_anisotropic_stop import ANISO_URDF, STARTS, Stop
from test_anisotropic_stop import _scene as aniso_scene
from test_coulomb_impacts import SPINS, _ball_scene, _fall, _impact_closed_form, _sphere_closed_form

import contactdiff as cd
from contactdiff.errors import InvalidInputError
from contactdiff.integration.options import JacobianError


@pytest.fixture(scope="module")
def aniso(tmp_path_factory):
    return load(tmp_path_factory, "aniso_error", ANISO_URDF)


def _oblique(block3, e):
    """The block of ``test_oblique_impact`` ("slide": |v_t| twice the cone's limit): it lands at
    t_td = _fall(0.05, 1), slips and stops at t_td + |v_T+| / (μ g) (e = 0), or bounces off with
    v_T+ and the run ends at the apex t_td + e V / g (e > 0). Returns (scene, t_final)."""
    h, w = 0.05, 1.0
    t_td, V = _fall(h, w)
    v_t = 2.0 * MU * (1 + e) * V * np.array([0.8, -0.6])
    v_plus, _ = _impact_closed_form(v_t, V, e, MU)
    t_final = t_td + e * V / G if e > 0 else t_td + np.linalg.norm(v_plus[:2]) / (MU * G) + 0.1
    scene = cd.Scene(
        block3,
        [cd.Contact("block", restitution=e, friction=MU)],
        gravity=[0, 0, -G],
        q0=np.array([0.0, 0.0, 0.05]),
        v0=np.array([*v_t, -w]),
    )
    return scene, t_final


def _case(name, block3, aniso, ball):
    """(scene, t_final, admissible FD directions (2nv each), expected event kinds) of a case."""
    if name == "anisotropic-stop":
        start = STARTS["oblique"]
        return aniso_scene(aniso, start), Stop(*start).t_s + 0.1, [unit(k, 6) for k in (0, 1, 3, 4)], ["stick"]
    if name == "impact-slip-stop":
        scene, t_final = _oblique(block3, 0.0)
        return scene, t_final, list(np.eye(6)), ["touchdown", "stick"]
    if name == "frictional-bounce":
        scene, t_final = _oblique(block3, 0.6)
        return scene, t_final, list(np.eye(6)), ["bounce"]
    case = "sidespin-and-twist"  # the directions of test_sphere_jacobian_matches_fd
    _, t_r, *_ = _sphere_closed_form(*SPINS[case], MU)
    return _ball_scene(ball, case), t_r + 0.1, [unit(c, 12) for c in (0, 1, 5, 6, 7, 9, 10, 11)], ["stick"]


CASES = ["anisotropic-stop", "impact-slip-stop", "frictional-bounce", "sphere-stop"]


def test_jacobian_error_refused_by_name(block3):
    """A value that is not a `JacobianError` is refused by `SimulateOptions` and `simulate`, the
    message naming it and the valid ones; the enum and its value are both accepted."""
    for bad in ("states", "", None, 1):
        with pytest.raises(InvalidInputError, match=r"jacobian_error must be one of control, state") as err:
            cd.SimulateOptions(jacobian_error=bad)
        assert repr(bad) in str(err.value)
    scene, t_final = _oblique(block3, 0.0)
    with pytest.raises(InvalidInputError, match="'full'"):
        cd.simulate(scene, t_final, jacobian=True, jacobian_error="full")
    assert cd.SimulateOptions(jacobian_error="state").jacobian_error is JacobianError.STATE
    assert cd.SimulateOptions(jacobian_error=JacobianError.STATE).jacobian_error is JacobianError.STATE
    assert cd.SimulateOptions().jacobian_error is JacobianError.CONTROL


@pytest.mark.parametrize("tol", [TOL, {}], ids=["tight", "default"])
@pytest.mark.parametrize("name", CASES)
def test_state_error_keeps_the_plain_run(block3, aniso, ball, name, tol):
    """Under ``"state"`` the accepted and rejected steps, every event (time, kind, state) and the
    final state are those of the run without derivatives, bit for bit: the Jacobian is carried
    over the plain run's steps and never changes them. (Under ``"control"`` the Jacobian's error
    takes part in choosing them: not compared here, it may or may not add steps.)"""
    scene, t_final, _, _ = _case(name, block3, aniso, ball)
    plain = cd.simulate(scene, t_final, **tol)
    with_jac = cd.simulate(scene, t_final, jacobian=True, jacobian_error="state", **tol)
    assert with_jac.jacobian is not None and plain.jacobian is None
    assert (with_jac.stats.steps, with_jac.stats.rejected_steps) == (plain.stats.steps, plain.stats.rejected_steps)
    assert event_kinds(with_jac) == event_kinds(plain)
    for a, b in zip(with_jac.events, plain.events):
        assert a.t == b.t
        assert np.array_equal(a.q, b.q) and np.array_equal(a.v_plus, b.v_plus)
    assert np.array_equal(with_jac.q, plain.q) and np.array_equal(with_jac.v, plain.v)


@pytest.mark.parametrize("name", CASES)
def test_state_error_jacobian_matches_fd(block3, aniso, ball, name):
    """The flow Jacobian and the event times' gradients under ``"state"`` against central
    differences along the admissible directions (those of the tests each case comes from).

    Tolerance `FD_RTOL` = 1e-5 relative to the Jacobian's scale (derived in `coulomb_models`: the
    central differences' worst-case noise, two runs within ~2e-12 each over 2 ε = 2e-6, is 2e-6
    of these Jacobians' scale >= 1). The Jacobian's own error under ``"state"``: over the state's
    steps at rtol = atol = 1e-12 its local error per step is the method's truncation error of the
    variational equation, not held to the tolerance; for it to reach 1e-5 it would have to be 1e7
    times the state's tolerance, while a missing or wrong saltation or reference term is an
    O(1e-2..1) relative error (`coulomb_models`): a pass says the derivative is the right one."""
    scene, t_final, directions, kinds = _case(name, block3, aniso, ball)
    traj = cd.simulate(scene, t_final, jacobian=True, jacobian_error="state", **TOL)
    assert [k for k, _ in event_kinds(traj)] == kinds
    fd, fd_times = central_differences(scene, t_final, directions, event_kinds(traj))
    D = np.array(directions).T
    assert_fd(f"jacobian_error=state {name}", traj.jacobian @ D, fd, traj.q, rtol=FD_RTOL)
    for k, event in enumerate(traj.events):
        assert_fd(
            f"jacobian_error=state {name} event {k} time", event.time_gradient @ D, fd_times[k], event.t, rtol=FD_RTOL
        )
