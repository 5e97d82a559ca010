"""Content-addressed run identity.

* ``point_key(values)``: canonical JSON of a parameter point {dotted key: resolved value}.
* ``run_id(resolved_preset, metrics, storage, seed)``: the first 20 hex digits of the SHA-256 of the
  canonical JSON of everything that determines a run's results: the resolved preset (model, initial
  conditions, run settings), the metric settings (warm-up, group radius resolved for the run,
  fragmentation threshold, leadership metrics when on, the directional correlation delays' largest
  delay when they are on, the obstacle/predator/prey metric settings and the settings of the observables
  of collective motion that differ from their defaults) and what is stored (keep, trajectory_every), the
  seed and ``simcore.MODEL_VERSION``. Run seeds are :func:`sweeps.seeds.run_seed`.
"""
from __future__ import annotations

import hashlib
import json

from flocksweep.observables.summary import encounter_settings, motion_settings
from flocksweep.simcore import MODEL_VERSION


def canonical(obj) -> str:
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), allow_nan=False)


def point_key(values: dict) -> str:
    return canonical(values)


def run_id(resolved_preset: dict, metrics, storage, seed: int) -> str:
    """``metrics``: the run's resolved MetricSettings; ``storage``: its Storage settings."""
    settings = {"warmup": metrics.warmup, "group_radius": float(metrics.group_radius),
                "fragmentation_cohesion": metrics.fragmentation_cohesion, "keep": storage.keep,
                "trajectory_every": storage.trajectory_every}
    if metrics.leadership:  # added later: absent when off, so earlier run ids stay valid
        settings["leadership"] = True
    if metrics.dcd:  # likewise
        settings["dcd_max_delay"] = metrics.dcd_max_delay
    settings.update(encounter_settings(metrics))  # likewise: only those that differ from their defaults
    settings.update(motion_settings(metrics))     # likewise
    spec = {"model_version": MODEL_VERSION, "preset": resolved_preset, "analysis": settings, "seed": seed}
    return hashlib.sha256(canonical(spec).encode()).hexdigest()[:20]
