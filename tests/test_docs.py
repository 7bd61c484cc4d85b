"""Every command and code block of the README and of docs/ runs as written.

Blocks are read from the Markdown itself, so a block that stops working fails
here. What runs:

* indented blocks (four spaces): each line that starts with ``contactdiff`` is
  run through the command line in a fresh folder and must exit with status 0
  (``pip install`` and ``pytest`` lines are the set-up CI runs itself);
* fenced ``python`` blocks: executed in a fresh folder, each on its own;
* fenced ``toml`` blocks: written next to copies of the project's URDF files and
  loaded with ``load_scene``.

A block whose line before is ``<!-- slow: REASON -->`` takes minutes (a trot, a
Newton search on a quadruped): it runs only with ``-m slow``.
"""

from __future__ import annotations

import re
import shlex
import shutil
from pathlib import Path

import pytest

import contactdiff as cd
from contactdiff.cli import main
from contactdiff.model.robot_files import ROBOTS_DIR

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
_SLOW = re.compile(r"<!--\s*slow\b")


def _blocks(path: Path):
    """``(kind, text, slow, line)`` of every code block: kind ``shell`` for indented
    blocks, else the fence's language."""
    lines = path.read_text().splitlines()
    i = 0
    while i < len(lines):
        line = lines[i]
        slow = (
            i > 0
            and bool(_SLOW.match(lines[i - 1].strip()))
            or (i > 1 and not lines[i - 1].strip() and bool(_SLOW.match(lines[i - 2].strip())))
        )
        fence = re.match(r"^```(\w*)", line)
        if fence:
            end = next(j for j in range(i + 1, len(lines)) if lines[j].startswith("```"))
            yield fence.group(1), "\n".join(lines[i + 1 : end]), slow, i + 1
            i = end + 1
            continue
        if line.startswith("    ") and line.strip() and (i == 0 or not lines[i - 1].strip()):
            end = i
            while end < len(lines) and (lines[end].startswith("    ") or not lines[end].strip()):
                end += 1
            yield "shell", "\n".join(x[4:] for x in lines[i:end]), slow, i + 1
            i = end
            continue
        i += 1


def _cases(kind: str):
    for path in DOCS:
        for block_kind, text, slow, line in _blocks(path):
            if block_kind != kind:
                continue
            items = [text] if kind != "shell" else [x for x in text.splitlines() if x.startswith("contactdiff ")]
            for item in items:
                marks = [pytest.mark.slow] if slow else []
                label = f"{path.relative_to(ROOT)}:{line}"
                if kind == "shell":
                    label += f":{item.split('#')[0].strip()[:60]}"
                yield pytest.param(item, id=label, marks=marks)


def test_the_docs_have_blocks_of_every_kind():
    """The extraction itself works: a README without runnable blocks would pass vacuously."""
    kinds = {kind for path in DOCS for kind, *_ in _blocks(path)}
    assert {"shell", "python", "toml"} <= kinds
    assert len(list(_cases("shell"))) >= 10


@pytest.mark.parametrize("command", list(_cases("shell")))
def test_command_runs_as_written(command, tmp_path, monkeypatch, capsys):
    argv = shlex.split(command, comments=True)[1:]
    if "--plot" in argv:
        pytest.importorskip("matplotlib")
    monkeypatch.chdir(tmp_path)
    status = main(argv)
    assert status == 0, capsys.readouterr().err


@pytest.mark.parametrize("code", list(_cases("python")))
def test_python_block_runs_as_written(code, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    exec(compile(code, "<docs block>", "exec"), {"__name__": "__docs__"})


@pytest.mark.parametrize("text", list(_cases("toml")))
def test_scene_file_block_loads(text, tmp_path):
    for urdf in ROBOTS_DIR.glob("*.urdf"):
        shutil.copy(urdf, tmp_path / urdf.name)
    path = tmp_path / "scene.toml"
    path.write_text(text)
    scene = cd.load_scene(path)
    assert scene.contacts
