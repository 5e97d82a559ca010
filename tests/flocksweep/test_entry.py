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


@pytest.mark.parametrize("signum, status, name", [(signal.SIGINT, 130, "SIGINT"), (signal.SIGTERM, 143, "SIGTERM")])
def test_a_signal_while_importing_is_one_line_and_the_documented_status(signum, status, name):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    process = subprocess.Popen([sys.executable, "-m", "flocksweep.entry", "status", "nowhere"], env=env,
                               stderr=subprocess.PIPE, text=True)
    time.sleep(0.4)          # the interpreter is up, the command line (about a second) still importing
    process.send_signal(signum)
    _, err = process.communicate(timeout=60)
    assert process.returncode == status, err[-500:]
    assert err.splitlines() == [f"flocksweep: interrupted ({name}) while starting; nothing was done"]


def test_the_entry_point_runs_the_command_line(capsys):
    from flocksweep.entry import main

    assert main(["status", "/nonexistent/folder"]) == 2
    assert "no sweep" in capsys.readouterr().err
