"""The steppers' former home, kept so that ``contactdiff.integration.steppers`` imports
keep working: the steppers live in `contactdiff.ode` (the factory in
`contactdiff.ode.factory`), whose names this module re-exports as they are."""

from ..ode.factory import *  # noqa: F403  (the factory's names, its __all__)
from ..ode.factory import __all__  # noqa: F401
