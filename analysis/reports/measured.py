"""``flocksweep measure``: measured tracks -> the tidy tables of a sweep and a short report.

``measure_folder(path, source, settings, out_dir, interval=None, max_gap=None, velocity_interval="auto",
formats=("html", "md"), figures=True, progress=False) -> dict`` reads a track file
(:func:`observables.tracks.load_tracks`), measures every flock
(:func:`observables.measured.measure_tracks`) and writes into ``out_dir``, an
:class:`sweeps.store.OutputFolder` (locked while it writes, every file atomic):

* ``runs.parquet`` (and ``runs.csv``): one row per flock, the summary columns of a sweep's runs table;
* ``timeseries.parquet``: run_id, t and every per-record metric (plus ``tracked``) per flock;
* ``validation.csv``: every issue the reading and the checks found (level, check, flock, id, column, rows,
  detail);
* ``measure.json``: the file, units, interval, velocity handling, metric settings, issue counts and the
  provenance stamp;
* ``figures/metrics_over_time.png`` (every flock, one panel per metric) and ``figures/flock_<name>.png``
  (one per flock, for the first 12 flocks: the time series of all are in ``timeseries.parquet``);
  ``figures/hierarchy_<name>.png`` (the same flocks with at least two individuals: the leader-follower
  network and hierarchy of the directional correlation delays, :mod:`analysis.reports.hierarchy`, computed
  by :func:`observables.summary.run_directional_correlation` as for the ``dcd_*`` columns);
  ``report.md`` and a self-contained ``report.html``. ``figures=False`` leaves the figures out (large
  data sets: matplotlib takes seconds per figure); ``progress`` shows progress bars (flocks, figures).

When the tracks have errors (:class:`~observables.validation.TrackError`), ``validation.csv`` is
written all the same and the error is raised: nothing is measured from tracks that are not right.
"""
from __future__ import annotations

import re
import time
from pathlib import Path

import pandas as pd
from tqdm import tqdm

from flocksweep.observables.measured import Measurement, measure_tracks, velocity_label
from flocksweep.observables.resample import RECORDED
from flocksweep.observables.summary import MetricSettings, run_directional_correlation
from flocksweep.observables.tracks import TrackSource, load_tracks, read_sidecar
from flocksweep.observables.validation import TrackError, issues_table
from flocksweep.sweeps.files import write_parquet
from flocksweep.sweeps.progress import Phases
from flocksweep.sweeps.store import OutputFolder

from .document import Figure, Heading, Para, Table, to_html, to_markdown
from .hierarchy import hierarchy_figure
from .plotting import pyplot, save

UNITS = {"nn_distance": "L", "gyration_radius": "L", "speed_mean": "L/s", "n_groups": "count",
         "tracked": "count"}   # L: the analysis length unit
FIGURE_METRICS = ("polarization", "nn_distance", "speed_mean", "cohesion", "n_groups", "gyration_radius",
                  "elongation", "milling", "tracked")
FLOCK_FIGURES = 12          # figures of single flocks drawn at most
TABLE_COLUMNS = ("flock", "status", "individuals", "records", "duration", "tracked_mean", "polarization_mean",
                 "nn_distance_mean", "speed_mean_mean", "speed_cv_mean", "cohesion_mean", "n_groups_mean",
                 "gyration_radius_mean", "elongation_mean", "milling_mean", "dcd_corr_mean", "dcd_delay_mean",
                 "dcd_edges", "dcd_leader_delay")


def _slug(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", str(name)).strip("_") or "flock"


def series_figure(ts: pd.DataFrame, names: list, metrics: list, path, unit: str, title: str = "") -> Path:
    """One panel per metric, one line per flock (plain subplots: cheaper than a constrained layout)."""
    plt = pyplot()
    ncols = 3
    nrows = -(-len(metrics) // ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(3.6 * ncols, 2.5 * nrows + 0.8), sharex=True, squeeze=False)
    colours = plt.get_cmap("tab10" if len(names) <= 10 else "turbo")
    for k, name in enumerate(names):
        flock = ts[ts["run_id"] == name]
        colour = colours(k) if len(names) <= 10 else colours(k / max(len(names) - 1, 1))
        for ax, metric in zip(axes.flat, metrics):
            ax.plot(flock["t"], flock[metric], color=colour, linewidth=1.1, label=str(name))
    for ax, metric in zip(axes.flat, metrics):
        ax.set_title(f"{metric} ({UNITS.get(metric, '1').replace('L', unit)})", fontsize=9)
        ax.tick_params(labelsize=7)
        ax.grid(True, alpha=0.3, linewidth=0.5)
    for ax in axes[-1]:
        ax.set_xlabel("t (s)", fontsize=8)
    for ax in axes.flat[len(metrics):]:
        ax.set_visible(False)
    if len(names) <= 12:
        handles, labels = axes.flat[0].get_legend_handles_labels()
        fig.legend(handles, labels, loc="lower center", ncols=min(len(names), 6), fontsize=7, frameon=False)
    fig.suptitle(title, fontsize=10)
    fig.subplots_adjust(left=0.07, right=0.98, top=0.92 - 0.02 * (nrows < 3), bottom=0.15 if len(names) <= 12 else 0.08,
                        hspace=0.35, wspace=0.25)
    return save(fig, path, tight=False)


def _hierarchy_figures(measurement: Measurement, folder: OutputFolder, settings: MetricSettings,
                       progress: bool) -> list:
    flocks = [f for f in measurement.flocks if f.n >= 2][:FLOCK_FIGURES]
    if not flocks:
        return []
    blocks = [Heading("Leader-follower hierarchy"),
              Para("Directional correlation delays (Nagy et al. 2010): an edge i -> j when j flies as i flew "
                   f"tau* earlier (maximum correlation C* >= 0.5 at tau* > 0, delays up to {settings.dcd_max_delay:g} s, "
                   f"records at t >= {settings.warmup:g} s). Individuals are ordered by their mean delay over "
                   "the pairs they correlate with (score, rank 1 on top).")]
    for flock in tqdm(flocks, desc="hierarchies", unit="flock", disable=not progress):
        dc = run_directional_correlation(flock, settings)
        path = hierarchy_figure(dc, flock.ids, folder.path(f"figures/hierarchy_{_slug(flock.name)}.png"),
                                f"flock {flock.name}: {int(dc.edges.sum())} leader-follower edges")
        blocks.append(Figure(path, f"Leader-follower network and delays of flock {flock.name}"))
    return blocks


def _figures(measurement: Measurement, folder: OutputFolder, unit: str, settings: MetricSettings,
             progress: bool) -> list:
    ts = measurement.timeseries
    if ts.empty:
        return []
    metrics = [m for m in FIGURE_METRICS if m in ts.columns]
    names = list(measurement.runs.loc[measurement.runs["status"] == "ok", "run_id"])
    blocks = [Heading("Metrics over time"),
              Para(f"Lengths in {unit}, speeds in {unit}/s, t in seconds since each flock's first sample. "
                   "`tracked` is the number of individuals with a known position and velocity.")]
    path = series_figure(ts, names, metrics, folder.path("figures/metrics_over_time.png"), unit, "every flock")
    blocks.append(Figure(path, "The per-record metrics of every flock"))
    if len(names) > FLOCK_FIGURES:
        blocks.append(Para(f"Figures of single flocks: the first {FLOCK_FIGURES} of {len(names)} (all time series "
                           "are in `timeseries.parquet`)."))
    for name in tqdm(names[:FLOCK_FIGURES], desc="figures", unit="flock", disable=not progress):
        path = series_figure(ts, [name], metrics, folder.path(f"figures/flock_{_slug(name)}.png"), unit,
                             f"flock {name}")
        blocks.append(Figure(path, f"Flock {name}"))
    return blocks + _hierarchy_figures(measurement, folder, settings, progress)


def _scales_table(scales: dict, info: dict) -> pd.DataFrame:
    rows = [{"quantity": name, "value": entry["value"], "from": entry["from"]} for name, entry in scales.items()]
    found = info["interval_found"]
    interval = info["interval"]
    rows.append({"quantity": "record interval (s)",
                 "value": interval if not isinstance(interval, dict) else "per flock (runs.interval)",
                 "from": found if not isinstance(found, dict) else "per flock (runs.clock)"})
    return pd.DataFrame(rows).astype(str)


def _report(measurement: Measurement, settings: MetricSettings, info: dict, issues: pd.DataFrame,
            figure_blocks: list) -> list:
    table, runs = measurement.table, measurement.runs
    counts = issues["level"].value_counts().to_dict()
    description = info.get("description", "")
    blocks = [Heading(f"Measured flocks: {table.path.name}", 1)]
    if description:
        blocks.append(Para(f"**{description}**"))
    blocks += [
        Para(f"{len(runs)} flock(s), {int((runs['status'] == 'ok').sum())} measured; "
             f"{'3-D' if table.dims == 3 else '2-D (planar: no z column)'} tracks; lengths in "
             f"**{table.unit_label}**"
             + (f" (body length {table.source.body_length:g} m)" if table.source.body_length else "")
             + f"; {info['velocities']}; group radius {settings.group_radius:g} {table.unit_label}; "
               f"window means over t >= {settings.warmup:g} s."),
        Heading("Units and clock"),
        Table(_scales_table(table.source.scales(), info), "Every unit and scale used, and where it came from "
                                                          "(file: the track file; sidecar: its JSON; given: a flag or "
                                                          "[targets.tracks]; default)"),
        Heading("Validation"),
        Para(f"{counts.get('error', 0)} errors, {counts.get('warning', 0)} warnings, {counts.get('note', 0)} notes "
             "(all in `validation.csv`)." + (" No issue found." if issues.empty else ""))]
    if not issues.empty:
        blocks.append(Table(issues, "What the checks found", max_rows=40))
    blocks += [Heading("Flocks"),
               Table(runs[[c for c in TABLE_COLUMNS if c in runs.columns]], "One row per flock (runs.parquet)")]
    missed = runs[(runs["status"] == "ok") & runs["overtake_rate_mean"].isna()] if "overtake_rate_mean" in runs else []
    if len(missed):
        blocks.append(Para("`overtake_rate` compares who is where at consecutive records, so it is defined only when "
                           "every individual is present at every record; flock(s) "
                           f"{', '.join(map(str, missed['flock'][:10]))}{' ...' if len(missed) > 10 else ''} have "
                           "missed detections (`tracked_mean` below the individuals), so their `overtake_rate_*` is "
                           "NaN."))
    failed = runs[runs["status"] == "failed"]
    if len(failed):
        blocks.append(Table(failed[["flock", "error"]], "Flocks that could not be measured"))
    return blocks + figure_blocks


def _clocks(runs: pd.DataFrame, interval: float | None) -> dict:
    """The record interval and how it was found: one value when every flock shares it, else per flock."""
    measured = runs[runs["status"] == "ok"]
    intervals = sorted(set(measured["interval"]))
    clocks = sorted(set(measured["clock"]))
    return {"interval": intervals[0] if len(intervals) == 1 else {str(f): float(i) for f, i in
                                                                   zip(measured["flock"], measured["interval"])},
            "interval_found": "given (--interval)" if interval is not None else (
                clocks[0] if len(clocks) == 1 else {str(f): c for f, c in zip(measured["flock"], measured["clock"])})}


def reading_settings(source: TrackSource) -> dict:
    """Every setting a track file was read with (enough to read it again the same way: flocksweep view of a
    measure folder), JSON-ready."""
    return {"format": source.format, "columns": dict(source.columns), "units": dict(source.units),
            "body_length": source.body_length, "fps": source.fps, "body_length_px": source.body_length_px,
            "layout": dict(source.layout) if source.layout else None, "keep_padding": source.keep_padding,
            "trim": source.trim, "max_speed": source.max_speed, "bad_speeds": source.bad_speeds,
            "burst_share": source.burst_share, "burst_frames": source.burst_frames, "burst_jump": source.burst_jump,
            "arena": source.arena}


def measure_folder(path, source: TrackSource, settings: MetricSettings, out_dir, interval: float | None = None,
                   max_gap: float | None = None, velocity_interval="auto", formats=("html", "md"),
                   figures: bool = True, progress: bool = False) -> dict:
    """Measure the track file at ``path`` and write the folder (see the module docstring); ``velocity_interval``
    "auto" uses the tracks' velocities when they have them, else one sampling interval."""
    started = time.perf_counter()
    folder = OutputFolder(out_dir)
    phases = Phases("measure", 2 + bool(figures), progress)
    phases.start(f"reading, checking and measuring {Path(path).name} (a bar of flocks)")
    try:    # read before the folder is made: a file that cannot be read leaves nothing behind
        table = load_tracks(path, source)
    except TrackError as err:
        with folder.lock():
            folder.write_csv("validation.csv", issues_table(err.issues, err.line_offset), index=False)
        raise
    with folder.lock():
        try:
            if velocity_interval == "auto":
                velocity_interval = RECORDED if table.has_velocity else None
            measurement = measure_tracks(table, settings, interval, max_gap, velocity_interval, progress)
        except TrackError as err:
            folder.write_csv("validation.csv", issues_table(err.issues, err.line_offset), index=False)
            raise
        issues = issues_table(measurement.issues, table.line_offset)
        folder.write_csv("validation.csv", issues, index=False)
        _write_parquet(folder, "runs.parquet", measurement.runs)
        folder.write_csv("runs.csv", measurement.runs, index=False)
        _write_parquet(folder, "timeseries.parquet", measurement.timeseries)
        velocities = velocity_label(velocity_interval, interval)
        info = {"tracks": str(Path(path).resolve()), "description": read_sidecar(path).get("description", ""),
                "dims": table.dims, "length_unit": table.unit_label, "units": dict(table.source.units),
                "columns": dict(table.source.columns), "body_length_m": table.source.body_length,
                "format": table.source.format, "scales": table.source.scales(),
                **_clocks(measurement.runs, interval),
                "max_gap": max_gap if max_gap is not None else "2.5 x interval", "velocities": velocities,
                "velocity_interval": velocity_interval, "reading": reading_settings(table.source),
                "interval_given": interval, "max_gap_given": max_gap,
                "warmup": settings.warmup, "group_radius": settings.group_radius,
                "fragmentation_cohesion": settings.fragmentation_cohesion, "dcd_max_delay": settings.dcd_max_delay,
                "flocks": int(len(measurement.runs)),
                "issues": issues["level"].value_counts().to_dict(), "t_origin": table.t_origin}
        folder.write_json("measure.json", {**info, **folder.provenance()})
        for stale in folder.path("figures").glob("*.png") if folder.path("figures").is_dir() else []:
            stale.unlink()
        if figures:
            phases.start(f"figures of {len(measurement.flocks)} flock(s)")
        drawn = _figures(measurement, folder, table.unit_label, settings, progress) if figures else []
        phases.start("the report")
        blocks = _report(measurement, settings, info, issues, drawn)
        written = {}
        if "md" in formats:
            written["md"] = folder.write_text("report.md", to_markdown(blocks, folder.root))
        if "html" in formats:
            written["html"] = folder.write_text("report.html", to_html(blocks, f"measured flocks: {Path(path).name}"))
        phases.done(f": {folder.root}")
    return {"out": folder.root, "measurement": measurement, "issues": issues, "paths": written,
            "seconds": time.perf_counter() - started}


def _write_parquet(folder: OutputFolder, name: str, frame: pd.DataFrame) -> None:
    write_parquet(folder.path(name), frame)
