"""The console script's entry point (flocksweep.entry): Ctrl-C or SIGTERM while the command line is
still importing ends with one line and 130/143 (docs/errors.md), never a KeyboardInterrupt traceback
and -2."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest

from paths import ROOT


# the command line imports in well under a second on a fast machine: a finder that holds the import of
# flocksweep.cli for a few seconds makes "a signal while it is still importing" certain, not a race
SLOW_IMPORT = """
import sys, time
class Slow:
    def find_spec(self, name, path=None, target=None):
        if name == "flocksweep.cli":
            print("importing", file=sys.stderr, flush=True)
            time.sleep(5)
        return None
sys.meta_path.insert(0, Slow())
from flocksweep.entry import main
sys.exit(main(["status", "nowhere"]))
"""


@pytest.mark.parametrize("signum, status, name", [(signal.SIGINT, 130, "SIGINT"), (signal.SIGTERM, 143, "SIGTERM")])
def test_a_signal_while_importing_is_one_line_and_the_documented_status(signum, status, name):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    process = subprocess.Popen([sys.executable, "-c", SLOW_IMPORT], env=env, stderr=subprocess.PIPE, text=True)
    assert process.stderr.readline().strip() == "importing"
    process.send_signal(signum)
    started = time.monotonic()
    _, err = process.communicate(timeout=60)
    assert process.returncode == status, err[-500:]
    assert err.splitlines() == [f"flocksweep: interrupted ({name}) while starting; nothing was done"]
    assert time.monotonic() - started < 4     # the signal ended the start, not the held import


def test_the_entry_point_runs_the_command_line(capsys):
    from flocksweep.entry import main

    assert main(["status", "/nonexistent/folder"]) == 2
    assert "no sweep" in capsys.readouterr().err


def test_the_callers_signal_handlers_are_back_when_the_entry_point_returns():
    import signal

    from flocksweep.entry import main

    before = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    main(["status", "/nonexistent/folder"])
    assert {sig: signal.getsignal(sig) for sig in before} == before


CONSOLE = """
import atexit, sys
atexit.register(lambda: print("atexit handler ran", file=sys.stderr))
sys.argv = ["flocksweep", *sys.argv[1:]]
from flocksweep.entry import console
console()
"""


def _console(*args):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run([sys.executable, "-c", CONSOLE, *args], env=env, capture_output=True, text=True,
                          timeout=120)


@pytest.mark.parametrize("args, status, out, err", [
    (["--version"], 0, "flocksweep ", ""),                               # argparse's SystemExit(0)
    (["status", "/nonexistent/folder"], 2, "", "no sweep stored here"),  # the command's own status
    (["--no-such-option"], 2, "", "usage: flocksweep"),                  # a usage error
])
def test_the_console_script_keeps_status_output_and_exit_handlers(args, status, out, err):
    """The quick exit (no interpreter teardown) still flushes both streams through pipes, keeps the
    command's status and runs the atexit handlers."""
    done = _console(*args)
    assert done.returncode == status, done.stderr[-500:]
    assert done.stdout.startswith(out)
    assert err in done.stderr
    assert done.stderr.rstrip().endswith("atexit handler ran")


# a non-daemon thread that is certainly still running when the command returns: it waits until
# flocksweep.entry.main has returned (an event set by a wrapper), then a little more, then prints. Only the
# order of events of the one process decides, never a sleep against the command line's start-up; a
# console that skipped the wait would end the process before the thread's line
WAITING_THREAD = """
import sys, threading, time
import flocksweep.entry as entry
returned = threading.Event()
_main = entry.main
def main(argv=None):
    try:
        return _main(argv)
    finally:
        returned.set()
entry.main = main
def late():
    returned.wait()
    time.sleep(0.5)
    print("thread done", flush=True)
threading.Thread(target=late).start()
"""


def _check_console_waits_for_the_thread():
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    done = subprocess.run([sys.executable, "-c", WAITING_THREAD + CONSOLE, "--version"], env=env,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-500:]
    lines = done.stdout.splitlines()
    assert lines[0].startswith("flocksweep ") and lines[-1] == "thread done", done.stdout


def test_the_console_script_waits_for_a_thread_that_python_would_wait_for():
    _check_console_waits_for_the_thread()


@pytest.mark.slow
def test_the_thread_wait_holds_on_a_machine_whose_cores_are_all_busy():
    """The same check while a process burns each core (the README's test command once failed here when
    the check raced a sleep against start-up on a loaded machine)."""
    burners = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(os.cpu_count() or 2)]
    try:
        for _ in range(3):
            _check_console_waits_for_the_thread()
    finally:
        for burner in burners:
            burner.kill()
            burner.wait()
