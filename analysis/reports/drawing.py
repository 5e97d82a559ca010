"""Figures drawn beside the report's other work: a figure's drawing (matplotlib, single-threaded, most of a
report's CPU) runs in a forked child process while the report goes on computing its statistics, claims and
re-simulated runs, at most :data:`WORKERS` children at a time.

``Figures(workers=None)`` is a context manager. ``submit(draw, target)`` calls ``draw(target)`` (a figure
function writing its files at ``target``) in a child forked from this process, which inherits ``draw`` and
its data as they are (nothing is pickled: the child is a copy of this process); ``wait()`` returns when
every submitted figure is written, and raises :class:`FigureFailed` with the child's traceback when one
failed (the report stops as an inline failure would). Leaving the context without ``wait`` (an error
elsewhere, Ctrl-C) stops the children still drawing; the children ignore Ctrl-C themselves, so an
interrupt is the report's, never a figure's failure.

The same figure function drawing the same data gives the same files in a child as inline (tested byte for
byte on PNGs). Figures are drawn inline, in submission order, when forking is not safe or not wanted:
``workers`` is 1 (``WORKERS`` is 1 on a one-core machine), the platform is not Linux (macOS's system
libraries do not survive a fork), or JAX is loaded (it runs threads that a fork would copy mid-work).
"""
from __future__ import annotations

import os
import signal
import sys
import traceback

WORKERS = min(2, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1)


class FigureFailed(RuntimeError):
    """A figure's drawing failed in its child process; the message holds the child's traceback."""


def _child(draw, target, send) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)   # Ctrl-C is the report's to handle: it stops its children
    try:
        draw(target)
        send.send_bytes(b"")
    except BaseException:   # noqa: BLE001 - any failure is reported to the parent, which raises it
        send.send_bytes(traceback.format_exc().encode())
    finally:
        send.close()


def forking_is_safe() -> bool:
    return sys.platform.startswith("linux") and "jax" not in sys.modules


class Figures:
    """Figures drawn in forked children, at most ``workers`` at a time (module docstring)."""

    def __init__(self, workers: int | None = None):
        self.workers = WORKERS if workers is None else workers
        self.running: list = []     # (process, receiving end of its pipe)

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        for process, receive in self.running:   # an error elsewhere: stop what is still drawing
            process.kill()
            process.join()
            receive.close()
        self.running = []
        return False

    def submit(self, draw, target) -> None:
        if self.workers <= 1 or not forking_is_safe():
            draw(target)
            return
        import multiprocessing

        while len(self.running) >= self.workers:
            self._finish_one()
        fork = multiprocessing.get_context("fork")
        receive, send = fork.Pipe(duplex=False)
        process = fork.Process(target=_child, args=(draw, target, send), daemon=True)
        process.start()
        send.close()
        self.running.append((process, receive))

    def wait(self) -> None:
        while self.running:
            self._finish_one()

    def _finish_one(self) -> None:
        from multiprocessing.connection import wait

        ready = wait([receive for _, receive in self.running])[0]
        index = next(i for i, (_, receive) in enumerate(self.running) if receive is ready)
        process, receive = self.running.pop(index)
        try:
            failure = receive.recv_bytes().decode(errors="replace")   # text only: nothing unpickled
        except EOFError:
            failure = None
        receive.close()
        process.join()
        if failure is None:
            raise FigureFailed(f"a figure's drawing process ended without a word (exit code {process.exitcode})")
        if failure:
            raise FigureFailed(f"a figure could not be drawn:\n{failure}")
