"""The command line's progress bar: simulated time, events and steps of a run on
stderr (a terminal), fed by `simulate`'s ``progress`` callback."""

from __future__ import annotations

import sys
import time
from typing import Any


class ProgressBar:
    """A progress bar on stderr (only on a terminal, and only once a run has lasted a
    second), fed by `simulate`'s ``progress(t, events, steps)`` callback: simulated
    time against the horizon, events and accepted steps. Without a horizon
    (``span=None``: a search of many runs) it counts steps."""

    _EVERY = 0.2  # s of wall time between redraws: the callback is called every step

    def __init__(self, label: str, span: tuple[float, float] | None):
        self.label, self.span = label, span
        self.bar: Any = None  # a tqdm bar while entered
        self.last = 0.0

    def __enter__(self):
        from tqdm import tqdm

        total = None if self.span is None else self.span[1] - self.span[0]
        fmt = "{desc} {percentage:3.0f}%|{bar}| [{elapsed}<{remaining}]" if total else "{desc} [{elapsed}]"
        self.bar = tqdm(
            total=total,
            desc=self.label,
            file=sys.stderr,
            delay=1.0,
            disable=None,
            bar_format=fmt,
            leave=False,
            dynamic_ncols=True,
        )
        return self

    def __call__(self, t: float, events: int, steps: int) -> None:
        """Redraw with the run at time ``t`` (s), ``events`` events and ``steps`` accepted steps."""
        now = time.monotonic()
        if now - self.last < self._EVERY or self.bar.disable:
            return
        self.last = now
        if self.span is None:
            self.bar.set_description_str(
                f"{self.label}: t = {t:.4g} s, {events} events, {steps} steps in this run", refresh=False
            )
            self.bar.update(0)
            return
        self.bar.set_description_str(
            f"{self.label}: t = {t:.4g} / {self.span[1]:g} s, {events} events, {steps} steps", refresh=False
        )
        self.bar.update((t - self.span[0]) - self.bar.n)

    def __exit__(self, *exc) -> None:
        self.bar.close()
