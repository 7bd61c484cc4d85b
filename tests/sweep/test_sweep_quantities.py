"""Swept quantities: every name checked against the scene, and what a point changes."""

from __future__ import annotations

import numpy as np
import pytest

import contactdiff as cd
from contactdiff.errors import InconsistentStateError, InvalidInputError, UnknownNameError
from contactdiff.sweeps.quantities import QuantityKind, apply, check_values, resolve, run_options, split


@pytest.fixture(scope="module")
def solo12():
    return cd.load_scene("solo12_drop")


def test_each_kind_of_name_resolves(solo12):
    names = ["q:root_joint[2]", "v:FL_KFE", "body:base_link:mass", "rtol", "t_final", "arg:pitch", "job:x"]
    kinds = [q.kind for q in resolve(names, solo12, arguments=None, job_arguments=None)]
    assert kinds == [
        QuantityKind.INITIAL_Q,
        QuantityKind.INITIAL_V,
        QuantityKind.PARAMETER,
        QuantityKind.OPTION,
        QuantityKind.OPTION,
        QuantityKind.SCENE_ARG,
        QuantityKind.JOB_ARG,
    ]


def test_an_unknown_coordinate_lists_the_valid_ones(solo12):
    with pytest.raises(UnknownNameError, match=r"q:root_joint\[2\].*q:FL_HAA"):
        resolve(["q:FL_HA"], solo12)
    with pytest.raises(UnknownNameError, match="v:FL_KFE"):
        resolve(["v:nope"], solo12)


def test_an_unknown_parameter_lists_those_of_its_kind(solo12):
    with pytest.raises(UnknownNameError) as err:
        resolve(["body:base_link:mas"], solo12)
    assert "body:base_link:mass" in str(err.value) and "contact:" not in str(err.value)


def test_an_unknown_name_lists_coordinates_options_and_suggests(solo12):
    with pytest.raises(UnknownNameError) as err:
        resolve(["rtoll"], solo12)
    message = str(err.value)
    assert "q:FL_HAA" in message and "t_final" in message and "did you mean rtol" in message


def test_factory_and_job_arguments_are_checked(solo12):
    with pytest.raises(InvalidInputError, match="scene factory"):
        resolve(["arg:pitch"], solo12, arguments=())
    with pytest.raises(UnknownNameError, match="arg:model, arg:pitch"):
        resolve(["arg:pich"], solo12, arguments=("model", "pitch"))
    with pytest.raises(UnknownNameError, match="job:foot"):
        resolve(["job:feet"], solo12, job_arguments=("foot",))


def test_values_must_be_numbers_where_the_quantity_is_one(solo12):
    quantities = resolve(["q:FL_KFE", "method", "arg:model"], solo12, arguments=None)
    check_values(quantities, [(0.1, "RK45", "soft")])
    with pytest.raises(InvalidInputError, match="q:FL_KFE must be a number.*point #1"):
        check_values(quantities, [(0.1, "RK45", "soft"), ("high", "RK45", "soft")])


def test_a_point_changes_one_coordinate_of_a_multi_coordinate_joint(solo12):
    quantities = resolve(["q:root_joint[2]", "v:root_joint[5]", "v:FL_KFE"], solo12)
    scene = apply(solo12, split(quantities, (0.4, 0.3, -1.0)))
    expected_q = solo12.q0.copy()
    expected_q[2] = 0.4
    assert np.array_equal(scene.q0, expected_q)
    changed = np.flatnonzero(scene.v0 != solo12.v0)
    assert changed.tolist() == [5, solo12.model.joints[solo12.model.getJointId("FL_KFE")].idx_v]
    assert scene.v0[5] == 0.3
    assert solo12.q0[2] == 0.285  # the kept scene is untouched


def test_a_point_changes_a_parameter_and_refuses_a_penetrating_state(solo12):
    quantities = resolve(["body:base_link:mass"], solo12)
    scene = apply(solo12, split(quantities, (3.5,)))
    assert scene.parameter_values(["body:base_link:mass"])[0] == 3.5
    assert solo12.parameter_values(["body:base_link:mass"])[0] != 3.5
    with pytest.raises(InconsistentStateError):
        apply(solo12, split(resolve(["q:root_joint[2]"], solo12), (0.05,)))


def test_counts_become_integers_and_methods_stay_names():
    assert run_options({"max_steps": 1e5, "rtol": 1e-6}) == {"max_steps": 100000, "rtol": 1e-6}
    assert type(run_options({"max_steps": 1e5})["max_steps"]) is int
    with pytest.raises(InvalidInputError, match="method must be a name"):
        run_options({"method": 3})
