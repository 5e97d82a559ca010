"""No silent minute (flocksweep.ticker, sweeps.progress): a slow block shows its time so far and its
estimate: on a terminal one line rewritten in place and cleared at the end, elsewhere a line every few
seconds; quiet under a progress bar unless it is a compile (which stops every bar); never left ticking
after the work it reports on. simcore's compile notice, `flocksweep compile` and the test suite's
compile step tick; report phases say how long each took.

Every wait here is for an event (a line read from a pseudo-terminal, a line in a stream), with a generous
timeout, never a sleep raced against the machine."""
from __future__ import annotations

import io
import os
import pty
import re
import select
import subprocess
import sys
import threading
import time

import pytest

from flocksweep.sweeps.progress import Phases, next_steps
from flocksweep.ticker import Ticker, elapsed_text
from paths import ROOT

WAIT_S = 60.0


def read_until(fd: int, pattern: str, seen: bytes = b"") -> bytes:
    """Read a pseudo-terminal until ``pattern`` (a regex) appears in what was read, or fail after WAIT_S."""
    deadline = time.monotonic() + WAIT_S
    while not re.search(pattern.encode(), seen):
        assert time.monotonic() < deadline, f"no {pattern!r} in {seen[-500:]!r}"
        ready, _, _ = select.select([fd], [], [], 0.5)
        if ready:
            try:
                chunk = os.read(fd, 4096)
            except OSError:
                break
            if not chunk:
                break
            seen += chunk
    return seen


def on_a_terminal(code: str):
    """Start ``code`` in a child process with stdout and stderr on a pseudo-terminal and stdin a pipe."""
    master, slave = pty.openpty()
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    env.pop("FLOCKSWEEP_NO_TICKER", None)
    child = subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.PIPE, stdout=slave, stderr=slave, env=env)
    os.close(slave)
    return child, master


def finish(child, master) -> bytes:
    child.stdin.write(b"go\n")
    child.stdin.flush()
    seen = read_until(master, "done")
    child.wait(timeout=WAIT_S)
    os.close(master)
    return seen


TICKING = """
import sys
from flocksweep.ticker import Ticker
with Ticker("simcore: compiling run_model", "usually about 1 min", tty_every=0.05):
    sys.stdin.readline()          # the test says when the slow work ends
print("done", flush=True)
"""


def test_on_a_terminal_the_line_is_rewritten_in_place_and_cleared():
    child, master = on_a_terminal(TICKING)
    seen = read_until(master, r"so far \(usually about 1 min\)\x1b\[K\r")   # a second rewrite began
    seen += finish(child, master)
    assert child.returncode == 0
    ticks = re.findall(rb"\rsimcore: compiling run_model: (\d+) s so far \(usually about 1 min\)\x1b\[K", seen)
    assert len(ticks) >= 2                                                  # rewritten in place, again and again
    assert b"\r\x1b[Kdone" in seen                                          # cleared before the work's own output
    assert b"\n" not in seen.split(b"done")[0]                              # no line of its own left behind


def test_in_a_pipe_or_a_log_a_line_comes_every_few_seconds():
    stream, lines_seen = io.StringIO(), threading.Event()

    class Watched(io.StringIO):
        def write(self, text):
            stream.write(text)
            if stream.getvalue().count("\n") >= 2:
                lines_seen.set()
            return len(text)

    with Ticker("measure", "usually a minute", Watched(), every=0.05) as ticker:
        ticker.status = "3 of 8 flocks"
        assert lines_seen.wait(WAIT_S)
    lines = stream.getvalue().splitlines()
    assert all(re.fullmatch(r"measure \(3 of 8 flocks\): \d+ s so far \(usually a minute\)", line) for line in lines)
    assert "\r" not in stream.getvalue()


def test_a_short_block_adds_nothing_to_a_log_and_the_switch_silences_every_ticker(monkeypatch):
    stream = io.StringIO()
    with Ticker("quick", stream=stream, every=3600):
        pass
    assert stream.getvalue() == ""
    monkeypatch.setenv("FLOCKSWEEP_NO_TICKER", "1")
    with Ticker("silenced", stream=stream, every=0.01) as ticker:
        assert ticker._thread is None
    assert stream.getvalue() == ""


def test_under_a_progress_bar_only_a_compile_ticks_and_it_writes_above_the_bar():
    from tqdm import tqdm

    quiet, loud = io.StringIO(), threading.Event()
    bar_stream = io.StringIO()
    lines = []

    class Catch:
        def write(self, text):
            lines.append(text)
            loud.set()

    with tqdm(total=3, file=bar_stream) as bar:
        with Ticker("phase", stream=quiet, every=0.05):
            with Ticker("simcore: compiling", every=0.05, under_bars=True):
                original = tqdm.write
                tqdm.write = classmethod(lambda cls, text, file=None, **kw: Catch().write(text))
                try:
                    assert loud.wait(WAIT_S)
                finally:
                    tqdm.write = original
        bar.update(3)
    assert quiet.getvalue() == ""                                   # the bar shows the progress
    assert lines and lines[0].startswith("simcore: compiling: ")    # the compile stops the bar: it says so


def test_a_phase_ticker_ends_with_the_function_that_started_it_even_when_it_raises():
    def command():
        phases = Phases("report", 2)
        phases.start("claims: 3 claims")
        raise RuntimeError("a section failed")

    before = {t.ident for t in threading.enumerate()}
    with pytest.raises(RuntimeError):
        command()
    started = [t for t in threading.enumerate() if t.ident not in before and t.name == "flocksweep-ticker"]
    for thread in started:
        thread.join(WAIT_S)
        assert not thread.is_alive()


def test_each_phase_line_says_how_long_the_one_before_took(capsys):
    phases = Phases("report", 3)
    phases.start("overview")
    phases.start("claims: 2 claims")
    phases.start("heatmaps")
    phases.done()
    err = capsys.readouterr().err.splitlines()
    assert err[0] == "report: [1/3] overview (0 s so far)"
    assert re.fullmatch(r"report: \[2/3\] claims: 2 claims \(overview took \d+ s; \d+ s so far\)", err[1])
    assert re.fullmatch(r"report: \[3/3\] heatmaps \(claims took \d+ s; \d+ s so far\)", err[2])
    assert re.fullmatch(r"report: done in \d+ s \(heatmaps took \d+ s\)", err[3])


def test_elapsed_time_in_words():
    assert [elapsed_text(s) for s in (0, 42.7, 65, 3599, 3720)] == ["0 s", "42 s", "1 min 05 s", "59 min 59 s",
                                                                   "1 h 02 min"]


def test_next_steps_are_the_last_lines_with_their_paths(capsys):
    next_steps("flocksweep report results/smoke", "", "open results/smoke/report/report.html")
    assert capsys.readouterr().out == ("next:\n  flocksweep report results/smoke\n"
                                       "  open results/smoke/report/report.html\n")


NOTICE = """
import sys
import importlib
s = importlib.import_module("flocksweep.simcore.simulate")
notice = s._CompileNotice("run_model (opensteer dynamics, binocular perception)")
notice.on_start(None)            # numba starts compiling a run loop ...
sys.stdin.readline()
notice.on_end(None)              # ... and is done
print("done", flush=True)
"""


@pytest.mark.slow   # over a second of CPU: out of the quick loop, still in CI
def test_simcore_compile_notice_ticks_on_a_terminal_with_its_estimate():
    child, master = on_a_terminal(NOTICE)
    seen = read_until(master, r"\rsimcore: compiling run_model: \d+ s so far \(usually about 1 min")
    seen += finish(child, master)
    text = seen.decode(errors="replace")
    assert child.returncode == 0, text
    assert "simcore: compiling the simulation kernels: run_model (opensteer dynamics, binocular perception)" in text
    assert re.search(r"\r\x1b\[Ksimcore: compiled run_model \(opensteer dynamics, binocular perception\) in \d+ s", text)


class FakeReporter:
    """What the compile step's ticker uses of pytest's terminal reporter."""

    def __init__(self, isatty: bool):
        self.isatty, self.lines, self.rewrites, self.raw = isatty, [], [], []

    def write_line(self, line):
        self.lines.append(line)

    def rewrite(self, line, erase=False):
        self.rewrites.append(line)

    def write(self, text, flush=False):
        self.raw.append(text)


@pytest.mark.parametrize("isatty", [True, False])
def test_the_test_suites_compile_step_ticks_through_pytests_reporter(isatty):
    import conftest

    reporter = FakeReporter(isatty)
    ticker = conftest.compile_ticker(reporter)
    ticker.every = ticker.tty_every = 0.05
    done = threading.Event()
    with ticker:
        ticker.status = "2 of 8 model families done"
        deadline = time.monotonic() + WAIT_S
        while len(reporter.rewrites if isatty else reporter.lines) < 2:
            assert time.monotonic() < deadline
            done.wait(0.05)
        ticker.say("  binocular perception, opensteer dynamics (holland): 92 kernels compiled in 224.0 s")
    shown = reporter.rewrites if isatty else reporter.lines
    assert re.fullmatch(r"compiling \(2 of 8 model families done\): \d+ s so far \(usually .*\)", shown[0])
    assert "  binocular perception, opensteer dynamics (holland): 92 kernels compiled in 224.0 s" in reporter.lines


@pytest.mark.slow
def test_flocksweep_compile_says_what_it_does_and_what_comes_next(tmp_path):
    code = (f"import sys; sys.argv = ['flocksweep', 'compile', {str(ROOT / 'configs/models/holland.toml')!r}, "
            "'--jobs', '1']\nfrom flocksweep.entry import console\nconsole()\n")
    child, master = on_a_terminal(code)
    seen = read_until(master, r"a first sweep\)")
    child.wait(timeout=600)
    os.close(master)
    text = seen.decode(errors="replace")
    assert child.returncode == 0, text
    assert "compiling the kernels of 1 model(s) in up to 1 processes ..." in text
    assert f"next:\r\n  flocksweep simulate {ROOT / 'configs/models/holland.toml'}" in text
