"""flocksweep compile (sweeps/compile.py): model families, the compile counter, the command's errors, and
that after it a new process compiles nothing for any shipped preset."""
from __future__ import annotations

import subprocess
import sys
import textwrap

import numba
import pytest

from paths import ROOT
from flocksweep.simcore import load_preset
from flocksweep.cli import main
from flocksweep.sweeps.compile import CompileCounter, group_models, shipped_models

MODELS = ROOT / "configs" / "models"


def test_every_shipped_preset_is_in_exactly_one_group_of_its_dynamics_and_kind_heaviest_first():
    groups = group_models(shipped_models())
    listed = [path for _, paths in groups for path in paths]
    assert sorted(listed) == sorted(str(p) for p in MODELS.glob("*.toml"))
    assert len(set(listed)) == len(listed)
    keys = [key for key, _ in groups]
    assert len(set(keys)) == len(keys)
    for (dynamics, kind), paths in groups:
        for path in paths:
            model = load_preset(path).model
            assert (model.dynamics, model.perception.kind) == (dynamics, kind)
    assert keys[0] == ("opensteer", "binocular")  # the largest compile starts first


def test_the_counter_counts_compiles_and_not_calls_of_a_compiled_function():
    from numba.core import event as numba_event

    @numba.njit(cache=False)
    def twice(x):
        return 2 * x

    counter = CompileCounter()
    with numba_event.install_listener("numba:compile", counter):
        twice(1)
        twice(2)
        assert counter.count == 1
        twice(1.5)   # a new signature is a new compile
    assert counter.count == 2


@pytest.mark.parametrize("argv, key", [
    (["compile", "--jobs", "0"], "--jobs"),
    (["compile", "no_such_model.toml"], "no_such_model.toml"),
])
def test_bad_arguments_are_refused_before_anything_compiles(argv, key, capsys):
    assert main(argv) == 2
    captured = capsys.readouterr()
    assert key in captured.err
    assert "compiling" not in captured.out


def test_a_bad_preset_is_named_before_anything_compiles(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text('[perception]\nkind = "telepathy"\n')
    assert main(["compile", str(bad)]) == 2
    captured = capsys.readouterr()
    assert "perception.kind" in captured.err and "telepathy" in captured.err
    assert "compiling" not in captured.out


PROBE = textwrap.dedent("""
    import glob, sys
    from numba.core import event as numba_event
    from flocksweep.sweeps.compile import CompileCounter, _simulations, measure_all
    counter = CompileCounter()
    with numba_event.install_listener("numba:compile", counter):
        runs = []
        for path in sorted(glob.glob(sys.argv[1] + "/*.toml")):
            runs += _simulations(path)
    print(counter.count, measure_all(runs))
""")


@pytest.mark.slow
def test_after_flocksweep_compile_a_new_process_compiles_nothing_for_any_shipped_preset():
    """Serial, batched and threaded runs of every shipped preset and their metrics: all loaded from numba's
    cache in a process that starts after the command (a second command finds nothing to compile)."""
    first = subprocess.run([sys.executable, "-m", "flocksweep.cli", "compile", "--jobs", "2"], cwd=ROOT,
                           capture_output=True, text=True, timeout=1800)
    assert first.returncode == 0, first.stderr
    assert "metrics:" in first.stdout and "binocular perception" in first.stdout
    probe = subprocess.run([sys.executable, "-c", PROBE, str(MODELS)], cwd=ROOT, capture_output=True,
                           text=True, timeout=600)
    assert probe.returncode == 0, probe.stderr
    assert probe.stdout.split() == ["0", "0"], probe.stdout
    again = subprocess.run([sys.executable, "-m", "flocksweep.cli", "compile", "--jobs", "2"], cwd=ROOT,
                           capture_output=True, text=True, timeout=600)
    assert again.returncode == 0, again.stderr
    assert "0 kernels compiled (none: all were cached)" in again.stdout
    assert "compiling the simulation kernels" not in again.stderr
