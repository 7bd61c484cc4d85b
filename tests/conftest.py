"""Shared test set-up.

The tests mirror the package (tests/model, tests/dynamics, tests/integration,
tests/analysis, tests/control, tests/bench; the command line, the docs and the
packaging at the top). ``helpers`` (finite differences on the manifold and
their tolerances) is importable from every test file: pytest puts this folder
on ``sys.path`` (``pythonpath`` in pyproject.toml).
"""
