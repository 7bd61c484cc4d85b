"""Every dotted name ``contactdiff.a.b`` that the docs, the scene files, the scripts and the
code's own docstrings mention exists: a module, or an attribute of one. A moved or renamed
name fails here, not in the hands of a reader who follows it."""

from __future__ import annotations

import importlib
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FILES = [
    ROOT / "README.md",
    *(ROOT / "docs").rglob("*.md"),
    *(ROOT / "robots").glob("*.toml"),
    *(ROOT / "scripts").glob("*.py"),
    *(ROOT / "contactdiff").rglob("*.py"),
]
NAME = re.compile(r"\bcontactdiff(?:\.[A-Za-z_][A-Za-z0-9_]*)+")
# packages that pyproject.toml's package-dir maps from another folder of the repository: from a
# checkout (the tests' own folder first on sys.path) they import only once installed
MAPPED = {"contactdiff.robots": ROOT / "robots"}


def _resolves(name: str) -> bool:
    if name in MAPPED:
        return MAPPED[name].is_dir()
    parts = name.split(".")
    for k in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:k]))
        except ImportError:
            continue
        for attribute in parts[k:]:
            if not hasattr(obj, attribute):
                return False
            obj = getattr(obj, attribute)
        return True
    return False


def test_every_dotted_contactdiff_name_exists():
    found = {
        (m.group(0).rstrip("."), path.relative_to(ROOT).as_posix())
        for path in FILES
        for m in NAME.finditer(path.read_text(encoding="utf-8"))
    }
    names = {name for name, _ in found}
    assert len(names) > 20  # the search is not vacuous
    missing = sorted(f"{where}: {name}" for name, where in found if not _resolves(name))
    assert not missing, missing
