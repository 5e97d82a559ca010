"""sweeps.interrupts: signals as exceptions, held writes, and an interrupt that cannot get lost."""
from __future__ import annotations

import gc
import os
import signal
import time

import pytest

from flocksweep.sweeps.executors import Executor
from flocksweep.sweeps.interrupts import Terminated, deferred, exit_status, signals_as_exceptions


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


def swallowed_signal(sig) -> None:
    """Deliver ``sig`` while the garbage collector runs a __del__: Python prints the handler's exception
    ("Exception ignored in ...") and goes on, as when a Ctrl-C lands in a weakref callback."""
    swallowed = []

    class Finalised:
        def __del__(self):
            try:
                os.kill(os.getpid(), sig)
                busy()
            finally:
                swallowed.append(True)

    cycle = Finalised()
    cycle.me = cycle   # freed only by the collector
    del cycle
    gc.collect()
    assert swallowed == [True]


@pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")
def test_a_signal_whose_exception_was_swallowed_is_raised_when_the_block_ends():
    """The command must still end as interrupted (this was an exit 0 after SIGINT)."""
    with pytest.raises(Terminated):
        with signals_as_exceptions():
            swallowed_signal(signal.SIGTERM)
            busy()   # the block goes on as if nothing had happened ...
    # ... and ends by raising the signal it received


@pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")
@pytest.mark.parametrize("sig, error", [(signal.SIGINT, KeyboardInterrupt), (signal.SIGTERM, Terminated)])
def test_a_swallowed_signal_stops_the_executor_at_its_next_task(sig, error):
    ran = []

    def task(x):
        ran.append(x)
        if x == 1:
            swallowed_signal(sig)
        return x

    with pytest.raises(error):
        with signals_as_exceptions(), Executor("serial", 1) as pool:
            list(pool.as_completed(task, range(5)))
    assert ran == [0, 1]


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


def test_a_signal_inside_a_compiler_callback_is_delivered_after_it_returns():
    """numba's compiler calls Python back from C (llvmlite's object cache); an exception raised there is
    printed as "Exception ignored" and dropped, so the signal comes again once the callback returned."""
    namespace: dict = {}
    exec(compile("import signal\ndef callback(log):\n    signal.raise_signal(signal.SIGINT)\n"
                 "    log.append('callback finished')\n", "/site-packages/llvmlite/binding/fake.py", "exec"),
         namespace)
    log: list[str] = []
    with pytest.raises(KeyboardInterrupt):
        with signals_as_exceptions():
            namespace["callback"](log)
            log.append("back in Python")
            deadline = time.monotonic() + 5
            while time.monotonic() < deadline:
                time.sleep(0.01)
    assert log == ["callback finished", "back in Python"]
