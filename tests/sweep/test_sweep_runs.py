"""Sweeps end to end: rows identical whatever the engine and the number of workers,
failed points recorded, results files resumed, every bad input a named error.

The scenes are the cheap ones of robots/ (a ball dropped under g = 1, the planar
trotters), with closed forms where a value is checked: a ball dropped from
height h under gravity g lands at sqrt(2 h / g); with restitution e it lands again
2 e sqrt(2 g h) / g later, and its stride map multiplies the landing speed by e.
"""

from __future__ import annotations

import json
import math
import os

import numpy as np
import pytest

import contactdiff as cd
from contactdiff.errors import InvalidInputError, ModelLoadError, UnknownNameError
from contactdiff.sweeps import engines, grid, point_list, sweep

BALL_HEIGHTS = {"q:z": "0.5:2:4"}


def _rows(result):
    return [row.to_dict(run_time=False) for row in result]


@pytest.fixture(scope="module")
def ball_rows():
    return sweep("ball", BALL_HEIGHTS, t_final=3.0, n_jobs=1)


def test_rows_follow_the_points_and_match_direct_runs(ball_rows):
    assert [row.point["q:z"] for row in ball_rows] == [0.5, 1.0, 1.5, 2.0]
    assert [row.index for row in ball_rows] == [0, 1, 2, 3]
    scene = cd.load_scene("ball")
    for row in ball_rows:
        assert row.ok and row.run_time > 0
        traj = cd.simulate(cd.load_scene("ball").with_state({"z": row.point["q:z"]}), 3.0)
        assert row.outputs["q_end:z"] == traj.q[0] and row.outputs["v_end:z"] == traj.v[0]
        assert row.outputs["events"] == len(traj.events)
    assert scene.q0[0] == 1.0
    # the first landing at sqrt(2 h): from 2 m at t = 2 s, the bounce leaves at 0.8 * 2 m/s
    assert ball_rows[3].outputs["q_end:z"] == pytest.approx(1.6 - 0.5, abs=1e-8)


def test_rows_are_identical_for_one_and_two_workers(ball_rows):
    two = sweep("ball", BALL_HEIGHTS, t_final=3.0, n_jobs=2)
    assert _rows(two) == _rows(ball_rows)


def test_two_workers_run_outside_this_process_and_one_inside():
    points = {"q:z": [1.0, 2.0, 3.0]}
    here = {r.outputs["pid"] for r in sweep("ball", points, "sweep_user_jobs:process_id", n_jobs=1)}
    there = {r.outputs["pid"] for r in sweep("ball", points, "sweep_user_jobs:process_id", n_jobs=2)}
    assert here == {os.getpid()} and os.getpid() not in there


def test_rows_are_identical_on_a_local_dask_cluster(ball_rows):
    pytest.importorskip("distributed", reason="Dask's distributed is not installed: pip install 'contactdiff[dask]'")
    on_dask = sweep("ball", BALL_HEIGHTS, t_final=3.0, backend="dask", n_jobs=2)
    assert _rows(on_dask) == _rows(ball_rows)


def test_a_failing_point_is_recorded_and_the_sweep_goes_on():
    # a start below the ground penetrates the contact; a 1-step budget stops a run that needs more
    result = sweep(
        "ball",
        point_list([{"q:z": 1.0, "max_steps": 1000}, {"q:z": -0.1, "max_steps": 1000}, {"q:z": 1.0, "max_steps": 1}]),
        t_final=3.0,
        n_jobs=2,
    )
    assert [r.ok for r in result] == [True, False, False]
    assert result[1].error.kind == "InconsistentStateError" and "penetrates" in result[1].error.message
    assert result[2].error.kind == "TooManyStepsError"
    assert result[1].outputs == {} and result.failed == [result[1], result[2]]
    flat = result[1].to_dict()
    assert flat["error"] == "InconsistentStateError" and flat["q:z"] == -0.1
    with pytest.raises(cd.ContactDiffError, match=r"InconsistentStateError at \{'q:z': -0.1, 'max_steps': 1000\}"):
        result.raise_failure()  # the first failure, named with its point
    fine = sweep("ball", {"q:z": [1.0]}, t_final=1.0, n_jobs=1)
    assert fine.raise_failure() is fine  # nothing failed: the rows themselves


def test_resuming_from_a_partial_results_file(tmp_path, ball_rows):
    for suffix in (".jsonl", ".csv"):
        out = tmp_path / f"results{suffix}"
        first = sweep("ball", {"q:z": [0.5, 1.0]}, t_final=3.0, n_jobs=1, out=out)
        assert first.skipped == 0
        whole = sweep("ball", BALL_HEIGHTS, t_final=3.0, n_jobs=2, out=out)
        assert whole.skipped == 2
        assert _rows(whole) == _rows(ball_rows)
        again = sweep("ball", BALL_HEIGHTS, t_final=3.0, n_jobs=2, out=out)
        assert again.skipped == 4 and _rows(again) == _rows(ball_rows)
        lines = out.read_text().splitlines()
        assert len(lines) == 4 + (suffix == ".csv")  # every point once, plus the CSV header


def test_a_row_cut_short_is_run_again(tmp_path, ball_rows):
    out = tmp_path / "results.jsonl"
    sweep("ball", BALL_HEIGHTS, t_final=3.0, n_jobs=1, out=out)
    text = out.read_text()
    out.write_text(text[:-40])  # the last write was interrupted
    resumed = sweep("ball", BALL_HEIGHTS, t_final=3.0, n_jobs=1, out=out)
    assert resumed.skipped == 3 and _rows(resumed) == _rows(ball_rows)
    assert [json.loads(line)["q:z"] for line in out.read_text().splitlines()] == [0.5, 1.0, 1.5, 2.0]


def test_failed_points_are_kept_unless_retried(tmp_path):
    out = tmp_path / "results.csv"
    points = {"q:z": [1.0, -0.1]}
    assert len(sweep("ball", points, t_final=1.0, n_jobs=1, out=out).failed) == 1
    assert sweep("ball", points, t_final=1.0, n_jobs=1, out=out).skipped == 2
    retried = sweep("ball", points, t_final=1.0, n_jobs=1, out=out, retry_failed=True)
    assert retried.skipped == 1 and retried[1].error.kind == "InconsistentStateError"


def test_a_results_file_of_another_sweep_is_refused(tmp_path):
    out = tmp_path / "results.jsonl"
    sweep("ball", {"q:z": [1.0]}, t_final=1.0, n_jobs=1, out=out)
    with pytest.raises(InvalidInputError, match="another sweep"):
        sweep("ball", {"q:z": [1.0]}, t_final=2.0, n_jobs=1, out=out)
    with pytest.raises(InvalidInputError, match="unknown format"):
        sweep("ball", {"q:z": [1.0]}, t_final=1.0, out=tmp_path / "results.txt")
    with pytest.raises(InvalidInputError, match="does not exist"):
        sweep("ball", {"q:z": [1.0]}, t_final=1.0, out=tmp_path / "nowhere" / "results.csv")
    (tmp_path / "broken.jsonl").write_text("{not json}\n")
    with pytest.raises(ModelLoadError, match="line 1"):
        sweep("ball", {"q:z": [1.0]}, t_final=1.0, out=tmp_path / "broken.jsonl")


def test_the_jacobian_job_differentiates_in_a_parameter():
    # from h = 2 (g = 1, e = 0.8): landing at t = 2 with speed 2; at t = 3, z = 2 e - 1/2 and v = 2 e - 1,
    # so dz/de = dv/de = 2 and the restitution's column has norm 2 sqrt(2)
    row = sweep(
        "ball",
        {"q:z": [2.0]},
        "jacobian",
        t_final=3.0,
        n_jobs=1,
        job_options={"parameters": ["contact:ball:restitution"]},
    )[0]
    assert row.outputs["parameter_jacobian_norm:contact:ball:restitution"] == pytest.approx(2 * math.sqrt(2), 1e-7)
    assert row.outputs["jacobian_norm"] >= 1.0 and row.outputs["differentiable"] is True


def test_the_stride_job_gives_the_ball_multiplier_e():
    result = sweep("ball", {"scene:gravity_z": [-1.0, -4.0]}, "stride", n_jobs=1)
    for row, g in zip(result, (1.0, 4.0)):
        assert row.outputs["stride_time"] == pytest.approx(2 * 0.8 * math.sqrt(2 * g) / g, rel=1e-8)
        assert row.outputs["max_multiplier"] == pytest.approx(0.8, abs=1e-8)


def test_the_order_gap_job_at_the_rigid_trot_simultaneous_touchdown():
    result = sweep("planar_trot_rigid", {"q:body_pitch": [-0.02, 0.0]}, "order-gap", t_final=1.5, n_jobs=1)
    # a pitched body lands one foot first: no simultaneous touchdown to measure
    assert result[0].outputs["order_gap_events"] == 0 and result[0].outputs["order_gap_outcome"] is None
    # level: both land at once; the hand value of docs/results/decoupling.md
    assert result[1].outputs["order_gap_events"] == 1
    assert result[1].outputs["order_gap_outcome"] == pytest.approx(
        2 * (1908 / 5041) * math.sqrt(31 / 24) / math.sqrt(3), rel=1e-9
    )


def test_a_scene_factory_with_swept_and_fixed_arguments():
    result = sweep(
        "contactdiff.paper:trot_touchdown",
        {"arg:pitch": [0.0, 0.1]},
        t_final=1.5,
        n_jobs=2,
        fixed={"arg:model": "soft"},
    )
    assert result.names == ("arg:model", "arg:pitch")
    assert [r.outputs["events:touchdown"] for r in result] == [1, 2]  # together when level, one by one pitched
    assert result[0].point == {"arg:model": "soft", "arg:pitch": 0.0}


def test_a_factory_is_built_in_the_workers_only_unless_a_name_needs_the_scene():
    # an expensive factory (a trot simulated to find touchdowns) should not run once more just to check names
    only_arguments = sweep("sweep_user_jobs:ball_not_in", {"arg:pid": [os.getpid()]}, t_final=1.0, n_jobs=2)
    assert only_arguments[0].ok
    with pytest.raises(InvalidInputError, match="RuntimeError: built in the process"):
        sweep("sweep_user_jobs:ball_not_in", {"arg:pid": [os.getpid()], "q:z": [2.0]}, t_final=1.0, n_jobs=2)
    with pytest.raises(InvalidInputError, match="needs arg:pid"):
        sweep("sweep_user_jobs:ball_not_in", {"t_final": [1.0]}, n_jobs=2)


def test_a_user_job_by_name_gets_the_scene_and_the_point():
    result = sweep("ball", grid({"q:z": [2.0]}), "sweep_user_jobs:fall_time", t_final=3.0, n_jobs=2)
    row = result[0]
    assert row.outputs["first_event"] == pytest.approx(2.0, abs=1e-9)
    assert row.outputs["given"] == ["q:z", "t_final"] and row.outputs["nan"] is None
    failed = sweep("ball", {"q:z": [1.0]}, "sweep_user_jobs:not_a_dict", n_jobs=1)
    assert failed[0].error.kind == "InvalidInputError" and "dict" in failed[0].error.message
    clash = sweep("ball", {"q:z": [1.0]}, "sweep_user_jobs:clashing", n_jobs=1)
    assert "own columns: error" in clash[0].error.message


def test_rows_as_a_dataframe(ball_rows):
    pd = pytest.importorskip("pandas", reason="pandas is not installed: pip install 'contactdiff[pandas]'")
    frame = ball_rows.to_pandas()
    assert isinstance(frame, pd.DataFrame) and len(frame) == 4
    assert list(frame["q:z"]) == [0.5, 1.0, 1.5, 2.0] and "run_time" in frame.columns


@pytest.mark.parametrize(
    "call, error, match",
    [
        (lambda: sweep("ball", {"q:zz": [1.0]}, t_final=1.0), UnknownNameError, "q:z"),
        (lambda: sweep("ball", {"q:z": "0:1:0"}, t_final=1.0), InvalidInputError, "positive integer"),
        (lambda: sweep("ball", {"q:z": [1.0]}, t_final=1.0, backend="threads"), UnknownNameError, "dask, loky, ray"),
        (lambda: sweep("ball", {"q:z": [1.0]}, t_final=1.0, n_jobs=0), InvalidInputError, "n_jobs"),
        (lambda: sweep("ball", {"q:z": [1.0]}, t_final=1.0, scheduler="tcp://x:1"), InvalidInputError, "loky"),
        (lambda: sweep("ball", {"q:z": [1.0]}, "nosuchmodule:run"), InvalidInputError, "cannot import"),
        (lambda: sweep("ball", {"q:z": [1.0]}, "sweep_user_jobs:missing"), UnknownNameError, "fall_time"),
        (lambda: sweep("ball", {"q:z": [1.0]}, "sweep_user_jobs:NOT_A_FUNCTION"), InvalidInputError, "not callable"),
        (lambda: sweep("ball", {"q:z": [1.0]}, "simulat"), UnknownNameError, "order-gap"),
        (lambda: sweep("ball", {"q:z": [1.0]}), InvalidInputError, "t_final"),
        (lambda: sweep("ball", {"q:z": [1.0]}, "stride", t_final=1.0), InvalidInputError, "no final time"),
        (lambda: sweep("ball", {"q:z": [1.0]}, "stride", job_options={"feet": "ball"}), UnknownNameError, "foot"),
        (lambda: sweep("ball", {"q:z": [1.0]}, t_final=1.0, options={"rtol": -1}), InvalidInputError, "rtol"),
        (lambda: sweep("ball", {"q:z": [1.0]}, t_final=1.0, options={"jacobian": True}), InvalidInputError, "job"),
        (lambda: sweep(cd.load_scene("ball"), {"q:z": [1.0]}, t_final=1.0), InvalidInputError, "pickle"),
        (lambda: sweep("no_such_scene", {"q:z": [1.0]}, t_final=1.0), UnknownNameError, "planar_trot_soft"),
        (lambda: sweep("ball", {"arg:x": [1.0]}, t_final=1.0), InvalidInputError, "factory"),
        (lambda: sweep("ball", {"q:z": ["high"]}, t_final=1.0), InvalidInputError, "number"),
    ],
)
def test_every_bad_input_is_a_named_error(call, error, match):
    with pytest.raises(error, match=match):
        call()


def test_an_unreachable_scheduler_is_a_named_error(monkeypatch):
    pytest.importorskip("distributed", reason="Dask's distributed is not installed: pip install 'contactdiff[dask]'")
    monkeypatch.setattr(engines, "CONNECT_TIMEOUT", 1.0)
    with pytest.raises(InvalidInputError, match="no Dask scheduler answers at 'tcp://127.0.0.1:9'"):
        sweep("ball", {"q:z": [1.0]}, t_final=1.0, backend="dask", scheduler="tcp://127.0.0.1:9")


def test_rows_and_values_write_as_json(ball_rows):
    text = json.dumps(ball_rows.to_dicts(), allow_nan=False)
    assert json.loads(text) == ball_rows.to_dicts()
    assert np.isfinite([r.run_time for r in ball_rows]).all()


@pytest.mark.slow  # a local Ray instance takes several seconds to start
def test_rows_are_identical_on_a_local_ray_cluster(ball_rows):
    pytest.importorskip("ray", reason="Ray is not installed: pip install 'contactdiff[ray]'")
    on_ray = sweep("ball", BALL_HEIGHTS, t_final=3.0, backend="ray", n_jobs=2)
    assert _rows(on_ray) == _rows(ball_rows)
