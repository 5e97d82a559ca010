"""Calibrations that never crash and never lose work: every method with one free parameter ends with its
report (a one-parameter corner plot once ended emcee in a traceback); held-out simulations outside an
estimator's support are counted and left out; an estimator with no posterior at the targets is a verdict;
the run's accounting is on disk before anything can fail, a failure mid-run says where it stopped, and the
same command resumes without redoing finished work."""
from __future__ import annotations

import json

import numpy as np
import pytest

from flocksweep.analysis.calibration.config import calibration_from_dict
from flocksweep.analysis.calibration.npe import coverage_check
from flocksweep.analysis.calibration.npe_flow import OutsideSupport
from flocksweep.analysis.calibration.run import run_calibration
from flocksweep.sweeps.config import load_sweep
from flocksweep.sweeps.runner import run_sweep
from paths import ROOT

HOLLAND = str(ROOT / "configs" / "models" / "holland.toml")
RUN = {"n": 6, "duration": 1.5, "record_interval": 0.5, "warmup": 0.5}
SWEEP = f'''name = "one_parameter"
seed = 2
replicates = 2
[model]
preset = "{HOLLAND}"
[run]
n = 6
duration = 1.5
record_interval = 0.5
warmup = 0.5
[[axes]]
key = "perception.field_deg"
values = [120.0, 180.0, 240.0, 300.0]
'''


def one_parameter(method: dict) -> dict:
    return {"name": "one", "seed": 3, "model": {"preset": HOLLAND}, "run": dict(RUN),
            "parameters": {"field": {"key": "perception.field_deg",
                                     "prior": {"dist": "uniform", "low": 120, "high": 300}}},
            "targets": {"stats": ["polarization", "visible_mean"], "mean": [0.8, 2.0], "sd": [0.1, 0.5],
                        "truth": {"field": 200}},
            "method": method}


@pytest.fixture(scope="module")
def sweep(tmp_path_factory):
    folder = tmp_path_factory.mktemp("one_parameter_sweep")
    (folder / "s.toml").write_text(SWEEP)
    run_sweep(load_sweep(folder / "s.toml"), SWEEP, folder / "out", executor="serial", progress=False)
    return folder / "out"


@pytest.mark.slow
@pytest.mark.parametrize("method", ["emcee", "optimize", "npe", "emulator"])
def test_every_method_with_one_free_parameter_ends_with_its_report(method, sweep, tmp_path):
    if method == "npe":
        pytest.importorskip("flowjax", reason="the sbi extra (pip install -e '.[sbi]')")
    settings = {"emcee": {"kind": "emcee", "n_sim": 4, "walkers": 4, "steps": 3},
                "optimize": {"kind": "optimize", "n_sim": 4, "popsize": 2, "maxiter": 1, "recheck": 4},
                "npe": {"kind": "npe", "simulations": 20, "heldout": 10, "draws": 200,
                        "flow": {"width": 8, "layers": 1, "max_epochs": 5, "patience": 2}},
                "emulator": {"kind": "emulator", "results": str(sweep), "n_sim": 4, "walkers": 4, "steps": 20,
                             "confirm": 2}}[method]
    out = tmp_path / "out"
    result = run_calibration(calibration_from_dict(one_parameter(settings), ROOT), out, progress=False,
                             predictive_draws=4)
    assert (out / "report.html").is_file() and (out / "report.md").is_file()
    report = json.loads((out / ("optimum.json" if method == "optimize" else "convergence.json")).read_text())
    assert report["verdict"].startswith(("credible", "NOT credible"))
    if method != "optimize":
        assert (out / "corner.png").is_file() and list(result.summary.index) == ["field"]
    assert not [w for w in result.warnings if "was not drawn" in w]
    assert json.loads((out / "accounting.json").read_text())["status"] == "done"


class Narrow:
    """A stand-in estimator: its posterior at x is N(x, 0.1^2), so a statistic outside [0, 10] has almost no
    mass inside a prior of [0, 10]."""

    last_leakage = 0.0

    def sample_many(self, x, count, seed, support=None, short="raise"):
        draws = np.random.default_rng(seed).normal(np.asarray(x)[:, None, :1], 0.1, (len(x), count, 1))
        bad = ~support(draws.reshape(-1, 1)).reshape(draws.shape[:2]).all(axis=1)
        if bad.any() and short != "nan":
            raise OutsideSupport("no mass inside")
        draws[bad] = np.nan
        return draws


def test_heldout_simulations_outside_the_support_are_counted_and_left_out():
    theta = np.linspace(0.5, 9.5, 40)[:, None]
    x = theta.copy()
    x[3] = 50.0                                        # one held-out simulation far outside the training set
    inside = lambda t: np.all((t >= 0) & (t <= 10), axis=1)     # noqa: E731
    check = coverage_check(Narrow(), theta, x, draws=99, seed=1, support=inside, tolerance=0.05, names=["a"])
    assert check["excluded"] == 1 and check["heldout"] == 39
    assert any("1 of 40 held-out simulations were left out" in m for m in check["messages"])
    x[:5] = 50.0                                       # 5 of 40 (12%): more than 5% fails the check
    assert not coverage_check(Narrow(), theta, x, draws=99, seed=1, support=inside, tolerance=0.05,
                              names=["a"])["passed"]


def test_an_estimator_without_mass_at_the_targets_is_a_verdict_not_a_traceback(tmp_path, monkeypatch):
    from flocksweep.analysis.calibration import npe as npe_module
    from flocksweep.analysis.calibration.outcome import NoPosterior

    def no_posterior(*args, **kwargs):
        raise NoPosterior("the estimator gives no posterior at the observed statistics: test",
                          {"npe": {"training_simulations": 20}})
    monkeypatch.setattr(npe_module, "run_npe", no_posterior)
    data = one_parameter({"kind": "npe", "simulations": 20, "heldout": 10})
    result = run_calibration(calibration_from_dict(data, ROOT), tmp_path / "out", progress=False)
    report = json.loads((tmp_path / "out" / "convergence.json").read_text())
    assert not report["credible"] and "no posterior at the observed statistics" in report["verdict"]
    assert report["npe"] == {"training_simulations": 20} and result.idata is None
    assert (tmp_path / "out" / "report.html").is_file()


@pytest.mark.slow
def test_a_failure_mid_run_writes_where_it_stopped_and_the_same_command_goes_on(tmp_path, monkeypatch):
    pytest.importorskip("flowjax", reason="the sbi extra (pip install -e '.[sbi]')")
    from flocksweep.analysis.calibration import posterior_outputs

    data = one_parameter({"kind": "npe", "simulations": 20, "heldout": 10, "draws": 200,
                          "flow": {"width": 8, "layers": 1, "max_epochs": 5, "patience": 2}})
    config = calibration_from_dict(data, ROOT)
    out = tmp_path / "out"
    real = posterior_outputs.predictive_runs

    def broken(*args, **kwargs):
        raise RuntimeError("the disk of the predictive runs")
    monkeypatch.setattr(posterior_outputs, "predictive_runs", broken)
    with pytest.raises(RuntimeError, match="the disk of the predictive runs"):
        run_calibration(config, out, progress=False, predictive_draws=4)
    stopped = json.loads((out / "accounting.json").read_text())
    assert stopped["status"] == "failed" and "predictive" in stopped["phase"]
    assert stopped["accounting"]["simulations"] == {"training": 20, "heldout": 10, "total": 30}
    assert "RuntimeError: the disk of the predictive runs" in stopped["error"]
    assert "run the same command again" in stopped["resume"]
    monkeypatch.setattr(posterior_outputs, "predictive_runs", real)
    run_calibration(config, out, progress=False, predictive_draws=4)
    again = json.loads((out / "convergence.json").read_text())
    assert again["npe"]["reused"] and "training" not in again["accounting"]["simulations"]   # nothing redone
    assert again["accounting"]["training_runs_reused"] == 10 and again["accounting"]["simulations"]["predictive"] == 4
