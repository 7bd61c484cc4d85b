"""Tests of contactdiff.ode's steppers against closed forms, finite differences and scipy."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from contactdiff.errors import IntegrationError, InvalidInputError, OutsideDomainError
from contactdiff.ode.factory import (
    DOP853,
    METHODS,
    PinocchioGroup,
    Radau,
    VectorSpace,
    make_stepper,
)


def run_to(stepper, T):
    """Step until T (the stepper must have t_bound = T)."""
    while stepper.t < T:
        stepper.step()
    assert stepper.t == T
    return stepper


# --------------------------------------------------------------------------
# Harmonic oscillator x'' = -w^2 x: closed-form state and flow Jacobian
# --------------------------------------------------------------------------

W = 2.0


def ho_accel(t, q, v):
    return -W * W * q


def ho_jac(t, q, v):
    return np.array([[-W * W]]), np.zeros((1, 1))


def ho_exact(t, x0=1.0, v0=0.0):
    c, s = np.cos(W * t), np.sin(W * t)
    return x0 * c + v0 * s / W, -x0 * W * s + v0 * c


def ho_phi(t):
    c, s = np.cos(W * t), np.sin(W * t)
    return np.array([[c, s / W], [-W * s, c]])


@pytest.mark.parametrize("method, tol, bound", [("DOP853", 1e-13, 1e-12), ("Radau", 1e-11, 1e-10)])
def test_harmonic_final_state_dense_and_jacobian(method, tol, bound):
    T = 10.0
    s = make_stepper(
        method,
        ho_accel,
        VectorSpace(1),
        0.0,
        [1.0],
        [0.0],
        rtol=tol,
        atol=tol,
        jac=ho_jac,
        t_bound=T,
        variational=np.eye(2),
    )
    dense_err = 0.0
    while s.t < T:
        s.step()
        d = s.dense()
        ts = np.linspace(s.t_old, s.t, 7)[1:-1]
        q, v = d(ts)
        xe, ve = ho_exact(ts)
        dense_err = max(dense_err, np.abs(q[:, 0] - xe).max(), np.abs(v[:, 0] - ve).max())
        # the interpolant's derivative is the field along it, up to the interpolation error
        qd, vd = d.derivative(ts[2])
        assert abs(vd[0] + W * W * d(ts[2])[0][0]) < 1e3 * bound
    xe, ve = ho_exact(T)
    assert abs(s.q[0] - xe) < bound and abs(s.v[0] - ve) < bound
    # Dense output: global error (~bound) plus the interpolant's own error; DOP853's
    # 7th-order interpolant and Radau's collocation polynomial are within 10x of the
    # global error at these tolerances.
    assert dense_err < 10 * bound
    assert np.abs(s.phi - ho_phi(T)).max() < bound
    assert s.n_accel > 0 and s.n_jac > 0


def test_dop853_matches_scipy_on_vector_space():
    """Same tableau, controller and first step as scipy: the same trajectory."""
    T = 20.0
    atol = np.array([1e-9, 1e-8])  # per component of (q, v)
    s = run_to(
        DOP853(lambda t, q, v: -np.sin(q), VectorSpace(1), 0.0, [2.5], [0.0], rtol=1e-9, atol=atol, t_bound=T), T
    )
    r = solve_ivp(lambda t, y: [y[1], -np.sin(y[0])], (0, T), [2.5, 0.0], method="DOP853", rtol=1e-9, atol=atol)
    assert s.n_steps == r.t.size - 1
    assert np.abs(np.r_[s.q, s.v] - r.y[:, -1]).max() < 1e-12


@pytest.mark.parametrize(
    "method, tol, bound", [("DOP853", 1e-12, 1e-10), ("Radau", 1e-11, 1e-9), ("RK45", 1e-11, 1e-8)]
)
def test_van_der_pol_against_scipy(method, tol, bound):
    mu = 2.0

    def accel(t, q, v):
        return mu * (1 - q * q) * v - q

    def jac(t, q, v):
        return np.array([[-2 * mu * q[0] * v[0] - 1]]), np.array([[mu * (1 - q[0] ** 2)]])

    T = 8.0
    s = run_to(
        make_stepper(method, accel, VectorSpace(1), 0.0, [2.0], [0.0], rtol=tol, atol=tol, jac=jac, t_bound=T), T
    )
    ref = solve_ivp(
        lambda t, y: [y[1], mu * (1 - y[0] ** 2) * y[1] - y[0]],
        (0, T),
        [2.0, 0.0],
        method="DOP853",
        rtol=1e-13,
        atol=1e-13,
    ).y[:, -1]
    assert np.abs(np.r_[s.q, s.v] - ref).max() < bound


@settings(max_examples=15, deadline=None)
@given(w=st.floats(0.1, 10.0), x0=st.floats(-2, 2), v0=st.floats(-2, 2), T=st.floats(0.1, 5.0))
def test_harmonic_property(w, x0, v0, T):
    s = run_to(
        DOP853(lambda t, q, v: -w * w * q, VectorSpace(1), 0.0, [x0], [v0], rtol=1e-10, atol=1e-10, t_bound=T), T
    )
    c, sn = np.cos(w * T), np.sin(w * T)
    assert abs(s.q[0] - (x0 * c + v0 * sn / w)) < 1e-8 * (1 + w * T)
    assert abs(s.v[0] - (-x0 * w * sn + v0 * c)) < 1e-8 * (1 + w) * (1 + w * T)


# --------------------------------------------------------------------------
# Stiff: x'' + c x' + k x = k sin t + c cos t (spring of stiffness 1e7 tracking sin t)
# --------------------------------------------------------------------------

K_STIFF = 1e7
C_STIFF = 1.2e4  # overdamped: eigenvalues about -1.1e3 and -1.1e4


def stiff_accel(t, q, v):
    return K_STIFF * (np.sin(t) - q) + C_STIFF * (np.cos(t) - v)


def stiff_jac(t, q, v):
    return np.array([[-K_STIFF]]), np.array([[-C_STIFF]])


def stiff_exact(t, x0, v0):
    """Particular solution a sin t + b cos t plus the homogeneous solution."""
    a, b = np.linalg.solve([[K_STIFF - 1, -C_STIFF], [C_STIFF, K_STIFF - 1]], [K_STIFF, C_STIFF])
    disc = np.sqrt(C_STIFF**2 - 4 * K_STIFF)
    l1, l2 = (-C_STIFF + disc) / 2, (-C_STIFF - disc) / 2
    c1, c2 = np.linalg.solve([[1, 1], [l1, l2]], [x0 - b, v0 - a])
    x = a * np.sin(t) + b * np.cos(t) + c1 * np.exp(l1 * t) + c2 * np.exp(l2 * t)
    v = a * np.cos(t) - b * np.sin(t) + c1 * l1 * np.exp(l1 * t) + c2 * l2 * np.exp(l2 * t)
    phi = np.array([[1, 1], [l1, l2]]) @ np.diag(np.exp([l1 * t, l2 * t])) @ np.linalg.inv([[1, 1], [l1, l2]])
    return x, v, phi, min(l1, l2)


def test_radau_stiff_spring_long_interval():
    T = 20.0
    s = run_to(Radau(stiff_accel, VectorSpace(1), 0.0, [0.5], [0.0], rtol=1e-7, atol=1e-9, jac=stiff_jac, t_bound=T), T)
    x, v, _, lam_min = stiff_exact(T, 0.5, 0.0)
    assert abs(s.q[0] - x) < 1e-9 and abs(s.v[0] - v) < 1e-7
    # Any explicit method needs |h lam| below its stability bound (~6 for DOP853), i.e.
    # at least T |lam| / 6 ~ 3.7e4 steps here; Radau's count is set by accuracy alone
    # (following sin t to rtol 1e-7 with a 3rd-order error estimate: ~1.3e3 steps, as scipy's Radau).
    explicit_min_steps = T * abs(lam_min) / 6
    assert explicit_min_steps > 3e4
    assert s.n_steps < 2000, s.n_steps
    assert s.n_steps < explicit_min_steps / 15


def test_radau_stiff_flow_jacobian_and_fd_jacobian():
    T = 2e-3  # the fast transient is still visible in phi
    s = run_to(
        Radau(
            stiff_accel,
            VectorSpace(1),
            0.0,
            [0.5],
            [0.0],
            rtol=1e-10,
            atol=1e-12,
            jac=stiff_jac,
            t_bound=T,
            variational=np.eye(2),
        ),
        T,
    )
    x, v, phi, _ = stiff_exact(T, 0.5, 0.0)
    assert abs(s.q[0] - x) < 1e-10
    assert np.abs(s.phi - phi).max() < 1e-7 * np.abs(phi).max()
    # without jac Radau builds its Newton matrix by forward differences
    s2 = run_to(Radau(stiff_accel, VectorSpace(1), 0.0, [0.5], [0.0], rtol=1e-10, atol=1e-12, t_bound=T), T)
    assert abs(s2.q[0] - x) < 1e-10 and s2.n_jac >= 1


# --------------------------------------------------------------------------
# Lie groups: torque-free rigid body on a free-flyer
# --------------------------------------------------------------------------


def rigid_body():
    model = pin.Model()
    j = model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), "root")
    inertia = np.array([[1.0, 0.1, -0.05], [0.1, 2.0, 0.2], [-0.05, 0.2, 3.0]])
    model.appendBodyToJoint(j, pin.Inertia(2.0, np.array([0.1, -0.2, 0.05]), inertia), pin.SE3.Identity())
    model.gravity = pin.Motion.Zero()
    data = model.createData()
    tau = np.zeros(6)

    def accel(t, q, v):
        return pin.aba(model, data, q, v, tau)

    def jac(t, q, v):
        dq, dv, _ = pin.computeABADerivatives(model, data, q, v, tau)
        return dq.copy(), dv.copy()

    q0 = pin.integrate(model, pin.neutral(model), np.array([0.1, -0.2, 0.3, 0.4, -0.5, 0.6]))
    v0 = np.array([0.3, -0.1, 0.2, 0.5, 2.0, -0.4])  # tumbling near the intermediate axis
    return model, data, accel, jac, q0, v0


def invariants(model, data, q, v):
    """Kinetic energy and world-frame spatial momentum (linear, angular about the origin)."""
    energy = 0.5 * v @ pin.crba(model, data, q) @ v
    pin.forwardKinematics(model, data, q)
    h = data.oMi[1].act(model.inertias[1] * pin.Motion(v))
    return energy, h.linear.copy(), h.angular.copy()


@pytest.mark.parametrize("method, tol", [("DOP853", 1e-12), ("Radau", 1e-10)])
def test_free_flyer_invariants_and_flow_jacobian(method, tol):
    model, data, accel, jac, q0, v0 = rigid_body()
    group = PinocchioGroup(model)
    assert not group.is_vector_space
    T = 2.0

    def simulate(q, v, phi=None):
        return run_to(
            make_stepper(method, accel, group, 0.0, q, v, rtol=tol, atol=tol, jac=jac, t_bound=T, variational=phi), T
        )

    s = simulate(q0, v0, np.eye(12))
    # dense output of the last step: q(t) = q_old ⊕ xi(t), its derivative ~ (v(t), accel)
    tm = 0.5 * (s.t_old + s.t)
    qm, vm = s.dense()(tm)
    qd, vd = s.dense().derivative(tm)
    assert np.abs(qd - vm).max() < 1e-7 and np.abs(vd - accel(tm, qm, vm)).max() < 1e-7
    e0, p0, l0 = invariants(model, data, q0, v0)
    e1, p1, l1 = invariants(model, data, s.q, s.v)
    assert abs(e1 - e0) < 1e-10 and np.abs(p1 - p0).max() < 1e-10 and np.abs(l1 - l0).max() < 1e-10
    assert abs(np.linalg.norm(s.q[3:7]) - 1) < 1e-14
    # central differences on the manifold: q0 ⊕ ±eps e_k, v0 ± eps e_k
    eps = 1e-5
    fd = np.empty((12, 12))
    for k in range(12):
        d = np.zeros(12)
        d[k] = eps
        a = simulate(pin.integrate(model, q0, d[:6]), v0 + d[6:])
        b = simulate(pin.integrate(model, q0, -d[:6]), v0 - d[6:])
        fd[:6, k] = pin.difference(model, b.q, a.q) / (2 * eps)
        fd[6:, k] = (a.v - b.v) / (2 * eps)
    assert np.abs(s.phi - fd).max() < 1e-6 * np.abs(fd).max()


def multi_joint_model():
    """Every supported Lie-group joint type plus Euclidean ones, in one chain."""
    model = pin.Model()
    joints = [
        pin.JointModelFreeFlyer(),
        pin.JointModelSpherical(),
        pin.JointModelPlanar(),
        pin.JointModelRUBZ(),
        pin.JointModelRX(),
        pin.JointModelPY(),
    ]
    parent = 0
    for i, jm in enumerate(joints):
        parent = model.addJoint(parent, jm, pin.SE3(np.eye(3), np.array([0.0, 0.0, 0.3])), f"j{i}")
        model.appendBodyToJoint(parent, pin.Inertia.Random(), pin.SE3.Identity())
    return model


def test_pinocchio_group_against_dintegrate():
    model = multi_joint_model()
    g = PinocchioGroup(model)
    assert (g.nq, g.nv) == (19, 15) and not g.is_vector_space
    rng = np.random.default_rng(1)
    q0 = pin.integrate(model, pin.neutral(model), rng.standard_normal(model.nv))
    xi, v = 0.3 * rng.standard_normal(model.nv), rng.standard_normal(model.nv)
    D1 = pin.dIntegrate(model, q0, xi, pin.ARG1)
    assert np.allclose(g.chart_velocity(q0, xi, v), np.linalg.solve(D1, v), rtol=0, atol=1e-12)
    assert np.allclose(g.tangent_velocity(q0, xi, v), D1 @ v, rtol=0, atol=1e-12)
    # velocity_jacobian_q = d/dh dIntegrate(q, h v, ARG0) at h = 0 (notes §5), central FD
    h = 1e-6
    fd = (pin.dIntegrate(model, q0, h * v, pin.ARG0) - pin.dIntegrate(model, q0, -h * v, pin.ARG0)) / (2 * h)
    assert np.abs(g.velocity_jacobian_q(q0, v) - fd).max() < 1e-8
    assert g.magnitude(q0).shape == (model.nv,)


def test_continuous_joint_is_not_a_vector_space():
    m1 = pin.Model()
    m1.addJoint(0, pin.JointModelRUBZ(), pin.SE3.Identity(), "c")
    m2 = pin.Model()
    m2.addJoint(0, pin.JointModelRZ(), pin.SE3.Identity(), "r")
    assert not PinocchioGroup(m1).is_vector_space
    assert PinocchioGroup(m2).is_vector_space


@pytest.mark.parametrize(
    "method, control, max_step",
    [("DOP853", True, np.inf), ("Radau", True, np.inf), ("DOP853", False, 0.1), ("Radau", False, 0.01)],
)
def test_free_motion_on_every_joint_group(method, control, max_step):
    """accel = 0: q(T) = q0 ⊕ T v0 and phi = [[dInt/dq, T dInt/dv], [0, I]] exactly.

    The chart solution xi = t v0 is polynomial, so the state error estimate is zero and
    steps would grow to the whole interval; phi solves d(δq)/dt = -ad(v0) δq + δv, whose
    exponential needs bounded steps: phi's error control chooses them, or (without it)
    max_step must.
    """
    model = multi_joint_model()
    nv = model.nv
    rng = np.random.default_rng(2)
    q0 = pin.integrate(model, pin.neutral(model), rng.standard_normal(nv))
    v0 = rng.standard_normal(nv)
    T = 1.5
    s = run_to(
        make_stepper(
            method,
            lambda t, q, v: np.zeros(nv),
            model,
            0.0,
            q0,
            v0,
            rtol=1e-11,
            atol=1e-11,
            jac=lambda t, q, v: (np.zeros((nv, nv)), np.zeros((nv, nv))),
            t_bound=T,
            variational=np.eye(2 * nv),
            max_step=max_step,
            variational_error_control=control,
        ),
        T,
    )
    assert np.abs(pin.difference(model, pin.integrate(model, q0, T * v0), s.q)).max() < 1e-9
    phi = np.eye(2 * nv)
    phi[:nv, :nv] = pin.dIntegrate(model, q0, T * v0, pin.ARG0)
    phi[:nv, nv:] = T * pin.dIntegrate(model, q0, T * v0, pin.ARG1)
    assert np.abs(s.phi - phi).max() < 1e-8


# --------------------------------------------------------------------------
# Error control on phi: a state that is trivial to integrate, a linearisation that is not
# --------------------------------------------------------------------------

K_REST = 10.0


def rest_spring_accel(t, q, v):
    """Two unit masses in free fall (g = 1) joined by a spring of stiffness K_REST.

    Started with x1 = x2 and v1 = v2 the spring stays at its rest length: the state is an
    exact parabola (zero error estimate at any step size), but J_q carries K_REST.
    """
    r = K_REST * (q[1] - q[0])
    return np.array([-1.0 + r, -1.0 - r])


def rest_spring_jac(t, q, v):
    return K_REST * np.array([[-1.0, 1.0], [1.0, -1.0]]), np.zeros((2, 2))


def rest_spring_phi(T):
    """Common mode: free particle; relative mode x2 - x1: oscillator with w^2 = 2 K_REST."""
    w = np.sqrt(2 * K_REST)
    pc = np.full((2, 2), 0.5)
    pr = np.eye(2) - pc
    c, s = np.cos(w * T), np.sin(w * T)
    return np.block([[pc + c * pr, T * pc + s / w * pr], [-w * s * pr, pc + c * pr]])


def rest_spring(method, control, T=1.0, **kw):
    return make_stepper(
        method,
        rest_spring_accel,
        VectorSpace(2),
        0.0,
        [0.3, 0.3],
        [0.5, 0.5],
        rtol=1e-10,
        atol=1e-12,
        jac=rest_spring_jac,
        t_bound=T,
        variational=np.eye(4),
        variational_error_control=control,
        **kw,
    )


@pytest.mark.parametrize("method", ["DOP853", "RK45", "Radau"])
def test_variational_error_control_spring_at_rest_length(method):
    T = 1.0
    phi = rest_spring_phi(T)
    s = run_to(rest_spring(method, True), T)
    assert np.abs(s.q - (0.3 + 0.5 * T - 0.5 * T * T)).max() < 1e-13
    assert np.abs(s.phi - phi).max() < 1e-8 * np.abs(phi).max()
    if method != "Radau":  # DF at the step's start once per step, not once per attempt
        assert s.n_jac <= s.n_stages * (s.n_steps + s.n_rejected) + 1
    # Without it the steps are chosen for the parabola alone: a few steps over the whole
    # interval (w T = 4.5 rad) and phi is wrong by percents (DOP853: 0.7%, RK45 and Radau: 15-25%).
    s0 = run_to(rest_spring(method, False), T)
    assert s0.n_steps <= 5
    assert np.abs(s0.phi - phi).max() > 1e-3 * np.abs(phi).max()


@pytest.mark.parametrize("method", ["DOP853", "RK45", "Radau"])
def test_variational_error_control_changes_only_the_steps(method):
    """phi is propagated the same way: replaying the controlled steps without control gives the same phi."""
    T = 0.5
    s = rest_spring(method, True, T)
    hs = []
    while s.t < T:
        s.step()
        hs.append(s.t - s.t_old)
    s0 = rest_spring(method, False, T)
    for h in hs:  # the state's error is ~0 here, so no step of the replay is rejected
        s0.h_abs = h
        s0.step()
    assert s0.n_rejected == 0 and s0.t == s.t
    np.testing.assert_array_equal(s0.phi, s.phi)
    np.testing.assert_array_equal(s0.q, s.q)


# --------------------------------------------------------------------------
# truncate / restart
# --------------------------------------------------------------------------


@pytest.mark.parametrize("method", ["DOP853", "RK45", "Radau"])
def test_truncate_matches_dense_and_continuation(method):
    tol = 1e-11
    T = 6.0
    s = make_stepper(
        method,
        ho_accel,
        VectorSpace(1),
        0.0,
        [1.0],
        [0.3],
        rtol=tol,
        atol=tol,
        jac=ho_jac,
        t_bound=T,
        variational=np.eye(2),
    )
    for _ in range(3):
        s.step()
    t_cut = s.t_old + 0.37 * (s.t - s.t_old)
    qd, vd = s.dense()(t_cut)
    s.truncate(t_cut)
    assert s.t == t_cut and s.q[0] == qd[0] and s.v[0] == vd[0]
    assert s.dense().t == t_cut
    xe, ve = ho_exact(t_cut, 1.0, 0.3)
    assert abs(s.q[0] - xe) < 100 * tol and abs(s.v[0] - ve) < 100 * tol
    assert np.abs(s.phi - ho_phi(t_cut)).max() < 100 * tol
    run_to(s, T)
    xe, ve = ho_exact(T, 1.0, 0.3)
    assert abs(s.q[0] - xe) < 100 * tol and abs(s.v[0] - ve) < 100 * tol
    assert np.abs(s.phi - ho_phi(T)).max() < 100 * tol
    with pytest.raises(InvalidInputError):
        s.truncate(T + 1.0)


@pytest.mark.parametrize("method", ["DOP853", "Radau"])
def test_restart_after_jump(method):
    """Velocity reversal at t1: afterwards x(t) is the oscillator from (x(t1), -v(t1))."""
    tol = 1e-11
    t1, T = 1.0, 4.0
    s = make_stepper(
        method,
        ho_accel,
        VectorSpace(1),
        0.0,
        [1.0],
        [0.0],
        rtol=tol,
        atol=tol,
        jac=ho_jac,
        t_bound=t1,
        variational=np.eye(2),
    )
    run_to(s, t1)
    x1, v1 = ho_exact(t1)
    reset = np.diag([1.0, -1.0])
    s.restart(t1, s.q, -s.v, phi=reset @ s.phi, t_bound=T)
    assert s.t_old is None
    run_to(s, T)
    xe, ve = ho_exact(T - t1, x1, -v1)
    assert abs(s.q[0] - xe) < 100 * tol and abs(s.v[0] - ve) < 100 * tol
    assert np.abs(s.phi - ho_phi(T - t1) @ reset @ ho_phi(t1)).max() < 100 * tol
    # a new vector field after the restart (mode change): free flight
    s.restart(T, [0.0], [1.0], accel=lambda t, q, v: np.zeros(1), t_bound=T + 2)
    run_to(s, T + 2)
    assert abs(s.q[0] - 2.0) < 1e-12


def test_step_at_bound_and_underflow():
    s = run_to(DOP853(ho_accel, VectorSpace(1), 0.0, [1.0], [0.0], t_bound=0.5), 0.5)
    with pytest.raises(IntegrationError, match="t_bound"):
        s.step()

    def blowup(t, q, v):  # finite-time singularity at t = 1: steps shrink to nothing
        return np.array([1.0 / (1.0 - t) ** 3])

    s = DOP853(blowup, VectorSpace(1), 0.0, [0.0], [0.0], rtol=1e-8, atol=1e-8, t_bound=2.0)
    with pytest.raises(IntegrationError, match=r"t=0\.99"):
        run_to(s, 2.0)


def test_nonfinite_accel_names_time():
    def accel(t, q, v):
        return np.array([np.nan if t > 0.3 else -q[0]])

    for method in METHODS:
        s = make_stepper(method, accel, VectorSpace(1), 0.0, [1.0], [0.0], jac=ho_jac, t_bound=2.0)
        with pytest.raises(IntegrationError, match="non-finite values at t=") as info:
            run_to(s, 2.0)
        t_bad = float(str(info.value).split("t=")[1].split()[0].rstrip(":"))
        assert 0.3 < t_bad < 1.0 and s.t <= 0.3
    with pytest.raises(IntegrationError, match="t=0.0"):
        DOP853(lambda t, q, v: np.array([np.inf]), VectorSpace(1), 0.0, [1.0], [0.0])


# --------------------------------------------------------------------------
# bad inputs
# --------------------------------------------------------------------------


def test_unknown_method_lists_valid_ones():
    with pytest.raises(InvalidInputError) as info:
        make_stepper("euler", ho_accel, VectorSpace(1), 0.0, [1.0], [0.0])
    for m in METHODS:
        assert m in str(info.value)
    assert make_stepper("radau", ho_accel, VectorSpace(1), 0.0, [1.0], [0.0], jac=ho_jac).method == "Radau"


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(q0=[np.nan]), "q0"),
        (dict(v0=[1.0, 2.0]), "v0"),
        (dict(rtol=0.0), "rtol"),
        (dict(rtol=-1e-3), "rtol"),
        (dict(atol=[1e-6]), "atol"),
        (dict(atol=-1.0), "atol"),
        (dict(first_step=0.0), "first_step"),
        (dict(max_step=-1.0), "max_step"),
        (dict(t0=np.inf), "t0"),
        (dict(t_bound=-1.0), "t_bound"),
        (dict(variational=np.eye(3)), "phi"),
        (dict(variational=np.eye(2), jac=None), "jac"),
        (dict(variational=np.eye(2), variational_atol=[1e-9]), "variational_atol"),
        (dict(variational=np.eye(2), variational_atol=0.0), "variational_atol"),
        (dict(accel=3.0), "accel"),
        (dict(accel=lambda t, q, v: np.zeros(2)), "shape"),
    ],
)
def test_bad_inputs(kwargs, match):
    args = dict(accel=ho_accel, group=VectorSpace(1), t0=0.0, q0=[1.0], v0=[0.0], jac=ho_jac)
    args.update(kwargs)
    with pytest.raises(InvalidInputError, match=match):
        DOP853(args.pop("accel"), args.pop("group"), args.pop("t0"), args.pop("q0"), args.pop("v0"), **args)


def test_bad_jac_and_truncate_before_step():
    with pytest.raises(InvalidInputError, match="jac must return"):
        Radau(ho_accel, VectorSpace(1), 0.0, [1.0], [0.0], jac=lambda t, q, v: (np.eye(2), np.eye(2)))
    s = DOP853(ho_accel, VectorSpace(1), 0.0, [1.0], [0.0])
    with pytest.raises(InvalidInputError):
        s.truncate(0.0)
    with pytest.raises(InvalidInputError):
        s.dense()
    with pytest.raises(InvalidInputError, match="group"):
        DOP853(ho_accel, object(), 0.0, [1.0], [0.0])


@pytest.mark.parametrize("method", ["DOP853", "RK45"])
def test_lazy_dense_output_equals_the_eager_one_after_later_steps(method):
    """A lazy interpolant read after the stepper has moved on (and changed its
    vector field) must give exactly the eager interpolant of its own step."""
    from contactdiff.ode.factory import VectorSpace, make_stepper

    def accel(t, q, v):
        return -4.0 * q

    st = make_stepper(method, accel, VectorSpace(1), 0.0, [1.0], [0.0], rtol=1e-8, atol=1e-10)
    st.step()
    lazy = st.dense(lazy=True)
    eager = st.dense()
    times = np.linspace(lazy.t_old, lazy.t, 7)
    expected = eager(times)
    st.step()
    st.restart(st.t, st.q, st.v, accel=lambda t, q, v: 100.0 * q)  # a new mode's field
    st.step()
    got = lazy(times)
    assert np.array_equal(got[0], expected[0]) and np.array_equal(got[1], expected[1])


# --------------------------------------------------------------------------
# A field defined on part of the state space: trial stages outside it
# --------------------------------------------------------------------------


def _bounded(accel, limit):
    """``accel`` defined only where |q| <= limit (as a slip mode only where A_n M^-1 F^T > 0)."""

    def bounded(t, q, v):
        if abs(q[0]) > limit:
            raise OutsideDomainError(f"q = {q[0]!r} outside |q| <= {limit}")
        return accel(t, q, v)

    return bounded


@pytest.mark.parametrize("method", METHODS)
def test_trial_stages_outside_the_domain_only_shorten_the_step(method):
    """The oscillator (amplitude 1) on the domain |q| <= 1.001: a first step of 1 s puts its trial
    stages far outside (|q| up to ~2 for ω = 2), so the step is rejected and retried shorter instead
    of failing, and the run ends on the closed form (tolerance as in the harmonic test above)."""
    s = make_stepper(
        method,
        _bounded(ho_accel, 1.001),
        VectorSpace(1),
        0.0,
        [1.0],
        [0.0],
        rtol=1e-11,
        atol=1e-11,
        jac=ho_jac,
        first_step=1.0,
        t_bound=3.0,
    )
    run_to(s, 3.0)
    assert s.n_rejected >= 1
    np.testing.assert_allclose([s.q[0], s.v[0]], ho_exact(3.0), atol=1e-8)


@pytest.mark.parametrize("method", METHODS)
def test_a_trajectory_leaving_the_domain_raises_the_fields_error(method):
    """x'' = x from (1, 1) grows as e^t and leaves |q| <= 2 at t = ln 2: every step there has a
    stage outside, the step underflows, and the field's own error is raised, not an underflow."""
    s = make_stepper(
        method,
        _bounded(lambda t, q, v: q, 2.0),
        VectorSpace(1),
        0.0,
        [1.0],
        [1.0],
        rtol=1e-10,
        atol=1e-10,
        jac=lambda t, q, v: (np.eye(1), np.zeros((1, 1))),
        t_bound=3.0,
    )
    with pytest.raises(OutsideDomainError, match="the trajectory itself does") as info:
        run_to(s, 3.0)
    assert s.t == pytest.approx(np.log(2.0), abs=1e-6)  # s: it stopped where the state reached the edge
    assert "outside |q| <= 2.0" in str(info.value)


def test_the_flow_jacobians_error_scale_has_a_floor_at_its_columns_round_off():
    """An entry of phi is formed by the field's Jacobian mixing its column's rows, so it carries
    round-off of ~eps times the column's largest entry: its error scale is at least
    ``RTOL_FLOOR`` (100 eps) times that entry, and otherwise ``atol + rtol |phi|``."""
    from contactdiff.ode.tolerances import RTOL_FLOOR

    s = make_stepper(
        "DOP853",
        lambda t, q, v: -q,
        VectorSpace(2),
        0.0,
        [1.0, 0.0],
        [0.0, 1.0],
        rtol=1e-8,
        atol=1e-10,
        jac=lambda t, q, v: (-np.eye(2), np.zeros((2, 2))),
        t_bound=1.0,
        variational=np.eye(4),
    )
    P = np.array([[2.5e5, 1.0], [1e-7, 0.5], [0.0, 0.0], [0.0, 0.0]])
    scale = s._phi_scale(P, P)
    assert scale[1, 0] == pytest.approx(RTOL_FLOOR * 2.5e5)  # the floor binds: atol + rtol 1e-7 ~ 1e-10
    assert scale[0, 0] == pytest.approx(1e-10 + 1e-8 * 2.5e5)
    assert scale[1, 1] == pytest.approx(1e-10 + 1e-8 * 0.5)  # a column of size 1: atol + rtol |phi|
