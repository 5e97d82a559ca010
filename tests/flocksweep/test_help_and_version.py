"""Help, version and quick starts: every command and option of `flocksweep` has a help line (none that
sends the reader elsewhere), `status` a description, `--version` prints the installed version (one source:
pyproject.toml), and the commands that simulate nothing (`--help`, `--version`, `measure --help`, `status`
of an empty and of a finished sweep folder) import neither numba nor the simulator (`--help`, `--version`
and `measure --help` not even pandas). Their warm start times are in
bench/RESULTS.md (bench/bench_startup.py)."""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tomllib

import pytest

from flocksweep.cli import ALL, ORDER, build_parser, main
from paths import ROOT


def subcommands(parser):
    return next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))


def test_every_command_and_option_has_a_help_line_and_every_command_a_description():
    sub = subcommands(build_parser(ALL))
    assert sorted(sub.choices) == sorted(ORDER)
    listed = {action.dest: action.help for action in sub._choices_actions}
    for name, parser in sub.choices.items():
        assert listed[name], f"{name}: no help line in the command list"
        assert parser.description and len(parser.description) > 40, f"{name}: no description"
        for action in parser._actions:
            assert action.help, f"{name} {action.option_strings or action.dest}: no help"
            assert "see flocksweep" not in action.help, f"{name} {action.option_strings}: {action.help}"


def test_version_is_the_installed_one_from_pyproject(capsys):
    version = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["version"]
    with pytest.raises(SystemExit) as stopped:
        main(["--version"])
    assert stopped.value.code == 0 and capsys.readouterr().out.strip() == f"flocksweep {version}"
    import flocksweep

    assert flocksweep.__version__ == version


def loaded_modules(argv, cwd) -> list[str]:
    code = ("import json, sys\nfrom flocksweep.cli import main\ntry:\n    main(%r)\nexcept SystemExit:\n    pass\n"
            "print(json.dumps(sorted(sys.modules)))\n" % (argv,))
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    done = subprocess.run([sys.executable, "-c", code], cwd=cwd, capture_output=True, text=True, env=env,
                          timeout=300)
    return json.loads(done.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("argv, forbidden", [
    (["--help"], ("numba", "pandas", "flocksweep.simcore.simulate", "matplotlib")),
    (["--version"], ("numba", "pandas", "flocksweep.simcore.simulate", "matplotlib")),
    (["view", "--help"], ("numba", "flocksweep.simcore.simulate", "matplotlib")),
    (["status", "."], ("numba", "flocksweep.simcore.simulate", "matplotlib", "scipy.stats")),
])
def test_commands_that_simulate_nothing_import_no_simulator(argv, forbidden, tmp_path):
    modules = loaded_modules(argv, tmp_path)
    assert "flocksweep.cli" in modules
    loaded = [m for m in modules if any(m == f or m.startswith(f + ".") for f in forbidden)]
    assert loaded == []


def test_measure_help_imports_neither_numpy_nor_the_kernels_and_states_the_true_defaults(tmp_path, capsys):
    modules = loaded_modules(["measure", "--help"], tmp_path)
    assert "flocksweep.commands.measure" in modules and "flocksweep.analysis.reports.measure_command" not in modules
    for heavy in ("numpy", "numba", "pandas", "matplotlib", "flocksweep.observables.metrics", "flocksweep.observables.measured"):
        assert not any(m == heavy or m.startswith(heavy + ".") for m in modules), heavy
    from flocksweep.observables.directional_correlation import DCD_MAX_DELAY
    from flocksweep.observables.metrics import FRAGMENTATION_COHESION

    with pytest.raises(SystemExit):
        main(["measure", "--help"])
    shown = " ".join(capsys.readouterr().out.split())     # the defaults the help states are the code's
    assert f"(default {FRAGMENTATION_COHESION:g}," in shown and f"default {DCD_MAX_DELAY:g} s)" in shown


@pytest.mark.slow
def test_status_of_a_finished_sweep_reads_its_parts_without_numba(tmp_path):
    """status reads and checks every runs part (its metric columns: observables.columns, no kernels)."""
    from flocksweep.sweeps.config import sweep_from_dict
    from flocksweep.sweeps.runner import run_sweep
    from tiny_sweeps import sweep

    data = {**sweep(), "axes": [{"key": "perception.field_deg", "values": [60, 180]}]}
    run_sweep(sweep_from_dict(data, ROOT), "# test\n", tmp_path / "tiny", executor="serial", progress=False)
    assert list((tmp_path / "tiny" / "runs").glob("part-*.parquet"))
    modules = loaded_modules(["status", str(tmp_path / "tiny")], tmp_path)
    assert "flocksweep.sweeps.status" in modules and "flocksweep.observables.columns" in modules
    for heavy in ("numba", "flocksweep.simcore.simulate", "flocksweep.observables.metrics", "flocksweep.observables.kernels", "flocksweep.sweeps.config",
                  "matplotlib"):
        assert not any(m == heavy or m.startswith(heavy + ".") for m in modules), heavy
