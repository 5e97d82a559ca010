"""Issue 40's recovery target on configs/calibration/recover_noise_ranges.toml: why the hand-picked statistics
leave the heading noise and the perception radius open and the observables of collective motion pin them.

    python bench/bench_recover_noise_ranges.py statistics [--points 200] [--out docs/calibration]
    python bench/bench_recover_noise_ranges.py marginals HANDPICKED_OUT OBSERVABLES_OUT [--out docs/calibration]
    python bench/bench_recover_noise_ranges.py flocks ESTIMATOR [--flocks 20] [--set run.duration=40 ...]

``statistics``: ``--points`` prior draws of the shipped file (one run each, seeds 5000 + i; the file's run
settings), every statistic of the file's 17 and of the hand-picked four measured; prints per parameter the
Spearman correlation of each statistic with it over the draws and the ratio of the between-draw variance
explained by the parameter, and draws recover_noise_ranges_statistics.png: per parameter, the hand-picked
statistic that follows it best beside the best new observable. ``marginals``: the posteriors of two
finished calibrations of the file (e.g. ``flocksweep calibrate ... --out A --set targets.stats=[four]`` and
the file as shipped ``--out B``) against the prior and the truth: recover_noise_ranges_marginals.png.
``flocks``: ``--flocks`` more flocks simulated at the truth (seeds 12, 13, ...; the file's settings with
``--set``'s overrides, which must be those the estimator was trained with), each given to the trained
``ESTIMATOR`` (amortised: no training simulation): per parameter the median, smallest and largest 90 %
width over the flocks as a fraction of the prior's, how many exceed half, and how many intervals hold
the truth. The one flock of the file is one draw of this distribution.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd

from flocksweep.analysis.calibration.config import load_calibration
from flocksweep.analysis.calibration.run import summary_simulator

FILE = Path(__file__).resolve().parents[1] / "configs/calibration/recover_noise_ranges.toml"
HANDPICKED = ("polarization_mean", "nn_distance_mean", "speed_mean_mean", "milling_mean")
LABELS = {"noise": "heading noise (deg/sqrt(s))", "cruise": "cruise speed", "separation": "separation radius",
          "range": "perception radius"}


def statistics(points: int, out: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    config = load_calibration(FILE)
    simulator = summary_simulator(config, n_sim=1)
    low = np.array([p.bounds[0] for p in config.parameters])
    high = np.array([p.bounds[1] for p in config.parameters])
    theta = low + (high - low) * np.random.default_rng(40).random((points, config.dim))
    rows = np.vstack([simulator.simulate(t, [5000 + i])[0] for i, t in enumerate(theta)])
    frame = pd.DataFrame(rows, columns=config.targets.columns)
    keep = np.isfinite(rows).all(axis=1)
    frame, theta = frame[keep].reset_index(drop=True), theta[keep]
    print(f"{keep.sum()} of {points} draws with every statistic finite")
    ranks = frame.rank()
    table = pd.DataFrame({name: ranks.corrwith(pd.Series(theta[:, j]).rank()) for j, name in enumerate(config.names)})
    print(table.round(2).to_string())
    new = [c for c in frame.columns if c not in HANDPICKED]
    fig, axes = plt.subplots(config.dim, 2, figsize=(9, 2.6 * config.dim), constrained_layout=True)
    for j, name in enumerate(config.names):
        for column, (pool, title) in enumerate(((HANDPICKED, "hand-picked"), (new, "new observable"))):
            best = table.loc[list(pool), name].abs().idxmax()
            ax = axes[j, column]
            ax.scatter(theta[:, j], frame[best], s=6, alpha=0.6)
            ax.set_xlabel(LABELS[name])
            ax.set_ylabel(best)
            ax.set_title(f"{title}: {best} (Spearman {table.loc[best, name]:+.2f})", fontsize=9)
            ax.axvline(config.targets.truth[name], color="red", lw=1)
    out.mkdir(parents=True, exist_ok=True)
    fig.savefig(out / "recover_noise_ranges_statistics.png", dpi=90)
    print(f"wrote {out / 'recover_noise_ranges_statistics.png'}")


def marginals(folders: list[Path], out: Path) -> None:
    import arviz as az
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    config = load_calibration(FILE)
    fig, axes = plt.subplots(1, config.dim, figsize=(3.2 * config.dim, 2.8), constrained_layout=True)
    for folder, label in zip(folders, ("hand-picked four", "with the new observables")):
        posterior = az.from_netcdf(folder / "posterior.nc").posterior
        for j, parameter in enumerate(config.parameters):
            draws = np.asarray(posterior[parameter.name]).ravel()
            axes[j].hist(draws, bins=40, range=parameter.bounds, density=True, histtype="step", lw=1.5, label=label)
    for j, parameter in enumerate(config.parameters):
        low, high = parameter.bounds
        axes[j].axhline(1.0 / (high - low), color="grey", ls=":", label="prior")
        axes[j].axvline(config.targets.truth[parameter.name], color="red", lw=1, label="truth")
        axes[j].set_xlabel(LABELS[parameter.name])
        axes[j].set_yticks([])
    axes[0].legend(fontsize=7)
    out.mkdir(parents=True, exist_ok=True)
    fig.savefig(out / "recover_noise_ranges_marginals.png", dpi=90)
    print(f"wrote {out / 'recover_noise_ranges_marginals.png'}")


def flocks(estimator: Path, count: int, sets: list[str]) -> None:
    from flocksweep.analysis.calibration.posterior_command import posteriors
    from flocksweep.analysis.calibration.synthetic import synthetic_observation

    config = load_calibration(FILE, sets)
    truth = config.targets.truth
    rows = [synthetic_observation(config, truth, seed=12 + i)[0] for i in range(count)]
    table = pd.DataFrame(rows, columns=config.targets.columns)
    table.insert(0, "flock", [f"seed{12 + i}" for i in range(count)])
    polarization = table["polarization_mean"]
    print(f"{count} flocks at the truth: polarization median {polarization.median():.4f}, "
          f"{(polarization > 0.99).sum()} above 0.99, smallest {polarization.min():.4f}")
    result, _ = posteriors(estimator, table, draws=4000, seed=1)
    for parameter in config.parameters:
        low, high = parameter.bounds
        name = parameter.name
        width = (result[f"{name}_q95"] - result[f"{name}_q5"]) / (high - low)
        inside = ((result[f"{name}_q5"] <= truth[name]) & (truth[name] <= result[f"{name}_q95"])).sum()
        print(f"{name:11s} 90% width / prior width: median {width.median():.2f}, {width.min():.2f}-{width.max():.2f}, "
              f"above 0.5 in {(width > 0.5).sum()} of {count}; truth inside {inside} of {count}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("what", choices=["statistics", "marginals", "flocks"])
    parser.add_argument("folders", nargs="*", type=Path)
    parser.add_argument("--points", type=int, default=200)
    parser.add_argument("--out", type=Path, default=Path("docs/calibration"))
    parser.add_argument("--flocks", type=int, default=20)
    parser.add_argument("--set", action="append", default=[], dest="sets", help="KEY=VALUE override of the file")
    args = parser.parse_args()
    if args.what == "statistics":
        statistics(args.points, args.out)
    elif args.what == "marginals":
        marginals(args.folders, args.out)
    else:
        flocks(args.folders[0], args.flocks, args.sets)


if __name__ == "__main__":
    main()
