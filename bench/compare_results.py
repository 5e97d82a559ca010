"""Bit-for-bit comparison of two result folders: a sweep's (runs.parquet and its time series) or a
calibration's (chain.h5 and posterior.csv). For checking that a change of code left results alone.

    python bench/compare_results.py BASELINE_DIR NEW_DIR [BASELINE_DIR NEW_DIR ...]

Sweeps: the same run ids in the same order, and every column except the timing ones (``wall_s``,
``sim_s``, ``part``) equal exactly (NaN equal to NaN); the time series of every run equal exactly.
Calibrations: the chain, log-probabilities and acceptance counts in ``chain.h5`` equal exactly, and
``posterior.csv`` byte for byte, or else every column of the baseline's exactly (columns added since,
e.g. ArviZ's R-hat and ESS, are listed). Prints one line per pair; exit status 1 when any pair differs.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd

from analysis.observables.summary import summary_columns

TIMING = ("wall_s", "sim_s", "part")


def _timeseries(folder: Path) -> pd.DataFrame:
    frames = [pd.read_parquet(p) for p in sorted((folder / "timeseries").glob("part-*.parquet"))]
    table = pd.concat(frames, ignore_index=True)
    return table.sort_values(["run_id", "t"], kind="stable").reset_index(drop=True)


def compare_sweep(old: Path, new: Path) -> str:
    a, b = pd.read_parquet(old / "runs.parquet"), pd.read_parquet(new / "runs.parquet")
    if list(a["run_id"]) != list(b["run_id"]):
        return "run ids differ"
    if list(a.columns) != list(b.columns):
        return f"columns differ: {sorted(set(a.columns) ^ set(b.columns))}"
    keep = [c for c in a.columns if c not in TIMING]
    pd.testing.assert_frame_equal(a[keep], b[keep], check_exact=True)
    ta, tb = _timeseries(old), _timeseries(new)
    pd.testing.assert_frame_equal(ta, tb, check_exact=True)
    metrics = [c for c in keep if c in set(summary_columns(leadership=True))]
    return (f"identical: {len(a)} runs, same run ids, {len(metrics)} metric columns and {len(keep)} columns "
            f"in all bit for bit, {len(ta)} time-series rows bit for bit")


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
