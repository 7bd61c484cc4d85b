"""`contactdiff.ode` is the contact-free ODE layer: its modules import nothing of the
contact model (`contactdiff.model`, `contactdiff.dynamics`, `contactdiff.integration`,
nor any other part of the package but `contactdiff.errors`), and the steppers' former
import path, documented in earlier releases, still gives the same objects."""

from __future__ import annotations

import ast
from pathlib import Path

import contactdiff.ode

ODE = Path(contactdiff.ode.__file__).resolve().parent
ALLOWED = ("contactdiff.ode", "contactdiff.errors")


def _imported_modules(path: Path) -> set[str]:
    """Every module an ``import`` or ``from ... import`` of ``path`` names, relative ones
    resolved against the package (those inside functions and ``if TYPE_CHECKING:`` too)."""
    package = ["contactdiff", "ode"]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = package[: len(package) - node.level + 1] if node.level else []
            module = ".".join(base + ([node.module] if node.module else []))
            found.add(module)
            if not node.module:  # ``from . import tableaus``: the names are modules
                found.update(f"{module}.{alias.name}" for alias in node.names)
    return found


def _outside(imports: dict[str, set[str]]) -> set[tuple[str, str]]:
    """The (file, module) pairs that import a part of contactdiff other than `ALLOWED`."""
    return {
        (name, module)
        for name, found in imports.items()
        for module in found
        if (module == "contactdiff" or module.startswith("contactdiff."))
        and not any(module == a or module.startswith(a + ".") for a in ALLOWED)
    }


def test_ode_imports_nothing_of_the_contact_model():
    modules = sorted(ODE.glob("*.py"))
    imports = {path.name: _imported_modules(path) for path in modules}
    # the scan sees the imports it must (not vacuous): the base class's errors and the
    # factory's methods, a module imported by name and one inside a function
    assert "contactdiff.errors" in imports["base.py"]
    assert "contactdiff.ode.explicit_rk" in imports["factory.py"]
    assert "contactdiff.ode.tableaus" in imports["explicit_rk.py"]
    assert "pinocchio" in imports["lie.py"]
    outside = _outside(imports)
    assert not outside, f"contactdiff.ode imports the contact model: {sorted(outside)}"


def test_scanner_resolves_a_relative_import_of_the_contact_model(tmp_path):
    """The scan itself: relative imports two levels up resolve to the contact model's
    modules, and the check above reports them (and not the allowed errors module)."""
    path = tmp_path / "probe.py"
    path.write_text(
        "from ..model import scene\nfrom ..integration.hybrid import simulate\n"
        "from ..errors import InvalidInputError\nimport contactdiff.dynamics.mode\n",
        encoding="utf-8",
    )
    found = _imported_modules(path)
    assert found == {
        "contactdiff.model",
        "contactdiff.integration.hybrid",
        "contactdiff.errors",
        "contactdiff.dynamics.mode",
    }
    assert _outside({"probe.py": found}) == {
        ("probe.py", "contactdiff.model"),
        ("probe.py", "contactdiff.integration.hybrid"),
        ("probe.py", "contactdiff.dynamics.mode"),
    }


def test_steppers_former_path_gives_the_same_objects():
    from contactdiff.integration import steppers

    assert steppers.make_stepper is contactdiff.ode.make_stepper
    assert steppers.METHODS == contactdiff.ode.METHODS == ("DOP853", "RK45", "Radau")
    assert steppers.PinocchioGroup is contactdiff.ode.PinocchioGroup
    assert steppers.VectorSpace is contactdiff.ode.VectorSpace
