"""The documentation site's configuration (mkdocs.yml): every page of docs/ is in its nav,
and every public subpackage has a page of the API reference generated from its docstrings.

The site itself is built by CI (`mkdocs build --strict`, the docs extra); these checks
need no mkdocs.
"""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CONFIG = (ROOT / "mkdocs.yml").read_text()
NAV = set(re.findall(r"^\s*-\s+(?:[^:\n]+:\s+)?([\w/.-]+\.md)\s*$", CONFIG, flags=re.M))


def test_every_docs_page_is_in_the_nav():
    pages = {str(p.relative_to(ROOT / "docs")) for p in (ROOT / "docs").rglob("*.md")}
    assert pages - NAV == set(), "pages of docs/ missing from mkdocs.yml's nav"
    assert NAV - pages == set(), "nav entries without a page"


def test_every_public_subpackage_has_an_api_page():
    packages = {p.parent.name for p in (ROOT / "contactdiff").glob("*/__init__.py")}
    documented = set()
    for page in (ROOT / "docs" / "api").glob("*.md"):
        documented |= set(re.findall(r"^::: contactdiff\.(\w+)", page.read_text(), flags=re.M))
    assert packages <= documented, f"subpackages without an API page: {sorted(packages - documented)}"
