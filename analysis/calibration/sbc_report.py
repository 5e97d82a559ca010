"""The report of an SBC study (:mod:`analysis.calibration.sbc`): ranks table, uniformity tests and
figures, rebuilt from the stored datasets alone.

``write_report(out, names, datasets, draws, bins=None, alpha=0.05, seed=0, columns=None)`` reads
``datasets/<j>.json`` for j = 0..datasets-1 and writes ``ranks.csv``, ``uniformity.csv``,
``uniformity.md``, ``rank_histogram.png``, ``ecdf_diff.png`` and ``summary.json`` (atomically); it
returns ``{"out", "table", "ranks", "calibrated", "verdict", "paths"}``.

Two uniformity tests per parameter: the chi-square test of the binned rank histogram
(:func:`~analysis.calibration.diagnostics.sbc_uniformity`, ``bins`` default :func:`default_bins`, the
largest divisor of S + 1 up to 20 that keeps >= 5 expected ranks per bin) and the ECDF test
(Saeilynoja et al. 2022; :func:`ecdf_band`, :func:`ecdf_test`), whose p-value is the probability, under
uniform ranks, of a rank ECDF whose most extreme point-wise binomial tail probability is as small as
the observed one. The band's uniform rank sets come from ``generator(seed, Tag.SBC, ECDF_BAND)``
(:mod:`sweeps.seeds`). :func:`verdict`: no significant miscalibration when every p-value is at least
``alpha / (2 d)`` (Bonferroni over both tests and the d parameters).
"""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np
import pandas as pd
from scipy import stats

from flocksweep.sweeps.files import read_json, write_csv, write_json, write_text
from flocksweep.sweeps.seeds import ECDF_BAND, Tag, generator

from .accounting import total_simulations
from .diagnostics import ecdf_counts, sbc_uniformity
from .plots import ecdf_figure, sbc_figure

BAND_TRIALS = 4000          # uniform rank sets simulated for the ECDF band and test
MIN_EXPECTED_PER_BIN = 5    # default bins keep at least this many expected ranks per bin


CHAIN_FIELDS = ("tau_max", "thin", "short", "acceptance", "steps", "walkers")   # BSL's records only


def dataset_path(out: Path, j: int) -> Path:
    return Path(out) / "datasets" / f"{int(j):06d}.json"


def default_bins(draws: int, datasets: int) -> int:
    """The largest divisor of S + 1 that is at most 20 and keeps >= 5 expected ranks per bin."""
    cap = max(1, min(20, datasets // MIN_EXPECTED_PER_BIN))
    return max(b for b in range(1, cap + 1) if (draws + 1) % b == 0)


def collect(out: Path, datasets: int) -> list[dict]:
    """The records of datasets 0..datasets-1 (FileNotFoundError naming the missing ones)."""
    records = [read_json(dataset_path(out, j)) for j in range(datasets)]
    missing = [j for j, r in enumerate(records) if r is None]
    if missing:
        raise FileNotFoundError(f"{len(missing)} SBC datasets not done yet in {out}: {missing[:10]}...")
    return records


def ranks_frame(records: list[dict], names: Sequence[str], columns: Sequence[str] | None = None) -> pd.DataFrame:
    """One row per dataset: theta, rank, posterior mean and sd per parameter, the observed summaries
    (``y_<column>``, or ``y<i>_<column>`` for several observed rows), and the records' own figures: tau, thinning, acceptance (BSL), outside_support (npe)."""
    rows = []
    for r in records:
        row = {"dataset": r["dataset"]}
        for i, name in enumerate(names):
            row.update({f"theta_{name}": r["theta"][i], f"rank_{name}": r["ranks"][i],
                        f"post_mean_{name}": r["post_mean"][i], f"post_sd_{name}": r["post_sd"][i]})
        observed = np.asarray(r["observed"], dtype=float)
        labels = columns or [str(c) for c in range(observed.shape[1])]
        for i, values in enumerate(observed):
            prefix = "y" if len(observed) == 1 else f"y{i}"
            row.update({f"{prefix}_{label}": value for label, value in zip(labels, values)})
        row.update({k: r[k] for k in CHAIN_FIELDS + ("outside_support", "wall_s") if k in r})
        rows.append(row)
    return pd.DataFrame(rows).set_index("dataset")


def ecdf_points(S: int) -> np.ndarray:
    """Fractional ranks z_m = (m + 1) / (S + 1), m = 0..S-1, where the rank ECDF is evaluated."""
    return np.arange(1, S + 1) / (S + 1)


def _min_tail(counts: np.ndarray, L: int, z: np.ndarray) -> np.ndarray:
    """Smallest point-wise two-sided binomial tail probability over the evaluation points."""
    low = stats.binom.cdf(counts, L, z)
    high = stats.binom.sf(counts - 1, L, z)
    return np.minimum(1.0, 2.0 * np.minimum(low, high)).min(axis=-1)


def ecdf_band(L: int, S: int, alpha: float, rng: np.random.Generator, trials: int = BAND_TRIALS):
    """Simultaneous (1 - alpha) band for the rank ECDF of L uniform ranks on 0..S (Saeilynoja et al.
    2022, simulation method). Returns z (S,), lower (S,), upper (S,) (ECDF values) and the simulated
    minimum tail probabilities (trials,) used by :func:`ecdf_test`."""
    z = ecdf_points(S)
    sims = rng.integers(0, S + 1, size=(trials, L))
    gammas = _min_tail(ecdf_counts(sims, S), L, z)
    gamma = float(np.quantile(gammas, alpha))
    lower = stats.binom.ppf(gamma / 2, L, z) / L
    upper = stats.binom.ppf(1 - gamma / 2, L, z) / L
    return z, lower, upper, gammas


def ecdf_test(ranks, S: int, gammas: np.ndarray) -> np.ndarray:
    """p-value per parameter: share of uniform rank sets whose ECDF is at least as extreme."""
    ranks = np.asarray(ranks)
    L = ranks.shape[0]
    observed = _min_tail(ecdf_counts(ranks.T, S), L, ecdf_points(S))
    return np.array([(1 + np.sum(gammas <= g)) / (1 + gammas.size) for g in np.atleast_1d(observed)])


def _markdown(table: pd.DataFrame) -> str:
    cols = ["chi2", "dof", "p", "ecdf_p", "n", "bins"]
    lines = ["| parameter | " + " | ".join(cols) + " |", "|---" * (len(cols) + 1) + "|"]
    for name, row in table.iterrows():
        cells = [f"{row['chi2']:.2f}", f"{int(row['dof'])}", f"{row['p']:.3f}", f"{row['ecdf_p']:.3f}",
                 f"{int(row['n'])}", f"{int(row['bins'])}"]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def verdict(table: pd.DataFrame, alpha: float) -> tuple[bool, str]:
    """Calibrated unless a chi-square or ECDF p-value is below alpha / (2 d) (Bonferroni over both tests
    and the d parameters, so the chance of a false alarm is at most alpha); not judged (False) when
    there are too few datasets for two histogram bins."""
    level = alpha / (2 * len(table))
    if not table["p"].notna().all():
        return False, (f"cannot judge: {int(table['n'].iloc[0])} datasets leave a single histogram bin; "
                       f"run at least {2 * MIN_EXPECTED_PER_BIN} datasets")
    bad = [name for name, row in table.iterrows() if not (row["p"] >= level and row["ecdf_p"] >= level)]
    pvals = "; ".join(f"{n}: chi-square p = {r['p']:.3f}, ECDF p = {r['ecdf_p']:.3f}" for n, r in table.iterrows())
    where = f"level {level:.3g} = {alpha} / (2 tests x {len(table)} parameters)"
    if bad:
        return False, f"significant miscalibration for {', '.join(bad)} at {where}; {pvals}"
    return True, f"no significant miscalibration at {where}; {pvals}"


def _chain_summary(frame: pd.DataFrame) -> dict:
    """The chains' figures of BSL datasets; the estimator's support misses of npe datasets."""
    out = {}
    if "tau_max" in frame:
        out.update({"short_datasets": int(frame["short"].sum()), "tau_max_median": float(frame["tau_max"].median()),
                    "tau_max_max": float(frame["tau_max"].max()),
                    "acceptance_median": float(frame["acceptance"].median())})
    if "outside_support" in frame:
        out["outside_support_datasets"] = int(frame["outside_support"].sum())
    return out


def write_report(out, names: Sequence[str], datasets: int, draws: int, bins: int | None = None,
                 alpha: float = 0.05, seed: int = 0, columns: Sequence[str] | None = None) -> dict:
    """Ranks table, uniformity tests, figures and summary.json from the stored datasets 0..datasets-1."""
    out = Path(out)
    records = collect(out, datasets)
    frame = ranks_frame(records, names, columns)
    ranks = np.array([r["ranks"] for r in records], dtype=int)
    bins = default_bins(draws, datasets) if bins is None else int(bins)
    band = ecdf_band(datasets, draws, alpha, generator(seed, Tag.SBC, ECDF_BAND))
    table = sbc_uniformity(ranks, draws, bins, names)
    table["ecdf_p"] = ecdf_test(ranks, draws, band[3])
    calibrated, sentence = verdict(table, alpha)
    paths = {"ranks": out / "ranks.csv", "uniformity": out / "uniformity.csv",
             "uniformity_md": out / "uniformity.md", "histogram": out / "rank_histogram.png",
             "ecdf": out / "ecdf_diff.png", "summary": out / "summary.json"}
    write_csv(paths["ranks"], frame)
    write_csv(paths["uniformity"], table)
    write_text(paths["uniformity_md"], _markdown(table))
    sbc_figure(ranks, draws, bins, names, paths["histogram"])
    ecdf_figure(ranks, draws, names, band, paths["ecdf"], level=1 - alpha)
    summary = {"datasets": datasets, "draws": draws, "bins": bins, "alpha": alpha, "calibrated": calibrated,
               "verdict": sentence, "table": table.reset_index().to_dict(orient="records"),
               **_chain_summary(frame), "dataset_wall_s_median": float(frame["wall_s"].median()),
               "dataset_wall_s_total": float(frame["wall_s"].sum()),
               "simulations": total_simulations(r["simulations"] for r in records if "simulations" in r),
               "datasets_without_count": sum("simulations" not in r for r in records)}
    write_json(paths["summary"], summary)
    return {"out": out, "table": table, "ranks": frame, "calibrated": calibrated, "verdict": sentence,
            "paths": paths}
