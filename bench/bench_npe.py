"""recover_holland by neural posterior estimation (issue 25): posterior against the BSL reference, width
against simulations, held-out coverage, and 100 posteriors from one trained estimator.

    python bench/bench_npe.py [--simulations 250 500 1000] [--heldout 200] [--ensemble 1] [--out results/bench_npe]
    python bench/bench_npe.py --curve --simulations 500 1000 1500 2000 --heldout 400 --ensemble 1 5
    python bench/bench_npe.py --simulations 500 --rounds 2 --ensemble 5     # sequential rounds (TSNPE)
    python bench/bench_npe.py --simulations 500 --rounds 2 --ensemble 10 --seeds 1 2 3 4 5 \
        --set method.npe.truncation=0.01 --jsonl OUT.jsonl   # one calibration per seed, each row appended as it ends

Each budget trains its own estimator (``--set method.npe.simulations=N``) into ``OUT/N``; the training
runs are stored there as they finish, so a rerun reuses them (``--rounds R``: R truncated
sequential rounds of N each into ``OUT/N-K-rR``). ``--curve``: one training design of the
largest budget plus the held-out runs (``OUT/curve``), then for each budget N and ensemble size K an
estimator trained on its first N runs, its posterior at the targets and its coverage on the held-out
runs (the budgets share their runs: the curve is not blurred by other designs). Prints a markdown table for
bench/RESULTS.md; each row also gives its flows' training CPU (this process's user + sys around every
``train_flow``), and each training set is saved as ``OUT/<name>/flows/train-<N>.npz`` for
``bench_sbi_flow.py``. Train many flows in one process with care: each flow compiles anew and about 90
of them exhaust the process's memory maps (bench/RESULTS.md, "Sequential npe on five seeds"): run a few
seeds per process. The BSL reference (configs/calibration/recover_holland.toml, 266,000 simulations):
field median 149.0, 90% 134.2-168.0, sd 10.4; direction median 43.9, 90% 36.0-51.9, sd 4.9.
"""
from __future__ import annotations

import argparse
import json
import os
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pandas as pd

from flocksweep.analysis.calibration.config import load_calibration
from flocksweep.analysis.calibration.posterior_command import posteriors
from flocksweep.analysis.calibration.run import run_calibration

FILE = Path(__file__).resolve().parents[1] / "configs/calibration/recover_holland.toml"
REFERENCE = {"field": {"median": 149.0, "q5": 134.2, "q95": 168.0, "sd": 10.4, "truth": 150.0},
             "direction": {"median": 43.9, "q5": 36.0, "q95": 51.9, "sd": 4.9, "truth": 45.0}}


def one(budget: int, heldout: int, ensemble: int, out: Path, rounds: int = 1, seed: int | None = None,
        extra: tuple = ()) -> dict:
    sets = [f"method.npe.simulations={budget}", f"method.npe.heldout={heldout}", f"method.npe.ensemble={ensemble}",
            f"method.npe.rounds={rounds}", *([f"seed={seed}"] if seed is not None else []), *extra]
    config = load_calibration(FILE, sets, "npe")
    name = f"{budget}-{ensemble}" + (f"-r{rounds}" if rounds > 1 else "") + (f"-s{seed}" if seed is not None else "")
    flows, where = [], out / (name + "".join(f"-{e}" for e in extra))
    with timed_flows(flows, where / "flows"):
        run = run_calibration(config, where, progress=True, workers=1)
    row = {"simulations": budget, "rounds": rounds, "ensemble": ensemble, "seed": config.seed, "extra": " ".join(extra),
           "wall_s": run.report["wall_s"], "cpu_s": run.report["accounting"]["cpu_s"],
           "coverage_passed": run.convergence["converged"], "flows_trained": len(flows),
           "train_cpu_s_per_flow": float(np.mean([f["cpu_s"] for f in flows])) if flows else float("nan"),
           "train_epochs_per_flow": float(np.mean([f["epochs"] for f in flows])) if flows else float("nan"),
           "flows": flows}
    row.update({f"prior_mass_round{r['round']}": r["prior_mass"] for r in run.report["npe"].get("rounds", [])})
    row.update(against_reference(run.summary))
    for record in run.report["npe"]["coverage"]["table"]:
        row[f"cov{int(record['level'] * 100)}_{record['parameter']}"] = record["coverage"]
    return row


@contextmanager
def timed_flows(flows: list, dump: Path | None = None):
    """Each flow trained inside: its CPU seconds (this process's user + sys, JAX's threads included), wall
    seconds, simulations and epochs appended to ``flows``; ``dump``: each training set (theta and the rows
    the flow sees) also saved there as ``train-<simulations>.npz`` (for bench_sbi_flow.py)."""
    from flocksweep.analysis.calibration import npe_flow

    original = npe_flow.train_flow

    def train_flow(theta, x, settings, seed, progress=False):
        if dump is not None:
            dump.mkdir(parents=True, exist_ok=True)
            np.savez(dump / f"train-{len(theta)}.npz", theta=np.asarray(theta), x=np.asarray(x))
        cpu, wall = _cpu(), time.perf_counter()
        estimator = original(theta, x, settings, seed, progress)
        flows.append({"simulations": len(theta), "cpu_s": _cpu() - cpu, "wall_s": time.perf_counter() - wall,
                      "epochs": len(estimator.losses.get("train", []))})
        return estimator

    npe_flow.train_flow = train_flow
    try:
        yield flows
    finally:
        npe_flow.train_flow = original


def _cpu() -> float:
    times = os.times()
    return times.user + times.system


def against_reference(summary: pd.DataFrame) -> dict:
    row = {}
    for name, ref in REFERENCE.items():
        s = summary.loc[name]
        width, ref_width = s["q95"] - s["q5"], ref["q95"] - ref["q5"]
        row.update({f"{name}_median": s["median"], f"{name}_q5": s["q5"], f"{name}_q95": s["q95"],
                    f"{name}_width_ratio": width / ref_width,
                    f"{name}_median_off_sd": abs(s["median"] - ref["median"]) / ref["sd"],
                    f"{name}_truth_inside": bool(s["q5"] <= ref["truth"] <= s["q95"])})
    return row


def curve(budgets, heldout: int, ensembles, out: Path) -> list[dict]:
    """Width and coverage against simulations on one shared training sweep (module docstring)."""
    from flocksweep.analysis.calibration.npe import (NPEStream, _jax_seed, _keys, _stream, _with_noise, coverage_check,
                                                     npe_simulator, observed_row, support_of, training_design)
    from flocksweep.analysis.calibration.npe_flow import train_ensemble
    from flocksweep.analysis.calibration.training_runs import design_rows
    from flocksweep.sweeps.executors import Executor

    largest = max(budgets)
    config = load_calibration(FILE, [f"method.npe.simulations={largest}", f"method.npe.heldout={heldout}"], "npe")
    theta = training_design(config)
    with Executor("local") as pool:     # the calibration's own runs, stored as they finish (a rerun finds them)
        rows = design_rows(npe_simulator(config), theta, _keys(config, len(theta)), out / "curve", pool).rows
    x = config.transforms.apply(_with_noise(config, rows, _stream(config, NPEStream.NOISE)))
    usable = np.isfinite(x).all(axis=1)
    held = (np.arange(len(theta)) >= largest) & usable
    support = support_of(config.prior)
    rows = []
    for budget in budgets:
        train = (np.arange(len(theta)) < budget) & usable
        for members in ensembles:
            started = time.time()
            estimator = train_ensemble(theta[train], x[train], config.method.flow,
                                       _jax_seed(config, NPEStream.TRAIN), members)
            row = {"simulations": budget, "ensemble": members, "train_s": time.time() - started}
            check = coverage_check(estimator, theta[held], x[held], 199, _jax_seed(config, NPEStream.COVERAGE),
                                   support, config.method.coverage_tolerance, config.names)
            observed = config.transforms.apply(observed_row(config)[None, :])[0]
            draws = estimator.sample(observed, 4000, _jax_seed(config, NPEStream.POSTERIOR), support)
            summary = pd.DataFrame({"q5": np.quantile(draws, 0.05, axis=0), "median": np.median(draws, axis=0),
                                    "q95": np.quantile(draws, 0.95, axis=0)}, index=config.names)
            row.update(against_reference(summary), coverage_passed=check["passed"])
            for record in check["table"].itertuples():
                row[f"cov{int(record.level * 100)}_{record.parameter}"] = record.coverage
            rows.append(row)
            print(pd.DataFrame([row]).round(3).to_string(index=False), flush=True)
    return rows


def amortised(estimator: Path, flocks: int = 100) -> float:
    """Seconds for ``flocks`` posteriors (4,000 draws each) from the stored estimator, load included."""
    identity = json.loads((estimator / "identity.json").read_text())
    rng = np.random.default_rng(0)
    record = json.loads((estimator / "flow.json").read_text())
    if "members" in record:   # an ensemble: its members share the standardisation
        record = json.loads((estimator / "member0" / "flow.json").read_text())
    x = np.asarray(record["x_mean"]) + rng.normal(size=(flocks, record["k"])) * np.asarray(record["x_sd"]) * 0.5
    table = pd.DataFrame(x, columns=identity["columns"])
    started = time.time()
    posteriors(estimator, table, draws=4000, seed=1)
    return time.time() - started


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--simulations", type=int, nargs="+", default=[250, 500, 1000])
    parser.add_argument("--heldout", type=int, default=200)
    parser.add_argument("--ensemble", type=int, nargs="+", default=[1])
    parser.add_argument("--rounds", type=int, default=1, help="sequential rounds of --simulations each (TSNPE)")
    parser.add_argument("--seeds", type=int, nargs="+", default=[None], help="the calibration's seed (each its own "
                        "estimator in OUT/...-s<seed>; default the file's)")
    parser.add_argument("--set", dest="sets", action="append", default=[], help="more KEY=VALUE overrides")
    parser.add_argument("--jsonl", type=Path, help="append each calibration's row to this file as it finishes")
    parser.add_argument("--curve", action="store_true", help="one shared training sweep for every budget")
    parser.add_argument("--out", type=Path, default=Path("results/bench_npe"))
    args = parser.parse_args()
    if args.curve:
        print(pd.DataFrame(curve(args.simulations, args.heldout, args.ensemble, args.out)).round(3).to_string(index=False))
        return
    rows = []
    for seed in args.seeds:
        for budget in args.simulations:
            for members in args.ensemble:
                rows.append(one(budget, args.heldout, members, args.out, args.rounds, seed, tuple(args.sets)))
                if args.jsonl is not None:
                    with open(args.jsonl, "a") as handle:
                        handle.write(json.dumps(rows[-1], default=float) + "\n")
    table = pd.DataFrame(rows).drop(columns="flows")
    print(table.round(3).to_string(index=False))
    if args.rounds > 1:
        return    # a sequential estimator serves one flock: no amortised timing
    largest = args.out / f"{max(args.simulations)}-{args.ensemble[-1]}" / "estimator"
    print(f"100 posteriors (4,000 draws each) from {largest}: {amortised(largest):.1f} s")


if __name__ == "__main__":
    main()
