"""``flocksweep posterior ESTIMATOR --targets FLOCKS.csv``: one posterior per observed flock from a trained
``npe`` estimator (:mod:`analysis.calibration.npe`), without a simulation; the command's work,
``run(args)``, for its declaration in ``flocksweep/commands/posterior.py``.

``posteriors(estimator_dir, table, draws=4000, seed=0) -> DataFrame``: the table's rows (one observed
flock or flight each: the estimator's statistic columns, e.g. the per-flight rows ``flocksweep
measure`` writes in ``runs.parquet``; its non-numeric columns, e.g. ``flock``, are kept as ids) -> one row per flock with, per parameter, the posterior
mean, sd, median and 5% / 95% quantiles, and ``leakage`` (the share of raw draws outside the prior).
All flocks are sampled in one vectorised call; flock i's draws depend only on ``seed`` and i. An
estimator of sequential rounds (``rounds > 1``) serves one flock only and is refused (ConfigError).
"""
from __future__ import annotations

import json
import time
from pathlib import Path
from typing import TYPE_CHECKING

from flocksweep.simcore.schema import ConfigError
from flocksweep.sweeps.failures import check_count, check_out
from flocksweep.sweeps.progress import next_steps

if TYPE_CHECKING:
    import pandas as pd


def _read_table(path: Path) -> pd.DataFrame:
    import pandas as pd   # numpy and pandas load when the command runs, not for --help

    if not path.is_file():
        raise ConfigError("--targets", f"file not found: {path}")
    return pd.read_parquet(path) if path.suffix == ".parquet" else pd.read_csv(path)


def posteriors(estimator_dir, table: pd.DataFrame, draws: int = 4000, seed: int = 0) -> pd.DataFrame:
    """One posterior summary per row of ``table`` (module docstring)."""
    import numpy as np
    import pandas as pd

    from .npe import IDENTITY_FILE, support_of
    from .npe_flow import load_estimator

    estimator_dir = Path(estimator_dir)
    identity_path = estimator_dir / IDENTITY_FILE
    if not identity_path.is_file():
        raise ConfigError("ESTIMATOR", f"{estimator_dir}: no {IDENTITY_FILE}; give the estimator/ folder of an npe "
                                       "calibration's output")
    identity = json.loads(identity_path.read_text())
    if identity.get("rounds", 1) != 1:
        raise ConfigError("ESTIMATOR", f"{estimator_dir} was trained in {identity['rounds']} sequential rounds, "
                                       "truncated to one flock's posterior region: it is not amortised; train "
                                       "with rounds = 1 for many flocks")
    columns, names = identity["columns"], [name for name, _ in identity["parameters"]]
    missing = [c for c in columns if c not in table.columns]
    if missing:
        raise ConfigError("--targets", f"no column {missing[0]!r}; the estimator needs the columns {', '.join(columns)}")
    x = table[columns].to_numpy(dtype=float)
    bad = ~np.isfinite(x).all(axis=1)
    if bad.any():
        raise ConfigError("--targets", f"row {int(np.flatnonzero(bad)[0])} has a missing or non-finite statistic")
    estimator = load_estimator(estimator_dir)
    samples = estimator.sample_many(x, draws, seed, support_of(bounds=identity["bounds"]))
    ids = [c for c in table.columns if c not in columns and not pd.api.types.is_numeric_dtype(table[c])]
    out = table[ids].reset_index(drop=True).copy()
    for j, name in enumerate(names):
        values = samples[:, :, j]
        out[f"{name}_mean"] = values.mean(axis=1)
        out[f"{name}_sd"] = values.std(axis=1, ddof=1)
        out[f"{name}_median"] = np.median(values, axis=1)
        out[f"{name}_q5"] = np.quantile(values, 0.05, axis=1)
        out[f"{name}_q95"] = np.quantile(values, 0.95, axis=1)
    out["leakage"] = estimator.last_leakage
    return out


def run(args) -> int:
    check_count("--draws", args.draws, 10)
    check_out("--out", args.out)
    started = time.time()
    table = posteriors(args.estimator, _read_table(args.targets), args.draws, args.seed)
    if args.out:
        table.to_csv(args.out, index=False)
        print(f"wrote {args.out}: {len(table)} posteriors in {time.time() - started:.1f} s")
        next_steps(f'pandas.read_csv("{args.out}")   (one posterior per row: mean, sd, median, 5% and 95% quantiles)')
    else:
        print(table.round(4).to_string())
        next_steps(f"flocksweep posterior {args.estimator} --targets {args.targets} --out posteriors.csv   "
                   "(the same as a table)")
    return 0
