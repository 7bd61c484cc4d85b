"""The package's modules import one another without a cycle. Every import counts:
those at the top of a module, inside functions and under ``if TYPE_CHECKING:`` (an
import moved into a function to dodge a cycle is still the cycle). A package's
``__init__`` is a module like the others; ``from . import name`` imports the module
``name``, not its package's ``__init__`` again."""

from __future__ import annotations

import ast
from pathlib import Path

import contactdiff

ROOT = Path(contactdiff.__file__).resolve().parent


def _module_name(path: Path, root: Path) -> str:
    parts = [root.name, *path.relative_to(root).with_suffix("").parts]
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _import_graph(root: Path) -> dict[str, set[str]]:
    """Module -> the modules of the same package (under ``root``) it imports, relative
    imports resolved; ``from X import a`` names the module ``X.a`` when it is one, else
    the module ``X``."""
    paths = {_module_name(p, root): p for p in root.rglob("*.py")}
    graph = {}
    for name, path in paths.items():
        package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
        found = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                found.update(alias.name for alias in node.names)
            elif isinstance(node, ast.ImportFrom):
                base = package[: len(package) - node.level + 1] if node.level else []
                module = ".".join(base + ([node.module] if node.module else []))
                submodules = {f"{module}.{alias.name}" for alias in node.names} & paths.keys()
                found |= submodules
                if len(submodules) < len(node.names):  # some names are not modules: X itself
                    found.add(module)
        graph[name] = {m for m in found if m in paths and m != name}
    return graph


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan's algorithm,
    iterative), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out = []
    for start in graph:
        if start in index:
            continue
        work = [(start, iter(sorted(graph[start])))]
        index[start] = low[start] = len(index)
        stack.append(start)
        on_stack.add(start)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph[child]))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    out.append(sorted(component))
    return out


def test_the_package_has_no_import_cycle():
    graph = _import_graph(ROOT)
    # the scan sees the imports it must (not vacuous): a scene calls its named
    # parameters at the top of its module, they read it through a protocol only
    assert "contactdiff.model.parameters" in graph["contactdiff.model.scene"]
    assert "contactdiff.model.parameter_types" in graph["contactdiff.model.contact_parameters"]
    assert "contactdiff.ode.tableaus" in graph["contactdiff.ode.explicit_rk"]
    assert "contactdiff.model.scene" not in graph["contactdiff.model.parameters"]
    assert _cycles(graph) == []


def test_the_scan_finds_a_cycle_through_a_function_local_import(tmp_path):
    """The scan itself: a cycle closed by an import inside a function, and one under
    ``TYPE_CHECKING``, are found; ``from . import c`` ties to ``c``, not to the package."""
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("from .a import f\n", encoding="utf-8")
    (pkg / "a.py").write_text("from .b import g\n\ndef f():\n    return g()\n", encoding="utf-8")
    (pkg / "b.py").write_text("def g():\n    from .a import f\n\n    return f\n", encoding="utf-8")
    (pkg / "c.py").write_text(
        "from typing import TYPE_CHECKING\n\nif TYPE_CHECKING:\n    from .d import D\n", encoding="utf-8"
    )
    (pkg / "d.py").write_text("from . import c\n", encoding="utf-8")
    graph = _import_graph(pkg)
    assert graph["pkg.d"] == {"pkg.c"}
    assert sorted(_cycles(graph)) == [["pkg.a", "pkg.b"], ["pkg.c", "pkg.d"]]
