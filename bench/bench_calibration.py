"""Calibration costs: one synthetic-likelihood evaluation, the emulator's fit and chain, a whole calibration.

    python bench/bench_calibration.py [--config configs/calibration/recover_holland.toml] [--repeats 5]
    python bench/bench_calibration.py --emulator configs/calibration/emulator_holland.toml
    python bench/bench_calibration.py --whole configs/calibration/recover_holland.toml   # the full run, once

* evaluation: ``n_sim`` replicates of the calibration's model at the prior mean plus the Gaussian
  synthetic log-likelihood, in this process (kernels already loaded), median over ``--repeats`` x 5 calls;
* emulator: ``training_set`` + ``build_surrogate`` (fit), then ``method.steps`` emcee steps on it;
* whole: ``flocksweep calibrate`` as a new process with the file's defaults, wall time.
"""
from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent


def evaluation(path: str, repeats: int) -> None:
    from flocksweep.analysis.calibration.config import load_calibration
    from flocksweep.analysis.calibration.likelihood import synthetic_loglik
    from flocksweep.analysis.calibration.run import simulate_fn, summary_simulator

    config = load_calibration(path)
    fn = simulate_fn(config, summary_simulator(config))
    theta = np.array([m.moments[0] for m in config.prior.marginals])
    rng = np.random.default_rng(0)
    fn(theta, rng)   # load the kernels
    times = []
    for _ in range(repeats * 5):
        start = time.perf_counter()
        synthetic_loglik(config.targets.observed, fn(theta, rng))
        times.append(time.perf_counter() - start)
    n_sim = config.method.n_sim
    print(f"{config.name}: one evaluation ({n_sim} runs) {1e3 * statistics.median(times):.0f} ms median "
          f"(min {1e3 * min(times):.0f}, max {1e3 * max(times):.0f}; {len(times)} calls)")


def emulator(path: str) -> None:
    from flocksweep.analysis.calibration.config import load_calibration
    from flocksweep.analysis.calibration.emulated import observation_covariance, run_emulator_mcmc
    from flocksweep.analysis.calibration.surrogates import build_surrogate
    from flocksweep.analysis.calibration.training import training_set

    config = load_calibration(path)
    settings = config.method
    start = time.perf_counter()
    training = training_set(settings.results, config)
    loaded = time.perf_counter()
    surrogate = build_surrogate(training, settings.surrogate)
    fitted = time.perf_counter()
    run_emulator_mcmc(surrogate, config.targets.observed, observation_covariance(config), config.prior,
                      walkers=settings.walkers, steps=settings.steps, seed=config.seed)
    done = time.perf_counter()
    print(f"{config.name}: load {loaded - start:.1f} s, fit ({settings.surrogate}, {len(training.points)} points) "
          f"{fitted - loaded:.1f} s, chain {settings.walkers} x {settings.steps} {done - fitted:.1f} s")


def whole(path: str) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        subprocess.run([sys.executable, "-m", "flocksweep.cli", "calibrate", path, "--out", tmp, "--no-progress"],
                       cwd=ROOT, check=True)
        print(f"{path}: whole calibration {time.perf_counter() - start:.0f} s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="configs/calibration/recover_holland.toml")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--emulator", metavar="CALIB", help="time the emulator method's fit and chain")
    parser.add_argument("--whole", metavar="CALIB", help="time a whole calibration (new process)")
    args = parser.parse_args()
    if args.emulator:
        emulator(args.emulator)
    elif args.whole:
        whole(args.whole)
    else:
        evaluation(args.config, args.repeats)


if __name__ == "__main__":
    main()
