"""Benchmarks and baselines: baselines right on the ball's closed form, the quick
bench's structure, the command. No timing is asserted (docs/design.md §7)."""

import json
import math

import numpy as np
import pytest

import contactdiff as cd
from contactdiff.bench.baselines import solve_ivp_baseline, time_stepping_baseline
from contactdiff.bench.metrics import state_error, time_at_error
from contactdiff.bench.runner import ball_closed_form, run_bench
from contactdiff.cli import main
from contactdiff.errors import InvalidInputError

T_BALL = 5.2


@pytest.fixture(scope="module")
def ball():
    scene = cd.load_scene("ball")
    return scene, ball_closed_form(scene, T_BALL)


def test_closed_form_matches_simulate(ball):
    scene, ref = ball
    assert ref.event_times == pytest.approx([math.sqrt(2), math.sqrt(2) * (1 + 2 * 0.8)], abs=1e-15)
    traj = cd.simulate(scene, T_BALL, rtol=1e-12, atol=1e-13)
    assert state_error(scene, traj.q, traj.v, ref.q, ref.v) < 1e-10


def test_solve_ivp_baseline_on_the_ball(ball):
    scene, ref = ball
    out = solve_ivp_baseline(scene, T_BALL, rtol=1e-12, atol=1e-14)
    assert len(out.event_times) == len(ref.event_times)
    assert np.max(np.abs(np.array(out.event_times) - ref.event_times)) < 1e-8
    assert state_error(scene, out.q, out.v, ref.q, ref.v) < 1e-8
    assert out.stats.dynamics_evaluations > 0 and out.stats.steps > 0


def test_solve_ivp_baseline_refuses_lie_groups():
    with pytest.raises(InvalidInputError, match="nq == nv"):
        solve_ivp_baseline(cd.load_scene("solo12_drop"), 0.1)


def test_time_stepping_converges_first_order(ball):
    scene, ref = ball
    errors = []
    for dt in (1e-2, 1e-3):
        out = time_stepping_baseline(scene, T_BALL, dt)
        assert len(out.event_times) == len(ref.event_times)
        assert np.max(np.abs(np.array(out.event_times) - ref.event_times)) <= 2 * dt
        errors.append(state_error(scene, out.q, out.v, ref.q, ref.v))
    assert errors[1] < errors[0]
    order = math.log10(errors[0] / errors[1])
    assert 0.6 < order < 1.5, errors


def test_time_stepping_on_a_lie_group():
    scene = cd.load_scene("solo12_drop")
    out = time_stepping_baseline(scene, 0.15, 1e-3)
    assert np.all(np.isfinite(out.q)) and abs(np.linalg.norm(out.q[3:7]) - 1) < 1e-12
    assert out.event_times and abs(out.event_times[0] - 0.101) < 5e-3


def test_time_at_error_interpolates_log_log():
    pts = [(1.0, 1e-2), (10.0, 1e-6), (100.0, 1e-10)]
    t, _ = time_at_error(pts, 1e-4)
    assert t == pytest.approx(math.sqrt(10.0))
    assert time_at_error(pts, 1e-12)[0] is None


@pytest.fixture(scope="module")
def quick():
    return run_bench(quick=True, repeats=1, progress=False)


def test_quick_bench_structure(quick):
    assert set(quick.references) == {"ball", "planar_trot_rigid"}
    assert quick.references["planar_trot_rigid"].convergence < 1e-9
    methods = {r["method"] for r in quick.runs}
    assert methods == {"ours-DOP853", "ours-Radau", "solve_ivp-DOP853", "time-stepping"}
    for r in quick.runs:
        assert r["failed"] is None
        assert math.isfinite(r["error"]) and math.isfinite(r["time"]) and r["time"] > 0
        assert r["n_events"] == r["n_events_ref"] and math.isfinite(r["event_error"])
        assert r["dynamics_evaluations"] > 0 and r["steps"] > 0
    for d in quick.derivatives:
        assert d["jacobian_vs_fd"] < 1e-5 and d["fd_runs"] == 4 * d["nv"]
        assert all(math.isfinite(d[k]) for k in ("jacobian_over_plain", "fd_over_jacobian"))
    assert {(r["scene"], r["baseline"], r["target"]) for r in quick.ratios} == {
        (s, b, t)
        for s in ("ball", "planar_trot_rigid")
        for b in ("solve_ivp-DOP853", "time-stepping")
        for t in (1e-6, 1e-9)
    }
    json.dumps(quick.to_dict())
    assert "time-stepping" in quick.format()


def test_quick_bench_plot(quick, tmp_path):
    pytest.importorskip("matplotlib")
    path = tmp_path / "bench.png"
    quick.plot(str(path))
    assert path.stat().st_size > 1000


def test_cli_bench_quick_json(capsys):
    assert main(["bench", "--quick", "--json", "--repeats", "1", "--scenes", "ball"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert list(data["references"]) == ["ball"] and data["runs"] and data["derivatives"]


def test_cli_bench_unknown_scene(capsys):
    assert main(["bench", "--quick", "--scenes", "nope"]) == 2
    assert "ball" in capsys.readouterr().err


def test_cli_bench_speed_json(capsys):
    """The speed rows are consistent counts of a real run (their times are not asserted):
    the wall time per evaluation times the evaluations is the wall time, the ratios are
    the quotients they name, and the same run's events are those of simulate."""
    assert main(["bench", "--speed", "--scenes", "solo12_trot", "--t-final", "0.05", "--repeats", "1", "--json"]) == 0
    (row,) = json.loads(capsys.readouterr().out)["trots"]
    traj = cd.simulate(cd.load_scene("solo12_trot"), 0.05)
    assert row["events"] == len(traj.events) and row["steps"] == traj.stats.steps
    assert row["evaluations"] == traj.stats.dynamics_evaluations > 0
    assert row["per_evaluation"] * row["evaluations"] == pytest.approx(row["wall"], rel=1e-12)
    assert row["real_time_ratio"] == pytest.approx(row["wall"] / 0.05, rel=1e-12)
    assert row["overhead_ratio"] == pytest.approx(row["per_evaluation"] / row["pinocchio"], rel=1e-12)
    assert row["constraint_dynamics"] > 0 and row["aba"] > 0 and row["pinocchio"] > 0


def test_speed_memory_peak_is_measured_in_a_child():
    from contactdiff.bench.speed import memory_peak

    m = memory_peak("solo12_trot", 0.02)
    assert 0 < m.before_mb <= m.peak_mb and m.events >= 0


def test_cli_bench_speed_rejects_bad_options(capsys):
    assert main(["bench", "--speed", "--t-final", "0"]) == 2
    assert "--t-final" in capsys.readouterr().err
