"""Lost runs are never silent. Scripts that start worker processes must guard their top level
(sweeps.main_guard): the README's API
example run as an unguarded script stops at once with one clear line and a non-zero exit status, before
anything is written; a guarded script runs; a worker that finds itself re-running an unguarded script
stops the parent at once (no retries, no lost runs); runs lost by dead workers raise from the API."""
from __future__ import annotations

import os
import re
import subprocess
import sys
import textwrap

import pytest

from flocksweep.sweeps.main_guard import guarded_lines
from paths import ROOT

GUARD_HINT = "guard your script with if __name__ == '__main__'"


def run_script(path, cwd, timeout=240) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), str(ROOT / "tests")])}
    return subprocess.run([sys.executable, str(path)], cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=timeout)


def readme_api_example() -> str:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    section = text[text.index("## Python API"):]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


def unguarded(code: str) -> str:
    """The example as a newcomer pastes it without its guard: the block's body at the top level."""
    head, _, body = code.partition('if __name__ == "__main__":')
    assert body, "the README's API example shows the guard"
    return head + textwrap.dedent(body.split("\n", 1)[1])


@pytest.mark.slow   # over half a second of CPU: out of the quick loop (CI runs it)
def test_the_readme_api_example_without_its_guard_stops_with_one_clear_line(tmp_path):
    code = readme_api_example()
    assert "run_sweep(" in code and guarded_lines(code)
    script = tmp_path / "example.py"
    script.write_text(unguarded(code).replace('"configs/', f'"{ROOT}/configs/'))
    done = run_script(script, tmp_path)
    assert done.returncode != 0
    assert "UnguardedScript: example.py starts worker processes" in done.stderr and GUARD_HINT in done.stderr
    assert not (tmp_path / "results").exists()   # nothing written


def test_the_guard_is_found_whichever_way_round_and_only_its_body_counts():
    source = "import x\nif '__main__' == __name__:\n    a = 1\n    b = 2\nc = 3\nif __name__ != '__main__':\n    d = 4\n"
    assert guarded_lines(source) == [(3, 4)]


POOL_SCRIPT = """
from flocksweep.sweeps.executors import Executor
import flocksweep.sweeps.main_guard as guard
def square(x):
    return x * x

{disable}
{body}
"""
BODY = "with Executor('local', 2) as pool:\n    print('squares', pool.map(square, range(4)))\n"


@pytest.mark.slow   # over half a second of CPU: out of the quick loop (CI runs it)
def test_a_guarded_script_runs_its_pool_and_an_unguarded_one_is_refused(tmp_path):
    good, bad = tmp_path / "good.py", tmp_path / "bad.py"
    good.write_text(POOL_SCRIPT.format(disable="", body="if __name__ == '__main__':\n"
                                       + textwrap.indent(BODY, "    ")))
    bad.write_text(POOL_SCRIPT.format(disable="", body=BODY))
    ran = run_script(good, tmp_path, timeout=120)
    assert ran.returncode == 0 and "squares [0, 1, 4, 9]" in ran.stdout, ran.stderr
    refused = run_script(bad, tmp_path, timeout=120)
    assert refused.returncode != 0 and GUARD_HINT in refused.stderr and "squares" not in refused.stdout


def test_a_worker_re_running_an_unguarded_script_stops_the_parent_at_once(tmp_path):
    """The parent's own check switched off (as if it could not read the script): the workers' check
    catches it, each says so in one line, and the parent raises UnguardedScript without retrying."""
    script = tmp_path / "bad.py"
    script.write_text(POOL_SCRIPT.format(disable="guard.check_caller_guarded = lambda: None", body=BODY))
    done = run_script(script, tmp_path, timeout=120)
    assert done.returncode != 0 and "sweeps.main_guard.UnguardedScript" in done.stderr
    assert f"flocksweep: bad.py starts worker processes from its top level" in done.stderr
    assert "squares" not in done.stdout and "BrokenProcessPool" not in done.stderr.split("UnguardedScript")[-1]


def dying_batch(n_dies: int):
    """worker.execute_batch, but the worker process dies (exit status 9) on the batch of init.n == n_dies."""
    from flocksweep.sweeps import worker

    real = worker.execute_batch

    def patched(specs, out_dir=None):
        if any(s.preset.init.n == n_dies for s in specs):
            os._exit(9)
        return real(specs, out_dir)
    return patched


@pytest.mark.slow
def test_run_sweep_raises_when_runs_were_lost_with_the_cause_and_what_was_saved(tmp_path, monkeypatch):
    from flocksweep.sweeps import RunsLost, Sweep, run_sweep, worker

    sweep = Sweep.from_dict({"name": "lossy", "seed": 3, "model": {"preset": str(ROOT / "configs/models/holland.toml")},
                             "run": {"n": 6, "duration": 1.0, "record_interval": 0.5, "warmup": 0.5},
                             "axes": [{"key": "init.n", "values": [6, 7, 8]}]}, ROOT)
    monkeypatch.setattr(worker, "execute_batch", dying_batch(7))
    with pytest.raises(RunsLost) as caught:
        run_sweep(sweep, tmp_path / "out", executor="local", workers=2, progress=False, batch_size=1)
    message = str(caught.value)
    assert message.startswith("1 of 3 runs were left missing in ") and "worker exit status 9" in message
    assert "Run the sweep again" in message
    result = caught.value.result
    assert [s.preset.init.n for s in result.lost] == [7]
    assert sorted(result.table["init.n"]) == [6, 8] and (result.table["status"] == "ok").all()
