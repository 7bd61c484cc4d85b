"""Robots by their robot_descriptions name, resolved through the package's cache (a cache
the test builds: a git repository at the commit the test asks for, so nothing is fetched)."""

from __future__ import annotations

import subprocess
import sys

import pytest
from mjcf_models import FREE_XML

pytest.importorskip("robot_descriptions", reason="the optional robot_descriptions package is not installed")

from contactdiff.errors import ModelLoadError  # noqa: E402
from contactdiff.model.robot_files import load_robot  # noqa: E402

MODULE = "robot_descriptions.go2_mj_description"


def _git(folder, *args) -> str:
    command = ["git", "-c", "user.name=test", "-c", "user.email=test@example.com", "-C", str(folder), *args]
    return subprocess.run(command, check=True, capture_output=True, text=True).stdout.strip()


@pytest.fixture
def fresh_module(monkeypatch):
    """The description module is imported anew (it resolves its path when imported)."""
    monkeypatch.delitem(sys.modules, MODULE, raising=False)
    yield
    sys.modules.pop(MODULE, None)


def _cache_with_go2(
    tmp_path, monkeypatch, repository="mujoco_menagerie", relative="unitree_go2/go2.xml", text=FREE_XML
):
    """The package looks for ``mujoco_menagerie-<commit>/mujoco_menagerie`` in its cache when
    ``ROBOT_DESCRIPTION_COMMIT`` names a commit; a repository there with that commit checked out
    is used as it is. Its ``unitree_go2/go2.xml`` here is the free body of the MJCF tests.
    Returns the file's path."""
    source = tmp_path / "work"
    (source / relative).parent.mkdir(parents=True)
    (source / relative).write_text(text)
    _git(source, "init", "-q")
    _git(source, "add", ".")
    _git(source, "commit", "-q", "-m", "model")
    commit = _git(source, "rev-parse", "HEAD")
    cache = tmp_path / "cache"
    (cache / f"{repository}-{commit}").mkdir(parents=True)
    source.rename(cache / f"{repository}-{commit}" / repository)
    monkeypatch.setenv("ROBOT_DESCRIPTIONS_CACHE", str(cache))
    monkeypatch.setenv("ROBOT_DESCRIPTION_COMMIT", commit)
    return cache / f"{repository}-{commit}" / repository / relative


def test_go2_mj_description_resolves_through_the_cache(tmp_path, monkeypatch, fresh_module):
    path = _cache_with_go2(tmp_path, monkeypatch)
    robot = load_robot("go2_mj_description")
    assert robot.urdf == str(path)
    assert robot.floating_base and robot.nv == 6


def test_cli_check_of_a_description_name(tmp_path, monkeypatch, fresh_module, capsys):
    """The same cache through ``contactdiff check``: the robot loads (one free body, no feet:
    the report says there is nothing to check)."""
    _cache_with_go2(tmp_path, monkeypatch)
    from contactdiff.cli import main

    assert main(["check", "go2_mj_description", "--samples", "1"]) == 0
    assert "fewer than two contacts" in capsys.readouterr().out


def test_an_empty_cache_without_network_is_a_load_error(tmp_path, monkeypatch, fresh_module):
    """Nothing cached and an unreachable repository (a commit that is nowhere): a named error
    that names the cache, not a git traceback."""
    monkeypatch.setenv("ROBOT_DESCRIPTIONS_CACHE", str(tmp_path / "empty"))
    monkeypatch.setenv("ROBOT_DESCRIPTION_COMMIT", "0" * 40)
    monkeypatch.setenv("GIT_TERMINAL_PROMPT", "0")
    monkeypatch.setenv("GIT_ALLOW_PROTOCOL", "file")  # no https: fails at once, offline or not
    with pytest.raises(
        ModelLoadError, match="robot_descriptions cannot provide 'go2_mj_description'.*ROBOT_DESCRIPTIONS_CACHE"
    ):
        load_robot("go2_mj_description")


def test_a_legged_urdf_description_gets_a_floating_base(tmp_path, monkeypatch):
    """``go2_description`` is a URDF the package tags ``quadruped``: loaded with a free-flyer
    (a URDF path alone is fixed). Its file here is the planar leg of the tests' helpers."""
    from helpers import LEG_URDF

    monkeypatch.delitem(sys.modules, "robot_descriptions.go2_description", raising=False)
    _cache_with_go2(tmp_path, monkeypatch, "unitree_ros", "robots/go2_description/urdf/go2_description.urdf", LEG_URDF)
    try:
        robot = load_robot("go2_description")
    finally:
        sys.modules.pop("robot_descriptions.go2_description", None)
    assert robot.floating_base and robot.nv == 6 + 3
