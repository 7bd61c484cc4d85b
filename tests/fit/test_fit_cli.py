"""``contactdiff fit``: a measured file in, the fitted value with its standard error out."""

import json

import numpy as np

import contactdiff as cd
from contactdiff.cli import main
from contactdiff.fit import Observations

E_TRUE = 0.6
NOISE = 1e-3  # m


def _observation_file(tmp_path, seed: int) -> str:
    """The ball of robots/ball.toml dropped with restitution E_TRUE, sampled at 100 Hz with
    1 mm noise, written as CSV with its measured velocity (the rollout's start)."""
    scene = cd.load_scene("ball").with_parameters({"contact:ball:restitution": E_TRUE})
    t = np.arange(0.0, 1.5, 0.01)
    samples = cd.simulate(scene, t[-1], sample_times=t, rtol=1e-10, atol=1e-12).samples
    q = samples.q + NOISE * np.random.default_rng(seed).standard_normal(samples.q.shape)
    path = tmp_path / f"drop{seed}.csv"
    Observations.from_states(scene, t, q, samples.v).save(path, scene)
    return str(path)


def test_fit_command_recovers_restitution(tmp_path, capsys):
    """Two noisy drops: the JSON holds the value within three standard errors of E_TRUE, and
    each trajectory's verdict (frictionless bounces: differentiable)."""
    files = [_observation_file(tmp_path, seed) for seed in (1, 2)]
    plot = tmp_path / "fit.png"
    assert main(["fit", "ball", *files, "--param", "contact:ball:restitution", "--json", "--plot", str(plot)]) == 0
    out = json.loads(capsys.readouterr().out)
    e = out["parameters"]["contact:ball:restitution"]
    assert abs(e["value"] - E_TRUE) < 3 * e["standard_error"]
    assert all(r["differentiable"] for r in out["recordings"])
    assert plot.stat().st_size > 0


def test_fit_command_text_and_errors(tmp_path, capsys):
    path = _observation_file(tmp_path, 3)
    assert main(["fit", "ball", path, "--param", "contact:ball:restitution", "--max-evaluations", "3"]) == 0
    text = capsys.readouterr().out
    assert "contact:ball:restitution" in text and "differentiable" in text
    assert main(["fit", "ball", path]) == 2
    assert "--param" in capsys.readouterr().err
    assert main(["fit", "ball", str(tmp_path / "missing.csv"), "--param", "scene:gravity_z"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "missing.csv" in err
    assert main(["fit", "ball", path, "--param", "contact:ball:springiness"]) == 2
    assert "springiness" in capsys.readouterr().err


def test_fit_command_on_windows(tmp_path, capsys):
    """--window 30 --window-stride 30: the drop cut into windows named by their samples, each
    window's start velocity fitted; the restitution within three standard errors of E_TRUE. Bad
    window options exit 2 with one named line."""
    path = _observation_file(tmp_path, 4)
    assert (
        main(
            [
                "fit",
                "ball",
                path,
                "--param",
                "contact:ball:restitution",
                "--window",
                "30",
                "--window-stride",
                "30",
                "--fit-state",
                "velocity",
                "--json",
            ]
        )
        == 0
    )
    out = json.loads(capsys.readouterr().out)
    names = [r["name"] for r in out["recordings"]]
    assert names[0].endswith("[2:32]") and len(names) == 5  # starts 2, 32, 62, 92, 122 of 150 samples
    e = out["parameters"]["contact:ball:restitution"]
    assert abs(e["value"] - E_TRUE) < 3 * e["standard_error"]
    for bad, fragment in (
        (["--window", "0"], "length must be a whole number of samples >= 1, got 0"),
        (["--window", "5", "--window-stride", "-1"], "stride must be"),
        (["--window-stride", "5"], "needs --window"),
    ):
        assert main(["fit", "ball", path, "--param", "contact:ball:restitution", *bad]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and fragment in err, err


def test_fit_command_with_a_robust_loss(tmp_path, capsys):
    """--loss soft_l1 with f_scale 3 mm (three times the noise) on two clean noisy drops: the
    value within three standard errors of E_TRUE; a zero f_scale exits 2 with one line."""
    files = [_observation_file(tmp_path, seed) for seed in (4, 5)]
    param = ["--param", "contact:ball:restitution"]
    assert main(["fit", "ball", *files, *param, "--loss", "soft_l1", "--f-scale", "0.003", "--json"]) == 0
    e = json.loads(capsys.readouterr().out)["parameters"]["contact:ball:restitution"]
    assert abs(e["value"] - E_TRUE) < 3 * e["standard_error"]
    assert main(["fit", "ball", files[0], *param, "--loss", "huber", "--f-scale", "0"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "f_scale" in err
