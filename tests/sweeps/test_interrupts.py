"""sweeps.interrupts: signals as exceptions, held writes, and an interrupt that cannot get lost."""
from __future__ import annotations

import gc
import os
import signal

import pytest

from sweeps.interrupts import Terminated, deferred, exit_status, signals_as_exceptions


def handlers():
    return {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}


def busy(n: int = 20_000) -> int:
    """Python bytecode to run, so a pending signal's handler gets its turn."""
    total = 0
    for k in range(n):
        total += k
    return total


@pytest.mark.parametrize("sig, error", [(signal.SIGINT, KeyboardInterrupt), (signal.SIGTERM, Terminated)])
def test_a_signal_inside_the_block_raises_and_the_handlers_come_back(sig, error):
    before = handlers()
    with pytest.raises(error) as caught:
        with signals_as_exceptions():
            os.kill(os.getpid(), sig)
            busy()
    assert exit_status(caught.value) == 128 + sig
    assert handlers() == before


@pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")
def test_a_signal_whose_exception_was_swallowed_is_raised_when_the_block_ends():
    """A handler's exception raised inside a __del__ run by the garbage collector is printed and dropped
    by Python; the command must still end as interrupted (this was an exit 0 after SIGINT)."""
    swallowed = []

    class Finalised:
        def __del__(self):
            try:
                os.kill(os.getpid(), signal.SIGTERM)
                busy()
            finally:
                swallowed.append(True)

    with pytest.raises(Terminated):
        with signals_as_exceptions():
            cycle = Finalised()
            cycle.me = cycle   # freed only by the collector, where exceptions are ignored
            del cycle
            gc.collect()
            assert swallowed == [True]
            busy()   # the block goes on as if nothing had happened ...
    # ... and ends by raising the signal it received


def test_a_block_without_signals_ends_normally():
    with signals_as_exceptions():
        busy()


def test_a_deferred_block_is_finished_before_the_signal_is_raised():
    steps = []
    with pytest.raises(Terminated):
        with signals_as_exceptions():
            with deferred():
                os.kill(os.getpid(), signal.SIGTERM)
                busy()
                steps.append("written whole")
            steps.append("after the block")
    assert steps == ["written whole"]
