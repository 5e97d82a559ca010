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
