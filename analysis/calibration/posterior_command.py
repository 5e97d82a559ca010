"""``flocksweep posterior ESTIMATOR --targets FLOCKS.csv`` (or ``--tracks TRACKS``): one posterior per
observed flock from a trained ``npe`` estimator (:mod:`analysis.calibration.npe`), without a simulation; the
command's work, ``run(args)``, for its declaration in ``flocksweep/commands/posterior.py``.

``posteriors(estimator_dir, table, draws=4000, seed=0, force=False, measured=None, raw=None) -> (DataFrame, notes)``: the
table's rows (one observed flock or flight each: the estimator's statistic columns, e.g. the per-flight rows
``flocksweep measure`` writes in ``runs.parquet``; its non-numeric columns, e.g. ``flock``, are kept as ids)
-> one row per flock with, per parameter, the posterior mean, sd, median and 5% / 95% quantiles, ``leakage``
(that flock's share of raw draws outside the prior, redrawn) and ``credible`` (False when the estimator failed
its coverage check and ``force`` gave the posteriors anyway). The flocks are sampled in vectorised calls of
several flocks each, by one compiled program whatever the table's size; flock i's draws depend only on its
statistics, ``draws``, ``seed`` and i (bit for bit, in a table of any size). ``notes``: the plain lines the
command prints (the estimator's coverage verdict first; the flocks whose leakage exceeds
:data:`LEAKAGE_WARN`, named).

Refused (a :class:`~simcore.schema.ConfigError` naming what to do):

* an estimator of sequential rounds (``rounds > 1``): it serves one flock only;
* an estimator with a learned summary (``[method.npe.summary] kind = "learned"``) given a table: it needs each
  flock's individuals and series (``raw`` (m, length), :func:`analysis.calibration.learned_inputs.measured_raw`),
  which ``--tracks`` measures;
* an estimator of f > 1 flocks at a time (its calibration's targets held f rows, ``samples`` or several flocks
  ``from_tracks``; ``replicates`` in its identity: each training simulation is the mean of f runs) given other
  than f flocks: with f it gives ONE posterior, given all of them (their mean statistics and, for a learned
  summary, each one's raw inputs; the flocks' names joined by "+" in its id columns). Each flock alone would
  be read as a mean of f: a posterior about sqrt(f) times too narrow;
* an estimator whose held-out coverage check failed (``coverage.json`` beside it), unless ``force``: then
  every row is marked ``credible = False``;
* a table measured otherwise than the estimator's training runs (:func:`check_measurement`): its ``interval``,
  ``velocity_interval``, ``dims`` and ``length_unit`` columns (written by ``flocksweep measure``) and, when a
  ``measure.json`` lies beside the table (``measured``), its group radius and fragmentation threshold, each
  against the estimator's ``measurement`` settings; the message names the setting. A table that does not say
  how it was measured (no such column) is taken with a note.

``measure_for(estimator_dir, tracks) -> (DataFrame, raw or None)``: the tracks measured as the estimator's settings
say (interval, velocity interval, gap limit, group radius, fragmentation threshold, warm-up; the file read as
its sidecar JSON says), the table ``--tracks`` gives to :func:`posteriors`, and for a learned summary each
flock's raw inputs (else None).
"""
from __future__ import annotations

import json
import math
import time
from pathlib import Path
from typing import TYPE_CHECKING

from flocksweep.simcore.schema import ConfigError
from flocksweep.sweeps.failures import check_count, check_out_file
from flocksweep.sweeps.files import atomic_path
from flocksweep.sweeps.progress import next_steps

if TYPE_CHECKING:
    import pandas as pd

TOLERANCE = 1e-6        # relative: two intervals this close are the same
LEAKAGE_WARN = 0.1      # a flock whose share of draws outside the prior exceeds this is named in the notes
MAX_NAMED = 10          # flocks named in a note at most


MAX_TABLE = 256 << 20   # bytes of a --targets table (a row per flock: a few kB as a rule)


def _read_table(path: Path) -> pd.DataFrame:
    """The ``--targets`` table: a regular file of at most :data:`MAX_TABLE` bytes, read as Parquet or CSV
    (ConfigError naming the file and what is wrong otherwise)."""
    import pandas as pd   # numpy and pandas load when the command runs, not for --help

    path = Path(path)
    if not path.exists():
        raise ConfigError("--targets", f"file not found: {path}")
    if not path.is_file():
        raise ConfigError("--targets", f"{path} is not a regular file (a folder, FIFO, device or socket); expected a "
                                       "CSV or Parquet table")
    if path.stat().st_size > MAX_TABLE:
        raise ConfigError("--targets", f"{path}: {path.stat().st_size:,} bytes, more than a table of flocks may hold "
                                       f"({MAX_TABLE >> 20} MiB)")
    kind = "Parquet" if path.suffix == ".parquet" else "CSV"
    try:
        table = pd.read_parquet(path) if kind == "Parquet" else pd.read_csv(path)
    except Exception as err:  # noqa: BLE001 - pandas and pyarrow raise many kinds for a file that is not a table
        raise ConfigError("--targets", f"{path} cannot be read as a {kind} table ({type(err).__name__}: "
                                       f"{str(err).strip().splitlines()[0] if str(err).strip() else 'empty'}); "
                                       "expected one row per flock, a column per statistic") from None
    if table.empty:
        raise ConfigError("--targets", f"{path} holds no rows; expected one row per flock, a column per statistic")
    return table


def _measure_json(path: Path) -> dict | None:
    """``measure.json`` beside a ``--targets`` table (how it was measured), or None."""
    if not path.is_file():
        return None
    try:
        data = json.loads(path.read_text(encoding="utf-8")) if path.stat().st_size <= MAX_TABLE else None
    except (ValueError, UnicodeDecodeError, OSError) as err:
        raise ConfigError("--targets", f"{path} (beside the table: how it was measured) is not valid JSON "
                                       f"({type(err).__name__}); fix or move it, or measure the tracks again "
                                       "(flocksweep measure)") from None
    if not isinstance(data, dict):
        raise ConfigError("--targets", f"{path} (beside the table: how it was measured) is not a JSON object; fix or "
                                       "move it, or measure the tracks again (flocksweep measure)")
    return data


def _identity(estimator_dir: Path) -> dict:
    """The estimator's identity, after its folder's checksums are verified (analysis.calibration.
    estimator_folder: DamagedEstimator, exit 2, naming the file otherwise)."""
    from .estimator_folder import read_identity, verify

    verify(estimator_dir)
    return read_identity(estimator_dir)


def coverage_verdict(estimator_dir: Path) -> dict | None:
    """The estimator's held-out coverage check as stored beside it (``coverage.json``), or None; one that
    is not a verdict flocksweep writes is DamagedEstimator."""
    from .estimator_folder import COVERAGE_FILE, DamagedEstimator, read_json, retrain_hint

    path = Path(estimator_dir) / COVERAGE_FILE
    verdict = read_json(path, missing=True)
    if verdict is None:
        return None
    if not (isinstance(verdict, dict) and isinstance(verdict.get("passed"), bool)
            and isinstance(verdict.get("messages"), list) and verdict["messages"]
            and all(isinstance(m, str) for m in verdict["messages"])):
        raise DamagedEstimator(f"{path}: not a coverage verdict flocksweep writes ({{passed, messages}}); "
                               f"{retrain_hint()}")
    return verdict


def _same(a, b) -> bool:
    if isinstance(a, str) or isinstance(b, str):
        return str(a) == str(b)
    return math.isclose(float(a), float(b), rel_tol=TOLERANCE, abs_tol=1e-12)


def _velocity(value, interval):
    """A measured table's velocity interval: "recorded", or seconds ("None": one interval)."""
    if value is None or (isinstance(value, float) and math.isnan(value)) or str(value) in ("None", "nan", ""):
        return float(interval)
    if str(value) == "recorded":
        return "recorded"
    return float(value)


def check_measurement(identity: dict, table, measured: dict | None = None) -> list[str]:
    """ConfigError when ``table`` (and its ``measure.json``, ``measured``) was measured otherwise than the
    estimator's statistics; the notes to print otherwise (module docstring)."""
    wanted = identity.get("measurement")
    if wanted is None:
        return ["this estimator was trained before estimators recorded how their statistics are measured: make "
                "sure the table was measured as its training runs were"]
    ids = [c for c in table.columns if table[c].dtype == object and c not in ("velocity_interval", "length_unit")]
    name = (lambda i: f"row {i} ({table[ids[0]].iloc[i]})") if ids else (lambda i: f"row {i}")
    hint = ("measure the tracks again with those settings (flocksweep measure), or give them with --tracks FILE to "
            "have them measured as the estimator needs")
    checked = []
    for i in range(len(table)):
        row = table.iloc[i]
        if "interval" in table.columns and wanted.get("interval") is not None:
            checked.append("interval")
            if not _same(row["interval"], wanted["interval"]):
                raise ConfigError("--targets", f"{name(i)} was measured every {float(row['interval']):g} s; the "
                                               f"estimator's statistics are measured every {wanted['interval']:g} s "
                                               f"(measurement.interval): {hint}")
            if "velocity_interval" in table.columns:
                checked.append("velocity_interval")
                have = _velocity(row["velocity_interval"], row["interval"])
                want = _velocity(wanted["velocity_interval"], wanted["interval"])
                if not _same(have, want):
                    raise ConfigError("--targets", f"{name(i)} has velocities {_say(have)}; the estimator's are "
                                                   f"{_say(want)} (measurement.velocity_interval): {hint}")
        if "dims" in table.columns and wanted.get("dims") is not None:
            checked.append("dims")
            if int(row["dims"]) != int(wanted["dims"]):
                raise ConfigError("--targets", f"{name(i)} holds {int(row['dims'])}-D tracks; the estimator was trained "
                                               f"on {wanted['dims']}-D ones (measurement.dims: the observation's "
                                               "projection)")
        if "length_unit" in table.columns:
            checked.append("length_unit")
            if str(row["length_unit"]) != wanted["length_unit"]:
                raise ConfigError("--targets", f"{name(i)} is in {row['length_unit']}; the estimator's lengths are "
                                               "in body lengths (measurement.length_unit): measure the tracks with "
                                               "--body-length")
    for key in ("group_radius", "fragmentation_cohesion", "warmup"):
        if measured and key in measured and wanted.get(key) is not None and isinstance(measured[key], (int, float)):
            checked.append(key)
            if not _same(measured[key], wanted[key]):
                raise ConfigError("--targets", f"the table was measured with {key} = {measured[key]:g} (measure.json); "
                                               f"the estimator's statistics use {wanted[key]:g} "
                                               f"(measurement.{key}): {hint}")
    if not checked:
        every = "as its training runs' own records" if wanted.get("interval") is None else (
            f"every {wanted['interval']:g} s, velocities "
            f"{_say(_velocity(wanted['velocity_interval'], wanted['interval']))}")
        return [f"the table does not say how it was measured (no interval, velocity_interval, dims or length_unit "
                f"column): the estimator expects statistics measured {every}, in body lengths, group radius "
                f"{wanted['group_radius']}"]
    return [f"measurement checked against the estimator's: {', '.join(dict.fromkeys(checked))}"]


def _say(velocity) -> str:
    return "as recorded by the tracker" if velocity == "recorded" else f"differenced over {velocity:g} s"


def posteriors(estimator_dir, table: pd.DataFrame, draws: int = 4000, seed: int = 0, force: bool = False,
               measured: dict | None = None, raw=None):
    """One posterior summary per row of ``table``, and the notes (module docstring)."""
    import numpy as np
    import pandas as pd

    from .learned_summary import load_any as load_estimator
    from .npe_flow import POSTERIOR_MARGIN, support_of
    from .transforms import Transforms

    estimator_dir = Path(estimator_dir)
    identity = _identity(estimator_dir)
    if identity.get("rounds", 1) != 1:
        raise ConfigError("ESTIMATOR", f"{estimator_dir} was trained in {identity['rounds']} sequential rounds, "
                                       "truncated to one flock's posterior region: it is not amortised; train "
                                       "with rounds = 1 for many flocks")
    learned = "learned_inputs" in (identity.get("simulator") or {})
    if learned and raw is None:
        raise ConfigError("--targets", f"{estimator_dir} learned its own summary of each flock from its individuals and "
                                       "series (method.npe.summary kind = \"learned\"), which a table of statistics "
                                       "does not hold: give the tracks with --tracks FILE")
    verdict = coverage_verdict(estimator_dir)
    notes = []
    credible = True
    if verdict is None:
        notes.append("coverage: not recorded beside this estimator (trained before coverage.json existed); run its "
                     "calibration again to check it")
    elif verdict["passed"]:
        notes.append(f"coverage: passed ({verdict['messages'][0]})")
    else:
        if not force:
            raise ConfigError("ESTIMATOR", f"{estimator_dir} FAILED its held-out coverage check "
                                           f"({'; '.join(verdict['messages'][1:3])}): its posteriors are not to be "
                                           "trusted; train a better one (more simulations, an ensemble), or pass "
                                           "--force to get them marked credible = false")
        credible = False
        notes.append("coverage: FAILED; --force: every posterior below is marked credible = false")
    notes += check_measurement(identity, table, measured)
    columns, names = identity["columns"], [name for name, _ in identity["parameters"]]
    missing = [c for c in columns if c not in table.columns]
    if missing:
        raise ConfigError("--targets", f"no column {missing[0]!r}; the estimator needs the columns {', '.join(columns)}")
    text = [c for c in columns if not pd.api.types.is_numeric_dtype(table[c])]
    if text:
        column = table[text[0]]
        row = int(np.flatnonzero((pd.to_numeric(column, errors="coerce").isna() & column.notna()).to_numpy())[0])
        raise ConfigError("--targets", f"column {text[0]!r}: row {row} holds {column.iloc[row]!r:.40}, not a number; "
                                       "every statistic must be a number")
    x = table[columns].to_numpy(dtype=float)
    if learned:
        x = np.concatenate([x, np.asarray(raw, dtype=float).reshape(len(x), -1)], axis=1)
    flocks = int(identity.get("replicates", 1))
    if flocks > 1:
        table, x = _all_flocks(table, x, columns, flocks, estimator_dir, "--tracks" if raw is not None else "--targets")
    bad = ~np.isfinite(x).all(axis=1)
    if bad.any():
        raise ConfigError("--targets", f"row {int(np.flatnonzero(bad)[0])} has a missing or non-finite statistic")
    try:
        transforms = Transforms.from_record(identity.get("transforms") or {}, columns)
        transforms.apply(x[:1, :len(columns)])
    except (KeyError, TypeError, ValueError) as err:
        from .estimator_folder import DamagedEstimator, retrain_hint
        raise DamagedEstimator(f"{estimator_dir}/identity.json: transforms: {err}; {retrain_hint()}") from None
    estimator = load_estimator(estimator_dir)
    if estimator.d != len(names) or estimator.k != x.shape[1]:
        from .estimator_folder import DamagedEstimator, retrain_hint
        raise DamagedEstimator(f"{estimator_dir}: its flow has {estimator.d} parameters and {estimator.k} statistics, "
                               f"its identity.json {len(names)} and {len(columns)}; {retrain_hint()}")
    x = np.concatenate([transforms.apply(x[:, :len(columns)]), x[:, len(columns):]], axis=1)
    samples = estimator.sample_many(x, draws, seed, support_of(bounds=identity["bounds"]), short="nan",
                                    margin=POSTERIOR_MARGIN)

    ids = [c for c in table.columns if c not in columns and not pd.api.types.is_numeric_dtype(table[c])]
    out = table[ids].reset_index(drop=True).copy()
    for j, name in enumerate(names):
        values = samples[:, :, j]
        out[f"{name}_mean"] = values.mean(axis=1)
        out[f"{name}_sd"] = values.std(axis=1, ddof=1)
        out[f"{name}_median"] = np.median(values, axis=1)
        out[f"{name}_q5"] = np.quantile(values, 0.05, axis=1)
        out[f"{name}_q95"] = np.quantile(values, 0.95, axis=1)
    out["leakage"] = estimator.last_row_leakage
    leaky = np.flatnonzero(out["leakage"].to_numpy() > LEAKAGE_WARN)
    if len(leaky):
        label = out[ids[0]].astype(str) if ids else [f"row {i}" for i in range(len(out))]
        named = ", ".join(f"{label[i]} ({out['leakage'].iloc[i]:.0%})" for i in leaky[:MAX_NAMED])
        more = f" and {len(leaky) - MAX_NAMED} more" if len(leaky) > MAX_NAMED else ""
        notes.append(f"{len(leaky)} of {len(out)} flock(s) had more than {LEAKAGE_WARN:.0%} of the estimator's draws "
                     f"outside the prior (redrawn; column leakage): {named}{more}; their statistics lie near or past "
                     "the edge of what the training simulations cover: check them, or train on a wider prior")
    outside = np.isnan(samples).any(axis=(1, 2))
    out["credible"] = credible & ~outside
    if outside.any():
        notes.append(f"{int(outside.sum())} row(s) lie outside what the training simulations cover (no posterior: "
                     "NaN, credible = false)")
    return out, notes


def _all_flocks(table, x, columns, flocks: int, estimator_dir, key: str):
    """(one-row table, (1, k [+ f length]) row) of the f measured flocks an estimator of f flocks is conditioned
    on at once: their mean statistics (and, for a learned summary, each one's raw inputs); its id columns name
    every flock. One row alone would be read as the mean of f flocks: a posterior f times too sure."""
    import numpy as np
    import pandas as pd

    if len(table) != flocks:
        raise ConfigError(key, f"{len(table)} flock(s) given; {estimator_dir} was trained on {flocks} flocks at a "
                               f"time (its calibration's targets held {flocks} rows: each training simulation is "
                               f"the mean of {flocks} runs) and gives the posterior given all of them: give exactly "
                               f"{flocks} flocks (one posterior), or calibrate an estimator on as many flocks as "
                               "you have (one flock each: targets of one row)")
    ids = [c for c in table.columns if c not in columns and not pd.api.types.is_numeric_dtype(table[c])]
    one = pd.DataFrame({**{c: ["+".join(map(str, table[c]))] for c in ids},
                        **{c: [float(v)] for c, v in zip(columns, x[:, :len(columns)].mean(axis=0))}})
    return one, np.concatenate([x[:, :len(columns)].mean(axis=0), x[:, len(columns):].ravel()])[None, :]


def measure_for(estimator_dir, tracks: Path):
    """The tracks measured as the estimator's statistics were (module docstring)."""
    from flocksweep.observables.measured import measure_tracks, track_settings
    from flocksweep.observables.tracks import load_tracks, track_source
    from flocksweep.observables.validation import TrackError

    identity = _identity(Path(estimator_dir))
    wanted = identity.get("measurement")
    if wanted is None:
        raise ConfigError("--tracks", "this estimator does not record how its statistics are measured (trained "
                                      "before estimators did): measure the tracks yourself and give --targets")
    if not Path(tracks).exists():
        raise ConfigError("--tracks", f"file not found: {tracks}")
    try:
        table = load_tracks(tracks, track_source(tracks, {}, "--tracks"))
        if table.unit_label != wanted["length_unit"]:
            raise ConfigError("--tracks", f"{Path(tracks).name} is in {table.unit_label}; the estimator's lengths are "
                                          "in body lengths: give body_length in the tracks' sidecar JSON")
        if wanted.get("dims") is not None and table.dims != wanted["dims"]:
            raise ConfigError("--tracks", f"{Path(tracks).name} holds {table.dims}-D tracks; the estimator was trained "
                                          f"on {wanted['dims']}-D ones")
        settings = track_settings(wanted["group_radius"], wanted.get("warmup", 0.0), wanted["fragmentation_cohesion"],
                                  wanted["dcd_max_delay"])
        velocity = wanted["velocity_interval"]
        if velocity == "recorded" and not table.has_velocity:
            raise ConfigError("--tracks", f"{Path(tracks).name} has no velocities; the estimator's statistics use "
                                          "recorded velocities (measurement.velocity_interval)")
        measurement = measure_tracks(table, settings, wanted["interval"], wanted["max_gap"], velocity)
    except TrackError as err:
        raise ConfigError("--tracks", str(err)) from None
    runs = measurement.runs
    ok = runs[runs["status"] == "ok"].reset_index(drop=True)
    if "learned_inputs" in (identity.get("simulator") or {}):   # a learned summary: each flock's raw inputs too
        from .learned_inputs import measured_raw

        names = list(ok["flock"])
        flocks = [next(f for f in measurement.flocks if f.name == name) for name in names]
        return ok, measured_raw(flocks, identity)
    return ok, None


def run(args) -> int:
    check_count("--draws", args.draws, 10)
    check_out_file("--out", args.out)
    if (args.targets is None) == (args.tracks is None):
        raise ConfigError("--targets", "give either --targets TABLE (measured statistics) or --tracks FILE (measured "
                                       "here as the estimator needs), one of them")
    started = time.time()
    if args.tracks is not None:
        (table, raw), measured = measure_for(args.estimator, args.tracks), None
    else:
        _identity(args.estimator)          # a damaged estimator is named before the table is read
        table, raw = _read_table(args.targets), None
        measured = _measure_json(Path(args.targets).parent / "measure.json")
    result, notes = posteriors(args.estimator, table, args.draws, args.seed, force=args.force, measured=measured,
                               raw=raw)
    for note in notes:
        print(note)
    if args.out:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        with atomic_path(args.out) as tmp:     # a table read while it is written again is whole, old or new
            result.to_csv(tmp, index=False)
        print(f"wrote {args.out}: {len(result)} posteriors in {time.time() - started:.1f} s")
        next_steps(f'pandas.read_csv("{args.out}")   (one posterior per row: mean, sd, median, 5% and 95% quantiles)')
    else:
        print(result.round(4).to_string())
        given = f"--tracks {args.tracks}" if args.tracks is not None else f"--targets {args.targets}"
        next_steps(f"flocksweep posterior {args.estimator} {given} --out posteriors.csv   (the same as a table)")
    return 0
