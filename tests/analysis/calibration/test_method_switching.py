"""Settings for several methods in one calibration file, and picking one (analysis.calibration.method_table,
``flocksweep calibrate --method``). Nothing simulates except the one end-to-end CLI run (slow)."""
from __future__ import annotations

import json

import pytest

from flocksweep.analysis.calibration.config import load_calibration
from flocksweep.analysis.calibration.settings import EmceeSettings, EmulatorSettings, NpeSettings, OptimizeSettings
from flocksweep.simcore.schema import ConfigError
from flocksweep.cli import main
from paths import ROOT

from test_calibration_config import VALID, write

FLAT = VALID[VALID.index("[method]"):]
SHIPPED = ROOT / "configs/calibration/recover_holland.toml"

SEVERAL = '''[method]
kind = "emcee"
n_sim = 20

[method.emcee]
walkers = 8
steps = 100
moves = "de"

[method.optimize]
algorithm = "nelder_mead"
maxiter = 5

[method.emulator]
results = "res/holland648"
n_sim = 30
'''


def load(tmp_path, method_text, overrides=(), method=None):
    return load_calibration(write(tmp_path, VALID.replace(FLAT, method_text)), overrides, method)


def error(tmp_path, method_text, overrides=(), method=None) -> ConfigError:
    with pytest.raises(ConfigError) as info:
        load(tmp_path, method_text, overrides, method)
    return info.value


def test_todays_flat_file_is_unchanged_and_another_method_takes_only_the_shared_keys(tmp_path):
    own = load(tmp_path, FLAT)
    assert own.method == EmceeSettings(n_sim=50, walkers=16, steps=2000, reevaluate_every=0)
    assert (own.folder_name, own.methods) == ("recover_holland", ("emcee",))
    other = load(tmp_path, FLAT, method="optimize")
    # walkers, steps and reevaluate_every stay emcee's; n_sim and likelihood are every method's
    assert other.method == OptimizeSettings(n_sim=50, likelihood="gaussian")
    assert other.folder_name == "recover_holland-optimize"


def test_sub_tables_default_kind_method_flag_and_set_kind(tmp_path):
    default = load(tmp_path, SEVERAL)
    assert default.method == EmceeSettings(n_sim=20, walkers=8, steps=100, moves="de")
    assert default.methods == ("emcee", "optimize", "emulator")
    opt = load(tmp_path, SEVERAL, method="optimize")
    assert opt.method == OptimizeSettings(n_sim=20, algorithm="nelder_mead", maxiter=5)
    assert opt.folder_name == "recover_holland-optimize"
    emu = load(tmp_path, SEVERAL, method="emulator")
    assert isinstance(emu.method, EmulatorSettings) and emu.method.n_sim == 30   # its own key wins
    assert emu.method.results == tmp_path / "res" / "holland648"
    # --set method.kind=optimize changes the file's own method: the same settings, the usual folder
    via_set = load(tmp_path, SEVERAL, ["method.kind=optimize"])
    assert via_set.method == opt.method and via_set.folder_name == "recover_holland"
    # overrides reach the sub-tables
    assert load(tmp_path, SEVERAL, ["method.emcee.steps=7"]).method.steps == 7


def test_without_kind_one_sub_table_is_the_method_and_several_ask_for_one(tmp_path):
    only = load(tmp_path, '[method.optimize]\nn_sim = 12\nmaxiter = 3\n')
    assert only.method == OptimizeSettings(n_sim=12, maxiter=3) and only.folder_name == "recover_holland"
    err = error(tmp_path, SEVERAL.replace('kind = "emcee"\n', ""))
    assert err.key == "method.kind"
    assert "emcee, optimize, emulator" in str(err) and "--method" in str(err)
    assert load(tmp_path, SEVERAL.replace('kind = "emcee"\n', ""), method="emulator").method.n_sim == 30


def test_unknown_keys_name_the_method_even_when_it_is_not_the_one_picked(tmp_path):
    err = error(tmp_path, SEVERAL.replace("walkers = 8", "walkrs = 8"), method="optimize")
    assert err.key == "method.emcee.walkrs"
    assert str(err).startswith("method.emcee.walkrs: unknown key (did you mean 'walkers'?)")
    err = error(tmp_path, SEVERAL.replace("maxiter = 5", "max_iter = 5"))
    assert err.key == "method.optimize.max_iter" and "did you mean 'maxiter'" in str(err)
    assert error(tmp_path, SEVERAL, ["method.optimize.steps=3"]).key == "method.optimize.steps"


def test_values_are_checked_where_they_are_written(tmp_path):
    assert error(tmp_path, SEVERAL.replace("maxiter = 5", "maxiter = 0")).key == "method.optimize.maxiter"
    assert error(tmp_path, SEVERAL.replace("walkers = 8", "walkers = 9")).key == "method.emcee.walkers"
    assert error(tmp_path, SEVERAL.replace("n_sim = 30", "n_sim = 3")).key == "method.emulator.n_sim"
    assert error(tmp_path, SEVERAL.replace("n_sim = 20", "n_sim = 3")).key == "method.n_sim"
    assert error(tmp_path, SEVERAL.replace('results = "res/holland648"\n', "")).key == "method.emulator.results"
    assert error(tmp_path, SEVERAL.replace("walkers = 8", "walkers = 8\nn_sim = 30")).key == "method.emcee.n_sim"
    assert error(tmp_path, SEVERAL + "[method.mcmc]\nsteps = 3\n").key == "method.mcmc"
    assert error(tmp_path, SEVERAL, method="mcmc").key == "--method"
    assert error(tmp_path, SEVERAL.replace('"emcee"', '"mcmc"', 1)).key == "method.kind"
    not_a_table = SEVERAL.replace("n_sim = 20\n", "n_sim = 20\noptimize = 3\n").replace(
        '[method.optimize]\nalgorithm = "nelder_mead"\nmaxiter = 5\n', "")
    assert error(tmp_path, not_a_table).key == "method.optimize"


def test_set_kind_on_a_flat_file_says_to_use_method(tmp_path):
    err = error(tmp_path, FLAT, ["method.kind=optimize"])
    assert err.key == "method.walkers"
    assert "unknown key" in str(err) and "--method optimize" not in str(err) and "--method NAME" in str(err)
    assert "[method.optimize]" in str(err)


def test_shipped_recovery_file_runs_npe_and_holds_emcee_and_optimize():
    npe = load_calibration(SHIPPED)
    assert isinstance(npe.method, NpeSettings) and npe.methods == ("npe", "emcee", "optimize")
    assert (npe.method.simulations, npe.method.heldout, npe.method.ensemble, npe.folder_name) == \
        (2000, 200, 5, "recover_holland")
    emcee = load_calibration(SHIPPED, method="emcee")   # the exact reference
    assert isinstance(emcee.method, EmceeSettings) and emcee.folder_name == "recover_holland-emcee"
    assert (emcee.method.walkers, emcee.method.steps, emcee.method.moves) == (8, 2000, "de")
    optimize = load_calibration(SHIPPED, method="optimize")
    assert isinstance(optimize.method, OptimizeSettings)
    assert optimize.method.n_sim == emcee.method.n_sim == 16   # the shared key
    assert npe.targets.flock["n_groups_mean"] == 1   # the observed flock is one group


@pytest.mark.slow
def test_cli_method_flag_runs_the_other_method(tmp_path, capsys):
    out = tmp_path / "opt"
    argv = ["calibrate", str(SHIPPED), "--method", "optimize", "--out", str(out), "--no-progress",
            "--set", "run.n=6", "--set", "run.duration=2.5", "--set", "method.n_sim=6",
            "--set", "method.optimize.maxiter=1", "--set", "method.optimize.popsize=2",
            "--set", "method.optimize.recheck=6"]
    assert main(argv) == 0
    optimum = json.loads((out / "optimum.json").read_text())
    assert optimum["method"] == "optimize" and optimum["settings"]["maxiter"] == 1
    assert not (out / "chain.h5").exists()
    assert main(["calibrate", str(SHIPPED), "--method", "optimise", "--out", str(tmp_path / "x")]) == 2
    assert "optimize" in capsys.readouterr().err
    assert main(["calibrate", str(SHIPPED), "--out", str(tmp_path / "y"), "--set", "method.optimize.maxiterr=3"]) == 2
    assert "method.optimize.maxiterr: unknown key (did you mean 'maxiter'?)" in capsys.readouterr().err
    assert not (tmp_path / "y").exists()
