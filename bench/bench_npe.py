"""recover_holland by neural posterior estimation (issue 25): posterior against the BSL reference, width
against simulations, held-out coverage, and 100 posteriors from one trained estimator.

    python bench/bench_npe.py [--simulations 250 500 1000] [--heldout 200] [--out results/bench_npe]

Each budget trains its own estimator (``--set method.npe.simulations=N``) into ``OUT/N``; the training
sweep's runs are content-addressed there, so a rerun reuses them. Prints a markdown table for
bench/RESULTS.md. The BSL reference (configs/calibration/recover_holland.toml, 266,000 simulations):
field median 149.0, 90% 134.2-168.0, sd 10.4; direction median 43.9, 90% 36.0-51.9, sd 4.9.
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import pandas as pd

from analysis.calibration.config import load_calibration
from analysis.calibration.posterior_command import posteriors
from analysis.calibration.run import run_calibration

FILE = Path(__file__).resolve().parents[1] / "configs/calibration/recover_holland.toml"
REFERENCE = {"field": {"median": 149.0, "q5": 134.2, "q95": 168.0, "sd": 10.4, "truth": 150.0},
             "direction": {"median": 43.9, "q5": 36.0, "q95": 51.9, "sd": 4.9, "truth": 45.0}}


def one(budget: int, heldout: int, out: Path) -> dict:
    config = load_calibration(FILE, [f"method.npe.simulations={budget}", f"method.npe.heldout={heldout}"], "npe")
    run = run_calibration(config, out / str(budget), progress=True)
    row = {"simulations": budget, "wall_s": run.report["wall_s"], "coverage_passed": run.convergence["converged"]}
    for name, ref in REFERENCE.items():
        s = run.summary.loc[name]
        width, ref_width = s["q95"] - s["q5"], ref["q95"] - ref["q5"]
        row.update({f"{name}_median": s["median"], f"{name}_q5": s["q5"], f"{name}_q95": s["q95"],
                    f"{name}_width_ratio": width / ref_width,
                    f"{name}_median_off_sd": abs(s["median"] - ref["median"]) / ref["sd"],
                    f"{name}_truth_inside": bool(s["q5"] <= ref["truth"] <= s["q95"])})
    for record in run.report["npe"]["coverage"]["table"]:
        row[f"cov{int(record['level'] * 100)}_{record['parameter']}"] = record["coverage"]
    return row


def amortised(estimator: Path, flocks: int = 100) -> float:
    """Seconds for ``flocks`` posteriors (4,000 draws each) from the stored estimator, load included."""
    identity = json.loads((estimator / "identity.json").read_text())
    rng = np.random.default_rng(0)
    record = json.loads((estimator / "flow.json").read_text())
    x = np.asarray(record["x_mean"]) + rng.normal(size=(flocks, record["k"])) * np.asarray(record["x_sd"]) * 0.5
    table = pd.DataFrame(x, columns=identity["columns"])
    started = time.time()
    posteriors(estimator, table, draws=4000, seed=1)
    return time.time() - started


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--simulations", type=int, nargs="+", default=[250, 500, 1000])
    parser.add_argument("--heldout", type=int, default=200)
    parser.add_argument("--out", type=Path, default=Path("results/bench_npe"))
    args = parser.parse_args()
    rows = [one(budget, args.heldout, args.out) for budget in args.simulations]
    table = pd.DataFrame(rows)
    print(table.round(3).to_string(index=False))
    largest = args.out / str(max(args.simulations)) / "estimator"
    print(f"100 posteriors (4,000 draws each) from {largest}: {amortised(largest):.1f} s")


if __name__ == "__main__":
    main()
