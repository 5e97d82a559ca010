"""The names of the metric columns, declared without the code that computes them.

A run's row (:func:`observables.summary.summarize_run`) and its time series hold these columns; this
module lists them and nothing else, importing nothing (no numpy, no numba), so code that only reads
results (``flocksweep status``, the results store's schema check of a part) knows every metric column
without loading the kernels. Each metric's home module takes its names from here:

* ``SERIES``: the per-record series of :func:`observables.metrics.frame_metrics`, in kernel column order
  (``observables.kernels.COLUMNS``, ``observables.metrics.METRIC_NAMES``);
* ``PERCEPTION_SERIES``: the series of ``SERIES`` read from the recorded perception (``visible``,
  ``binocular``), which no tracker measures (nan in measured tracks, refused as track targets);
* ``PAIRWISE_SERIES``: the series of ``SERIES`` that rank every pair of every record (k nearest
  neighbours, correlation length), nan when ``MetricSettings.pairwise`` is off;
* ``MOTION_METRIC_NAMES``: the per-run scalars of collective motion of every row (:mod:`~observables.motion`:
  autocorrelation times, turning-rate and speed distributions, state occupancy);
* ``WALL_METRIC_NAMES``: a tank's wall scalars (:mod:`~observables.walls`), in the rows of runs and tracks
  with one;
* ``RUN_COLUMNS``: the run scalars of every row; ``LEADERSHIP_METRIC_NAMES`` (:mod:`~observables.leadership`),
  ``DCD_METRIC_NAMES`` (:mod:`~observables.directional_correlation`), ``MIGRATION_METRIC_NAMES``
  (:mod:`~observables.migration`);
* the encounter families (:mod:`~observables.encounters`): ``FAMILIES`` {family: (series, scalars)};
* ``encounter_columns(families)`` and ``summary_columns(leadership, migration, encounters, dcd, walls)``: the row
  columns in order; ``EVERY_METRIC_COLUMN``: the columns any run's row may hold (a sweep's metric columns).
"""
from __future__ import annotations

SERIES = ("polarization", "polarization_largest", "milling", "n_groups", "cohesion", "stray_fraction",
          "nn_distance", "gyration_radius", "elongation", "aspect_heading", "speed_mean", "speed_cv",
          "visible_mean", "visible_sd", "binocular_share", "segregation", "elongation_heading", "overtake_rate",
          # the field's observables of collective motion (docs/metrics.md "Observables of collective motion")
          "nn_ahead_fraction", "nn_bearing_deg", "nn_anisotropy", "knn_ahead_fraction", "knn_bearing_deg",
          "knn_anisotropy", "corr_length", "edge_spacing_ratio", "front_spacing_ratio")
PAIRWISE_SERIES = ("knn_ahead_fraction", "knn_bearing_deg", "knn_anisotropy", "corr_length")  # off: nan (pairwise_metrics)
PERCEPTION_SERIES = ("visible_mean", "visible_sd", "binocular_share")   # what a simulated boid perceives: no tracker measures it
RUN_COLUMNS = ("time_to_fragmentation", "fragmented")
# per-run scalars of every row, from the records of the window (observables.motion)
MOTION_METRIC_NAMES = ("heading_autocorr_time", "turn_rate_mean", "turn_rate_q10", "turn_rate_q50", "turn_rate_q90",
                       "speed_autocorr_time", "speed_q10", "speed_q50", "speed_q90", "speed_cv_pooled",
                       "swarming_fraction", "polarized_fraction", "milling_fraction")
LEADERSHIP_METRIC_NAMES = ("trigger_rate", "leader_time_fraction", "leaders_mean", "follow_corr_lag0",
                           "follow_corr_max", "follow_lag_max", "follow_corr_before", "heading_change_deg",
                           "escape_gain")
DCD_METRIC_NAMES = ("dcd_corr_mean", "dcd_delay_mean", "dcd_edges", "dcd_leader_delay")
MIGRATION_METRIC_NAMES = ("migratory_progress", "migratory_efficiency")
WALL_METRIC_NAMES = ("wall_distance_mean", "wall_distance_q10", "wall_distance_q50", "wall_facing_near")

OBSTACLE_SERIES = ("collisions", "collision_fraction", "clearance")
OBSTACLE_SCALARS = ("collided_boids", "collision_events", "clearance_min")
PREDATOR_SERIES = ("predator_distance", "predator_near", "predator_in_capture", "flock_gyration_radius")
PREDATOR_SCALARS = ("predator_captures", "predator_distance_min", "flash_nn_ratio", "flash_gyration_ratio",
                    "groups_before_predator", "groups_near_predator", "groups_near_predator_max", "remerge_time")
PREY_SERIES = ("prey_distance", "prey_within_fraction")
PREY_SCALARS = ("prey_reach_time", "prey_first_reach_time")
FAMILIES = {"obstacles": (OBSTACLE_SERIES, OBSTACLE_SCALARS), "predator": (PREDATOR_SERIES, PREDATOR_SCALARS),
            "prey": (PREY_SERIES, PREY_SCALARS)}


def encounter_columns(families=("obstacles", "predator", "prey")) -> tuple[str, ...]:
    """Row columns of the given families, in row order: each family's series means and finals, then
    its scalars."""
    columns = []
    for family in families:
        series, scalars = FAMILIES[family]
        columns += [f"{name}_{kind}" for name in series for kind in ("mean", "final")]
        columns += list(scalars)
    return tuple(columns)


def summary_columns(leadership: bool = True, migration: bool = False,
                    encounters: tuple[str, ...] = (), dcd: bool = False, walls: bool = False) -> tuple[str, ...]:
    """The columns :func:`~observables.summary.summarize_run`'s row may hold, in order: every series' mean and
    final value, the motion scalars, the fragmentation columns, then with or without the
    leadership scalars, the directional correlation delays, the migration scalars, the tank's wall scalars
    (a run in an arena, tracks that declare theirs: :mod:`~observables.walls`), then the columns of the
    given encounter families (all of ``FAMILIES`` for all; a row has a family's columns only when its run
    has obstacles, a predator or prey, see :mod:`observables.encounters`)."""
    columns = tuple(f"{name}_{kind}" for name in SERIES for kind in ("mean", "final")) + MOTION_METRIC_NAMES
    columns += RUN_COLUMNS
    columns += LEADERSHIP_METRIC_NAMES if leadership else ()
    columns += DCD_METRIC_NAMES if dcd else ()
    columns += MIGRATION_METRIC_NAMES if migration else ()
    columns += WALL_METRIC_NAMES if walls else ()
    return columns + encounter_columns(encounters)


EVERY_METRIC_COLUMN = frozenset(summary_columns(leadership=True, migration=True, encounters=tuple(FAMILIES),
                                                walls=True))
