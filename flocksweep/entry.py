"""The ``flocksweep`` command's entry point: interrupts are handled from its first instant.

The console script calls :func:`console` (:func:`main`, then a quick exit). Importing the command line
takes about a second (numpy, pandas, numba, pyarrow); Python's default SIGINT handler would turn a Ctrl-C in that second into a
``KeyboardInterrupt`` traceback and the status -2. So :func:`main` installs its own SIGINT and SIGTERM
handlers before it imports anything heavy: a signal while starting ends the command with one line
(``flocksweep: interrupted (SIGINT) while starting; nothing was done``) and the status of docs/errors.md
(130, 143). Once a command runs, :func:`flocksweep.cli.main` handles signals itself
(:func:`sweeps.interrupts.signals_as_exceptions`); when :func:`main` returns, the caller's handlers
are back.
"""
from __future__ import annotations

import atexit
import os
import signal
import sys
import threading

NAMES = {signal.SIGINT: "SIGINT", signal.SIGTERM: "SIGTERM"}


class _Stopped(BaseException):
    """A signal arrived while the command was starting."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


def _stop(signum, frame):
    raise _Stopped(signum)


def main(argv=None) -> int:
    """Run the command line with its own signal handlers; the caller's handlers are back when it returns
    (a program or a test that calls it in-process keeps its own Ctrl-C)."""
    previous = {sig: signal.getsignal(sig) for sig in NAMES}
    for sig in NAMES:
        signal.signal(sig, _stop)
    try:
        from flocksweep.cli import main as run   # the heavy imports

        return run(argv)
    except _Stopped as stopped:
        for sig in NAMES:   # a second Ctrl-C does not cut the message short
            signal.signal(sig, signal.SIG_IGN)
        print(f"flocksweep: interrupted ({NAMES[stopped.signum]}) while starting; nothing was done",
              file=sys.stderr)
        return 128 + stopped.signum
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def console() -> None:
    """The console script: :func:`main`, then the process ends without the interpreter's teardown.

    Once a command has returned, its output flushed and the ``atexit`` handlers run (multiprocessing's
    finalizers, logging, temporary folders), nothing is left to do; tearing down every module of numpy,
    pandas, numba and pyarrow would still take 0.3-0.5 s (bench/RESULTS.md). So the process ends there
    with the command's status, unless a thread other than the main one that Python's exit would wait for
    (not a daemon) is still running: then Python's ordinary exit waits for it."""
    try:
        code = main()
    except SystemExit as stop:   # argparse's --help, --version and usage errors
        code = stop.code
    if isinstance(code, str) or any(not thread.daemon for thread in threading.enumerate()
                                    if thread is not threading.main_thread()):
        sys.exit(code)
    for sig in NAMES:   # the command is done: a late Ctrl-C cannot cut its exit handlers short with a traceback
        signal.signal(sig, signal.SIG_IGN)
    atexit._run_exitfuncs()
    os._exit(_flushed(code or 0))


def _flushed(code: int) -> int:
    """Flush the standard streams; as Python's own exit, status 120 when stdout cannot be written."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            code = code or (120 if stream is sys.stdout else 0)
    return code


if __name__ == "__main__":
    console()
