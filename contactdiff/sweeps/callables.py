"""Functions named ``module:function``: a sweep's scene factories and user jobs.

A worker process cannot receive a scene (Pinocchio objects do not pickle), but
it can receive the name of a function that builds one, or that runs one point.
`import_callable` resolves such a name with named errors; `reference` gives the
name of a callable passed from Python.
"""

from __future__ import annotations

import importlib
import inspect
from collections.abc import Callable

from ..errors import InvalidInputError, unknown_name


def is_reference(text: str) -> bool:
    """Whether ``text`` has the form ``module:function`` (a dotted module, one colon)."""
    module, sep, name = text.partition(":")
    return (
        bool(sep)
        and bool(module)
        and bool(name)
        and ":" not in name
        and all(part.isidentifier() for part in module.split("."))
        and all(part.isidentifier() for part in name.split("."))
    )


def import_callable(text: str, what: str) -> Callable:
    """The callable named ``module:function`` (``function`` may be dotted: ``Class.method``).

    Args:
        text: the reference.
        what: what it is for, in messages ("scene factory", "job").

    Raises:
        InvalidInputError: not of the form ``module:function``, the module does not
            import (the reason is given), or the name is not callable.
        UnknownNameError: the module has no such name (its public callables are listed).
    """
    if not is_reference(text):
        raise InvalidInputError(f"{what} {text!r} must be module:function, e.g. mypackage.study:run_point")
    module_name, _, name = text.partition(":")
    try:
        module = importlib.import_module(module_name)
    except Exception as exc:  # ImportError, or the module's own code failing
        raise InvalidInputError(
            f"{what} {text!r}: cannot import module {module_name!r} ({type(exc).__name__}: {exc})"
        ) from None
    target = module
    for part in name.split("."):
        if not hasattr(target, part):
            public = [n for n, v in vars(module).items() if callable(v) and not n.startswith("_")]
            raise unknown_name(f"function of module {module_name!r} for the {what}", name, public)
        target = getattr(target, part)
    if not callable(target):
        raise InvalidInputError(f"{what} {text!r} is not callable: it is {type(target).__name__}")
    return target


def reference(function: Callable) -> str:
    """``module:qualname`` of a callable (its label in rows and in the sweep's identity)."""
    module = getattr(function, "__module__", None) or "?"
    name = getattr(function, "__qualname__", None) or getattr(function, "__name__", None) or repr(function)
    return f"{module}:{name}"


def keyword_names(function: Callable) -> tuple[str, ...] | None:
    """Names ``function`` accepts as keywords; None where it takes ``**kwargs`` (any name)."""
    try:
        parameters = inspect.signature(function).parameters.values()
    except (TypeError, ValueError):
        return None
    if any(p.kind is inspect.Parameter.VAR_KEYWORD for p in parameters):
        return None
    return tuple(
        p.name
        for p in parameters
        if p.kind in (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)
    )


def required_names(function: Callable) -> tuple[str, ...]:
    """Names of ``function``'s arguments that have no default (those a call must give)."""
    try:
        parameters = inspect.signature(function).parameters.values()
    except (TypeError, ValueError):
        return ()
    return tuple(
        p.name
        for p in parameters
        if p.default is inspect.Parameter.empty
        and p.kind in (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)
    )


__all__ = ["import_callable", "reference", "keyword_names", "required_names", "is_reference"]
