"""Only what a scene needs is computed: counted calls, not times (docs/design.md §7)."""

from __future__ import annotations

import subprocess
import sys

import pinocchio as pin
import pytest

import contactdiff as cd
from contactdiff.bench import footprint


@pytest.mark.parametrize("name,t_final", [("solo12_trot", 0.5), ("pushed_ball", 0.6), ("ball", 3.0)])
@pytest.mark.parametrize("method", ["auto", "DOP853"])
def test_no_derivative_work_without_jacobian(name, t_final, method):
    """A plain run without simultaneous touchdowns calls no Pinocchio derivative
    algorithm and solves no mode with derivatives (auto measures stiffness by
    difference quotients); asking for the Jacobian calls them."""
    scene = cd.load_scene(name)
    assert not any(e.simultaneous for e in cd.simulate(scene, t_final, method=method).events)
    plain = footprint.derivative_work(scene, t_final, method=method)
    assert plain["pinocchio_derivative_calls"] == 0 and plain["derivative_solves"] == 0
    assert plain["dynamics_solves"] > 0
    with_jacobian = footprint.derivative_work(scene, t_final, method=method, jacobian=True)
    assert with_jacobian["pinocchio_derivative_calls"] > 0


@pytest.mark.parametrize("name,t_final", [("planar_trot_soft", 1.8), ("solo12_drop", 0.3), ("panda_lift", 0.3)])
def test_the_landing_order_verdict_does_not_depend_on_the_jacobian(name, t_final):
    """A simultaneous touchdown's verdict (do its landing orders give one saltation
    matrix?) is the same whether sensitivities were asked for or not: a plain run
    computes the orders' saltation matrices at that event only."""
    plain = cd.simulate(cd.load_scene(name), t_final)
    full = cd.simulate(cd.load_scene(name), t_final, jacobian=True)
    assert any(e.simultaneous for e in plain.events)
    assert [set(e.nonsmooth) for e in plain.events] == [set(e.nonsmooth) for e in full.events]
    assert plain.differentiable == full.differentiable


def test_stiff_method_needs_jacobians_only_for_its_newton_matrix():
    """Radau uses the mode's Jacobian for its Newton matrix (re-evaluated only when Newton
    slows down): far fewer derivative solves than steps on a smooth scene."""
    scene = cd.load_scene("two_limb")
    run = footprint.derivative_work(scene, 2.0, method="Radau")
    traj = cd.simulate(scene, 2.0, method="Radau")
    assert 0 < run["derivative_solves"] < traj.stats.steps / 5


def test_counting_restores_what_it_wraps():
    before = (pin.computeRNEADerivatives, cd.ModeDynamics.solve)
    with footprint.counting_derivative_work() as counts:
        cd.simulate(cd.load_scene("ball"), 1.0, jacobian=True)
    assert counts["dynamics_solves"] > 0
    assert (pin.computeRNEADerivatives, cd.ModeDynamics.solve) == before


def test_load_robot_builds_no_geometry():
    """load_robot parses the URDF for dynamics only: no geometry model is built (no mesh
    read), while example-robot-data's loader builds the visual and collision models."""
    import example_robot_data

    builders = [n for n in ("buildGeomFromUrdf", "buildModelsFromUrdf") if hasattr(pin, n)]
    with footprint.counting([(pin, n) for n in builders]) as ours:
        robot = cd.load_robot("solo12")
    assert sum(ours.values()) == 0
    assert not any(hasattr(robot, a) for a in ("visual_model", "collision_model"))
    loaded = example_robot_data.load("solo12")
    assert loaded.visual_model.ngeoms > 0 and loaded.collision_model.ngeoms > 0
    assert robot.model.nv == loaded.model.nv  # the same dynamics


def test_only_listed_frames_and_efforts_are_evaluated():
    """solo12 with contacts on FL and HR only and one spring base_link-FR_FOOT, with the
    flow Jacobian (the most work per frame): exactly those four frames are queried, the
    other feet (FR as a contact, HL at all) and every leg frame never; the one spring is
    evaluated."""
    out = footprint.frame_queries(t_final=0.3, jacobian=True)
    assert set(out["queried"]) == {"FL_FOOT", "HR_FOOT", "base_link", "FR_FOOT"}
    assert "HL_FOOT" not in out["queries_per_frame"]
    assert out["frames_in_model"] > 30
    assert list(out["effort_evaluations"]) == ["base_link-FR_FOOT spring"]
    assert out["effort_evaluations"]["base_link-FR_FOOT spring"] > 0


def test_import_loads_no_plotting_library():
    code = "import contactdiff, sys; print('matplotlib' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
    assert not any(footprint.imports()["plotting_modules_loaded"].values())


def test_footprint_report_formats():
    report = footprint.Footprint(imports=footprint.imports())
    text = report.format()
    assert "plotting modules loaded: none" in text


def test_bench_studies_flag_puts_both_in_the_output(monkeypatch, capsys):
    """`contactdiff bench --studies` carries the studies' rows and the footprint into the
    table and the JSON (the studies themselves are replaced by stubs here: they have
    their own tests in test_extreme_cases.py)."""
    import json

    from contactdiff.bench import extreme_cases as studies
    from contactdiff.cli import main

    row = studies.StudyRow("zeno", "ball", "e = 0.5", "auto", 1e-6, "limit time", 0.01, 3, 30, "ok", True)
    monkeypatch.setattr(studies, "run_studies", lambda quick: studies.StudyResult([row]))
    monkeypatch.setattr(
        footprint,
        "measure_footprint",
        lambda quick: footprint.Footprint(
            imports={"import_time": 0.5, "plotting_modules_loaded": {"matplotlib": False}}
        ),
    )
    args = ["bench", "--quick", "--scenes", "ball", "--repeats", "1", "--studies"]
    assert main(args) == 0
    text = capsys.readouterr().out
    assert "== study: zeno" in text and "only what a scene needs" in text
    assert main(args + ["--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["studies"]["rows"][0]["parameter"] == "e = 0.5" and out["studies"]["all_ok"] is True
    assert out["footprint"]["imports"]["plotting_modules_loaded"] == {"matplotlib": False}


def test_simulate_command_defaults_to_auto(capsys):
    from contactdiff.cli import main

    assert main(["simulate", "ball", "--t-final", "1"]) == 0
    assert "method auto: DOP853" in capsys.readouterr().out
