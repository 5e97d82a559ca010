"""A sweep's run, re-simulated from its stored spec and seed and checked bit for bit, for viewing.

``select_run(results_dir, run_id=None, where=None, replicate=0, showcase=None) -> dict`` finds one
row of ``runs.parquet``: by run id (or a unique prefix of at least 6 characters), by
``where`` ({column: value}, e.g. from :func:`parse_where` of ``"perception.field_deg=60, init.n=100"``;
``n`` means ``init.n``) and ``replicate``, or by the name of a ``[report.showcase]`` entry of the sweep.
Anything but exactly one finished run raises :class:`RunNotFound` saying what matched.

``reproduce(results_dir, row, record_step=1) -> Reproduction`` rebuilds the run's spec from
``model.json`` and its row, and

1. checks that the spec hashes to the stored run id (same model version, same resolved preset);
2. runs it again through the sweep worker (``sweeps.worker.execute_run``) and compares every summary
   metric of the fresh row with the stored one, bit for bit (nan equals nan);
3. simulates it once more, recording every ``record_step`` steps (the viewer's frames), and checks that
   the metric time series of those frames at the sweep's record times equal the worker's, bit for bit,
   so the trajectory shown is the run in the table.

Any difference raises :class:`NotReproduced` naming the columns with the stored and re-simulated values.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from flocksweep.observables.summary import every_nth
from flocksweep.simcore import simulate
from flocksweep.simcore.params import canonical_key
from flocksweep.simcore.schema import parse_value
from flocksweep.sweeps.design import stored_spec
from flocksweep.sweeps.store import ResultsStore
from flocksweep.sweeps.worker import close_sandbox, execute_run, has_sandbox

from .observables import record_metrics

NOT_METRICS = ("run_id", "index", "point_index", "replicate", "seed", "status", "error", "sim_s", "wall_s", "part")


class RunNotFound(ValueError):
    pass


class NotReproduced(RuntimeError):
    pass


@dataclass
class Reproduction:
    obs: object            # simcore Observations, recorded every ``record_step`` steps
    preset: object         # simcore Preset of the run
    row: dict              # the stored row
    group_radius: float
    checks: pd.DataFrame   # column, stored, resimulated, identical


def parse_where(text: str) -> dict:
    """``"key=value, key=value"`` -> {key: value} (values as in ``--set``: numbers, booleans, strings)."""
    out = {}
    for item in filter(None, (part.strip() for part in text.split(","))):
        key, sep, value = item.partition("=")
        if not sep or not key.strip() or not value.strip():
            raise RunNotFound(f"--where: got {item!r}; expected key=value items separated by commas, "
                              "e.g. \"perception.field_deg=60, init.n=100\"")
        key = canonical_key(key.strip())
        out[key] = parse_value(value.strip())
    if not out:
        raise RunNotFound("--where: no key=value given")
    return out


def _matches(column: pd.Series, value) -> np.ndarray:
    if isinstance(value, bool) or pd.api.types.is_bool_dtype(column):
        return (column == value).to_numpy() if isinstance(value, bool) else np.zeros(len(column), bool)
    if isinstance(value, (int, float)) and pd.api.types.is_numeric_dtype(column):
        return np.isclose(column.to_numpy(dtype=float), float(value), rtol=0, atol=1e-9)
    return (column.astype(str) == str(value)).to_numpy()


def _levels(runs: pd.DataFrame, column: str) -> str:
    values = runs[column].dropna().unique()
    return ", ".join(map(str, sorted(values, key=str)[:20])) + (" ..." if len(values) > 20 else "")


def _showcase(root: Path, name: str) -> dict:
    path = root / "sweep.effective.json"
    showcase = json.loads(path.read_text()).get("report", {}).get("showcase", {}) if path.exists() else {}
    if name not in showcase:
        known = ", ".join(showcase) or "none"
        raise RunNotFound(f"--showcase: {name!r} is not a [report.showcase] entry of this sweep (entries: {known})")
    return {canonical_key(k): v for k, v in showcase[name].items()}


def select_run(results_dir, run_id: str | None = None, where: dict | None = None, replicate: int = 0,
               showcase: str | None = None) -> dict:
    """One finished run's row (see the module docstring)."""
    root = Path(results_dir)
    store = ResultsStore(root)
    if not (root / "model.json").exists():
        raise RunNotFound(f"{root}: not a sweep results directory (no model.json); run the sweep first")
    runs = store.runs()
    if runs.empty:
        raise RunNotFound(f"{root}: no runs stored yet")
    if sum(x is not None for x in (run_id, where, showcase)) != 1:
        raise RunNotFound("name the run with exactly one of --run RUN_ID, --where \"key=value, ...\" "
                          "or --showcase NAME")
    if run_id is not None:
        hits = runs[runs["run_id"] == run_id]
        if hits.empty and len(run_id) >= 6:
            hits = runs[runs["run_id"].str.startswith(run_id)]
        if len(hits) != 1:
            raise RunNotFound(f"--run: {run_id!r} matches {len(hits)} runs of {root} "
                              f"({'give more characters' if len(hits) else 'see runs.parquet for the ids'})")
    else:
        where = _showcase(root, showcase) if showcase is not None else where
        mask = np.ones(len(runs), bool)
        for key, value in where.items():
            if key not in runs.columns:
                design = store.design()
                columns = design.columns if design is not None else ()
                factors = ", ".join(c for c in columns if c not in NOT_METRICS + ("n", "steps"))
                raise RunNotFound(f"--where: {key!r} is not a column of runs.parquet; swept columns: {factors}")
            hit = _matches(runs[key], value)
            if not (mask & hit).any():
                raise RunNotFound(f"--where: no run has {key} = {value!r} together with the keys before it; "
                                  f"{key} takes: {_levels(runs, key)}")
            mask &= hit
        hits = runs[mask & (runs["replicate"] == replicate).to_numpy()]
        if hits.empty:
            raise RunNotFound(f"--replicate: no replicate {replicate} at that point (replicates: "
                              f"{_levels(runs[mask], 'replicate')})")
        if len(hits) > 1:
            varying = [c for c in runs.columns if c not in NOT_METRICS and "." in c and hits[c].nunique() > 1]
            raise RunNotFound(f"--where matches {len(hits)} runs of replicate {replicate}; they differ in "
                              + "; ".join(f"{c} ({_levels(hits, c)})" for c in varying) + ": add those keys")
    row = hits.iloc[0].to_dict()
    if row["status"] != "ok":
        raise RunNotFound(f"run {row['run_id']} failed in the sweep ({row.get('error')}); nothing to show")
    return row


def _same(a, b) -> bool:
    a, b = float(a), float(b)
    return (math.isnan(a) and math.isnan(b)) or a == b


def _spec(root: Path, row: dict):
    spec = stored_spec(ResultsStore(root).model(), row)
    if spec.run_id != row["run_id"]:
        raise NotReproduced(f"run {row['run_id']}: its spec rebuilt from model.json hashes to {spec.run_id}, so "
                            "this code (model version or preset resolution) is not the one that ran the sweep; "
                            "re-run the sweep to view its runs")
    return spec


def reproduce(results_dir, row: dict, record_step: int = 1) -> Reproduction:
    """Re-simulate a stored run and check it (see the module docstring)."""
    root = Path(results_dir)
    spec = _spec(root, row)
    had_sandbox = has_sandbox()
    try:
        fresh, series = execute_run(spec)
    finally:   # a contained run's sandbox started here ends here: a report or view leaves no process behind
        if not had_sandbox:
            close_sandbox()
    if fresh["status"] != "ok":
        raise NotReproduced(f"run {row['run_id']}: the re-simulation failed: {fresh['error']}")
    columns = [c for c in fresh if c not in NOT_METRICS and c not in dict(spec.columns) and c in row]
    checks = pd.DataFrame([{"column": c, "stored": float(row[c]), "resimulated": float(fresh[c]),
                            "identical": _same(row[c], fresh[c])} for c in columns])
    run = spec.preset.run
    every = run.record_every
    step = math.gcd(int(record_step), every)
    obs = simulate(spec.preset.model, spec.preset.init, spec.seed, run.duration, run.dt, step)
    viewed = record_metrics(obs, every // step, spec.metrics.group_radius, spec.preset.model)
    trajectory = [{"column": f"series:{name}", "stored": float("nan"), "resimulated": float("nan"),
                   "identical": bool(np.array_equal(viewed[name], series[name].to_numpy(), equal_nan=True))}
                  for name in viewed if name in series]
    checks = pd.concat([checks, pd.DataFrame(trajectory)], ignore_index=True)
    bad = checks[~checks["identical"]]
    if len(bad) or not len(columns):
        listed = "; ".join(f"{r.column}: stored {r.stored!r}, re-simulated {r.resimulated!r}" for r in bad.itertuples())
        raise NotReproduced(f"run {row['run_id']} does not reproduce its stored results bit for bit "
                            f"({listed or 'no metric columns to compare'}); refusing to show a different run")
    return Reproduction(obs=every_nth(obs, int(record_step) // step), preset=spec.preset, row=row,
                        group_radius=float(spec.metrics.group_radius), checks=checks)


def record_step_for(n_steps: int, n: int, max_bytes: float = 400e6) -> int:
    """The smallest recording interval (steps) keeping positions and velocities under ``max_bytes``."""
    per_record = n * 3 * 8 * 2
    return max(1, math.ceil((n_steps + 1) * per_record / max_bytes))
