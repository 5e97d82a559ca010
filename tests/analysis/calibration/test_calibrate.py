"""`flocksweep calibrate` end to end on a tiny configuration: targets made by the simulator at a known
perception range, a short emcee chain, every output written (posterior.nc opened by ArviZ with the
parameter named, the report); an existing chain continued by the same command, refusals for a chain of other settings and for methods this version does not
run."""
from __future__ import annotations

import json
from pathlib import Path

import h5py
import numpy as np
import pandas as pd
import pytest

from flocksweep.analysis.calibration.config import calibration_from_dict
from flocksweep.analysis.calibration import calibrate, load_calibration_results, run_calibration
from flocksweep.analysis.calibration.inference import arviz
from flocksweep.analysis.calibration.run import summary_simulator
from flocksweep.simcore import ConfigError
from flocksweep.cli import main
from flocksweep.sweeps.seeds import common_seeds
from paths import ROOT

HOLLAND = str(ROOT / "configs/models/holland.toml")
STATS = ["cohesion", "polarization"]


def tiny(targets: dict, **method) -> dict:
    return {"name": "tiny", "seed": 4, "model": {"preset": HOLLAND},
            "run": {"n": 10, "duration": 2.0, "record_interval": 0.5, "warmup": 0.5},
            "parameters": {"range": {"key": "perception.range",
                                     "prior": {"dist": "uniform", "low": 5, "high": 40}}},
            "targets": targets,
            "method": {"kind": "emcee", "n_sim": 8, "walkers": 4, "steps": 30, **method}}


@pytest.fixture(scope="module")
def truth_targets():
    """Mean and sd of the target statistics over 24 replicates at range 20."""
    config = calibration_from_dict(tiny({"stats": STATS, "mean": [0.5, 0.5], "sd": [0.1, 0.1]}, n_sim=24), ROOT)
    sims = summary_simulator(config).simulate(np.array([20.0]), common_seeds(99, 24))
    return {"stats": STATS, "mean": sims.mean(axis=0).tolist(), "sd": (sims.std(axis=0, ddof=1) + 1e-3).tolist()}


@pytest.mark.slow
def test_calibrate_writes_posterior_diagnostics_and_figures(truth_targets, tmp_path):
    config = calibration_from_dict(tiny(truth_targets), ROOT)
    idata = calibrate(config, tmp_path / "cal", progress=False, predictive_draws=10)
    out = tmp_path / "cal"
    posterior = pd.read_csv(out / "posterior.csv", index_col=0)
    assert list(posterior.index) == ["range"]
    assert {"mean", "sd", "median", "q2.5", "q97.5", "tau", "ess", "acceptance", "r_hat", "ess_bulk", "ess_tail",
            "mcse_mean"} <= set(posterior.columns)
    burn = json.loads((out / "convergence.json").read_text())["burn"]
    assert list(idata.posterior.data_vars) == ["range"] and idata.posterior.sizes == {"chain": 4, "draw": 30 - burn}
    back = arviz().from_netcdf(str(out / "posterior.nc"))
    np.testing.assert_array_equal(back.posterior["range"].values, idata.posterior["range"].values)
    assert back.posterior["range"].attrs["key"] == "perception.range"
    assert set(back.posterior_predictive.data_vars) == {"cohesion_mean", "polarization_mean"}
    assert back.posterior_predictive.sizes["draw"] == 10 and back.prior.sizes["draw"] == 1000
    np.testing.assert_allclose(back.observed_data["cohesion_mean"].values, [truth_targets["mean"][0]])
    lp = back.sample_stats["lp"].values
    np.testing.assert_allclose(back.sample_stats["log_likelihood"].values + back.sample_stats["log_prior"].values, lp)
    assert back.sample_stats["walker_acceptance"].values == pytest.approx(posterior.loc["range", "acceptance"] *
                                                                           np.ones(4), abs=0.5)
    summary = arviz().summary(back)
    assert summary.loc["range", "r_hat"] == pytest.approx(posterior.loc["range", "r_hat"], abs=0.01)
    assert load_calibration_results(out).posterior["range"].shape == (4, 30 - burn)
    for name in ("report.html", "report.md", "rank.png"):
        assert (out / name).stat().st_size > 1000, name
    assert "verdict" in (out / "report.md").read_text().lower()
    assert 5 <= posterior.loc["range", "q2.5"] <= posterior.loc["range", "q97.5"] <= 40
    check = pd.read_csv(out / "predictive.csv", index_col=0)
    assert list(check.index) == ["cohesion_mean", "polarization_mean"]
    assert check["p"].between(0, 1).all()
    for name in ("trace.png", "corner.png", "predictive.png", "chain.h5"):
        assert (out / name).stat().st_size > 1000, name
    report = json.loads((out / "convergence.json").read_text())
    assert report["steps"] == 30 and report["walkers"] == 4 and report["convergence"]["messages"]
    assert {"rhat_ok", "ess_ok", "rhat_max", "ess_bulk_min"} <= set(report["convergence"])
    assert not report["convergence"]["converged"]                 # 30 steps: too short, and the report says so
    assert posterior.loc["range", "acceptance"] > 0


@pytest.mark.slow
def test_an_existing_chain_is_continued_never_replaced_and_resume_extends_it(truth_targets, tmp_path):
    config = calibration_from_dict(tiny(truth_targets, steps=10), ROOT)
    calibrate(config, tmp_path / "c", progress=False, predictive_draws=4)
    def stored():
        with h5py.File(tmp_path / "c" / "chain.h5", "r") as f:
            return f["mcmc"].attrs["iteration"], f["mcmc"]["chain"][...]
    steps, chain = stored()
    calibrate(config, tmp_path / "c", progress=False, predictive_draws=4)   # the same command: nothing to add
    again = stored()
    assert again[0] == steps == 10 and np.array_equal(again[1], chain)
    other = calibration_from_dict({**tiny(truth_targets, steps=10), "seed": 5}, ROOT)
    with pytest.raises(ConfigError) as info:
        calibrate(other, tmp_path / "c", progress=False)
    assert info.value.key == "--resume" and "bsl_seed: stored 4, now 5" in str(info.value)
    longer = calibration_from_dict(tiny(truth_targets, steps=16), ROOT)
    calibrate(longer, tmp_path / "c", resume=True, progress=False, predictive_draws=4)
    assert json.loads((tmp_path / "c" / "convergence.json").read_text())["steps"] == 16


@pytest.mark.slow
def test_optimize_finds_the_range_and_rechecks_it(truth_targets, tmp_path):
    data = tiny(truth_targets)
    data["method"] = {"kind": "optimize", "n_sim": 8, "maxiter": 5, "popsize": 4, "recheck": 16}
    result = run_calibration(calibration_from_dict(data, ROOT), tmp_path / "o", progress=False)
    optimum = json.loads((tmp_path / "o" / "optimum.json").read_text())
    assert 5 <= optimum["theta"]["range"] <= 40
    assert np.isfinite(optimum["objective_common_seeds"]) and np.isfinite(optimum["objective_recheck"])
    assert result.predictive["p"].between(0, 1).all()
    assert not (tmp_path / "o" / "chain.h5").exists()
    idata = load_calibration_results(tmp_path / "o")       # no posterior: the optimum and its re-check runs
    assert float(idata.constant_data["optimum_range"]) == pytest.approx(optimum["theta"]["range"])
    assert idata.posterior_predictive.sizes["draw"] == 16 and "posterior" not in idata.groups()
    assert (tmp_path / "o" / "report.html").exists()


@pytest.mark.slow   # over half a second of CPU: out of the quick loop (CI runs it)
def test_optimize_distance_objective_with_nelder_mead(truth_targets, tmp_path):
    data = tiny(truth_targets)
    data["method"] = {"kind": "optimize", "n_sim": 8, "algorithm": "nelder_mead", "objective": "distance",
                      "maxiter": 15, "recheck": 16}
    calibrate(calibration_from_dict(data, ROOT), tmp_path / "o", progress=False)
    optimum = json.loads((tmp_path / "o" / "optimum.json").read_text())
    assert optimum["settings"]["objective"] == "distance" and 5 <= optimum["theta"]["range"] <= 40
    assert 0 <= optimum["objective_common_seeds"] < 20      # a sum of 2 squared z-scores near the fit


EMULATOR_SWEEP = """
name = "emu_sweep"
seed = 5
replicates = 3
[model]
preset = "{preset}"
[run]
n = 10
duration = 2.0
record_interval = 0.5
warmup = 0.5
[[axes]]
key = "perception.range"
values = [5.0, 10.0, 15.0, 20.0, 25.0, 30.0, 40.0]
"""


@pytest.fixture(scope="module")
def emulator_sweep(tmp_path_factory):
    folder = tmp_path_factory.mktemp("emu")
    path = folder / "sweep.toml"
    path.write_text(EMULATOR_SWEEP.format(preset=HOLLAND))
    assert main(["run", str(path), "--out", str(folder / "results"), "--executor", "serial",
                 "--no-progress"]) == 0
    return folder / "results"


@pytest.mark.slow
def test_emulator_method_end_to_end(truth_targets, emulator_sweep, tmp_path):
    data = tiny(truth_targets)
    data["method"] = {"kind": "emulator", "results": str(emulator_sweep), "walkers": 8, "steps": 400,
                      "confirm": 24}
    result = run_calibration(calibration_from_dict(data, ROOT), tmp_path / "emu", progress=False, predictive_draws=12)
    out = tmp_path / "emu"
    posterior = pd.read_csv(out / "posterior.csv", index_col=0)
    assert posterior.loc["range", "q5"] <= 20.0 <= posterior.loc["range", "q95"], posterior.loc["range"].to_dict()
    assert posterior.loc["range", "sd"] < 0.6 * 35 / np.sqrt(12)          # narrower than the U(5, 40) prior
    comparison = pd.read_csv(out / "confirm.csv", index_col=0)
    assert list(comparison.index) == ["cohesion_mean", "polarization_mean"]
    assert (comparison["n_real"] == 24).all() and np.isfinite(comparison["z"]).all()
    report = json.loads((out / "convergence.json").read_text())
    assert report["method"] == "emulator" and report["emulator"]["training_points"] == 7
    assert report["emulator"]["training_runs"] == 21 and report["confirm"]["messages"]
    assert not any("beyond the swept range" in w for w in report["warnings"])   # box = prior support [5, 40]
    for name in ("trace.png", "corner.png", "predictive.png", "chain.h5"):
        assert (out / name).stat().st_size > 1000, name
    assert result.confirm["theta"]["range"] == pytest.approx(posterior.loc["range", "median"], rel=0.05)
    assert report["confirm"]["passed"] == (report["confirm"]["messages"][0].startswith("confirmed"))


def test_emulator_refuses_a_missing_results_folder(truth_targets, tmp_path):
    data = tiny(truth_targets)
    data["method"] = {"kind": "emulator", "n_sim": 8, "results": str(tmp_path / "nowhere")}
    with pytest.raises(ConfigError, match="method.results"):
        calibrate(calibration_from_dict(data, ROOT), tmp_path / "o", progress=False)
    assert not (tmp_path / "o" / "chain.h5").exists()


@pytest.mark.slow
def test_calibrate_cli(truth_targets, tmp_path, capsys):
    path = tmp_path / "cal.toml"
    lines = ['name = "cli"', "seed = 4", "[model]", f'preset = "{HOLLAND}"',
             "[run]", "n = 10", "duration = 2.0", "record_interval = 0.5", "warmup = 0.5",
             "[parameters.range]", 'key = "perception.range"', 'prior = { dist = "uniform", low = 5, high = 40 }',
             "[targets]", f"stats = {json.dumps(STATS)}", f"mean = {truth_targets['mean']}",
             f"sd = {truth_targets['sd']}", "[method]", 'kind = "emcee"', "n_sim = 8", "walkers = 4",
             "steps = 8"]
    path.write_text("\n".join(lines) + "\n")
    assert main(["calibrate", str(path), "--out", str(tmp_path / "o"), "--no-progress"]) == 0
    printed = capsys.readouterr().out
    assert "range" in printed and "verdict: NOT converged" in printed and "report.html" in printed
    assert main(["calibrate", str(path), "--set", "method.walkers=3", "--out", str(tmp_path / "p")]) == 2
    assert "method.walkers" in capsys.readouterr().err


@pytest.mark.slow
def test_local_workers_give_the_serial_chain_and_outputs(truth_targets, tmp_path):
    import h5py

    config = calibration_from_dict(tiny(truth_targets, steps=6), ROOT)
    serial = run_calibration(config, tmp_path / "serial", progress=False, predictive_draws=6)
    pooled = run_calibration(config, tmp_path / "pooled", progress=False, predictive_draws=6, executor="local",
                             workers=2)
    chains = []
    for name in ("serial", "pooled"):
        with h5py.File(tmp_path / name / "chain.h5", "r") as f:
            chains.append(np.array(f["mcmc/chain"]))
    np.testing.assert_array_equal(chains[0], chains[1])
    pd.testing.assert_frame_equal(serial.predictive, pooled.predictive)
    assert "2 processes" in pooled.report["executor"]
