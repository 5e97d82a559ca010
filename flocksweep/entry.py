"""The ``flocksweep`` command's entry point: interrupts are handled from its first instant.

The console script calls :func:`main`. Importing the command line takes about a second (numpy, pandas,
numba, pyarrow); Python's default SIGINT handler would turn a Ctrl-C in that second into a
``KeyboardInterrupt`` traceback and the status -2. So :func:`main` installs its own SIGINT and SIGTERM
handlers before it imports anything heavy: a signal while starting ends the command with one line
(``flocksweep: interrupted (SIGINT) while starting; nothing was done``) and the status of docs/errors.md
(130, 143). Once a command runs, :func:`flocksweep.cli.main` handles signals itself
(:func:`sweeps.interrupts.signals_as_exceptions`) and restores these handlers when it returns.
"""
from __future__ import annotations

import signal
import sys

NAMES = {signal.SIGINT: "SIGINT", signal.SIGTERM: "SIGTERM"}


class _Stopped(BaseException):
    """A signal arrived while the command was starting (or after it had returned)."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


def _stop(signum, frame):
    raise _Stopped(signum)


def main(argv=None) -> int:
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


if __name__ == "__main__":
    sys.exit(main())
