"""Bit-for-bit comparison of two result folders: a sweep's (runs.parquet and its time series) or a
calibration's (chain.h5 and posterior.csv). For checking that a change of code left results alone.

    python bench/compare_results.py BASELINE_DIR NEW_DIR [BASELINE_DIR NEW_DIR ...]

Sweeps: the same run ids in the same order, and every column of the baseline except the timing ones
(``wall_s``, ``sim_s``, ``part``) equal exactly (NaN equal to NaN); the time series of every run equal
exactly in the baseline's columns. Columns only the new folder has (a metric added since the baseline)
are allowed and listed; a baseline column missing from the new folder is a difference.
Calibrations: the chain, log-probabilities and acceptance counts in ``chain.h5`` equal exactly, and
``posterior.csv`` byte for byte, or else every column of the baseline's exactly (columns added since,
e.g. ArviZ's R-hat and ESS, are listed). Prints one line per pair; exit status 1 when any pair differs.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd

from flocksweep.observables.summary import ENCOUNTER_FAMILIES, summary_columns

TIMING = ("wall_s", "sim_s", "part")


def _timeseries(folder: Path) -> pd.DataFrame:
    frames = [pd.read_parquet(p) for p in sorted((folder / "timeseries").glob("part-*.parquet"))]
    table = pd.concat(frames, ignore_index=True)
    return table.sort_values(["run_id", "t"], kind="stable").reset_index(drop=True)


def compare_sweep(old: Path, new: Path) -> str:
    a, b = pd.read_parquet(old / "runs.parquet"), pd.read_parquet(new / "runs.parquet")
    if list(a["run_id"]) != list(b["run_id"]):
        return "run ids differ"
    missing = [c for c in a.columns if c not in b.columns]
    if missing:
        return f"columns missing from the new table: {missing}"
    keep = [c for c in a.columns if c not in TIMING]
    pd.testing.assert_frame_equal(a[keep], b[keep], check_exact=True)
    ta, tb = _timeseries(old), _timeseries(new)
    missing_ts = [c for c in ta.columns if c not in tb.columns]
    if missing_ts:
        return f"time-series columns missing from the new folder: {missing_ts}"
    pd.testing.assert_frame_equal(ta, tb[list(ta.columns)], check_exact=True)
    metrics = [c for c in keep if c in set(summary_columns(leadership=True, migration=True, encounters=ENCOUNTER_FAMILIES))]
    added = [c for c in b.columns if c not in a.columns] + [f"series:{c}" for c in tb.columns if c not in ta.columns]
    return (f"identical: {len(a)} runs, same run ids, {len(metrics)} metric columns and {len(keep)} columns "
            f"in all bit for bit, {len(ta)} time-series rows bit for bit"
            + (f"; new columns (not in the baseline): {', '.join(added)}" if added else ""))


def compare_calibration(old: Path, new: Path) -> str:
    import h5py

    with h5py.File(old / "chain.h5", "r") as fa, h5py.File(new / "chain.h5", "r") as fb:
        for name in ("chain", "log_prob", "accepted"):
            x, y = fa["mcmc"][name][()], fb["mcmc"][name][()]
            if x.shape != y.shape or not np.array_equal(x, y, equal_nan=True):
                return f"{name} differs"
        shape = fa["mcmc"]["chain"].shape
    if (old / "posterior.csv").read_bytes() == (new / "posterior.csv").read_bytes():
        return f"identical: chain {shape} (steps, walkers, d), log_prob and acceptance bit for bit; posterior.csv byte for byte"
    a, b = pd.read_csv(old / "posterior.csv", index_col=0), pd.read_csv(new / "posterior.csv", index_col=0)
    if not set(a.columns) <= set(b.columns):
        return f"posterior.csv differs: columns {sorted(set(a.columns) - set(b.columns))} missing"
    pd.testing.assert_frame_equal(a, b[a.columns], check_exact=True)
    added = [c for c in b.columns if c not in a.columns]
    return (f"identical: chain {shape} (steps, walkers, d), log_prob and acceptance bit for bit; posterior.csv's "
            f"{len(a.columns)} columns exactly (new columns {added})")


def main(argv: list[str]) -> int:
    if len(argv) < 2 or len(argv) % 2:
        print(__doc__)
        return 2
    failed = False
    for old, new in zip(argv[0::2], argv[1::2]):
        old, new = Path(old), Path(new)
        try:
            verdict = compare_calibration(old, new) if (old / "chain.h5").exists() else compare_sweep(old, new)
        except AssertionError as err:
            verdict = f"differs: {str(err).splitlines()[0]}"
        failed |= not verdict.startswith("identical")
        print(f"{old} vs {new}: {verdict}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
