"""Honest accounting: the simulations a calibration reports, by phase, against an independent count (the
simulator's batch call, wrapped), on tiny calibrations of the shipped recovery file."""
from __future__ import annotations

import json

import pytest

import flocksweep.analysis.calibration.simulator as simulator_module
from flocksweep.analysis.calibration.accounting import Accounting, lines
from flocksweep.cli import main
from paths import ROOT

SHIPPED = str(ROOT / "configs/calibration/recover_holland.toml")
TINY = ["--no-progress", "--set", "method.kind=emcee", "--set", "run.n=6", "--set", "run.duration=2.5", "--set", "method.n_sim=6"]


@pytest.fixture
def counted(monkeypatch):
    """Every run the calibration simulates in this process (the serial executor), counted at the batch call."""
    runs = []
    batch = simulator_module.simulate_batch

    def counting(model, init, seeds, *args, **kwargs):
        runs.append(len(seeds))
        return batch(model, init, seeds, *args, **kwargs)

    monkeypatch.setattr(simulator_module, "simulate_batch", counting)
    return runs


def test_accounting_counts_by_phase_and_rejects_unknown_phases():
    cost = Accounting()
    cost.add("search", 12, 2)
    cost.add("search", 6, 1)
    cost.add("predictive", 5)
    block = cost.block(resumed_from=40)
    assert block["simulations"] == {"search": 18, "predictive": 5, "total": 23}
    assert block["likelihood_evaluations"] == {"search": 3, "total": 3}
    assert block["wall_s"] >= 0 and block["resumed_from"] == 40
    assert lines(block)[0].startswith("cost: 23 simulations (search 18, predictive 5), 3 likelihood evaluations")
    assert "step 40" in lines(block)[1]
    with pytest.raises(ValueError, match="phase"):
        cost.add("warmup", 1)


@pytest.mark.slow
def test_emcee_accounting_matches_the_simulator_and_the_schedule(tmp_path, counted, capsys):
    out = tmp_path / "emcee"
    steps, walkers, every = 5, 8, 2
    assert main(["calibrate", SHIPPED, "--out", str(out), *TINY, "--set", f"method.emcee.steps={steps}",
                 "--set", f"method.emcee.reevaluate_every={every}", "--set", "method.emcee.until_converged=false"]) == 0
    report = json.loads((out / "convergence.json").read_text())
    cost = report["accounting"]
    sims = cost["simulations"]
    assert sims["total"] == sum(counted)                  # the independent count
    assert sims["predictive"] == min(100, (steps - report["burn"]) * walkers)   # one run per posterior draw
    # re-evaluations happen before rows 2 and 4: 2 x walkers evaluations of n_sim runs
    assert sims["reevaluation"] == ((steps - 1) // every) * walkers * 6
    assert cost["likelihood_evaluations"]["reevaluation"] == ((steps - 1) // every) * walkers
    assert sims["initial"] >= walkers * 6 and sims["initial"] % 6 == 0
    # every proposal inside the prior is one evaluation of n_sim runs; at most walkers per step
    assert 0 < sims["search"] <= steps * walkers * 6 and sims["search"] == 6 * cost["likelihood_evaluations"]["search"]
    assert sims["total"] == sims["initial"] + sims["search"] + sims["reevaluation"] + sims["predictive"]
    assert cost["wall_s"] > 0
    assert f"cost: {sims['total']:,} simulations" in capsys.readouterr().out
    assert "Simulations run by this calibration" in (out / "report.md").read_text()


@pytest.mark.slow
def test_optimize_reports_simulations_and_optimizer_evaluations(tmp_path, counted, capsys):
    out = tmp_path / "opt"
    assert main(["calibrate", SHIPPED, "--method", "optimize", "--out", str(out), *TINY,
                 "--set", "method.optimize.maxiter=2", "--set", "method.optimize.popsize=3",
                 "--set", "method.optimize.recheck=12"]) == 0
    optimum = json.loads((out / "optimum.json").read_text())
    cost = optimum["accounting"]
    assert "evaluations" not in optimum and optimum["optimizer_evaluations"] == cost["optimizer_evaluations"]
    assert cost["simulations"]["total"] == sum(counted)   # the independent count
    assert cost["simulations"]["recheck"] == 12 and cost["likelihood_evaluations"]["recheck"] == 2
    search = cost["likelihood_evaluations"]["search"]
    assert cost["simulations"]["search"] == 6 * search
    # scipy's count (outside-the-prior trials included, the final value at the optimum not) against ours
    assert search <= optimum["optimizer_evaluations"] + 1
    assert "cost:" in capsys.readouterr().out
