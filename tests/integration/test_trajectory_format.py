"""A trajectory's text form (`Trajectory.format`), what ``contactdiff simulate`` prints."""

import math

import contactdiff as cd
from contactdiff.cli import main


def test_format_lists_the_bounce_and_the_final_state_of_the_ball(capsys):
    """robots/ball.toml: dropped from z = 1 m at rest under g = 1 m/s², restitution 0.8.
    It lands at t1 = sqrt(2 z / g) = sqrt(2) s at u = sqrt(2) m/s and leaves at 0.8 u;
    the next landing, t1 + 2 (0.8 u) / g = 3.68 s, is past T = 2.5 s, so the text has one
    bounce, and with tau = T - t1 the final state is z = 0.8 u tau - tau² / 2,
    v = 0.8 u - tau. Tolerance 1e-9: the run's rtol 1e-12 on O(1) values, printed with
    12 significant digits (|error| <= 5e-13 of the print)."""
    scene = cd.load_scene("ball")
    traj = cd.simulate(scene, 2.5, rtol=1e-12, atol=1e-13, jacobian=True)
    text = traj.format(scene)
    lines = text.splitlines()
    assert lines[:2] == ["simulation of ball from t = 0 to 2.5 s", "1 events"]
    t1, u = math.sqrt(2.0), math.sqrt(2.0)
    event = next(line.split() for line in lines if "bounce" in line and "ball" in line)
    assert abs(float(event[0]) - t1) < 1e-9 and event[1:] == ["bounce", "ball", "no", "(flight)"]
    tau = 2.5 - t1
    q = float(next(line.split()[-1] for line in lines if line.startswith("  q z ")))
    v = float(next(line.split()[-1] for line in lines if line.startswith("  v z ")))
    assert abs(q - (0.8 * u * tau - tau**2 / 2)) < 1e-9
    assert abs(v - (0.8 * u - tau)) < 1e-9
    assert "flow Jacobian d x(2.5) / d x(0): 2 x 2, tangent space" in lines
    assert lines[-1] == "  the trajectory is differentiable"
    assert main(["simulate", "ball", "--t-final", "2.5", "--rtol", "1e-12", "--atol", "1e-13", "--jacobian"]) == 0
    assert capsys.readouterr().out.rstrip("\n") == text  # the command prints the same text
