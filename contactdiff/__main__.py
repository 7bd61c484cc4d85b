"""``python -m contactdiff``: the command line (`contactdiff.cli`)."""

import sys

from .cli import main

sys.exit(main())
