"""A line that ticks while something slow runs: the person waiting is never left with a silent minute.

``with Ticker("simcore: compiling run_model", estimate="usually about a minute"):`` runs its block while
a daemon thread reports the time so far on stderr::

    simcore: compiling run_model: 1 min 05 s so far (usually about a minute)

* On a terminal the line is rewritten in place every second and cleared when the block ends, so the
  lines printed before and after it stay as they were.
* Elsewhere (a pipe, a log file; or in a worker process, whose terminal its siblings share) a new line
  is written every ``every`` seconds, the first after ``every`` seconds: a short wait adds nothing to a
  log.
* While a tqdm progress bar is open in this process, a ticker with ``under_bars=False`` stays quiet
  (the bar shows the progress); one with ``under_bars=True`` (a compile, which stops every bar) writes
  its lines through ``tqdm.write``, above the bars, every ``every`` seconds.

``owner`` (a frame, e.g. ``sys._getframe(1)``) ties a ticker started without a ``with`` block to a
function call: it stops by itself once that frame has left its thread's stack (the function returned or
raised), so a ticker is never left ticking after the work it reports on.

``status`` may be changed while the block runs (``ticker.status = "3 of 7 done"``): it is shown after
the text. ``line``, ``rewrite`` and ``clear`` replace the stream: callables writing a whole line,
rewriting the current one in place (None: lines only) and clearing it. ``say(text)`` prints a line of
the work's own output (through ``output``, default stdout) above a rewritten ticker line. Set ``FLOCKSWEEP_NO_TICKER=1`` to silence every ticker.
Nothing here touches what is computed: a ticker only writes to its stream.

This module belongs to the namespace root, below every layer (docs/architecture.md): it imports only the
standard library, so any layer may use it (simcore's compile notice does), and tweaking it leaves
simcore's compiled kernels in their cache.
"""
from __future__ import annotations

import os
import sys
import threading
import time
from typing import Callable, TextIO

EVERY_S = 20.0        # seconds between lines where the output is not a terminal
TTY_EVERY_S = 1.0     # seconds between rewrites on a terminal


def elapsed_text(seconds: float) -> str:
    """``42 s``, ``1 min 05 s``, ``1 h 02 min``."""
    seconds = max(0, int(seconds))
    if seconds < 60:
        return f"{seconds} s"
    if seconds < 3600:
        return f"{seconds // 60} min {seconds % 60:02d} s"
    return f"{seconds // 3600} h {seconds % 3600 // 60:02d} min"


def _in_worker_process() -> bool:
    """True in a process started by multiprocessing (its terminal is shared with its siblings)."""
    mp = sys.modules.get("multiprocessing")
    return mp is not None and mp.parent_process() is not None


def _open_bars() -> bool:
    """True while a tqdm bar that shows is open in this process."""
    tqdm_module = sys.modules.get("tqdm.std")
    if tqdm_module is None:
        return False
    try:
        return any(not getattr(bar, "disable", True) for bar in list(tqdm_module.tqdm._instances))
    except Exception:  # noqa: BLE001 - tqdm's internals changed: behave as if no bar were open
        return False


class Ticker:
    """The time so far of a slow block, on a stream (see the module docstring)."""

    def __init__(self, text: str, estimate: str = "", stream: TextIO | None = None, *, every: float = EVERY_S,
                 tty_every: float = TTY_EVERY_S, under_bars: bool = False,
                 line: Callable[[str], None] | None = None, rewrite: Callable[[str], None] | None = None,
                 clear: Callable[[], None] | None = None, output: Callable[[str], None] | None = None,
                 owner=None):
        self.text, self.estimate, self.status = text, estimate, ""
        self.owner, self.owner_thread = owner, threading.get_ident()
        self.every, self.tty_every, self.under_bars = float(every), float(tty_every), under_bars
        self.started = 0.0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._rewritten = False
        self._lock = threading.Lock()   # one writer at a time: the ticking thread or say()
        if line is None:
            out = sys.stderr if stream is None else stream
            line = lambda text: print(text, file=out, flush=True)   # noqa: E731
            if rewrite is None and _isatty(out) and not _in_worker_process():
                rewrite = lambda text: (out.write("\r" + _fit(text) + "\x1b[K"), out.flush())   # noqa: E731
            self._clear = (lambda: (out.write("\r\x1b[K"), out.flush())) if rewrite is not None else None
        else:
            self._clear = clear if clear is not None else ((lambda: rewrite("")) if rewrite is not None else None)
        self._line, self._rewrite, self._output = line, rewrite, output
        self.enabled = os.environ.get("FLOCKSWEEP_NO_TICKER", "") in ("", "0")

    def message(self) -> str:
        """The line as it reads now."""
        status = f" ({self.status})" if self.status else ""
        estimate = f" ({self.estimate})" if self.estimate else ""
        return f"{self.text}{status}: {elapsed_text(time.perf_counter() - self.started)} so far{estimate}"

    def __enter__(self) -> "Ticker":
        self.started = time.perf_counter()
        if self.enabled:
            self._thread = threading.Thread(target=self._run, name="flocksweep-ticker", daemon=True)
            self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self.stop()

    def say(self, text: str) -> None:
        """Print a line of the work's own output (through ``output``; default: stdout) without mixing it
        into a rewritten ticker line: the line is cleared first, and the next tick draws it again below."""
        with self._lock:
            self._clear_line()
            if self._output is not None:
                self._output(text)
            else:
                print(text, flush=True)

    def _clear_line(self) -> None:
        if self._rewritten and self._clear is not None:
            try:
                self._clear()
            except (OSError, ValueError):
                pass
        self._rewritten = False

    def stop(self) -> None:
        """End the ticking (and clear a rewritten line); the block's own output follows on a clean line."""
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join()
        self._thread = None
        self.owner = None
        with self._lock:
            self._clear_line()

    def _run(self) -> None:
        last_line = time.perf_counter()
        while not self._stop.wait(self.tty_every if self._rewrite is not None else min(self.every, 1.0)):
            try:
                with self._lock:
                    if self._stop.is_set():
                        return
                    if self.owner is not None and not self._owner_running():
                        self._stop.set()
                        self._clear_line()
                        return
                    last_line = self._tick(last_line)
            except (OSError, ValueError):   # the stream was closed: stop quietly
                return

    def _owner_running(self) -> bool:
        """True while the owner frame is on the stack of the thread that started this ticker."""
        frame = sys._current_frames().get(self.owner_thread)
        while frame is not None:
            if frame is self.owner:
                return True
            frame = frame.f_back
        return False

    def _tick(self, last_line: float) -> float:
        now = time.perf_counter()
        if _open_bars():
            self._clear_line()
            if self.under_bars and now - last_line >= self.every:
                sys.modules["tqdm.std"].tqdm.write(self.message(), file=sys.stderr)   # above the bars
                return now
            return last_line
        if self._rewrite is not None:
            self._rewrite(self.message())
            self._rewritten = True
            return now
        if now - last_line >= self.every:
            self._line(self.message())
            return now
        return last_line


def _fit(text: str) -> str:
    """The text cut to the terminal's width (a wrapped line could not be rewritten in place)."""
    import shutil

    width = shutil.get_terminal_size((80, 24)).columns - 1
    return text if len(text) <= width else text[:max(1, width - 3)] + "..."


def _isatty(stream) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError, OSError):
        return False
