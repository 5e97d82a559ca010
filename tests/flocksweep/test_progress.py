"""Every command that can run for more than a few seconds shows progress on stderr, and --no-progress
quiets it: `run` (a bar of runs), `report` (each section as it starts), `view --animate` (its phases and a
bar of frames). Each is driven on a tiny config in a pseudo-terminal (python's pty module), as a person
at a terminal would see it."""
from __future__ import annotations

import fcntl
import os
import re
import pty
import select
import struct
import subprocess
import sys
import termios

import pytest

from paths import ROOT

HOLLAND = str(ROOT / "configs/models/holland.toml")
TINY = ["--set", "run.n=6", "--set", "run.duration=1.0", "--set", "run.record_interval=0.5",
        "--set", "run.warmup=0.25"]


def in_pty(argv: list[str], cwd) -> tuple[int, str, str]:
    """Run ``flocksweep ARGV`` with stderr on a pseudo-terminal; (exit status, stderr as seen, stdout)."""
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 40, 120, 0, 0))   # a 120-column terminal
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    process = subprocess.Popen([sys.executable, "-m", "flocksweep.cli", *argv], cwd=cwd, env=env,
                               stdout=subprocess.PIPE, stderr=slave, stdin=subprocess.DEVNULL)
    os.close(slave)
    seen = b""
    while True:
        ready, _, _ = select.select([master], [], [], 1.0)
        if ready:
            try:
                chunk = os.read(master, 65536)
            except OSError:   # the child closed the terminal
                break
            if not chunk:
                break
            seen += chunk
        elif process.poll() is not None:
            break
    os.close(master)
    out = process.stdout.read().decode()
    return process.wait(timeout=600), seen.decode(errors="replace"), out


@pytest.mark.slow
def test_run_report_and_view_show_progress_in_a_terminal_and_are_quiet_without(tmp_path):
    results = tmp_path / "tiny"
    code, err, _ = in_pty(["run", "--model", HOLLAND, "--axis", "perception.field_deg=60,120,180", *TINY,
                           "--executor", "serial", "--out", str(results)], tmp_path)
    assert code == 0, err
    assert "3/3" in err and "run" in err                                   # the sweep's bar of runs
    code, err, _ = in_pty(["report", str(results)], tmp_path)
    assert code == 0, err
    for section in ("[1/", "overview", "claims", "statistics and main effects", "heatmaps", "3-D traces",
                    "writing html and md", "report: done in"):
        assert section in err, section
    code, err, _ = in_pty(["view", HOLLAND, "--n", "5", "--duration", "1", "--animate", "a.gif", "--no-page",
                           "--fps", "10"], tmp_path)
    assert code == 0, err
    assert "view: [1/2] simulating the run" in err and "view: [2/2] drawing the animation a.gif" in err
    assert re.search(r"a\.gif: 100%.*\b(\d+)/\1 .*frame/s", err)             # the bar of frames, to the end
    quiet = [["run", "--model", HOLLAND, "--axis", "perception.field_deg=60,90", *TINY, "--executor", "serial",
              "--out", str(tmp_path / "quiet"), "--no-progress"],
             ["report", str(results), "--out", str(tmp_path / "quiet_report"), "--no-progress"],
             ["view", HOLLAND, "--n", "5", "--duration", "1", "--animate", "b.gif", "--no-page", "--fps", "10",
              "--no-progress"]]
    for argv in quiet:
        code, err, _ = in_pty(argv, tmp_path)
        assert code == 0 and err.strip() == "", (argv, err)
