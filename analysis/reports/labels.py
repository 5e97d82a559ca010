"""Readable names for figure axes and tables: a preset key or a metric column -> words and units.

``parameter_label(key)`` -> e.g. ``"field of vision phi (deg)"`` for ``perception.field_deg``; a key not
listed is spelled out from its last part (``vehicle.max_force`` -> ``"max force"``, a ``_deg`` suffix
becomes ``(deg)``). ``metric_label(column)`` -> e.g. ``"alignment (polarization)"`` for
``polarization_mean``; a column not listed keeps its name. Units follow docs/model.md (lengths in model
units, body lengths for the Holland preset) and docs/metrics.md.
"""
from __future__ import annotations

PARAMETERS = {
    "perception.field_deg": "field of vision phi (deg)",
    "perception.direction_deg": "direction of vision delta (deg)",
    "perception.eye_position_deg": "eye position alpha (deg)",
    "perception.range": "range of vision R (units)",
    "perception.radius": "perception radius (units)",
    "perception.head_radius": "head radius (units)",
    "perception.cohesion_radius": "cohesion radius (units)",
    "perception.alignment_radius": "alignment radius (units)",
    "perception.separation_radius": "separation radius (units)",
    "init.n": "flock size N (boids)",
    "vehicle.max_speed": "speed cap (units/s)",
    "vehicle.max_force": "force cap (units/s^2)",
    "leadership.x": "leadership X",
    "run.duration": "duration (s)",
}

METRICS = {
    "cohesion_mean": "cohesion (largest group share)",
    "polarization_mean": "alignment (polarization)",
    "stray_fraction_mean": "stray fraction",
    "n_groups_mean": "number of groups",
    "elongation_mean": "elongation of the largest group",
    "speed_mean_mean": "mean speed",
    "segregation_mean": "pattern segregation",
    "aspect_heading_mean": "length/width along heading",
    "visible_mean_mean": "visible neighbours",
    "visible_sd_mean": "spread of visible neighbours across boids",
    "binocular_share_mean": "binocular share of sightings",
    "nn_distance_mean": "nearest-neighbour distance",
}


def parameter_label(key: str) -> str:
    """Words and units for a swept preset key (see the module docstring)."""
    key = str(key)
    if key in PARAMETERS:
        return PARAMETERS[key]
    last = key.rsplit(".", 1)[-1]
    if last.endswith("_deg"):
        return f"{last[:-4].replace('_', ' ')} (deg)"
    return last.replace("_", " ")


def metric_label(column: str) -> str:
    """Words for a metric column (see the module docstring)."""
    return METRICS.get(str(column), str(column))
