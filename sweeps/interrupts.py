"""Interrupts: SIGINT and SIGTERM as exceptions, and writes they cannot cut in half.

* ``signals_as_exceptions()``: a context manager under which SIGINT raises :class:`KeyboardInterrupt` (as
  Python does by default) and SIGTERM raises :class:`Terminated` (a ``KeyboardInterrupt``), so one
  ``except KeyboardInterrupt`` / ``finally`` path saves what is finished, stops the workers and
  releases the results folder after either. The previous handlers come back on exit. A handler's
  exception can land anywhere, also in code that swallows it: a ``__del__`` method or a generator
  finalised by the garbage collector (Python prints "Exception ignored in ..." and goes on). So the
  handlers also record the signal: ``raise_if_received()``, called by the executor at every turn of
  its loops, raises it again, and a block that ends normally after one raises it on exit. An
  interrupted command always ends as interrupted, as a rule at its next task. A signal that lands in
  a C callback (numba's compiler calls Python back while it caches objects) would be printed there as
  "Exception ignored ...": the handler sends it again 50 ms later instead of raising it in the callback.
* ``deferred()``: a context manager whose block is not interrupted by SIGINT or SIGTERM: a signal that
  arrives inside is held and delivered (to the handler in force before the block) when the block ends.
  Used around writes that must be whole (a results part with its time series, a chain step).
* ``ignored()``: a context manager under which SIGINT and SIGTERM are ignored (a second Ctrl-C while
  the first one's message is printed).
* ``exit_status(err)``: the shell's convention for a process stopped by a signal: 130 after SIGINT,
  143 after SIGTERM.

Signal handlers belong to the main thread: outside it both context managers do nothing. SIGKILL
cannot be caught; what it leaves behind is made safe by atomic writes and by the results folder's
lock recognising a dead holder (:mod:`sweeps.lock`).
"""
from __future__ import annotations

import os
import signal
import threading
from contextlib import contextmanager

HANDLED = (signal.SIGINT, signal.SIGTERM)


class Terminated(KeyboardInterrupt):
    """The process received SIGTERM."""

    signum = signal.SIGTERM


def exit_status(err: BaseException) -> int:
    """130 for an interrupt (SIGINT), 143 for SIGTERM (128 + the signal number)."""
    return 128 + int(getattr(err, "signum", signal.SIGINT))


def _main_thread() -> bool:
    return threading.current_thread() is threading.main_thread()


def _exception(signum: int) -> KeyboardInterrupt:
    return Terminated() if signum == signal.SIGTERM else KeyboardInterrupt()


_received: list[list[int]] = []   # the signals each active signals_as_exceptions block received, innermost last


def raise_if_received() -> None:
    """Raise the interrupt that the innermost :func:`signals_as_exceptions` block received, if any: its
    exception was swallowed on the way (a loop that goes on after an interrupt was not told of it).
    Called where work goes on, never in clean-up paths."""
    if _received and _received[-1]:
        raise _exception(_received[-1][0])


CALLBACK_FILES = ("/llvmlite/",)   # code that runs as a ctypes callback (numba's compiler caching objects)
REDELIVER_S = 0.05


def _inside_a_callback(frame) -> bool:
    """Whether the interrupted Python frame runs inside a C callback, where an exception is printed as
    "Exception ignored on calling ctypes callback function" and dropped."""
    return frame is not None and any(part in frame.f_code.co_filename for part in CALLBACK_FILES)


def _redeliver(signum: int) -> None:
    """Send ``signum`` to this process again shortly, once the callback has returned."""
    timer = threading.Timer(REDELIVER_S, os.kill, (os.getpid(), signum))
    timer.daemon = True
    timer.start()


@contextmanager
def signals_as_exceptions():
    """SIGINT -> KeyboardInterrupt, SIGTERM -> Terminated inside the block (main thread only); a signal
    whose exception was swallowed inside is raised when the block ends."""
    if not _main_thread():
        yield
        return
    received: list[int] = []

    def handler(signum, frame):
        received.append(signum)
        if _inside_a_callback(frame):   # raised there, Python would print "Exception ignored" and go on
            _redeliver(signum)
            return
        raise _exception(signum)

    before = {sig: signal.getsignal(sig) for sig in HANDLED}
    _received.append(received)
    for sig in HANDLED:
        signal.signal(sig, handler)
    try:
        yield
    finally:
        for sig, previous in before.items():
            signal.signal(sig, previous if previous is not None else signal.SIG_DFL)
        _received.pop()   # blocks nest: this one is the innermost
    if received:   # the block ended normally although a signal came: its exception was swallowed
        raise _exception(received[0])


@contextmanager
def deferred():
    """Hold SIGINT and SIGTERM until the block ends, then deliver them (main thread only)."""
    if not _main_thread():
        yield
        return
    held: list[int] = []
    before = {sig: signal.getsignal(sig) for sig in HANDLED}
    for sig in HANDLED:
        signal.signal(sig, lambda signum, frame: held.append(signum))
    try:
        yield
    finally:
        for sig, handler in before.items():
            signal.signal(sig, handler if handler is not None else signal.SIG_DFL)
        if held:
            signal.raise_signal(held[0])


@contextmanager
def ignored():
    """Ignore SIGINT and SIGTERM inside the block (main thread only)."""
    if not _main_thread():
        yield
        return
    before = {sig: signal.getsignal(sig) for sig in HANDLED}
    for sig in HANDLED:
        signal.signal(sig, signal.SIG_IGN)
    try:
        yield
    finally:
        for sig, handler in before.items():
            signal.signal(sig, handler if handler is not None else signal.SIG_DFL)
