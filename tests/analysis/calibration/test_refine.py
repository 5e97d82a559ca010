"""The emulator's sequential design (analysis.calibration.refine).

* ``select_points`` puts new points where the posterior is and the GP is uncertain (a gap in the
  training data under the posterior gets them, the first at the posterior's centre, never twice the
  same), deterministically; the RBF fallback spreads them over the posterior draws;
* ``confirmation_passed`` follows the |z| and p limits;
* ``emulator_share`` drives the stopping rule: on a toy simulator with a known exact posterior, a
  coarse design's emulated posterior is far wider than the exact one and its share large; refining
  with ``select_points`` until the share is at most 0.1 brings the emulated sd within 10 % of the
  exact sd and the mean within a quarter of it;
* end to end on a coarse real sweep: the rounds add runs to the sweep's own store (same identities),
  the training set grows by exactly those points, each round is recorded, the last round's chain is
  ``chain.h5``, and the loop stops when the confirmation passes or the rounds run out.
"""
from __future__ import annotations

import json

import h5py
import numpy as np
import pandas as pd
import pytest

from flocksweep.analysis.calibration.calibration_report import _share_lines
from flocksweep.analysis.calibration.config import calibration_from_dict
from flocksweep.analysis.calibration.emulated import emulated_logliks
from flocksweep.analysis.calibration.refine import confirmation_passed, emulator_share, select_points
from flocksweep.analysis.calibration.run import run_calibration, summary_simulator
from flocksweep.analysis.calibration.surrogates import build_surrogate
from flocksweep.analysis.calibration.training import group_replicates
from flocksweep.simcore import ConfigError
from flocksweep.cli import main
from flocksweep.sweeps.results import load_results
from flocksweep.sweeps.seeds import common_seeds
from paths import ROOT

HOLLAND = str(ROOT / "configs/models/holland.toml")


def gapped_surrogate(kind: str = "gp"):
    """1-D training set on [0, 10] with no points inside (3.5, 7.5), 4 replicates each."""
    rng = np.random.default_rng(0)
    x = np.array([0.0, 1.0, 2.0, 3.0, 3.5, 7.5, 8.0, 9.0, 10.0])
    rows = np.repeat(x, 4)[:, None]
    summaries = np.sin(rows / 2.0) + 0.05 * rng.standard_normal(rows.shape)
    return build_surrogate(group_replicates(rows, summaries, ["a"], ["s"]), kind)


def chain_around(centre: float, sd: float, steps: int = 400, walkers: int = 8) -> np.ndarray:
    rng = np.random.default_rng(1)
    return (centre + sd * rng.standard_normal((steps, walkers)))[:, :, None]


def test_new_points_go_where_the_posterior_and_the_uncertainty_are():
    surrogate = gapped_surrogate()
    picks = select_points(surrogate, chain_around(5.5, 0.8), burn=50, count=3, obs_cov=np.array([[0.01]]),
                          replicates=4)
    assert picks.shape == (3, 1)
    assert np.all((picks > 3.5) & (picks < 7.5))                   # inside the gap, under the posterior
    assert abs(picks[0, 0] - 5.5) < 0.5 and len(np.unique(picks)) == 3   # the first where both peak
    again = select_points(surrogate, chain_around(5.5, 0.8), burn=50, count=3, obs_cov=np.array([[0.01]]),
                          replicates=4)
    np.testing.assert_array_equal(again, picks)
    covered = select_points(surrogate, chain_around(1.5, 0.3), burn=50, count=4, obs_cov=None, replicates=4)
    assert np.all(np.abs(covered - 1.5) < 1.5) and len(np.unique(covered)) == 4


def test_rbf_refinement_spreads_points_over_the_posterior():
    surrogate = gapped_surrogate("rbf")
    picks = select_points(surrogate, chain_around(5.5, 0.8), burn=50, count=3, obs_cov=None, replicates=4)
    draws = chain_around(5.5, 0.8)[50:].ravel()
    assert np.all((picks >= draws.min()) & (picks <= draws.max()))
    assert np.ptp(picks) > 2.0                                     # the extremes of the posterior draws


TOY_NOISE, TOY_OBS_SD, TOY_TRUTH, TOY_REPLICATES = 0.05, 0.02, 5.5, 8
TOY_GRID = np.linspace(0.0, 10.0, 2001)


def toy_runs(x: np.ndarray, rng) -> np.ndarray:
    """A toy simulator: tanh((x - 5) / 2) plus Gaussian run-to-run noise, one row per run."""
    return np.tanh((x - 5.0) / 2.0) + TOY_NOISE * rng.standard_normal(x.shape)


def grid_moments(log_density: np.ndarray) -> tuple[float, float, np.ndarray]:
    weights = np.exp(log_density - log_density.max())
    weights /= weights.sum()
    mean = float(weights @ TOY_GRID)
    return mean, float(np.sqrt(weights @ (TOY_GRID - mean) ** 2)), weights


@pytest.mark.slow
def test_refining_until_the_emulator_share_is_small_reaches_the_exact_posterior_width():
    observed = np.tanh((np.array([TOY_TRUTH]) - 5.0) / 2.0)
    obs_cov = np.array([[TOY_OBS_SD ** 2]])
    exact_mean, exact_sd, _ = grid_moments(-0.5 * (observed[0] - np.tanh((TOY_GRID - 5.0) / 2.0)) ** 2
                                           / (TOY_NOISE ** 2 + TOY_OBS_SD ** 2))
    rng = np.random.default_rng(0)
    rows = np.repeat([0.0, 1.0, 2.0, 3.0, 3.5, 7.5, 8.0, 9.0, 10.0], TOY_REPLICATES)[:, None]
    summaries = toy_runs(rows, rng)
    history = []
    for _ in range(6):
        surrogate = build_surrogate(group_replicates(rows, summaries, ["a"], ["s"]), "gp")
        mean, sd, weights = grid_moments(emulated_logliks(TOY_GRID[:, None], observed, surrogate, obs_cov))
        draws = np.random.default_rng(1).choice(TOY_GRID, size=(400, 8), p=weights)[:, :, None]
        share = emulator_share(surrogate, draws, 0, obs_cov)
        history.append((share, mean, sd))
        if share <= 0.1:
            break
        picks = np.repeat(select_points(surrogate, draws, 0, 2, obs_cov, TOY_REPLICATES)[:, 0], TOY_REPLICATES)
        rows = np.vstack([rows, picks[:, None]])
        summaries = np.vstack([summaries, toy_runs(picks[:, None], rng)])
    first, last = history[0], history[-1]
    assert first[0] > 1.0 and first[2] > 1.3 * exact_sd        # the gap: emulator variance dominates
    assert last[0] <= 0.1 and len(history) > 1                  # the rule stopped the refinement
    assert abs(last[2] / exact_sd - 1.0) < 0.1                  # sqrt(1.1) = 1.05 plus the variance estimate's error
    assert abs(last[1] - exact_mean) < 0.25 * exact_sd


def test_confirmation_passes_only_within_the_limits():
    def check(z, p):
        return {"comparison": pd.DataFrame({"z": z}), "predictive": pd.DataFrame({"p": p})}

    assert confirmation_passed(check([0.5, -2.9], [0.3, 0.02]))
    assert not confirmation_passed(check([0.5, 3.1], [0.3, 0.5]))
    assert not confirmation_passed(check([0.5, 0.1], [0.3, 0.005]))
    assert not confirmation_passed(check([np.nan, 0.1], [0.3, 0.5]))


def test_the_verdict_reports_the_emulator_share_against_its_limit(tmp_path):
    config = calibration_from_dict(calibration(tmp_path, rounds=2, max_emulator_share=0.1), ROOT)
    settled = _share_lines(config, pd.DataFrame({"emulator_share": [0.6, 0.05]}))
    assert len(settled) == 1 and "0.05 of the likelihood's" in settled[0] and "at most about 2 %" in settled[0]
    unsettled = _share_lines(config, pd.DataFrame({"emulator_share": [0.6, 0.3]}))
    assert "still 0.3" in unsettled[0] and "more rounds" in unsettled[0]
    assert _share_lines(config, None) == [] and _share_lines(config, pd.DataFrame({"passed": [True]})) == []


COARSE_SWEEP = """
name = "coarse"
seed = 8
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
values = [2.0, 6.0, 40.0]
"""


def calibration(results, **refine) -> dict:
    return {"name": "refine", "seed": 4, "model": {"preset": HOLLAND},
            "run": {"n": 10, "duration": 2.0, "record_interval": 0.5, "warmup": 0.5},
            "parameters": {"range": {"key": "perception.range", "prior": {"dist": "uniform", "low": 2, "high": 40}}},
            "targets": {"stats": ["cohesion", "polarization"], "mean": [0.5, 0.5], "sd": [0.05, 0.05]},
            "method": {"kind": "emulator", "results": str(results), "walkers": 8, "steps": 300, "confirm": 16,
                       "refine": refine}}


def test_refine_settings_are_validated(tmp_path):
    with pytest.raises(ConfigError, match="method.refine.rounds"):
        calibration_from_dict({**calibration(tmp_path, rounds=2), "method": {
            **calibration(tmp_path)["method"], "refine": {"rounds": 2}, "confirm": 0}}, ROOT)
    with pytest.raises(ConfigError, match="method.refine.runs_per_round"):
        calibration_from_dict(calibration(tmp_path, rounds=1, runs_per_round=0), ROOT)
    with pytest.raises(ConfigError, match="method.refine.round"):
        calibration_from_dict(calibration(tmp_path, round=1), ROOT)
    with pytest.raises(ConfigError, match="method.refine.max_emulator_share.*got 0"):
        calibration_from_dict(calibration(tmp_path, rounds=1, max_emulator_share=0), ROOT)
    assert calibration_from_dict(calibration(tmp_path, rounds=1), ROOT).method.refine.max_emulator_share == 0.1


@pytest.mark.slow
def test_refinement_rounds_add_runs_to_the_sweep_until_confirmed(tmp_path):
    sweep = tmp_path / "sweep.toml"
    sweep.write_text(COARSE_SWEEP.format(preset=HOLLAND))
    results = tmp_path / "results"
    assert main(["run", str(sweep), "--out", str(results), "--executor", "serial", "--no-progress"]) == 0
    data = calibration(results, rounds=2, runs_per_round=6)
    probe = calibration_from_dict(data, ROOT)
    truth = summary_simulator(probe, n_sim=24).simulate(np.array([15.0]), common_seeds(7, 24)).mean(axis=0)
    data["targets"]["mean"] = truth.tolist()
    config = calibration_from_dict(data, ROOT)
    before = load_results(results).runs
    outcome = run_calibration(config, tmp_path / "cal", progress=False, predictive_draws=8)
    rounds = pd.read_csv(tmp_path / "cal" / "refine.csv")
    assert not rounds["passed"].iloc[0]                          # 3 coarse points: the first fit fails its check
    assert len(rounds) - 1 == (rounds["runs_added"] > 0).sum()   # every round but the last added runs
    settled = rounds["passed"] & (rounds["emulator_share"] <= 0.1)
    assert not settled.iloc[:-1].any()                           # no round stopped too early ...
    assert settled.iloc[-1] or len(rounds) == 3                  # ... nor late: settled, or out of rounds
    assert np.all(np.diff(rounds["training_points"]) == rounds["runs_added"].iloc[:-1].to_numpy() // 3)
    runs = load_results(results).runs
    assert len(runs) == len(before) + rounds["runs_added"].sum()
    assert set(before["run_id"]) < set(runs["run_id"]) and (runs["status"] == "ok").all()
    report = json.loads((tmp_path / "cal" / "convergence.json").read_text())
    assert report["refine"]["rounds_run"] == len(rounds) and report["emulator"]["training_points"] == \
        rounds["training_points"].iloc[-1]
    last = len(rounds) - 1
    with h5py.File(tmp_path / "cal" / "chain.h5", "r") as a, \
            h5py.File(tmp_path / "cal" / "rounds" / f"chain_round{last}.h5", "r") as b:
        np.testing.assert_array_equal(a["mcmc/chain"][:], b["mcmc/chain"][:])
    assert outcome.report["confirm"]["passed"] == bool(rounds["passed"].iloc[-1])
    # accounting: the refinement's runs are the rows the sweep gained (an independent count), every
    # round confirmed with 16 real runs, one predictive run per draw; the training runs reported apart
    cost = report["accounting"]["simulations"]
    assert cost["refinement"] == len(runs) - len(before)
    assert cost["confirmation"] == 16 * len(rounds) and cost["predictive"] == 8
    assert cost["total"] == cost["refinement"] + cost["confirmation"] + cost["predictive"]
    assert report["accounting"]["training_runs_reused"] == len(before)
    assert any(line.startswith("refinement:") for line in outcome.verdicts(config))
    assert any("emulator's own variance" in line for line in outcome.verdicts(config))
    assert "Refinement rounds" in (tmp_path / "cal" / "report.md").read_text()
