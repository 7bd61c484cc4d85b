"""`contactdiff simulate`'s run options: every option an error message names is on the
command line, validated in one place (`SimulateOptions`), and a collapsing run stops fast."""

import json
import math

import pytest

from contactdiff.cli import main


def _events(capsys, argv):
    assert main(argv + ["--json"]) == 0
    return json.loads(capsys.readouterr().out)["events"]


def test_max_steps_zero_is_one_named_line(capsys):
    """Regression: --max-steps 0 raised TypeError from the budget message."""
    assert main(["simulate", "ball", "--t-final", "1", "--max-steps", "0"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "max_steps must be an integer >= 1, got 0" in err


def test_max_events_is_an_option(capsys):
    """The budget error says "raise max_events or zeno_speed": both are options. The ball
    of robots/ball.toml (h = 1, g = 1, e = 0.8) bounces at sqrt 2, 1.131, ... m/s: its
    fourth event comes at t = sqrt 2 (1 + 2 (0.8 + 0.64 + 0.512)) = 6.935 s."""
    assert main(["simulate", "ball", "--t-final", "20", "--max-events", "3"]) == 2
    err = capsys.readouterr().err
    assert "more than max_events = 3 events by t = 6.935" in err and "raise max_events or zeno_speed" in err


def test_zeno_speed_ends_the_bounces_earlier(capsys):
    """With zeno_speed 0.1 m/s the bounces end at the first impact slower than it:
    sqrt 2 · 0.8^k < 0.1 first at k = ceil(ln(0.1 / sqrt 2) / ln 0.8) = 12, so 13 events,
    the last a zeno event."""
    events = _events(capsys, ["simulate", "ball", "--t-final", "20", "--zeno-speed", "0.1"])
    k = math.ceil(math.log(0.1 / math.sqrt(2.0)) / math.log(0.8))
    assert len(events) == k + 1 and events[-1]["kind"] == "zeno"


def test_grazing_speed_and_on_grazing(capsys):
    """grazing_speed 2 m/s makes the first impact (sqrt 2 m/s) grazing: an event, or with
    --on-grazing raise the error that names grazing_speed."""
    events = _events(capsys, ["simulate", "ball", "--t-final", "1.5", "--grazing-speed", "2"])
    assert [e["kind"] for e in events] == ["grazing"]
    assert main(["simulate", "ball", "--t-final", "1.5", "--grazing-speed", "2", "--on-grazing", "raise"]) == 2
    err = capsys.readouterr().err
    assert "grazing touchdown of ball" in err and "grazing_speed 2" in err


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--zeno-speed", "-1"], "zeno_speed must be >= 0, got -1.0"),
        (["--grazing-speed", "-1"], "grazing_speed must be >= 0, got -1.0"),
        (["--grazing-gap", "-1"], "grazing_gap must be >= 0, got -1.0"),
        (["--max-events", "-1"], "--max-events: must be an integer >= 0, got '-1'"),
    ],
)
def test_bad_run_options_are_one_named_line(capsys, argv, message):
    assert main(["simulate", "ball", "--t-final", "1"] + argv) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


def test_solo8_folding_runs(capsys):
    """The issue's command: solo8 folding under gravity ran 200,000 steps and failed; it
    now runs its 0.5 s (tests/integration/test_step_collapse.py says why)."""
    assert main(["simulate", "solo8", "--t-final", "0.5"]) == 0
    assert "from t = 0 to 0.5 s" in capsys.readouterr().out


def test_fast_spin_stops_at_its_step_budget(capsys):
    """The issue's other command: a body pitching at 1e6 rad/s needs steps of ~1e-6 s from
    its start (no collapse), ~2e6 of them for 2 s against the default 200,000; it stops
    after the step budget's first window of 1,000 steady steps (seconds, not the minutes
    of the whole budget), in one line that says when, in which mode, at which step and
    what it would need."""
    assert main(["simulate", "planar_trot_soft", "--t-final", "2", "--v", "body_pitch=1e6"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "collapsed" not in err
    assert "max_steps = 200000 cannot reach t_final = 2 s: at t = " in err and "free flight" in err
    assert "after 1000 steps" in err and "raise max_steps to about" in err


@pytest.mark.parametrize("option, bad", [("--jacobian-error", "full"), ("--on-grazing", "warn")])
def test_bad_choice_lists_the_valid_values(capsys, option, bad):
    """A bad value of an enum option is refused in one line naming it and the valid values
    (their strings, not the enum's repr)."""
    assert main(["simulate", "ball", "--t-final", "1", option, bad]) == 2
    err = capsys.readouterr().err
    valid = "'control', 'state'" if option == "--jacobian-error" else "'event', 'raise'"
    assert err.count("\n") == 1 and f"invalid choice: '{bad}'" in err and valid in err and "<" not in err


def test_jacobian_error_state_keeps_the_plain_steps(capsys):
    """`--jacobian-error state` reaches the run: two_limb for 1.5 s with the flow Jacobian takes
    the plain run's steps, events and final state (`tests/integration/test_jacobian_error.py`
    says why), while under the default ``control`` the Jacobian's error chooses other steps."""

    def run(*extra):
        assert main(["simulate", "two_limb", "--t-final", "1.5", "--json", *extra]) == 0
        return json.loads(capsys.readouterr().out)

    def state_of(out):
        steps = (out["stats"]["steps"], out["stats"]["rejected_steps"])
        events = [(e["t"], e["kind"], e["q"], e["v_plus"]) for e in out["events"]]
        return steps, events, out["q"], out["v"]

    plain, state, control = run(), run("--jacobian", "--jacobian-error", "state"), run("--jacobian")
    assert state["jacobian"] is not None and control["jacobian"] is not None
    assert state_of(state) == state_of(plain)
    assert state_of(control)[0] != state_of(plain)[0]
