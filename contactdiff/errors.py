"""Exceptions of contactdiff: one base class, one subclass per kind of fault.

Every message names the argument, shows the offending value and, where a
finite set of values is valid, lists them.
"""

from __future__ import annotations

import importlib
from enum import StrEnum
from pathlib import Path
from types import ModuleType
from typing import TypeVar


class ContactDiffError(Exception):
    """Base class of every error raised on purpose by contactdiff."""


class InvalidInputError(ContactDiffError, ValueError):
    """An argument, file entry or number is malformed or out of range."""


class OutputFileError(InvalidInputError):
    """A file to write (``--plot``, ``--html``, ``--out``) cannot be written: its folder is
    missing, not a folder, or refuses a new file; or the write failed after the work
    was done. ``.result`` then holds the work (a run, a sweep's rows); else None."""

    def __init__(self, message: str, result=None):
        super().__init__(message)
        self.result = result


class ObservationFileError(InvalidInputError):
    """A file of observations (`contactdiff.fit.load_observations`) cannot be used: it is
    missing or unreadable, or a column, time, value or quaternion in it is bad. The
    one-line message names the file and what is wrong (the row, the column, the valid
    column names)."""


class GroupMismatchError(InvalidInputError):
    """A group parameter (``group:GROUP:field``) was read while the group's contacts hold
    different values of the field: there is no one value to report. The message lists
    each member's value; setting the parameter gives them all one value."""


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


class UnsafeModelFileError(ModelLoadError):
    """A model file is refused as unsafe to read: it declares XML entities or a DTD
    (entity expansion, "billion laughs"), is too large, or names a file outside
    the model's folder without the caller allowing it."""


class UnsupportedModelError(ModelLoadError):
    """A model uses a feature the dynamics cannot represent (Pinocchio would drop it
    and give a different robot); the message names the feature and where it is."""


class MissingExtraError(ContactDiffError, ImportError):
    """An optional dependency is not installed: the message says what needs it and the
    extra that installs it (``pip install 'contactdiff[EXTRA]'``; `require_extra`)."""


class InconsistentStateError(ContactDiffError):
    """An initial state violates a unilateral constraint (penetration)."""


class IntegrationError(ContactDiffError):
    """The integrator cannot continue (step size underflow, no convergence)."""


class StepSizeUnderflowError(IntegrationError):
    """A stepper's step shrank below the resolution of time at ``.t`` (s): its last
    try was ``.h`` (s). The hybrid loop reports it as a `StepCollapseError` with the run
    so far."""

    def __init__(self, message: str, t: float, h: float):
        super().__init__(message)
        self.t, self.h = t, h


class StoppedRunError(IntegrationError):
    """A run stopped before its final time by a budget of the user's; ``.trajectory``
    holds the run up to there (events, segments, statistics)."""

    def __init__(self, message: str, trajectory):
        super().__init__(message)
        self.trajectory = trajectory


class TooManyStepsError(StoppedRunError):
    """More than ``max_steps`` accepted steps: a runaway run (steps far shorter than
    the horizon, e.g. a body spinning at 1e6 rad/s)."""


class StepBudgetError(TooManyStepsError):
    """The run cannot reach its final time within ``max_steps``: its steady recent steps
    project far more steps than the budget has left (`contactdiff.ode.step_budget`),
    and it stopped early rather than spend the budget. ``.trajectory`` holds the run so
    far; ``.t`` (s), ``.mode`` (the names of the active contacts), ``.step`` (s, the
    reference step of the projection) and ``.steps_needed`` say where and how far."""

    def __init__(self, message: str, trajectory, t: float, mode: tuple[str, ...], step: float, steps_needed: float):
        super().__init__(message, trajectory)
        self.t, self.mode, self.step, self.steps_needed = t, mode, step, steps_needed


class StepCollapseError(StoppedRunError):
    """The step size collapsed with no event in sight: many accepted steps in a row, each
    far shorter than the mode's own steps (`contactdiff.ode.step_collapse`), as
    where the vector field is singular (a mechanism reaching a singular pose, e.g. a leg
    folded flat with its foot held). ``.trajectory`` holds the run so far; ``.t`` (s),
    ``.mode`` (the names of the active contacts) and ``.step`` (s, the last step) say
    where."""

    def __init__(self, message: str, trajectory, t: float, mode: tuple[str, ...], step: float):
        super().__init__(message, trajectory)
        self.t, self.mode, self.step = t, mode, step


class TooManyEventsError(StoppedRunError):
    """More than ``max_events`` events; ``.trajectory`` holds the run up to there."""


class GrazingError(IntegrationError):
    """A contact closed with (nearly) zero normal speed and ``on_grazing="raise"``."""


class StrideError(IntegrationError):
    """A stride did not end in a transversal touchdown of the foot: it never came
    back within ``t_max``, or it came back grazing (zero normal speed) or in a
    Zeno sequence."""


class FitError(ContactDiffError):
    """A recording's run failed during a fit (the message names the recording, the values and the run's error)."""


class SolverError(ContactDiffError):
    """A complementarity or linear-algebra subproblem has no valid solution."""


class EnergyGainError(SolverError):
    """A frictional impact law's solution increases the kinetic energy (``e > 0`` with
    friction coupling: Kane's paradox; `contactdiff.dynamics.frictional_impact`)."""


class OutsideDomainError(SolverError):
    """The vector field is not defined at the state asked for. A stepper meeting it at a
    trial stage rejects the step and tries a shorter one (as CVODES treats a recoverable
    right-hand-side failure); it is raised only if the step then underflows."""


class PainleveError(OutsideDomainError):
    """A contact slipping with Coulomb friction has no consistent contact force, or
    several (Painlevé's paradox: the friction turns the normal force's effect on the
    normal acceleration around, ``A_n M^-1 (A_n - μ s^T A_T)^T <= 0``;
    `contactdiff.dynamics.slip`). Met at a trial stage of a step it only shortens the
    step; raised when the trajectory itself gets there (or at an event's mode choice).

    Attributes:
        contact: scene index of the slipping contact whose own block failed, where one did
            (None for a singular problem of several); the hybrid loop reads it to tell a
            slip that jams (`contactdiff.integration.jam`) from the paradox itself.
    """

    def __init__(self, message: str, contact: int | None = None):
        super().__init__(message)
        self.contact = contact


def require_extra(module: str, extra: str, purpose: str) -> ModuleType:
    """Import an optional dependency: the module, or `MissingExtraError` naming the extra.

    Args:
        module: the module's dotted name (``"matplotlib"``, ``"meshcat.geometry"``).
        extra: the extra of contactdiff that installs it (``pyproject.toml``: ``"plot"``).
        purpose: what needs it, the start of the message (``"plotting"``).

    Raises:
        MissingExtraError: the import failed; e.g. ``plotting needs matplotlib (No module
            named 'matplotlib'): pip install 'contactdiff[plot]'``.
    """
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise MissingExtraError(
            f"{purpose} needs {module.split('.')[0]} ({exc}): pip install 'contactdiff[{extra}]'"
        ) from None


def check_names(owner: str, what: str, value) -> tuple[str, ...]:
    """``value`` (a sequence, not one string) as a tuple of one or more distinct
    non-empty names, else `InvalidInputError` naming ``owner`` and ``what`` (``joints``,
    ``feet``) and showing the value."""
    where = f"{owner}: {what}" if owner else what
    try:
        names = tuple(value) if not isinstance(value, str) else None
    except TypeError:
        names = None
    if names is None:
        raise InvalidInputError(f"{where} must be a sequence of names, got {value!r}")
    if not names or not all(isinstance(n, str) and n for n in names):
        raise InvalidInputError(f"{where} must be one or more non-empty names, got {value!r}")
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated:
        raise InvalidInputError(f"{where} must be distinct; repeated: {', '.join(map(repr, repeated))}")
    return names


def check_number(owner: str, name: str, value, *, minimum: float | None = None, allow_inf: bool = False) -> float:
    """``value`` as a finite float (>= ``minimum`` if given; ``allow_inf`` admits
    ±inf), else `InvalidInputError` naming ``owner`` and ``name`` and showing the value.

    The project's one set of input checks: `check_number`, `check_count`,
    `check_vector`, `check_member`, `check_output_file`; every module validates
    through them.
    A boolean is not a number here (``restitution = true`` would be 1)."""
    import numpy as np

    if isinstance(value, (bool, np.bool_)):
        raise InvalidInputError(f"{owner}: {name} must be a number, got {value!r}")
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise InvalidInputError(f"{owner}: {name} must be a number, got {value!r}") from None
    if x != x or (x in (float("inf"), float("-inf")) and not allow_inf):
        raise InvalidInputError(f"{owner}: {name} must be finite, got {value!r}")
    if minimum is not None and x < minimum:
        raise InvalidInputError(f"{owner}: {name} must be >= {minimum:g}, got {value!r}")
    return x


def check_count(owner: str, name: str, value, *, minimum: int = 0) -> int:
    """``value`` as an ``int`` >= ``minimum`` (not a bool, not a float), else
    `InvalidInputError` naming ``owner`` and ``name`` and showing the value."""
    import numbers

    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < minimum:
        raise InvalidInputError(f"{owner}: {name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


_E = TypeVar("_E", bound=StrEnum)


def check_member(name: str, value: object, enum_type: type[_E]) -> _E:
    """``value`` as a member of the string enum ``enum_type`` (a member or its value),
    else `InvalidInputError` naming the option ``name``, showing the value and listing
    the valid values. Only a string can be one: a bool, None or an array is refused."""
    if not isinstance(value, str) or value not in tuple(enum_type):
        raise InvalidInputError(f"{name} must be one of {', '.join(enum_type)}; got {value!r}")
    return enum_type(value)


def check_vector(owner: str, name: str, value, size: int, labels=None):
    """``value`` as a float array of shape ``(size,)`` with finite entries, else
    `InvalidInputError` naming ``owner``, ``name`` and the first bad entry (by its
    label, e.g. a joint name, where ``labels`` are given)."""
    import numpy as np

    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise InvalidInputError(f"{owner}: {name} must be {size} real numbers, got {value!r}") from None
    if arr.shape != (size,):
        raise InvalidInputError(
            f"{owner}: {name} has shape {arr.shape}; expected ({size},): {size} entries, got {value!r}"
        )
    if not np.isfinite(arr).all():
        i = int(np.flatnonzero(~np.isfinite(arr))[0])
        where = f" ({labels[i]})" if labels is not None else ""
        raise InvalidInputError(f"{owner}: {name}[{i}]{where} is {float(arr[i])!r}; entries must be finite")
    return arr


def unknown_name(kind: str, name: object, valid) -> UnknownNameError:
    """Build an `UnknownNameError` listing the valid names of `kind`."""
    listed = ", ".join(sorted(str(v) for v in valid)) or "(none)"
    return UnknownNameError(f"unknown {kind} {name!r}; valid: {listed}")


def check_output_file(option: str, path, example: str) -> Path:
    """``path`` as a file to write, checked before any work: not a folder, in a folder
    that exists, is a folder and takes a new file (a temporary file is created there
    and removed: permission bits alone do not tell, e.g. for root or a read-only
    mount), and, if the file exists, writable; else `OutputFileError` naming ``option``
    (``--plot``, ``--out``, ...) and the path, suggesting ``example`` as a file name
    inside a folder given by mistake."""
    import os
    import tempfile

    target = Path(path)
    if target.is_dir():
        raise OutputFileError(f"{option} {str(path)!r} is a folder; give a file name such as {str(target / example)!r}")
    folder = target.parent
    if not folder.exists():
        raise OutputFileError(f"{option} {str(path)!r}: folder {str(folder)!r} does not exist")
    if not folder.is_dir():
        raise OutputFileError(f"{option} {str(path)!r}: {str(folder)!r} is a file, not a folder")
    try:
        fd, probe = tempfile.mkstemp(prefix=".contactdiff-", dir=folder)
        os.close(fd)
        os.unlink(probe)
        if target.exists():
            with target.open("r+b"):  # opened for writing, not truncated
                pass
    except OSError as exc:
        raise OutputFileError(f"{option} {str(path)!r} cannot be written: {exc.strerror or exc}") from None
    return target


def write_failed(option: str, path, exc: Exception, result=None) -> OutputFileError:
    """The `OutputFileError` of a write of ``path`` (for ``option``) that failed with
    ``exc`` after the work was done; ``result`` is the work, kept in the error."""
    reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
    return OutputFileError(f"{option} {str(path)!r} could not be written: {reason}", result)
