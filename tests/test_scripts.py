"""Smoke runs of every script in scripts/: each one's ``--quick`` (or smallest) run, as a user
types it, in a fresh interpreter, writing its files into a temporary folder. A name a script
uses that moved or vanished fails here, not in a user's hands. The runs check that a script
still runs to the end and writes what it says; their numbers are meaningless (the scripts'
studies themselves are measured by the docs' commands)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPTS = ROOT / "scripts"
PNG = b"\x89PNG\r\n\x1a\n"

# script -> (arguments, files it must write, text its output must hold); "{tmp}" is the test's folder
SMOKE = {
    "bench_error_vs_time.py": (
        ["--quick", "--out", "{tmp}/bench.png", "--json", "{tmp}/bench.json"],
        ["bench.png", "bench.json"],
        "plot written to",
    ),
    "cube_metric_search.py": (["--quick", "--jobs", "1"], [], "least training mean"),
    "cube_toss_runs.py": (["--quick", "--jobs", "1"], [], "3 tosses x 1 settings"),
    "cube_tosses.py": (
        ["--quick", "--jobs", "1", "--plot-dir", "{tmp}"],
        ["cube_toss_errors.png", "cube_toss_rollouts.png"],
        "held out: 2 tosses",
    ),
    "decoupling_atlas.py": (["--quick", "--out", "{tmp}/atlas.md"], ["atlas.md"], "atlas written"),
    "fig1_trot.py": (["--quick", "--out", "{tmp}/fig1.png"], ["fig1.png"], "figure written to"),
    "friction_trots.py": (["--quick"], [], "where the time goes"),
    "loop_floor.py": (["--quick"], [], "the whole run's time"),
    "loop_share.py": (["--quick"], [], "two_limb"),
    "gradient_bench.py": (
        ["--quick", "--plots", "{tmp}", "--json", "{tmp}/gradients.json"],
        [f"task_{t}.png" for t in ("1_bounce", "2_wall", "2_wall_friction", "3_two_balls", "4_brax", "5_cube")]
        + ["gradients.json"],
        "no MuJoCo variant reaches",
    ),
    "mjcf_vs_mujoco.py": (["--quick"], [], "max rel. diff of M"),
    "mode_dynamics_cost.py": (["--quick", "planar_trot_soft"], [], "pin.aba"),
    "panda_lift_targets.py": ([], [], "residual"),  # its whole run takes well under a second
    "parameter_cost.py": (["--quick"], [], "central difference"),
    "quadruped_coupling.py": (["--quick"], [], "| solo12 |"),
    "quadruped_decoupling_table.py": (["--quick", "--plot", "{tmp}/trend.png"], ["trend.png"], "compliant feet"),
    "replay_screenshot.py": (["--quick", "--out", "{tmp}/replay.png"], ["replay.png"], "replay.png"),
    "stiff_study.py": (
        ["--quick", "--figure", "{tmp}/stiff.png", "--json", "{tmp}/stiff.json"],
        ["stiff.png", "stiff.json"],
        "steps by method of auto",
    ),
    "stride_noise.py": (["--quick"], [], "pairwise |Δr|"),
    "sweep_bench.py": (["--quick"], [], "speed-up of 2 workers over 1"),
    "trot_design_gradient.py": (["--quick", "--plot", "{tmp}/gradient.png"], ["gradient.png"], "check at step 0"),
    "trot_floquet.py": (["--quick"], [], "stroboscopic map"),
    "toss_events.py": (["record", "--limit", "1", "{tmp}/events.npz"], ["events.npz"], "1 tosses recorded"),
    "trot_table.py": (["--quick"], [], "solo12"),
}


NEEDS_MENAGERIE = ("decoupling_atlas.py", "mjcf_vs_mujoco.py")
MENAGERIE = ROOT.parent / "shared" / "data" / "menagerie"


def test_every_script_has_a_smoke_run():
    assert sorted(p.name for p in SCRIPTS.glob("*.py")) == sorted(SMOKE)


@pytest.mark.parametrize("script", sorted(SMOKE))
def test_script_runs(script, tmp_path):
    if script in NEEDS_MENAGERIE and not MENAGERIE.is_dir():
        pytest.skip(f"{script} reads the Menagerie models beside the repository ({MENAGERIE} is absent)")
    args, files, expected = SMOKE[script]
    argv = [a.replace("{tmp}", str(tmp_path)) for a in args]
    env = dict(os.environ, MPLBACKEND="Agg")
    docs = {p: p.stat().st_mtime_ns for p in (ROOT / "docs").rglob("*")}
    done = subprocess.run(
        [sys.executable, str(SCRIPTS / script), *argv],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    if script == "replay_screenshot.py" and done.returncode == 1 and "no headless" in done.stderr:
        # no Chromium on this machine: the page is still written, and the missing browser is one line
        assert "Traceback" not in done.stderr and len(done.stderr.strip().splitlines()) == 1
        assert "replay written to" in done.stdout
        return
    assert done.returncode == 0, f"{script} {' '.join(argv)} failed:\n{done.stdout[-2000:]}\n{done.stderr[-4000:]}"
    assert "Traceback" not in done.stderr
    assert expected in done.stdout + done.stderr
    for name in files:
        data = (tmp_path / name).read_bytes()
        if name.endswith(".png"):
            assert data.startswith(PNG) and len(data) > 1000
        elif name.endswith(".md"):
            assert data.startswith(b"# ")
        elif name.endswith(".npz"):
            assert data.startswith(b"PK")  # numpy's archive is a zip file
        else:
            json.loads(data)
    # nothing else was written: not beside the named files, not into docs/ (where the full runs write)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(files)
    assert {p: p.stat().st_mtime_ns for p in (ROOT / "docs").rglob("*")} == docs


def test_cube_toss_runs_takes_one_setting(tmp_path):
    """``--setting MU E`` runs that friction and restitution alone (here on the first shipped
    toss, as JSON); with ``--nominal-only`` it is refused with the reason, not run."""
    script = str(SCRIPTS / "cube_toss_runs.py")
    args = [sys.executable, script, "--setting", "0.5", "0", "--limit", "1", "--jobs", "1", "--json"]
    done = subprocess.run(args, cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-4000:]
    settings = json.loads(done.stdout)["settings"]
    assert [(s["friction"], s["restitution"], s["tosses"]) for s in settings] == [(0.5, 0.0, 1)]
    refused = subprocess.run([*args, "--nominal-only"], cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert refused.returncode == 2 and "Traceback" not in refused.stderr
    assert "--setting chooses the settings" in refused.stderr
