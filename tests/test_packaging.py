"""The package as a user installs it: the wheel holds the project's robots/ folder,
a non-editable install finds its scenes, and ``python -m contactdiff`` runs."""

from __future__ import annotations

import re
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCENE_FILES = sorted(p.name for p in (ROOT / "robots").iterdir() if p.suffix in (".urdf", ".toml"))


def test_python_m_contactdiff_help():
    out = subprocess.run([sys.executable, "-m", "contactdiff", "--help"], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert "check" in out.stdout and "simulate" in out.stdout


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    """A wheel built from the checkout as a user builds it: ``pip wheel .`` (its own
    build environment with the newest setuptools; the dependencies are not built)."""
    out = tmp_path_factory.mktemp("wheel")
    build = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "-w", str(out), str(ROOT)],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert build.returncode == 0, build.stderr
    (path,) = out.glob("contactdiff-*.whl")
    return path


def test_wheel_contains_the_robot_and_scene_files(wheel):
    names = set(zipfile.ZipFile(wheel).namelist())
    assert SCENE_FILES  # the check is not vacuous
    for name in SCENE_FILES:
        assert f"contactdiff/robots/{name}" in names, name
    assert "contactdiff/py.typed" in names


def test_scenes_load_from_a_non_editable_install(wheel, tmp_path):
    """Installed into a folder of its own and imported from elsewhere (not the
    checkout), the package finds ball.toml and its URDF inside itself."""
    site = tmp_path / "site"
    install = subprocess.run(
        [sys.executable, "-m", "pip", "install", "--no-deps", "--no-index", "--target", str(site), str(wheel)],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert install.returncode == 0, install.stderr
    code = (
        "import contactdiff, pathlib; s = contactdiff.load_scene('ball'); "
        "print(pathlib.Path(contactdiff.__file__).parent, s.name, len(s.contacts))"
    )
    run = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=tmp_path,
        env={"PYTHONPATH": str(site), "PATH": "/usr/bin:/bin"},
    )
    assert run.returncode == 0, run.stderr
    package, name, contacts = run.stdout.split()
    assert Path(package) == site / "contactdiff" and name == "ball" and contacts == "1"


def _extras() -> dict[str, list[str]]:
    import tomllib

    return tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]


def _name(requirement: str) -> str:
    return re.split(r"[\[<>=!~ ;]", requirement, maxsplit=1)[0].lower()


def test_the_dev_extra_holds_what_the_development_instructions_use():
    """docs/development.md installs ``.[dev]`` and runs pytest and ruff: the extra holds ruff and
    every package of the test, plot, viz and pandas extras (the tests' optional parts)."""
    extras = _extras()
    dev = {_name(r) for r in extras["dev"]}
    assert "ruff" in dev
    for extra in ("test", "plot", "viz", "pandas"):
        assert {_name(r) for r in extras[extra]} <= dev, extra
    text = (ROOT / "docs" / "development.md").read_text()
    assert 'pip install -e ".[dev]"' in text and "ruff check" in text


def test_the_browser_tests_have_an_extra():
    """The tests marked browser import playwright: an extra installs it, and the docs name it."""
    assert "playwright" in {_name(r) for r in _extras()["browser"]}
    assert 'pip install -e ".[browser]"' in (ROOT / "docs" / "development.md").read_text()


def test_every_subpackage_is_listed_for_the_wheel():
    """pyproject's explicit package list names every folder of contactdiff with an __init__.py:
    a subpackage left out installs nowhere (an editable checkout hides it; a wheel does not)."""
    import tomllib

    root = Path(__file__).resolve().parents[1]
    listed = set(tomllib.loads((root / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    found = {".".join(p.parent.relative_to(root).parts) for p in (root / "contactdiff").rglob("__init__.py")}
    assert found - listed == set(), f"not in pyproject's packages: {sorted(found - listed)}"
