"""Calibration config parsing and validation (analysis.calibration.config).

Configs are written as TOML into ``tmp_path`` with an absolute preset path; nothing simulates.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from flocksweep.analysis.calibration.config import CalibrationConfig, load_calibration
from flocksweep.analysis.calibration.settings import EmceeSettings, EmulatorSettings, OptimizeSettings
from flocksweep.analysis.calibration.priors import TruncatedNormal, Uniform
from flocksweep.simcore.schema import ConfigError
from paths import ROOT

PRESET = (ROOT / "configs/models/holland.toml").as_posix()   # this checkout's, found from this file

VALID = f'''
name = "recover_holland"
description = "recover field and direction"
seed = 7

[model]
preset = "{PRESET}"
set = {{ "perception.range" = 20 }}

[run]
n = 30
duration = 10.0
dt = 0.016666666666666666
record_interval = 1.0
warmup = 3.0

[parameters.field]
key = "perception.field_deg"
prior = {{ dist = "uniform", low = 30, high = 360 }}
bounds = [30, 360]

[parameters.direction]
key = "perception.direction_deg"
prior = {{ dist = "truncnormal", mean = 45, sd = 30, low = 0, high = 90 }}

[targets]
summary = "mean"
stats = ["cohesion", "polarization", "nn_distance"]
mean = [0.9, 0.8, 2.5]
sd = [0.05, 0.05, 0.3]

[method]
kind = "emcee"
n_sim = 50
walkers = 16
steps = 2000
reevaluate_every = 0
likelihood = "gaussian"
'''


def write(tmp_path, text=VALID, name="cal.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def load_with(tmp_path, old, new, overrides=()):
    assert old in VALID, old
    return load_calibration(write(tmp_path, VALID.replace(old, new)), overrides)


def error_key(tmp_path, old, new, overrides=()) -> str:
    with pytest.raises(ConfigError) as info:
        load_with(tmp_path, old, new, overrides)
    return info.value.key


def test_valid_config_loads(tmp_path):
    cfg = load_calibration(write(tmp_path))
    assert isinstance(cfg, CalibrationConfig)
    assert (cfg.name, cfg.description, cfg.seed, cfg.warmup) == ("recover_holland", "recover field and direction", 7, 3.0)
    assert str(cfg.preset_path) == PRESET
    assert cfg.preset_data["init"]["n"] == 30
    assert cfg.preset_data["run"]["duration"] == 10.0
    assert cfg.preset_data["perception"]["range"] == 20
    assert cfg.names == ("field", "direction")
    assert cfg.keys == ("perception.field_deg", "perception.direction_deg")
    assert isinstance(cfg.parameters[0].prior, Uniform)
    assert isinstance(cfg.parameters[1].prior, TruncatedNormal)
    assert cfg.parameters[0].bounds == (30.0, 360.0)
    assert cfg.parameters[1].bounds == (0.0, 90.0)
    assert cfg.prior.dim == 2
    assert cfg.prior.explicit_bounds == {"field": (30.0, 360.0), "direction": (0.0, 90.0)}
    t = cfg.targets
    assert t.summary == "mean"
    assert t.stats == ("cohesion", "polarization", "nn_distance")
    assert t.columns == ("cohesion_mean", "polarization_mean", "nn_distance_mean")
    assert t.observed.shape == (1, 3)
    np.testing.assert_allclose(t.observed[0], [0.9, 0.8, 2.5])
    assert t.cov.shape == (3, 3)
    np.testing.assert_allclose(t.cov, np.diag([0.05 ** 2, 0.05 ** 2, 0.3 ** 2]))
    assert cfg.method.kind == "emcee"
    assert cfg.method == EmceeSettings(n_sim=50, likelihood="gaussian", walkers=16, steps=2000,
                                       reevaluate_every=0, moves="stretch")
    assert cfg.source["name"] == "recover_holland"


def test_preset_relative_to_config_file(tmp_path):
    (tmp_path / "models").mkdir()
    (tmp_path / "models" / "h.toml").write_text(open(PRESET).read())
    (tmp_path / "cal").mkdir()
    cfg = load_calibration(write(tmp_path / "cal", VALID.replace(f'"{PRESET}"', '"../models/h.toml"')))
    assert cfg.preset_path == (tmp_path / "models" / "h.toml").resolve()


def test_overrides_apply(tmp_path):
    cfg = load_calibration(write(tmp_path), ["method.walkers=40", "targets.summary=final"])
    assert cfg.method.walkers == 40
    assert cfg.targets.columns == ("cohesion_final", "polarization_final", "nn_distance_final")


def test_cov_and_leadership_stat(tmp_path):
    cfg = load_with(tmp_path, 'stats = ["cohesion", "polarization", "nn_distance"]\nmean = [0.9, 0.8, 2.5]\n'
                              'sd = [0.05, 0.05, 0.3]',
                    'stats = ["cohesion", "trigger_rate"]\nmean = [0.9, 0.1]\ncov = [[0.01, 0.001], [0.001, 0.02]]')
    assert cfg.targets.columns == ("cohesion_mean", "trigger_rate")
    assert cfg.targets.cov.shape == (2, 2)


def test_samples_csv(tmp_path):
    (tmp_path / "observed.csv").write_text("polarization,cohesion,nn_distance,extra\n"
                                           "0.8,0.9,2.5,1\n0.7,0.95,2.4,2\n0.75,0.85,2.6,3\n0.8,0.9,2.5,4\n")
    cfg = load_with(tmp_path, 'mean = [0.9, 0.8, 2.5]\nsd = [0.05, 0.05, 0.3]', 'samples = "observed.csv"')
    assert cfg.targets.cov is None
    assert cfg.targets.observed.shape == (4, 3)
    np.testing.assert_allclose(cfg.targets.observed[1], [0.95, 0.7, 2.4])  # stats order, not file order


def test_samples_errors(tmp_path):
    old = 'mean = [0.9, 0.8, 2.5]\nsd = [0.05, 0.05, 0.3]'
    assert error_key(tmp_path, old, 'samples = "missing.csv"') == "targets.samples"
    (tmp_path / "partial.csv").write_text("cohesion,polarization\n0.9,0.8\n")
    assert error_key(tmp_path, old, 'samples = "partial.csv"') == "targets.samples"
    assert error_key(tmp_path, 'sd = [0.05, 0.05, 0.3]', 'sd = [0.05, 0.05, 0.3]\nsamples = "partial.csv"') \
        == "targets.samples"  # both mean/sd and samples
    assert error_key(tmp_path, old, "") == "targets.mean"  # neither


@pytest.mark.parametrize("old, new, key", [
    ('seed = 7', 'seed = 7\nseeds = 3', "seeds"),
    ('set = {', 'sett = {', "model.sett"),
    ('warmup = 3.0', 'warmup = 3.0\nwarm = 1', "run.warm"),
    ('warmup = 3.0', 'warmup = 12.0', "run.warmup"),
    ('bounds = [30, 360]', 'bounds = [30, 360]\nbound = 1', "parameters.field.bound"),
    ('summary = "mean"', 'summary = "mean"\nstat = 1', "targets.stat"),
    ('summary = "mean"', 'summary = "median"', "targets.summary"),
    ('steps = 2000', 'steps = 2000\nstep = 3', "method.step"),
    ('steps = 2000', 'steps = 2000\nmaxiter = 3', "method.maxiter"),  # an optimize key under emcee
    ('"perception.range" = 20', '"perception.rnage" = 20', "model.set.perception.rnage"),
    ('duration = 10.0', 'duration = -1.0', "run.duration"),
    # targets
    ('"nn_distance"]', '"nn_distanse"]', "targets.stats"),
    ('mean = [0.9, 0.8, 2.5]', 'mean = [0.9, 0.8]', "targets.mean"),
    ('sd = [0.05, 0.05, 0.3]', 'sd = [0.05, 0.05]', "targets.sd"),
    ('sd = [0.05, 0.05, 0.3]', 'sd = [0.05, 0.0, 0.3]', "targets.sd"),
    ('sd = [0.05, 0.05, 0.3]', 'sd = [0.05, -1, 0.3]', "targets.sd"),
    ('sd = [0.05, 0.05, 0.3]', '', "targets.sd"),
    ('sd = [0.05, 0.05, 0.3]', 'sd = [0.05, 0.05, 0.3]\ncov = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]', "targets.sd"),
    ('sd = [0.05, 0.05, 0.3]', 'cov = [[1, 0], [0, 1]]', "targets.cov"),
    ('sd = [0.05, 0.05, 0.3]', 'cov = [[1, 0.5, 0], [0, 1, 0], [0, 0, 1]]', "targets.cov"),
    ('sd = [0.05, 0.05, 0.3]', 'cov = [[1, 2, 0], [2, 1, 0], [0, 0, 1]]', "targets.cov"),
    # parameters
    ('bounds = [30, 360]', 'bounds = [40, 360]', "parameters.field.prior"),  # prior outside bounds
    ('bounds = [30, 360]', 'bounds = [30, "x"]', "parameters.field.bounds"),
    ('high = 360 }', 'hihg = 360 }', "parameters.field.prior.hihg"),
    ('key = "perception.field_deg"', 'key = "perception.feild_deg"', "parameters.field.key"),
    ('key = "perception.field_deg"', 'key = "perception.radius"', "parameters.field.key"),  # other kind's key
    ('key = "perception.field_deg"', 'key = "perception.occlusion"', "parameters.field.key"),  # not numeric
    ('key = "perception.direction_deg"', 'key = "perception.field_deg"', "parameters.direction.key"),  # twice
    ('prior = { dist = "truncnormal", mean = 45, sd = 30, low = 0, high = 90 }',
     'prior = { dist = "normal", mean = 45, sd = 30 }', "parameters.direction.bounds"),  # unbounded
    # method
    ('walkers = 16', 'walkers = 2', "method.walkers"),
    ('walkers = 16', 'walkers = 17', "method.walkers"),
    ('n_sim = 50', 'n_sim = 4', "method.n_sim"),
    ('steps = 2000', 'steps = 0', "method.steps"),
    ('kind = "emcee"', 'kind = "mcmc"', "method.kind"),
    ('likelihood = "gaussian"', 'likelihood = "exact"', "method.likelihood"),
])
def test_errors_name_the_key(tmp_path, old, new, key):
    assert error_key(tmp_path, old, new) == key


def test_unknown_stat_suggests(tmp_path):
    with pytest.raises(ConfigError, match="did you mean 'nn_distance'"):
        load_with(tmp_path, '"nn_distance"]', '"nn_distanse"]')


def test_n_sim_minimum_is_k_plus_2(tmp_path):
    assert load_with(tmp_path, "n_sim = 50", "n_sim = 5").method.n_sim == 5
    assert error_key(tmp_path, "n_sim = 50", "n_sim = 4") == "method.n_sim"
    unbiased = ["method.likelihood=unbiased"]
    assert load_calibration(write(tmp_path), unbiased + ["method.n_sim=7"]).method.n_sim == 7
    with pytest.raises(ConfigError) as info:  # the unbiased estimator needs n_sim >= k + 4
        load_calibration(write(tmp_path), unbiased + ["method.n_sim=6"])
    assert info.value.key == "method.n_sim"


def test_integer_parameter_key(tmp_path):
    cfg = load_with(tmp_path, 'key = "perception.field_deg"\nprior = { dist = "uniform", low = 30, high = 360 }\n'
                              'bounds = [30, 360]',
                    'key = "n"\nprior = { dist = "uniform", low = 20, high = 101 }')
    assert cfg.parameters[0].key == "init.n"


def test_optimize_and_emulator_methods(tmp_path):
    method = VALID[VALID.index("[method]"):]
    opt = load_with(tmp_path, method, '[method]\nkind = "optimize"\nalgorithm = "nelder_mead"\n')
    assert opt.method == OptimizeSettings(n_sim=50, likelihood="gaussian", algorithm="nelder_mead",
                                          objective="loglik", maxiter=100, popsize=15, recheck=200)
    assert error_key(tmp_path, method, '[method]\nkind = "optimize"\nobjective = "l2"\n') == "method.objective"
    assert error_key(tmp_path, method, '[method]\nkind = "optimize"\nalgorithm = "bfgs"\n') == "method.algorithm"
    emu = load_with(tmp_path, method, '[method]\nkind = "emulator"\nresults = "res/holland648"\nsurrogate = "rbf"\n')
    assert isinstance(emu.method, EmulatorSettings) and emu.method.results == tmp_path / "res" / "holland648"
    assert emu.method.surrogate == "rbf" and emu.method.confirm == 100
    assert error_key(tmp_path, method, '[method]\nkind = "emulator"\n') == "method.results"
    assert error_key(tmp_path, method, '[method]\nkind = "emulator"\nresults = "r"\nwalkers = 3\n') == "method.walkers"
    assert error_key(tmp_path, method, '[method]\nkind = "emulator"\nresults = "r"\nconfirm = 1\n') == "method.confirm"
    assert error_key(tmp_path, method, '[method]\nkind = "emulator"\nresults = "r"\nmoves = "walk"\n') == "method.moves"
    assert error_key(tmp_path, method, '[method]\nkind = "optimize"\nmoves = "de"\n') == "method.moves"
    assert error_key(tmp_path, method, '[method]\nkind = "emulator"\nresults = "r"\nreevaluate_every = 5\n') \
        == "method.reevaluate_every"


def test_frozen(tmp_path):
    cfg = load_calibration(write(tmp_path))
    with pytest.raises(AttributeError):
        cfg.seed = 1
    with pytest.raises(ValueError):
        cfg.targets.observed[0, 0] = 1.0


@pytest.mark.parametrize("path", sorted((ROOT / "configs/calibration").glob("*.toml")),
                         ids=lambda p: p.stem)
def test_shipped_calibrations_are_valid(path):
    from flocksweep.analysis.calibration.config import load_calibration

    config = load_calibration(path)
    assert config.name == path.stem
    assert config.dim >= 1 and config.targets.k >= 1
    assert np.isfinite(config.prior.logpdf(np.array([m.moments[0] for m in config.prior.marginals])))
