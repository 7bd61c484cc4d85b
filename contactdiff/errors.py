"""Exceptions of contactdiff: one base class, one subclass per kind of fault.

Every message names the argument, shows the offending value and, where a
finite set of values is valid, lists them.
"""

from __future__ import annotations


class ContactDiffError(Exception):
    """Base class of every error raised on purpose by contactdiff."""


class InvalidInputError(ContactDiffError, ValueError):
    """An argument, file entry or number is malformed or out of range."""


class UnknownNameError(InvalidInputError, KeyError):
    """A robot, frame, joint, contact or key name is not known.

    The message lists the valid names.
    """

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0]) if self.args else ""


class UnknownRobotError(UnknownNameError):
    """A robot source is neither a URDF file nor a known model name."""


class ModelLoadError(ContactDiffError):
    """A URDF or scene file is missing, unreadable or malformed."""


class InconsistentStateError(ContactDiffError):
    """An initial state violates a unilateral constraint (penetration)."""


class IntegrationError(ContactDiffError):
    """The integrator cannot continue (step size underflow, no convergence)."""


class StoppedRunError(IntegrationError):
    """A run stopped before its final time by a budget of the user's; ``.trajectory``
    holds the run up to there (events, segments, statistics)."""

    def __init__(self, message: str, trajectory):
        super().__init__(message)
        self.trajectory = trajectory


class TooManyStepsError(StoppedRunError):
    """More than ``max_steps`` accepted steps: a runaway run (steps far shorter than
    the horizon, e.g. a body spinning at 1e6 rad/s)."""


class SolverError(ContactDiffError):
    """A complementarity or linear-algebra subproblem has no valid solution."""


def check_number(owner: str, name: str, value, *, minimum: float | None = None) -> float:
    """``value`` as a finite float (>= ``minimum`` if given), else `InvalidInputError`
    naming ``owner`` and ``name`` and showing the value."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise InvalidInputError(f"{owner}: {name} must be a number, got {value!r}") from None
    if x != x or x in (float("inf"), float("-inf")):
        raise InvalidInputError(f"{owner}: {name} must be finite, got {value!r}")
    if minimum is not None and x < minimum:
        raise InvalidInputError(f"{owner}: {name} must be >= {minimum:g}, got {value!r}")
    return x


def unknown_name(kind: str, name: object, valid) -> UnknownNameError:
    """Build an `UnknownNameError` listing the valid names of `kind`."""
    listed = ", ".join(sorted(str(v) for v in valid)) or "(none)"
    return UnknownNameError(f"unknown {kind} {name!r}; valid: {listed}")
