"""Every command that can run for more than a few seconds shows progress on stderr, and --no-progress
quiets it: `run` (a bar of runs), `report` (each section as it starts), `view --animate` (its phases and a
bar of frames), `calibrate` (its phases for each method: the chain's steps, the optimiser's evaluations,
npe's training sweep, flow and coverage check; the predictive check's simulations), `sbc` (a bar of
datasets) and `measure` (its phases and a bar of flocks). Each is driven on a tiny config in a pseudo-terminal (python's pty module), as a person
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
from pathlib import Path

import pytest

from malformed import calibration_text
from paths import ROOT

HOLLAND = str(ROOT / "configs/models/holland.toml")
TINY = ["--set", "run.n=6", "--set", "run.duration=1.0", "--set", "run.record_interval=0.5",
        "--set", "run.warmup=0.25"]


def next_lines(out: str) -> list[str]:
    """The steps a command printed after its last ``next:`` line (stdout), without their indent."""
    lines = out.splitlines()
    assert "next:" in lines, out
    start = len(lines) - lines[::-1].index("next:")
    return [line.strip() for line in lines[start:]]


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
    code, err, out = in_pty(["run", "--model", HOLLAND, "--axis", "perception.field_deg=60,120,180", *TINY,
                             "--executor", "serial", "--out", str(results)], tmp_path)
    assert code == 0, err
    assert "3/3" in err and "run" in err                                   # the sweep's bar of runs
    assert next_lines(out)[0].startswith(f"flocksweep report {results}   (")   # and what comes next
    assert next_lines(out)[1].startswith(f"flocksweep view {results} --run ")
    code, err, out = in_pty(["report", str(results)], tmp_path)
    assert code == 0, err
    for section in ("[1/", "overview", "claims", "statistics and main effects", "heatmaps", "3-D traces",
                    "writing html and md", "report: done in"):
        assert section in err, section
    assert re.search(r"report: \[3/\d+\] leadership \(claims took \d+ s; \d+ s so far\)", err)  # each phase's time
    assert next_lines(out)[0].startswith(f"open {results / 'report' / 'report.html'} in a browser")
    code, err, out = in_pty(["view", HOLLAND, "--n", "5", "--duration", "1", "--animate", "a.gif", "--no-page",
                             "--fps", "10"], tmp_path)
    assert code == 0, err
    assert "view: [1/2] simulating the run" in err and "view: [2/2] drawing the animation a.gif" in err
    assert re.search(r"a\.gif: 100%.*\b(\d+)/\1 .*frame/s", err)             # the bar of frames, to the end
    # a bare file name goes beside the page the command would write (results/view/), not into the cwd
    assert (tmp_path / "results" / "view" / "a.gif").is_file() and not (tmp_path / "a.gif").exists()
    assert next_lines(out) == [f"open {Path('results') / 'view' / 'a.gif'}"]
    quiet = [["run", "--model", HOLLAND, "--axis", "perception.field_deg=60,90", *TINY, "--executor", "serial",
              "--out", str(tmp_path / "quiet"), "--no-progress"],
             ["report", str(results), "--out", str(tmp_path / "quiet_report"), "--no-progress"],
             ["view", HOLLAND, "--n", "5", "--duration", "1", "--animate", "b.gif", "--no-page", "--fps", "10",
              "--no-progress"]]
    for argv in quiet:
        code, err, _ = in_pty(argv, tmp_path)
        assert code == 0 and err.strip() == "", (argv, err)


# the malformed battery's small calibration (8 boids for 1 s, one parameter, two target statistics)
CAL_HEAD = calibration_text().split("[method]")[0].replace("{holland}", HOLLAND) + "[method]\n"
METHODS = {"emcee": 'kind = "emcee"\nn_sim = 5\nwalkers = 4\nsteps = 3\n',
           "optimize": 'kind = "optimize"\nn_sim = 5\nmaxiter = 2\npopsize = 3\nrecheck = 10\n',
           "npe": 'kind = "npe"\nsimulations = 30\nheldout = 10\ndraws = 100\n'
                  'flow = { width = 8, layers = 1, max_epochs = 5, patience = 2 }\n'}
TRACKS = "id,t,x,y,z\n" + "".join(f"{i},{t},{t * 1.0 + 0.1 * i},{i},0\n" for i in range(1, 5) for t in range(12))


@pytest.mark.slow
def test_calibrate_sbc_and_measure_show_progress_in_a_terminal_and_are_quiet_without(tmp_path):
    for kind, method in METHODS.items():
        (tmp_path / f"{kind}.toml").write_text(CAL_HEAD + method)
    (tmp_path / "t.csv").write_text(TRACKS)
    expected = {
        "emcee": (["calibrate", "emcee.toml", "--out", "o_emcee"],
                  [r"calibrate: \[1/3\] the chain: 4 walkers x 3 steps", r"cal: 100%.*3/3 \[",
                   r"calibrate: \[2/3\] the posterior predictive check: \d+ simulations", r"predictive: 100%",
                   r"calibrate: \[3/3\] the report", r"calibrate: done in \d+ s"]),
        "optimize": (["calibrate", "optimize.toml", "--out", "o_optimize"],
                     [r"calibrate: \[1/4\] searching \(differential_evolution\): up to 15 evaluations",
                      r"search: 100%.*15/15 \[.*<00:00",                  # a known count: an ETA, to the end
                      r"calibrate: \[2/4\] re-checked the optimum with 10 fresh simulations",
                      r"calibrate: \[3/4\] the posterior predictive check", r"calibrate: \[4/4\] the report"]),
        "npe": (["calibrate", "npe.toml", "--out", "o_npe"],
                [r"calibrate: \[1/5\] the training simulations: 40 \(30 for training, 10 held out\)", r"training: 100%.*40/40",
                 r"calibrate: \[2/5\] training the flow on 30 simulations", r"\d+/5 \[",   # flowjax's epochs
                 r"calibrate: \[3/5\] the coverage check on 10 held-out", r"calibrate: \[4/5\] the posterior",
                 r"calibrate: \[5/5\] the report"]),
        "sbc": (["sbc", "emcee.toml", "--out", "o_sbc", "--datasets", "2", "--draws", "3", "--steps", "3"],
                [r"sbc: \[1/2\] fitting 2 of 2 datasets", r"SBC cal: 100%.*2/2", r"sbc: \[2/2\] the rank",
                 r"sbc: done in"]),
        "measure": (["measure", "t.csv", "--group-radius", "5", "--out", "o_measure"],
                    [r"measure: \[1/3\] reading, checking and measuring t.csv", r"flocks: 100%.*1/1",
                     r"measure: \[2/3\] figures of 1 flock", r"measure: \[3/3\] the report",
                     r"measure: done in"]),
    }
    first_steps = {"emcee": f"open {Path('o_emcee') / 'report.html'} in a browser",
                   "optimize": f"open {Path('o_optimize') / 'report.html'} in a browser",
                   "npe": f"open {Path('o_npe') / 'report.html'} in a browser",
                   "sbc": f"open {Path('o_sbc') / 'rank_histogram.png'} and {Path('o_sbc') / 'ecdf_diff.png'}",
                   "measure": f"open {Path('o_measure') / 'report.html'} in a browser"}
    for name, (argv, lines) in expected.items():
        code, err, out = in_pty(argv, tmp_path)
        assert code == 0, (name, err)
        for line in lines:
            assert re.search(line, err), (name, line, err)
        assert next_lines(out)[0].startswith(first_steps[name]), (name, out)       # what comes next
    assert next_lines(out)[1].startswith("flocksweep view t.csv")
    assert next_lines(out)[2].startswith("flocksweep init t.csv --model configs/models/holland.toml --out fit.toml")
    for name, (argv, _) in expected.items():
        argv = [a.replace("o_", "quiet_") for a in argv] + ["--no-progress"]
        code, err, _ = in_pty(argv, tmp_path)
        assert code == 0 and "%|" not in err and not re.search(r"\[\d/\d\]", err), (name, err)

