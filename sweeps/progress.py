"""Progress of long work, on stderr, and what to do next, on stdout: what a person waits for is never
silent (quiet with ``--no-progress``), and every command ends by naming the next one.

``Phases(command, total, enabled=True)``: a command made of named phases. ``phases.start(name)`` prints
``report: [4/11] claims (heatmaps took 4 s; 16 s so far)`` as each begins: its number, and the time the
phase before it took; ``phases.done(extra="")`` prints ``report: done in 61 s`` (after the last phase's
time) at the end. While a phase runs, a :class:`Ticker` shows its time so far (on a terminal a line
rewritten every second; in a pipe or a log a line every 20 s; quiet while a progress bar shows; ended
with the function that started the phase, should it raise), so a phase that takes a minute is never a
silent minute. Plain lines, flushed at once: readable in a terminal,
a pipe or a log, never written into a result file. ``enabled=False`` prints nothing.

Counted progress (runs, frames, chain steps) uses tqdm bars on stderr; ``bar(total, desc, unit, enabled)``
makes one the same way everywhere.

``next_steps(*steps)`` prints a command's last lines: ``next:`` and what to run or open next, one per
line, each with its real paths (``flocksweep report results/smoke``, ``open results/smoke/report/report.html``).
"""
from __future__ import annotations

import sys
import time

from flocksweep.ticker import Ticker, elapsed_text

__all__ = ["Phases", "Ticker", "bar", "elapsed_text", "next_steps"]


class Phases:
    """Numbered phase lines of one command on stderr, with each phase's time (see the module docstring)."""

    def __init__(self, command: str, total: int, enabled: bool = True):
        self.command, self.total, self.enabled = command, total, enabled
        self.count, self.started = 0, time.perf_counter()
        self.current: tuple[str, float] | None = None   # (name, start) of the phase running
        self.ticker: Ticker | None = None

    def _say(self, text: str) -> None:
        if self.enabled:
            print(f"{self.command}: {text}", file=sys.stderr, flush=True)

    def _end_phase(self) -> str:
        """Stop the running phase's ticker; the words saying how long it took ("" when none ran)."""
        if self.ticker is not None:
            self.ticker.stop()
            self.ticker = None
        if self.current is None:
            return ""
        name, start = self.current
        self.current = None
        return f"{_short(name)} took {elapsed_text(time.perf_counter() - start)}"

    def start(self, name: str) -> None:
        took = self._end_phase()
        self.count += 1
        so_far = f"{elapsed_text(time.perf_counter() - self.started)} so far"
        label = f"[{min(self.count, self.total)}/{self.total}]"
        self._say(f"{label} {name} ({took + '; ' if took else ''}{so_far})")
        self.current = (name, time.perf_counter())
        if self.enabled:   # it stops by itself should the caller raise before the next phase (owner)
            self.ticker = Ticker(f"{self.command}: {label} {_short(name)}", owner=sys._getframe(1)).__enter__()

    def done(self, extra: str = "") -> None:
        took = self._end_phase()
        self._say(f"done in {elapsed_text(time.perf_counter() - self.started)}"
                  f"{' (' + took + ')' if took else ''}{extra}")


def _short(name: str) -> str:
    """A phase's name up to its first colon (``the chain: 8 walkers x 600 steps`` -> ``the chain``)."""
    return name.split(":", 1)[0].strip()


def bar(total: int, desc: str, unit: str, enabled: bool = True):
    """A tqdm progress bar on stderr (refreshed at most twice a second; disabled: silent)."""
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit=unit, disable=not enabled, file=sys.stderr, mininterval=0.5,
                dynamic_ncols=True)


def next_steps(*steps: str, file=None) -> None:
    """Print ``next:`` and each step on its own line (a command to run, or a file to open), to stdout."""
    steps = [step for step in steps if step]
    if not steps:
        return
    out = sys.stdout if file is None else file
    print("next:", file=out)
    for step in steps:
        print(f"  {step}", file=out)
    out.flush()
