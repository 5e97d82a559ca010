"""The measurement error a tracker adds to each statistic of a comparison or calibration file: the `sd`
of its [targets] block, measured rather than guessed.

    python bench/tracker_error.py configs/compare/perception_tracks.toml --truth field=150 --truth direction=45
        [--model metric] [--replicates 40] [--detection 0.95] [--position-sd 0.02]

The file's first model (or ``--model``) at the given truth, with the comparison's [run] keys, is simulated
``--replicates`` times (seeds 0, 1, ...). Each run's statistics are measured twice: exactly (the
simulator's records) and as a tracker delivers them (:func:`observables.observation.observe_run`: samples at
the record interval, each detected with probability ``--detection``, Gaussian position noise of sd
``--position-sd`` length units on every coordinate, gaps bridged, velocities differenced over one
interval, or over ``--velocity-interval`` s, or the tracker's own velocities with ``recorded``). Printed per
statistic: the mean exact value, its sd over the replicates (the flock's own
variation, which the simulations already hold), the mean and the sd of the tracker's error (observed -
exact) and their root mean square, and then an ``sd = [...]`` line: the root mean square error, at least
5 % of the replicate sd (a statistic the tracker measures exactly still gets a small, non-zero error).
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from flocksweep.observables.observation import Observation, observe_run
from flocksweep.observables.summary import summarize_run
from flocksweep.simcore import simulate


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("config", type=Path, help="a comparison file (or a calibration file)")
    parser.add_argument("--truth", action="append", default=[], metavar="NAME=VALUE")
    parser.add_argument("--model", default=None, help="the comparison's model (default: its first)")
    parser.add_argument("--replicates", type=int, default=40)
    parser.add_argument("--detection", type=float, default=0.95)
    parser.add_argument("--position-sd", type=float, default=0.02)
    parser.add_argument("--velocity-interval", default=None,
                        help='seconds to difference positions over (default: one interval), or "recorded" (the '
                             "tracker's own velocities: the simulator's, exact)")
    args = parser.parse_args()
    text = args.config.read_text()
    if "[models]" in text:
        from flocksweep.analysis.calibration.compare import load_comparison
        models = dict(load_comparison(args.config).models)
        config = models[args.model] if args.model else next(iter(models.values()))
    else:
        from flocksweep.analysis.calibration.config import load_calibration
        config = load_calibration(args.config)
    truth = dict(item.split("=", 1) for item in args.truth)
    theta = np.array([float(truth[name]) for name in config.names])
    from flocksweep.analysis.calibration.run import summary_simulator
    preset = summary_simulator(config, n_sim=1).preset(theta)
    run = preset.run
    settings = config.metrics.resolve(preset.model)
    velocity = args.velocity_interval
    velocity = float(velocity) if velocity not in (None, "recorded") else velocity
    observation = Observation(interval=run.record_every * run.dt, detection_probability=args.detection,
                              position_sd=args.position_sd, velocity_interval=velocity)
    columns = list(config.targets.columns)
    exact, seen = [], []
    for seed in range(args.replicates):
        obs = simulate(preset.model, preset.init, seed, run.duration, run.dt, run.record_every)
        exact.append([summarize_run(obs, settings)[c] for c in columns])
        seen.append([summarize_run(observe_run(obs, observation, seed), settings)[c] for c in columns])
    exact, seen = np.array(exact), np.array(seen)
    error = seen - exact
    with np.errstate(invalid="ignore"):
        rms = np.sqrt(np.nanmean(np.where(np.isfinite(error), error ** 2, np.nan), axis=0))
    spread = np.nanstd(exact, axis=0)
    sd = np.maximum(rms, 0.05 * spread)
    sd = np.where(sd > 0, sd, 1e-3)
    print(f"{config.name}: truth {truth}; {args.replicates} replicates, {observation.describe()}")
    print("| statistic | exact mean | replicate sd | tracker error mean | error sd | rms error | target sd |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for k, column in enumerate(columns):
        print(f"| {column} | {np.nanmean(exact[:, k]):.4g} | {spread[k]:.3g} | {np.nanmean(error[:, k]):.3g} | "
              f"{np.nanstd(error[:, k]):.3g} | {rms[k]:.3g} | {sd[k]:.3g} |")
    print("sd = [" + ", ".join(f"{v:.3g}" for v in sd) + "]")


if __name__ == "__main__":
    main()
