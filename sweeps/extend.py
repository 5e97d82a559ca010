"""Adding design points to a stored sweep, through the sweep machinery: the same store, the same run
identities, the same runner. The emulator's refinement (analysis.calibration.refine) adds its points
this way; so can anyone.

Contract
--------
``stored_sweep(results_dir) -> (SweepConfig, sweep_text)``
    The sweep as it was run, rebuilt from ``sweep.effective.json`` (its tables, with the sampled
    block's bounds put back in the order of ``model.json``'s swept keys: the stored JSON sorts keys, and
    the order fixes a sample's columns) and ``model.json`` (the preset path it named, and the preset data
    it ran with, which replaces the file's current content), and ``sweep.toml``'s text. Every run id of
    the rebuilt design must be in ``design.parquet``: otherwise ValueError (this code or the preset
    file resolves the design differently, so its runs would be new ones, not the stored ones).

``add_points(results_dir, points, *, executor, workers, scheduler, progress) -> (SweepResult, added)``
    The stored sweep with ``points`` ({swept key: value}, every swept key given) appended to its
    ``[[points]]``, run with :func:`sweeps.runner.run_sweep`: finished runs are found by id and skipped,
    the new points' runs (``replicates`` each, seeds and ids as every design point's) are computed and
    everything is consolidated into ``runs.parquet``; ``sweep.effective.json`` records the points, so
    the next ``stored_sweep`` includes them. Points already in the design are skipped. Runs of the
    stored design that the rebuilt one does not list (replicates added by ``--until-ci``) are kept in
    the table. ``added`` lists the new points' specs.
"""
from __future__ import annotations

import copy
import dataclasses
from pathlib import Path

from flocksweep.simcore.params import canonical_key
from flocksweep.simcore.schema import get_dotted

from .config import SweepConfig, sweep_from_dict
from .design import RunSpec, base_preset, expand, stored_spec
from .identity import point_key
from .runner import SweepResult, run_sweep
from .store import ResultsStore

DESIGN_COLUMNS = ("run_id", "index", "point_index", "replicate", "seed", "n", "steps")


def _ordered_bounds(source: dict, swept_keys: list[str]) -> dict:
    order = {key: i for i, key in enumerate(swept_keys)}
    out = copy.deepcopy(source)
    for block in ("sample", "design"):
        if block in out and isinstance(out[block].get("bounds"), dict):
            items = sorted(out[block]["bounds"].items(), key=lambda kv: order.get(canonical_key(kv[0]), len(order)))
            out[block]["bounds"] = dict(items)
    return out


def stored_sweep(results_dir) -> tuple[SweepConfig, str]:
    """The stored sweep, rebuilt and checked against its stored design (see the module docstring)."""
    store = ResultsStore(results_dir)
    record, source, design = store.model(), store.read_json("sweep.effective.json"), store.design()
    if not record or source is None or design is None:
        raise FileNotFoundError(f"{results_dir}: not a sweep results folder (model.json, sweep.effective.json or "
                                "design.parquet missing)")
    if "command" in record:
        raise ValueError(f"{results_dir}: a sweep of an external command (model.json names a command, not a preset):"
                         " add points by adding them to its sweep file's [[points]] and running it again")
    source = _ordered_bounds(source, [str(k) for k in record.get("swept_keys", [])])
    rebuilt = copy.deepcopy(source)
    rebuilt["model"] = {**rebuilt.get("model", {}), "preset": record["preset_path"]}
    config = sweep_from_dict(rebuilt, Path(results_dir))
    config = dataclasses.replace(config, preset_data=copy.deepcopy(record["preset"]), source=source)
    stored = set(design["run_id"])
    missing = [spec for spec in expand(config) if spec.run_id not in stored]
    if missing:
        raise ValueError(f"{results_dir}: {len(missing)} run(s) of the rebuilt design are not in the stored "
                         "design (this version resolves the sweep differently from the one that ran it); run the "
                         "sweep again with `flocksweep run` before adding points")
    text_path = Path(results_dir) / "sweep.toml"
    return config, text_path.read_text() if text_path.exists() else ""


def _kept_stored_specs(store: ResultsStore, specs: list[RunSpec]) -> list[RunSpec]:
    """Specs of stored design rows the rebuilt design does not list (e.g. --until-ci replicates)."""
    listed = {spec.run_id for spec in specs}
    record, design = store.model(), store.design()
    extra = design[~design["run_id"].isin(listed)]
    out = []
    for row in extra.to_dict("records"):
        spec = stored_spec(record, row)
        columns = tuple((c, row[c]) for c in design.columns if c not in DESIGN_COLUMNS)
        out.append(dataclasses.replace(spec, columns=columns))
    return out


def add_points(results_dir, points: list[dict], *, executor: str = "local", workers: int | None = None,
               scheduler: str | None = None, progress: bool = True) -> tuple[SweepResult, list[RunSpec]]:
    """Append ``points`` to the stored sweep and run them (see the module docstring)."""
    config, text = stored_sweep(results_dir)
    current = expand(config)
    base = base_preset(config)
    known = {_resolved_point(spec.preset, config) for spec in current}
    fresh = []
    for point in points:
        point = {canonical_key(k): v for k, v in point.items()}
        key = _resolved_point(base.replace(point), config)
        if key not in known:
            known.add(key)
            fresh.append(point)
    all_points = list(config.points) + fresh
    extended = dataclasses.replace(config, points=tuple(all_points),
                                   source={**config.source, "points": [dict(p) for p in all_points]})
    specs = expand(extended)
    before = {spec.run_id for spec in current}
    store = ResultsStore(results_dir)
    result = run_sweep(extended, text, results_dir, executor=executor, workers=workers, scheduler=scheduler,
                       progress=progress, specs=specs + _kept_stored_specs(store, specs))
    return result, [spec for spec in specs if spec.run_id not in before]


def _resolved_point(preset, config: SweepConfig) -> str:
    """The canonical point key of a preset's swept values (as :func:`sweeps.design.expand` computes it)."""
    values = preset.full_dict()
    return point_key({key: get_dotted(values, key) for key in config.swept_keys})
