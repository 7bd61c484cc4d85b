"""Parameter derivatives at a fixed state, against central finite differences
through `Scene.with_parameters`.

What is checked (conventions in `contactdiff.dynamics.parameter_forces` and
`contactdiff.integration.parameter_jumps`):

* ``∂ddq/∂p = ddq_dtau @ ∂f/∂p`` and ``∂λ/∂p = forces_dtau @ ∂f/∂p``
  (`ParameterForces.forces`) in the three code paths of `ModeDynamics`: flight
  (ABA), sticking 3-D feet on the ground (Pinocchio's constraint dynamics) and
  any other mode (the Python KKT solve: solo12 with one foot sliding, the planar
  soft trot's frictionless feet, the rigid bar on both feet); masses, centres of
  mass, all six inertia entries, armatures, gravity, springs, a joint spring,
  the trot's gains and (through its feed-forward) the model's share of the
  efforts; a contact's restitution and offset give zero columns;
* `ParameterJumps.force_guard` (one normal force) and `ParameterJumps.gap_guard`;
* `ParameterForces.impulse_forces` against ``-∂(M(q) dv)/∂p`` with ``M`` from
  ``pin.crba`` on the perturbed model, and ``∂v+/∂p`` of an impact
  (`impact_parameter_jacobian`, `ParameterJumps.impact`) against `resolve_impact`
  on the perturbed scene: one foot, two feet, two feet of which one has its
  restitution set to 0 by the caller (then not a live contact), two sticking
  solo12 feet;
* `ParameterJumps.projection`'s offset columns against the configuration that
  `project_state` returns on the perturbed scene;
* `dynamic_parameter_derivative` against ``pin.Inertia(m, c, I).toDynamicParameters()``.

Reference. The scene is rebuilt with one parameter moved by ``±h``
(``with_parameters``: a copied robot, efforts and contacts bound again), a new
`ModeDynamics` evaluates the quantity at the same state and time, and
``(f(p + h) - f(p - h)) / 2h`` is compared with the code's column. Nothing is
taken from the code under test.

Step and tolerance. The step is ``h = δ s`` with ``δ = REL = 1e-4`` and ``s`` the
parameter's size, or where it is 0 a natural scale (`_step`: |g| for gravity,
5 cm for a centre of mass, the body's largest moment for a product of inertia,
1 cm for an offset). A central difference's error is

    truncation  h² |f'''| / 6 ≈ C δ² |∂f/∂p| / 6   (f rational in p on the scale s, C = O(1..10)),
    round-off   ε_f max|f| / h,   ε_f the relative accuracy of one evaluation of f.

With ``δ = 1e-4`` the truncation is ~2e-9 C relative to the column (the base's
products of inertia, whose scale is the base's largest moment, show 7e-9 at
δ = 1e-4 and 7e-7 at δ = 1e-3: the δ² law), and ``ε_f`` is bounded by
``ROUND = 1e-12`` (~5000 u: solo12's mass matrix, with 38 g shanks and leg
inertias down to 3e-5 kg m², has condition number 7e3 at the trot's pose). A
column passes when

    max|analytic - fd| <= RTOL (max|fd| + (ROUND / RTOL) max|f| / h),   RTOL = 1e-6,

i.e. within 1e-6 of its own size (50 times the truncation bound) plus the
round-off the difference can be measured to; measured, the worst column of any
case is at 7e-8 of that scale. A wrong term (a sign, a swapped inertia entry, a
missing effort share, a wrong row) is an O(1) error of its column. ``v+`` is
affine in a restitution and ``M`` and ``π`` are polynomial in a body's
parameters: there only round-off remains and the bound is looser than needed.

Set ``CONTACTDIFF_FD_REPORT=1`` (and ``pytest -s``) to print the largest error of
each category, relative to the scale above (to be compared with ``RTOL``).
"""

from __future__ import annotations

import functools

import numpy as np
import pinocchio as pin
import pytest
from helpers import FD_ERRORS

import contactdiff as cd
from contactdiff.dynamics.impacts import resolve_impact
from contactdiff.dynamics.mode import ModeDynamics
from contactdiff.dynamics.parameter_forces import ParameterForces, dynamic_parameter_derivative
from contactdiff.integration.parameter_jumps import ParameterJumps
from contactdiff.integration.projection import close, mode_rows, project_state
from contactdiff.integration.sensitivity import impact_parameter_jacobian
from contactdiff.model.parameters import BODY_FIELDS, resolve

REL = 1e-4
RTOL = 1e-6
ROUND = 1e-12


# ----------------------------------------------------------------------------------
# scenes, steps, central differences
# ----------------------------------------------------------------------------------
def _solo() -> cd.Scene:
    """solo12_trot with its initial pose raised 10 cm (a larger contact offset must not
    make it penetrate; the states studied are passed explicitly), armature on one knee
    and restitutions inside (0, 1), so that both sides of every difference exist."""
    scene = cd.load_scene("solo12_trot")
    q = scene.q0.copy()
    q[2] += 0.1
    return scene.with_state(q).with_parameters(
        {
            "joint:FL_KFE:armature": 2e-5,
            "contact:FL_FOOT:restitution": 0.3,
            "contact:FR_FOOT:restitution": 0.2,
            "contact:HR_FOOT:restitution": 0.6,
        }
    )


def _planar() -> cd.Scene:
    """The planar soft trot (a body on two spring legs ending in point feet on x-z
    slides) with a torsional joint spring on the body's pitch; the rear spring's damping,
    two armatures and a restitution moved off 0."""
    base = cd.trot_touchdown("soft", 0.0)
    efforts = base.effort_specs + (cd.JointSpring("body_pitch", 2.0, 0.1, 0.05),)
    scene = cd.Scene(base.robot, base.contact_specs, efforts, None, base.q0, base.v0, name="planar")
    return scene.with_parameters(
        {
            "spring:rear_hip-rear_foot:damping": 0.3,
            "joint:body_pitch:armature": 0.05,
            "joint:front_foot_x:armature": 0.02,
            "contact:rear_foot:restitution": 0.5,
        }
    )


def _bar() -> cd.Scene:
    """The planar rigid trot (one body, feet at ±0.25 m) with restitutions 0.5 (rear) and
    0.3 (front) and armature on its pitch and height."""
    base = cd.trot_touchdown("rigid", 0.05)
    contacts = [cd.Contact(c.frame, restitution=e) for c, e in zip(base.contact_specs, (0.5, 0.3))]
    scene = cd.Scene(base.robot, contacts, (), None, base.q0, base.v0, name="bar")
    return scene.with_parameters({"joint:body_pitch:armature": 0.1, "joint:body_z:armature": 0.2})


SCENES = {"solo12": _solo, "planar": _planar, "bar": _bar}


@functools.lru_cache(maxsize=None)
def _scene(name: str) -> cd.Scene:
    return SCENES[name]()


def _step(scene: cd.Scene, name: str) -> tuple[float, float]:
    """The parameter's value and the step ``h = REL · s`` of the module notes."""
    value = float(scene.parameter_values([name])[0])
    if value != 0.0:
        return value, REL * abs(value)
    field = name.rsplit(":", 1)[1]
    if field.startswith("gravity_"):
        size = float(np.linalg.norm(scene.model.gravity.linear))
    elif field.startswith("com_"):
        size = 0.05
    elif field in ("ixy", "ixz", "iyz"):
        body = name.rsplit(":", 1)[0]
        size = float(max(scene.parameter_values([f"{body}:{f}" for f in ("ixx", "iyy", "izz")])))
    elif field == "offset":
        size = 0.01
    else:
        raise AssertionError(f"no natural scale for {name!r} at 0")
    return value, REL * size


@functools.lru_cache(maxsize=None)
def _perturbed(scene_name: str, name: str) -> tuple[float, cd.Scene, cd.Scene]:
    """``(h, scene with p + h, scene with p - h)``."""
    scene = _scene(scene_name)
    value, h = _step(scene, name)
    return h, scene.with_parameters({name: value + h}), scene.with_parameters({name: value - h})


def _central(scene_name: str, name: str, evaluate) -> tuple[np.ndarray, float]:
    """Central difference of ``evaluate(scene)`` (an array) in parameter ``name``, and its step."""
    h, plus, minus = _perturbed(scene_name, name)
    return (np.asarray(evaluate(plus), dtype=float) - np.asarray(evaluate(minus), dtype=float)) / (2 * h), h


def _check(category: str, analytic, fd, value, h: float) -> float:
    """``max|analytic - fd| <= RTOL (max|fd| + ROUND/RTOL max|value| / h)`` (module notes);
    returns the error relative to that scale (recorded under ``category``)."""
    analytic, fd = np.asarray(analytic, dtype=float), np.asarray(fd, dtype=float)
    assert analytic.shape == fd.shape, (category, analytic.shape, fd.shape)
    scale = np.abs(fd).max(initial=0.0) + ROUND / RTOL * np.abs(np.asarray(value, dtype=float)).max(initial=0.0) / h
    err = float(np.abs(analytic - fd).max(initial=0.0)) / max(scale, 1e-300)
    FD_ERRORS[category] = max(FD_ERRORS.get(category, 0.0), err)
    assert err <= RTOL, (
        f"{category}: error {err:.3e} (relative to {scale:.3e}) > {RTOL:g}\nanalytic = {analytic}\nfd       = {fd}"
    )
    return err


def _rng_velocity(scene: cd.Scene, seed: int, size: float) -> np.ndarray:
    return size * np.random.default_rng(seed).standard_normal(scene.nv)


# ----------------------------------------------------------------------------------
# ∂ddq/∂p and ∂λ/∂p in each code path of ModeDynamics, and the force guard
# ----------------------------------------------------------------------------------
SOLO_PARAMETERS = (
    "scene:gravity_x",
    "scene:gravity_y",
    "scene:gravity_z",
    "body:base_link:mass",
    "body:FL_LOWER_LEG:mass",
    "body:base_link:com_x",
    "body:FL_UPPER_LEG:com_y",
    "body:HR_LOWER_LEG:com_z",
    *(f"body:base_link:{f}" for f in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")),
    "body:FL_UPPER_LEG:iyz",
    "joint:FL_KFE:armature",
    "trot:kp",
    "trot:kd",
    "contact:FL_FOOT:restitution",
    "contact:HR_FOOT:offset",
)
PLANAR_PARAMETERS = (
    "scene:gravity_x",
    "scene:gravity_z",
    "body:body:mass",
    "body:body:com_x",
    "body:body:iyy",
    "body:front_foot:mass",
    "joint:body_pitch:armature",
    "joint:front_foot_x:armature",
    "spring:rear_hip-rear_foot:stiffness",
    "spring:rear_hip-rear_foot:damping",
    "spring:rear_hip-rear_foot:rest_length",
    "joint_spring:body_pitch:stiffness",
    "joint_spring:body_pitch:damping",
    "joint_spring:body_pitch:rest",
    "contact:rear_foot:restitution",
    "contact:front_foot:offset",
)
BAR_PARAMETERS = (
    "scene:gravity_x",
    "scene:gravity_z",
    "body:body:mass",
    "body:body:com_x",
    "body:body:com_z",
    "body:body:iyy",
    "joint:body_pitch:armature",
    "joint:body_z:armature",
    "contact:rear_foot:restitution",
    "contact:front_foot:offset",
)


def _solo_air():
    scene = _scene("solo12")
    return scene.q0, _rng_velocity(scene, 1, 0.5)


def _solo_down(seed):
    """solo12_trot's initial pose with all four feet closed onto the ground (M-orthogonally)."""
    scene = _scene("solo12")
    q = close(ModeDynamics(scene), cd.load_scene("solo12_trot").q0, (0, 1, 2, 3))
    return q, _rng_velocity(scene, seed, 0.3)


def _planar_moved(seed):
    """The planar trot's initial pose moved at random (springs stretched and tilted)."""
    scene = _scene("planar")
    return pin.integrate(scene.model, scene.q0, 0.1 * np.random.default_rng(seed).standard_normal(scene.nv))


def _planar_air():
    scene = _scene("planar")
    return _planar_moved(4), _rng_velocity(scene, 4, 1.0)


def _planar_down():
    """Moved, then both feet closed onto the ground."""
    scene = _scene("planar")
    return close(ModeDynamics(scene), _planar_moved(5), (0, 1)), _rng_velocity(scene, 5, 1.0)


def _bar_down():
    scene = _scene("bar")
    return close(ModeDynamics(scene), scene.q0, (0, 1)), _rng_velocity(scene, 6, 1.0)


# case: (scene, mode, t, state, code path, parameters); the trot at t = 0.15 s, inside its schedule
MODE_CASES = {
    "solo12_flight": ("solo12", (), 0.15, _solo_air, "flight", SOLO_PARAMETERS),
    "solo12_stance": ("solo12", (0, 1, 2, 3), 0.15, lambda: _solo_down(2), "pinocchio", SOLO_PARAMETERS),
    # FR_FOOT (contact 1) sliding: key 4 + 1, its normal row only, between 3-row contacts
    "solo12_sliding": ("solo12", (0, 2, 3, 5), 0.15, lambda: _solo_down(3), "kkt", SOLO_PARAMETERS),
    "planar_flight": ("planar", (), 0.0, _planar_air, "flight", PLANAR_PARAMETERS),
    "planar_stance": ("planar", (0, 1), 0.0, _planar_down, "kkt", PLANAR_PARAMETERS),
    "bar_stance": ("bar", (0, 1), 0.0, _bar_down, "kkt", BAR_PARAMETERS),
}


def _pack(scene: cd.Scene, q, v, t, mode) -> np.ndarray:
    """``(ddq, row forces, normal forces)`` of a fresh `ModeDynamics` of ``scene``."""
    sol = ModeDynamics(scene).solve(q, v, t, mode)
    return np.concatenate([sol.ddq, sol.forces, sol.normal_forces()])


@functools.lru_cache(maxsize=None)
def _mode_study(case: str):
    scene_name, mode, t, state, _, names = MODE_CASES[case]
    scene = _scene(scene_name)
    q, v = state()
    dyn = ModeDynamics(scene)
    sol, der = dyn.solve(q, v, t, mode, derivatives=True)
    forces = ParameterForces(scene, resolve(scene, names)).forces(dyn.kin, q, v, sol.ddq, t)
    fd, steps = [], []
    for name in names:
        column, h = _central(scene_name, name, lambda s: _pack(s, q, v, t, mode))
        fd.append(column)
        steps.append(h)
    return scene, dyn, q, v, sol, der, forces, np.array(fd).T, steps


@pytest.mark.parametrize("case", list(MODE_CASES))
def test_mode_parameter_derivatives_match_finite_differences(case):
    scene_name, mode, t, _, path, names = MODE_CASES[case]
    scene, dyn, q, v, sol, der, forces, fd, steps = _mode_study(case)
    # the code path the case is meant to exercise
    rigid = dyn._mode(mode)[2]
    assert (path == "flight") == (mode == ())
    assert (rigid is not None) == (path == "pinocchio")
    nv, rows = scene.nv, sol.forces.size
    assert forces.shape == (nv, len(names)) and der.ddq_dtau.shape == (nv, nv)
    ddq_p, lam_p = der.ddq_dtau @ forces, der.forces_dtau @ forces
    assert lam_p.shape == (rows, len(names))
    for k, name in enumerate(names):
        # each column: the tolerance of the module notes, f = ddq (rad/s², m/s²) or λ (N)
        _check(f"ddq/{case}", ddq_p[:, k], fd[:nv, k], sol.ddq, steps[k])
        _check(f"lambda/{case}", lam_p[:, k], fd[nv : nv + rows, k], sol.forces, steps[k])
        if name.startswith("contact:"):
            # restitution and offset act at events only: exactly zero, by construction
            assert not np.any(forces[:, k]), name
        else:
            assert np.abs(fd[:nv, k]).max() > 0.0, f"{name} does not move ddq in {case}: an empty check"


def test_stance_columns_include_the_trot_feedforward_share():
    """On solo12_trot the controller's feed-forward holds the robot's weight: its torques
    move with the masses, the centres of mass and gravity. Without that share
    (`Scene.tau_parameter_derivatives`) the stance's force columns of the base's mass, of
    gravity and of a thigh's centre of mass miss the finite differences by far more than
    the tolerance (measured: 0.34 to 0.96 of the column), so the test above does check it."""
    scene, dyn, q, v, sol, der, forces, fd, steps = _mode_study("solo12_stance")
    t = MODE_CASES["solo12_stance"][2]
    names = list(SOLO_PARAMETERS)
    dyn.kin.update(q, v)
    for name in ("body:base_link:mass", "scene:gravity_z", "body:FL_UPPER_LEG:com_y"):
        k = names.index(name)
        share = scene.tau_parameter_derivatives(dyn.kin, t, [name])[:, 0]
        assert np.abs(share).max() > 0.0, name
        without = der.forces_dtau @ (forces[:, k] - share)
        nv, rows = scene.nv, sol.forces.size
        err = np.abs(without - fd[nv : nv + rows, k]).max() / np.abs(fd[nv : nv + rows, k]).max()
        assert err > 1e3 * RTOL, (name, err)


@pytest.mark.parametrize("case", [c for c, spec in MODE_CASES.items() if spec[1]])
def test_force_guard_matches_finite_differences_of_the_normal_forces(case):
    """``force_guard(q, v, t, mode, key)`` is ``∂λ_n/∂p`` of contact key ``key``: the
    finite difference of ``solve(...).normal_forces()[mode.index(key)]``."""
    scene_name, mode, t, _, _, names = MODE_CASES[case]
    scene, dyn, q, v, sol, _, _, fd, steps = _mode_study(case)
    jumps = ParameterJumps(ModeDynamics(scene), resolve(scene, names))
    normals = fd[scene.nv + sol.forces.size :]
    assert normals.shape == (len(mode), len(names))
    for j, key in enumerate(mode):
        guard = jumps.force_guard(q, v, t, mode, key)
        assert guard.shape == (len(names),)
        for k in range(len(names)):
            _check(f"force_guard/{case}", guard[k], normals[j, k], sol.normal_forces(), steps[k])


def test_gap_guard_is_minus_one_on_the_contacts_own_offset():
    """The gap ``n · p(q) - offset``: ``∂h/∂offset = -1`` for the contact's own offset, 0
    for any other parameter (finite differences of `Scene.gaps` at fixed q)."""
    scene = _scene("solo12")
    names = [
        "contact:FL_FOOT:offset",
        "contact:HR_FOOT:offset",
        "body:base_link:mass",
        "contact:FL_FOOT:restitution",
        "scene:gravity_z",
    ]
    q, _ = _solo_down(0)
    jumps = ParameterJumps(ModeDynamics(scene), resolve(scene, names))
    for contact in range(4):
        guard = jumps.gap_guard(contact)
        for k, name in enumerate(names):
            fd, h = _central("solo12", name, lambda s: s.gaps(q)[contact])
            # affine in the offset: exact up to the round-off of n · p - offset (|n · p| ≈ 0.02 m,
            # h = 1.9e-6 m): ~1e-12 of the unit column, far inside the bound
            _check("gap_guard", guard[k], fd, scene.gaps(q), h)
        expected = [-1.0 if n == f"contact:{scene.contact_names[contact]}:offset" else 0.0 for n in names]
        assert guard.tolist() == expected


# ----------------------------------------------------------------------------------
# impacts
# ----------------------------------------------------------------------------------
SOLO_INERTIAL = (
    "body:base_link:mass",
    "body:FL_LOWER_LEG:mass",
    "body:base_link:com_x",
    "body:FL_UPPER_LEG:com_y",
    "body:HR_LOWER_LEG:com_z",
    *(f"body:base_link:{f}" for f in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")),
    "body:FL_LOWER_LEG:iyz",
    "joint:FL_KFE:armature",
)
STILL = ("scene:gravity_z", "trot:kp", "contact:FL_FOOT:restitution", "contact:HR_FOOT:offset")


def test_impulse_forces_are_minus_the_derivative_of_the_momentum_change():
    """``impulse_forces(q, dv) = -∂(M(q) dv)/∂p``: central differences of ``M`` from
    ``pin.crba`` (armature included) on the perturbed models, at a generic configuration
    and velocity change. ``M`` is affine in each body's ten dynamic parameters, which are
    polynomial in the named ones, so only round-off remains. Gravity, the controller and
    the contacts are forces of finite size, which give no impulse in an instant: zero
    columns."""
    scene = _scene("solo12")
    rng = np.random.default_rng(7)
    q = pin.integrate(scene.model, cd.load_scene("solo12_trot").q0, 0.3 * rng.standard_normal(scene.nv))
    dv = rng.standard_normal(scene.nv)
    names = SOLO_INERTIAL + STILL
    analytic = ParameterForces(scene, resolve(scene, names)).impulse_forces(q, dv)

    def momentum(s):
        return pin.crba(s.model, s.model.createData(), q) @ dv

    value = momentum(scene)
    for k, name in enumerate(names):
        fd, h = _central("solo12", name, lambda s: -momentum(s))
        _check("impulse_forces", analytic[:, k], fd, value, h)
        if name in STILL:
            assert not np.any(analytic[:, k]), name
        else:
            assert np.abs(fd).max() > 0.0, name


BAR_IMPACT = (
    "body:body:mass",
    "body:body:com_x",
    "body:body:com_z",
    "body:body:iyy",
    "body:body:ixx",
    "joint:body_pitch:armature",
    "joint:body_z:armature",
    "contact:rear_foot:restitution",
    "contact:front_foot:restitution",
    "contact:rear_foot:offset",
    "scene:gravity_z",
)
SOLO_IMPACT = (
    "body:base_link:mass",
    "body:base_link:com_x",
    "body:FL_UPPER_LEG:com_y",
    "body:base_link:ixy",
    "body:FL_LOWER_LEG:ixx",
    "joint:FL_KFE:armature",
    "contact:FL_FOOT:restitution",
    "contact:HR_FOOT:restitution",
    "contact:FR_FOOT:restitution",
    "contact:FL_FOOT:offset",
    "scene:gravity_z",
    "trot:kp",
)


def _bar_rear():
    """The bar lowered onto its rear foot (front foot 2.5 cm up), falling and pitching."""
    scene = _scene("bar")
    q = scene.q0.copy()
    q[1] -= scene.gaps(q)[0]
    return q, np.array([0.3, -1.0, 0.4])


def _bar_both():
    """The bar flat on both feet, falling and pitching: both feet approach (-0.9, -1.1 m/s)."""
    return _bar_down()[0], np.array([0.3, -1.0, -0.4])


def _solo_two_feet():
    """solo12_trot's initial pose, where FL_FOOT and HR_FOOT touch, falling at 0.8 m/s."""
    scene = _scene("solo12")
    q = close(ModeDynamics(scene), cd.load_scene("solo12_trot").q0, (0, 3))
    v = _rng_velocity(scene, 3, 0.2)
    v[2] = -0.8
    return q, v


def _own(scene):
    return None


def _rear_only(scene):
    """The caller's coefficients: the rear foot's own (from the scene at hand, so the
    perturbed one's), the front foot's bounce ended (0): only the rear one is live."""
    return [scene.contact_specs[0].restitution, 0.0]


# The bar on both feet has three velocities and two active normal rows: x keeps its speed
# and the rows fix the other two (A_n v+ = -e A_n v-), whatever the inertia. Its inertial
# columns are zero, computed through the KKT solve (not set to 0): checked against the
# finite differences, not required to move v+.
BAR_INERTIAL = {
    "body:body:mass",
    "body:body:com_x",
    "body:body:com_z",
    "body:body:iyy",
    "body:body:ixx",
    "joint:body_pitch:armature",
    "joint:body_z:armature",
}
# case: (scene, state, closed keys, caller's restitution, live keys, active positions, parameters,
#        parameters whose column is exactly zero by construction, parameters whose column is
#        zero physically)
IMPACT_CASES = {
    "bar_rear_foot": (
        "bar",
        _bar_rear,
        (0,),
        _own,
        (0,),
        (0,),
        BAR_IMPACT,
        {"contact:front_foot:restitution", "contact:rear_foot:offset", "scene:gravity_z"},
        {"body:body:ixx"},
    ),
    "bar_both_feet": (
        "bar",
        _bar_both,
        (0, 1),
        _own,
        (0, 1),
        (0, 1),
        BAR_IMPACT,
        {"contact:rear_foot:offset", "scene:gravity_z"},
        BAR_INERTIAL,
    ),
    "bar_front_bounce_ended": (
        "bar",
        _bar_both,
        (0, 1),
        _rear_only,
        (0,),
        (0, 1),
        BAR_IMPACT,
        {"contact:front_foot:restitution", "contact:rear_foot:offset", "scene:gravity_z"},
        BAR_INERTIAL,
    ),
    "solo12_two_feet": (
        "solo12",
        _solo_two_feet,
        (0, 3),
        _own,
        (0, 3),
        (0, 1),
        SOLO_IMPACT,
        {"contact:FR_FOOT:restitution", "contact:FL_FOOT:offset", "scene:gravity_z", "trot:kp"},
        set(),
    ),
}


@pytest.mark.parametrize("case", list(IMPACT_CASES))
def test_impact_parameter_jacobian_matches_finite_differences(case):
    """``∂(q+, v+)/∂p`` of the impact reset at fixed ``(q, v-)`` against central
    differences of `resolve_impact`'s ``v+`` on the perturbed scene (same active set).
    solo12 through `impact_parameter_jacobian` with its restitution columns, the bar
    through `ParameterJumps.impact` with its live keys."""
    scene_name, state, closed, restitution, live, active, names, zero, flat = IMPACT_CASES[case]
    scene = _scene(scene_name)
    q, v = state()
    assert np.abs(scene.gaps(q)[list(closed)]).max() <= 1e-12
    dyn = ModeDynamics(scene)
    impact = resolve_impact(dyn, q, v, closed, restitution(scene))
    assert impact.active == active and impact.tangential_only == ()
    assert np.all(impact.normal_speeds_before < 0.0)
    params = resolve(scene, names)
    if scene_name == "solo12":
        columns = {key: names.index(f"contact:{scene.contact_names[key]}:restitution") for key in live}
        J = impact_parameter_jacobian(dyn, q, v, impact, ParameterForces(scene, params), columns)
    else:
        J = ParameterJumps(dyn, params).impact(q, v, impact, live)
    nv = scene.nv
    assert J.shape == (2 * nv, len(names))
    assert not np.any(J[:nv]), "an impact does not move q"

    def v_plus(s):
        other = resolve_impact(ModeDynamics(s), q, v, closed, restitution(s))
        assert other.active == impact.active and other.tangential_only == impact.tangential_only
        return other.v_plus

    for k, name in enumerate(names):
        fd, h = _central(scene_name, name, v_plus)
        _check(f"impact/{case}", J[nv:, k], fd, impact.v_plus, h)
        if name in zero:
            assert not np.any(J[:, k]), name
        elif name not in flat:
            assert np.abs(fd).max() > 0.0, f"{name} does not move v+ in {case}: an empty check"


# ----------------------------------------------------------------------------------
# the projection onto a mode's constraints
# ----------------------------------------------------------------------------------
def test_projection_offset_columns_match_project_state():
    """``projection(q, mode)``: ``∂/∂offset`` of the projected configuration.

    Reference: ``q`` on the mode's manifold (gaps closed to 1e-15 m); on the scene with
    one contact's offset moved by ±h it lies off the manifold by ∓h along that normal,
    and `project_state` (Gauss–Newton to convergence) brings it back. Its first step
    ``q + P e_j h`` is the linear term; the others are O(h²), so the derivative of the
    converged result at a point of the manifold is ``P e_j``: the code's column. (Off the
    manifold by ε the derivative moves by O(ε): a reference from such a state carries
    that error, hence the state on it.) Truncation: h² |q'''| / 6 with ``h = 1e-4 ·
    0.019 m`` and curvature lengths ≳ 5 cm: ≲ 1e-9 relative; round-off: the
    gaps' 1e-15 m over 2h: ~3e-10 m per m of offset. Within the module's bound.

    The velocity rows are zero: the linearised map ``(q - P a(q), v - P A(q) v)``
    evaluates ``A`` at the incoming ``q``, which does not depend on the offset (the
    change of ``A`` along the projected ``q`` is the state block's ``-P d(A v)/dq``).
    Also ``A_n`` times an offset's column is that contact's unit vector: the projection
    moves that gap, and only it, by the offset's change.
    """
    scene = _scene("solo12")
    mode = (0, 2, 3, 5)  # FL, HL, HR sticking, FR (contact 1) sliding
    dyn = ModeDynamics(scene)
    q = close(dyn, cd.load_scene("solo12_trot").q0, mode)
    assert np.abs(scene.gaps(q)).max() <= 1e-15
    v = _rng_velocity(scene, 8, 1.0)
    names = [
        "contact:HL_FOOT:offset",
        "contact:FR_FOOT:offset",
        "contact:FL_FOOT:offset",
        "contact:HR_FOOT:offset",
        "body:base_link:mass",
        "contact:FL_FOOT:restitution",
    ]
    jumps = ParameterJumps(dyn, resolve(scene, names))
    D = jumps.projection(q, mode)
    nv = scene.nv
    assert D.shape == (2 * nv, len(names))
    assert not np.any(D[nv:])

    def projected(s):
        return project_state(ModeDynamics(s), q, v, mode)[0]

    for k, name in enumerate(names):
        h, plus, minus = _perturbed("solo12", name)
        fd = pin.difference(scene.model, projected(minus), projected(plus)) / (2 * h)
        _check("projection", D[:nv, k], fd, q, h)
    dyn.kin.update(q, np.zeros(nv))
    A = mode_rows(dyn, mode)
    normal = [0, 3, 6, 9]  # rows of the mode's normals: 3 + 3 + 3 + 1
    # the unit vector of each offset's contact in the mode's order (HL: 1, FR: 3, FL: 0, HR: 2)
    expected = np.zeros((4, len(names)))
    for k, j in enumerate((1, 3, 0, 2)):
        expected[j, k] = 1.0
    # A_n P = I up to the round-off of M^-1 (condition 7e3) and of the 4 × 4 Delassus
    # solve (condition ~1): ~1e-12 for these O(1) rows
    assert np.abs(A[normal] @ D[:nv] - expected).max() <= 1e-10


# ----------------------------------------------------------------------------------
# the dynamic parameters of one body
# ----------------------------------------------------------------------------------
def test_dynamic_parameter_derivative_matches_pinocchio():
    """``∂π/∂p`` against central differences of ``pin.Inertia(m, c, I).toDynamicParameters()``
    (m, m c, the inertia about the frame's origin in Pinocchio's order), with ``ixy``
    moving both of its symmetric entries. ``π`` is linear in ``m`` and in the entries of
    ``I`` and quadratic in each ``c_k``, so the difference is exact up to round-off:
    ``~4 u |π| / h`` = 1e-12 for ``|π| <= 2`` and ``h = 1e-3``; tolerance 1e-10."""
    m, c = 1.7, np.array([0.03, -0.05, 0.08])
    root = np.array([[0.3, 0.1, -0.05], [0.0, 0.25, 0.07], [0.02, -0.04, 0.2]])
    rotational = root @ root.T
    indices = {"ixx": (0, 0), "ixy": (0, 1), "ixz": (0, 2), "iyy": (1, 1), "iyz": (1, 2), "izz": (2, 2)}

    def pi(field, x):
        mass, lever, rot = m, c.copy(), rotational.copy()
        if field == "mass":
            mass += x
        elif field.startswith("com_"):
            lever["xyz".index(field[-1])] += x
        else:
            a, b = indices[field]
            rot[a, b] += x
            if a != b:
                rot[b, a] += x
        return pin.Inertia(mass, lever, rot).toDynamicParameters()

    h = 1e-3
    assert BODY_FIELDS == ("mass", "com_x", "com_y", "com_z", "ixx", "ixy", "ixz", "iyy", "iyz", "izz")
    inertia = pin.Inertia(m, c, rotational)
    for field in BODY_FIELDS:
        fd = (pi(field, h) - pi(field, -h)) / (2 * h)
        analytic = dynamic_parameter_derivative(inertia, field)
        assert analytic.shape == (10,)
        err = float(np.abs(analytic - fd).max())
        FD_ERRORS["dynamic_parameters"] = max(FD_ERRORS.get("dynamic_parameters", 0.0), err)
        assert err <= 1e-10, (field, analytic, fd)
