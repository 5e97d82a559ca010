"""Progress of long work, on stderr: what a person waits for is never silent (quiet with ``--no-progress``).

``Phases(command, total, enabled=True)``: a command made of named phases. ``phases.start(name)`` prints
``report: [3/11] heatmaps (12 s so far)`` as each begins, ``phases.done(extra="")`` prints ``report: done
in 61 s`` at the end. Plain lines, flushed at once: readable in a terminal, a pipe or a log, never
written into a result file. ``enabled=False`` prints nothing. Counted progress (runs, frames, chain
steps) uses tqdm bars on stderr; ``bar(total, desc, unit, enabled)`` makes one the same way everywhere.
"""
from __future__ import annotations

import sys
import time


class Phases:
    """Numbered phase lines of one command on stderr (see the module docstring)."""

    def __init__(self, command: str, total: int, enabled: bool = True):
        self.command, self.total, self.enabled = command, total, enabled
        self.count, self.started = 0, time.perf_counter()

    def _say(self, text: str) -> None:
        if self.enabled:
            print(f"{self.command}: {text}", file=sys.stderr, flush=True)

    def start(self, name: str) -> None:
        self.count += 1
        elapsed = time.perf_counter() - self.started
        self._say(f"[{min(self.count, self.total)}/{self.total}] {name} ({elapsed:.0f} s so far)")

    def done(self, extra: str = "") -> None:
        self._say(f"done in {time.perf_counter() - self.started:.0f} s{extra}")


def bar(total: int, desc: str, unit: str, enabled: bool = True):
    """A tqdm progress bar on stderr (refreshed at most twice a second; disabled: silent)."""
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit=unit, disable=not enabled, file=sys.stderr, mininterval=0.5,
                dynamic_ncols=True)
