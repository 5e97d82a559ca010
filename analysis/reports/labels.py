"""Readable names for figure axes, tables and sentences: a preset key or a metric column -> words and units.

* ``parameter_label(key)`` -> ``"field of vision phi (deg)"`` for ``perception.field_deg``: words and unit;
  ``parameter_words(key)`` -> ``"field of vision phi"``; ``parameter_unit(key)`` -> ``"deg"`` ("" for a
  count or a ratio, or when unknown). A key not listed is spelled out from its last part
  (``vehicle.max_force`` -> ``"max force"``; a ``_deg`` suffix gives the unit ``deg``); a non-key factor
  (``mode``) keeps its name.
* ``metric_label(column)`` -> ``"cohesion (share in the largest group)"`` for ``cohesion_mean``; with a
  unit, ``"mean speed (units/s)"``; ``_final`` columns say so (``"... at the end of the run"``);
  ``metric_words(column)`` and ``metric_unit(column)`` split it. A column not listed keeps its name.

Units follow docs/model.md (lengths in model units; body lengths for presets written so) and
docs/metrics.md (its "units, range" column); a share or correlation has no unit (its range is said in
the words where it helps).
"""
from __future__ import annotations

# key -> (words, unit)
PARAMETERS = {
    "perception.field_deg": ("field of vision phi", "deg"),
    "perception.direction_deg": ("direction of vision delta", "deg"),
    "perception.eye_position_deg": ("eye position alpha", "deg"),
    "perception.range": ("range of vision R", "units"),
    "perception.radius": ("perception radius", "units"),
    "perception.head_radius": ("head radius", "units"),
    "perception.cohesion_radius": ("cohesion radius", "units"),
    "perception.alignment_radius": ("alignment radius", "units"),
    "perception.separation_radius": ("separation radius", "units"),
    "perception.neighbours": ("neighbours heeded k", "boids"),
    "init.n": ("flock size N", "boids"),
    "vehicle.max_speed": ("speed cap", "units/s"),
    "vehicle.max_force": ("force cap", "units/s^2"),
    "leadership.x": ("leadership X", ""),
    "run.duration": ("duration", "s"),
    "patterns.enabled": ("pattern mode", ""),
    "mode": ("mode", ""),
}

# metric name (column without its _mean / _final suffix) -> (words, unit)
METRIC_NAMES = {
    "cohesion": ("cohesion (share in the largest group)", ""),
    "polarization": ("alignment (polarization, 0-1)", ""),
    "polarization_largest": ("alignment of the largest group", ""),
    "milling": ("milling (0-1)", ""),
    "stray_fraction": ("stray fraction", ""),
    "n_groups": ("number of groups", ""),
    "elongation": ("elongation of the largest group", ""),
    "elongation_heading": ("elongation along the heading", ""),
    "aspect_heading": ("length/width along heading", ""),
    "speed_mean": ("mean speed", "units/s"),
    "speed_cv": ("speed spread (cv)", ""),
    "segregation": ("pattern segregation", ""),
    "visible_mean": ("visible neighbours", "boids"),
    "visible_sd": ("spread of visible neighbours across boids", "boids"),
    "binocular_share": ("binocular share of sightings", ""),
    "nn_distance": ("nearest-neighbour distance", "units"),
    "gyration_radius": ("gyration radius", "units"),
    "overtake_rate": ("overtakes", "per boid per s"),
    "trigger_rate": ("leadership triggers", "per boid per min"),
    "leaders": ("simultaneous leaders", "boids"),
    "leader_time_fraction": ("share of time with a leader", ""),
    "follow_corr_lag0": ("follow response at lag 0 (correlation)", ""),
    "follow_corr_max": ("follow response (best correlation)", ""),
    "follow_lag_max": ("follow delay", "s"),
    "follow_corr_before": ("correlation before a trigger", ""),
    "heading_change_deg": ("group turn over an escape", "deg"),
    "escape_gain": ("escape speed gain", "x"),
    "collided_boids": ("boids that collided", "boids"),
    "clearance_min": ("least clearance", "units"),
    "migratory_progress": ("migratory progress", "units/s"),
    "fragmented": ("fragmented (0/1)", ""),
    "time_to_fragmentation": ("time to fragmentation", "s"),
}
SUFFIXES = {"_mean": "", "_final": " at the end of the run"}


def _split_key(key: str) -> tuple[str, str]:
    key = str(key)
    if key in PARAMETERS:
        return PARAMETERS[key]
    last = key.rsplit(".", 1)[-1]
    if last.endswith("_deg"):
        return last[:-4].replace("_", " "), "deg"
    return last.replace("_", " "), ""


def parameter_words(key: str) -> str:
    return _split_key(key)[0]


def parameter_unit(key: str) -> str:
    return _split_key(key)[1]


def parameter_label(key: str) -> str:
    """Words and unit for a swept preset key (see the module docstring)."""
    words, unit = _split_key(key)
    return f"{words} ({unit})" if unit else words


def _split_metric(column: str) -> tuple[str, str]:
    column = str(column)
    if column in METRIC_NAMES:
        return METRIC_NAMES[column]
    for suffix, words in SUFFIXES.items():
        if column.endswith(suffix) and column[:-len(suffix)] in METRIC_NAMES:
            name, unit = METRIC_NAMES[column[:-len(suffix)]]
            return name + words, unit
    return column, ""


def metric_words(column: str) -> str:
    return _split_metric(column)[0]


def metric_unit(column: str) -> str:
    return _split_metric(column)[1]


def metric_label(column: str) -> str:
    """Words (and unit) for a metric column (see the module docstring)."""
    words, unit = _split_metric(column)
    return f"{words} ({unit})" if unit else words


# the table of the earlier interface: column -> label
METRICS = {f"{name}_mean": metric_label(f"{name}_mean") for name in METRIC_NAMES}
