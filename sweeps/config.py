"""Sweep definitions: a TOML file -> a frozen, validated :class:`SweepConfig`.

A sweep file names a model preset (plus overrides), the run settings, the axes of the design and the
replicates. Its tables (every key is checked; unknown keys get a did-you-mean)::

    name = "holland648"            # results go to results/<name>/ by default
    description = "..."
    seed = 648                      # sweep seed: every run seed derives from it
    replicates = 1
    common_random_numbers = false   # true: replicate r has the same seed at every design point

    [model]
    preset = "../models/holland.toml"        # relative to this file (or absolute, or to the cwd)
    set = { "perception.occlusion" = true }  # preset overrides, dotted keys

    [run]                           # all optional; defaults from the preset / analysis
    n = 100                         # init.n
    duration = 30.0                 # seconds      (run.duration)
    dt = 0.016666666666666666       #              (run.dt)
    record_interval = 1.0           # seconds between metric records (run.record_interval)
    warmup = 3.0                    # seconds excluded from window summaries
    group_radius = "auto"           # "auto" = the model's perception range, or a number
    fragmentation_cohesion = 0.5    # cohesion below this counts as fragmented
    keep = "metrics"                # or "trajectories" (positions and velocities per run)
    trajectory_every = 6            # steps between stored trajectory frames when keep = "trajectories"
    leadership_metrics = "auto"     # trigger rate, follow response...: "auto" = when leadership.x is swept or > 0

    [[axes]]                        # one factor: a key and its values (cartesian product of all axes)
    name = "mode"                   # column name (default: the key)
    key = "patterns.enabled"
    values = [false, true]
    labels = ["normal", "pattern"]  # optional display labels, one per value

    [[axes]]                        # a zipped factor: several keys varied together
    name = "vision"
    keys = ["perception.direction_deg", "perception.field_deg"]
    values = [[20, 60], [90, 60]]

    [[axes]]                        # evenly spaced values
    key = "perception.range"
    linspace = { start = 10, stop = 40, num = 4 }

    [sample]                        # a sampled block over bounds, one more factor of the product
    method = "lhs"                  # "random", "lhs" or "sobol" (scipy.stats.qmc)
    n = 32
    bounds = { "perception.field_deg" = [30, 360], "init.n" = [20, 100] }   # integer keys are rounded

    [report]                        # free-form settings for `flocksweep report`

Axis keys are preset keys (``perception.*``, ``steering.*``, ``vehicle.*``, ``world.*``,
``patterns.*``, ``init.*``, ``run.*``) or ``n`` (= ``init.n``). Values are validated by building every
run's preset before anything runs (see :mod:`sweeps.design`).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from simcore.params import read_toml
from simcore.schema import ConfigError, read_config, set_dotted, suggest

SAMPLE_METHODS = ("random", "lhs", "sobol")
KEEP = ("metrics", "trajectories")
KEY_ALIASES = {"n": "init.n"}

TOP_KEYS = ("name", "description", "seed", "replicates", "common_random_numbers", "model", "run", "axes",
            "sample", "report")
MODEL_KEYS = ("preset", "set")
RUN_KEYS = ("n", "duration", "dt", "record_interval", "warmup", "group_radius", "fragmentation_cohesion",
            "keep", "trajectory_every", "leadership_metrics")
AXIS_KEYS = ("name", "key", "keys", "values", "labels", "linspace", "range")
SAMPLE_KEYS = ("method", "n", "bounds", "scramble")
RESERVED_COLUMNS = ("run_id", "index", "point_index", "replicate", "seed", "status", "error", "sim_s", "wall_s",
                    "part", "n", "steps")


@dataclass(frozen=True)
class Axis:
    """One factor of the design: ``points`` are tuples of values for ``keys`` (one key unless zipped)."""

    name: str
    keys: tuple[str, ...]
    points: tuple[tuple, ...]
    labels: tuple[str, ...] | None = None


@dataclass(frozen=True)
class Sample:
    method: str
    n: int
    bounds: tuple[tuple[str, float, float], ...]
    scramble: bool = True


@dataclass(frozen=True)
class Analysis:
    """Run settings that shape what is computed from a simulation (not the simulation itself)."""

    warmup: float = 3.0
    group_radius: float | None = None  # None: the model's perception range
    fragmentation_cohesion: float = 0.5
    keep: str = "metrics"
    trajectory_every: int = 6
    leadership: bool = False  # leadership metrics (trigger rate, follow response, ...) for every run


@dataclass(frozen=True)
class SweepConfig:
    name: str
    description: str
    seed: int
    replicates: int
    common_random_numbers: bool
    preset_path: Path
    preset_data: dict = field(repr=False, compare=False, hash=False)  # preset TOML with all overrides
    analysis: Analysis
    axes: tuple[Axis, ...]
    sample: Sample | None
    report: dict = field(repr=False, compare=False, hash=False)
    source: dict = field(repr=False, compare=False, hash=False)  # the sweep file as given (+ --set)

    @property
    def factors(self) -> tuple[str, ...]:
        names = [a.name for a in self.axes]
        if self.sample:
            names += [key for key, _, _ in self.sample.bounds]
        return tuple(names)


def _check_keys(table: dict, allowed, where: str) -> None:
    if not isinstance(table, dict):
        raise ConfigError(where, f"expected a table, got {table!r}")
    for key in table:
        if key not in allowed:
            raise ConfigError(f"{where}.{key}" if where else key,
                              "unknown key" + suggest(key, allowed) + f"; allowed keys: {', '.join(allowed)}")


def _typed(value, kind, key: str, allowed: str):
    ok = isinstance(value, kind) and not (kind is not bool and isinstance(value, bool))
    if kind is float:
        ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
    if not ok:
        raise ConfigError(key, f"got {value!r}; expected {allowed}")
    return float(value) if kind is float else value


def _resolve_preset_path(text: str, base: Path) -> Path:
    candidates = [Path(text)] if Path(text).is_absolute() else [base / text, Path.cwd() / text]
    for path in candidates:
        if path.is_file():
            return path.resolve()
    tried = ", ".join(str(p) for p in candidates)
    raise ConfigError("model.preset", f"model file not found: {text!r} (looked at {tried})")


def canonical_key(key: str, where: str) -> str:
    if not isinstance(key, str) or not key:
        raise ConfigError(where, f"got {key!r}; expected a dotted preset key such as 'perception.field_deg'")
    return KEY_ALIASES.get(key, key)


def _axis_points(axis: dict, where: str, n_keys: int) -> list:
    given = [k for k in ("values", "linspace", "range") if k in axis]
    if len(given) != 1:
        raise ConfigError(where, "give exactly one of 'values', 'linspace' or 'range'")
    if "values" in axis:
        values = axis["values"]
        if not isinstance(values, list) or not values:
            raise ConfigError(f"{where}.values", f"got {values!r}; expected a non-empty list")
    elif "linspace" in axis:
        spec = axis["linspace"]
        _check_keys(spec, ("start", "stop", "num"), f"{where}.linspace")
        start, stop = (_typed(spec.get(k), float, f"{where}.linspace.{k}", "a number") for k in ("start", "stop"))
        num = _typed(spec.get("num"), int, f"{where}.linspace.num", "an integer >= 1")
        if num < 1:
            raise ConfigError(f"{where}.linspace.num", f"got {num}; expected an integer >= 1")
        values = [start + (stop - start) * k / (num - 1) if num > 1 else start for k in range(num)]
    else:
        spec = axis["range"]
        _check_keys(spec, ("start", "stop", "step"), f"{where}.range")
        start, stop, step = (_typed(spec.get(k), float, f"{where}.range.{k}", "a number")
                             for k in ("start", "stop", "step"))
        if step <= 0 or stop < start:
            raise ConfigError(f"{where}.range", "needs step > 0 and stop >= start")
        count = int(math.floor((stop - start) / step + 1e-9)) + 1
        values = [start + k * step for k in range(count)]
    if n_keys == 1:
        return [(v,) for v in values]
    points = []
    for k, value in enumerate(values):
        if not isinstance(value, list) or len(value) != n_keys:
            raise ConfigError(f"{where}.values[{k}]",
                              f"got {value!r}; a zipped axis needs lists of {n_keys} values, one per key")
        points.append(tuple(value))
    return points


def parse_axis(axis: dict, index: int) -> Axis:
    where = f"axes[{index}]"
    _check_keys(axis, AXIS_KEYS, where)
    if ("key" in axis) == ("keys" in axis):
        raise ConfigError(where, "give exactly one of 'key' (one factor) or 'keys' (zipped factors)")
    if "key" in axis:
        keys = (canonical_key(axis["key"], f"{where}.key"),)
    else:
        raw = axis["keys"]
        if not isinstance(raw, list) or len(raw) < 2:
            raise ConfigError(f"{where}.keys", f"got {raw!r}; a zipped axis needs a list of >= 2 keys")
        keys = tuple(canonical_key(k, f"{where}.keys") for k in raw)
    points = _axis_points(axis, where, len(keys))
    name = axis.get("name", keys[0] if len(keys) == 1 else "+".join(keys))
    _typed(name, str, f"{where}.name", "a string")
    if name in RESERVED_COLUMNS:
        raise ConfigError(f"{where}.name", f"got {name!r}; that name is a results column "
                                           f"({', '.join(RESERVED_COLUMNS)}); choose another")
    labels = axis.get("labels")
    if labels is not None:
        if not isinstance(labels, list) or len(labels) != len(points) or not all(isinstance(s, str) for s in labels):
            raise ConfigError(f"{where}.labels", f"got {labels!r}; expected {len(points)} strings, one per value")
        labels = tuple(labels)
    if len(set(map(repr, points))) != len(points):
        raise ConfigError(f"{where}.values", "values repeat; use 'replicates' for repeated runs")
    return Axis(name=name, keys=keys, points=tuple(points), labels=labels)


def parse_sample(sample: dict) -> Sample:
    _check_keys(sample, SAMPLE_KEYS, "sample")
    method = sample.get("method", "lhs")
    if method not in SAMPLE_METHODS:
        raise ConfigError("sample.method", f"got {method!r}; allowed: {', '.join(SAMPLE_METHODS)}" +
                          suggest(str(method), SAMPLE_METHODS))
    n = _typed(sample.get("n"), int, "sample.n", "an integer >= 1")
    if n < 1:
        raise ConfigError("sample.n", f"got {n}; expected an integer >= 1")
    bounds = sample.get("bounds")
    if not isinstance(bounds, dict) or not bounds:
        raise ConfigError("sample.bounds", "expected a table of key = [low, high]")
    out = []
    for key, pair in bounds.items():
        where = f"sample.bounds.{key}"
        if not (isinstance(pair, list) and len(pair) == 2):
            raise ConfigError(where, f"got {pair!r}; expected [low, high]")
        low, high = (_typed(v, float, where, "numbers [low, high]") for v in pair)
        if not low < high:
            raise ConfigError(where, f"got {pair!r}; low must be < high")
        out.append((canonical_key(key, where), low, high))
    scramble = _typed(sample.get("scramble", True), bool, "sample.scramble", "true or false")
    return Sample(method=method, n=n, bounds=tuple(out), scramble=scramble)


def _parse_run(run: dict) -> tuple[list[str], Analysis]:
    _check_keys(run, RUN_KEYS, "run")
    overrides = []
    for key, target in (("n", "init.n"), ("duration", "run.duration"), ("dt", "run.dt"),
                        ("record_interval", "run.record_interval")):
        if key in run:
            overrides.append((target, run[key]))
    warmup = _typed(run.get("warmup", 3.0), float, "run.warmup", "a number >= 0")
    if warmup < 0:
        raise ConfigError("run.warmup", f"got {warmup}; expected a number >= 0")
    radius = run.get("group_radius", "auto")
    if radius != "auto":
        radius = _typed(radius, float, "run.group_radius", "\"auto\" or a number > 0")
        if radius <= 0:
            raise ConfigError("run.group_radius", f"got {radius}; expected \"auto\" or a number > 0")
    frag = _typed(run.get("fragmentation_cohesion", 0.5), float, "run.fragmentation_cohesion", "a number in (0, 1]")
    if not 0 < frag <= 1:
        raise ConfigError("run.fragmentation_cohesion", f"got {frag}; expected a number in (0, 1]")
    keep = run.get("keep", "metrics")
    if keep not in KEEP:
        raise ConfigError("run.keep", f"got {keep!r}; allowed: {', '.join(KEEP)}" + suggest(str(keep), KEEP))
    every = _typed(run.get("trajectory_every", 6), int, "run.trajectory_every", "an integer >= 1")
    if every < 1:
        raise ConfigError("run.trajectory_every", f"got {every}; expected an integer >= 1")
    lead = run.get("leadership_metrics", "auto")
    if lead not in ("auto", True, False):
        raise ConfigError("run.leadership_metrics", f"got {lead!r}; allowed: \"auto\", true, false")
    analysis = Analysis(warmup=warmup, group_radius=None if radius == "auto" else radius,
                        fragmentation_cohesion=frag, keep=keep, trajectory_every=every,
                        leadership=lead is True)
    return overrides, analysis, lead == "auto"


def sweep_from_dict(data: dict, base: Path) -> SweepConfig:
    """Validated sweep from a parsed TOML dict; ``base`` is the folder relative paths start from."""
    _check_keys(data, TOP_KEYS, "")
    name = _typed(data.get("name"), str, "name", "a non-empty string naming the sweep")
    if not name or "/" in name or name.startswith("."):
        raise ConfigError("name", f"got {name!r}; expected a plain folder name")
    seed = _typed(data.get("seed", 0), int, "seed", "an integer >= 0")
    replicates = _typed(data.get("replicates", 1), int, "replicates", "an integer >= 1")
    if seed < 0:
        raise ConfigError("seed", f"got {seed}; expected an integer >= 0")
    if replicates < 1:
        raise ConfigError("replicates", f"got {replicates}; expected an integer >= 1")
    crn = _typed(data.get("common_random_numbers", False), bool, "common_random_numbers", "true or false")
    model = data.get("model")
    if model is None:
        raise ConfigError("model", "missing table: name a preset with [model] preset = \"...\"")
    _check_keys(model, MODEL_KEYS, "model")
    preset_text = _typed(model.get("preset"), str, "model.preset", "a path to a model preset TOML")
    preset_path = _resolve_preset_path(preset_text, base)
    model_set = model.get("set", {})
    _check_keys(model_set, tuple(model_set), "model.set")
    run_overrides, analysis, lead_auto = _parse_run(data.get("run", {}))
    preset_data = read_toml(preset_path)
    for key, value in list(model_set.items()) + run_overrides:
        set_dotted(preset_data, canonical_key(key, f"model.set.{key}"), value)
    axes_data = data.get("axes", [])
    if not isinstance(axes_data, list):
        raise ConfigError("axes", "expected an array of tables: [[axes]]")
    axes = tuple(parse_axis(a, k) for k, a in enumerate(axes_data))
    sample = parse_sample(data["sample"]) if "sample" in data else None
    names = [a.name for a in axes] + ([k for k, _, _ in sample.bounds] if sample else [])
    keys = [k for a in axes for k in a.keys] + ([k for k, _, _ in sample.bounds] if sample else [])
    for label, items in (("axis name", names), ("key", keys)):
        dupes = sorted({x for x in items if items.count(x) > 1})
        if dupes:
            raise ConfigError("axes", f"{label} {dupes[0]!r} is swept twice")
    if lead_auto:  # leadership metrics when leadership is swept or switched on
        x = preset_data.get("leadership", {}).get("x", 0)
        uses = "leadership.x" in keys or (isinstance(x, (int, float)) and x > 0)
        analysis = dataclasses.replace(analysis, leadership=bool(uses))
    report = data.get("report", {})
    _check_keys(report, tuple(report), "report")
    return SweepConfig(name=name, description=str(data.get("description", "")), seed=seed,
                       replicates=replicates, common_random_numbers=crn, preset_path=preset_path,
                       preset_data=preset_data, analysis=analysis, axes=axes, sample=sample, report=report,
                       source=data)


def load_sweep(path, overrides=(), replicates: int | None = None) -> SweepConfig:
    """Read a sweep TOML, apply ``key=value`` overrides (of the sweep file's own keys), validate."""
    path = Path(path)
    data = read_config(path, "sweep file", overrides)
    if replicates is not None:
        data["replicates"] = replicates
    return sweep_from_dict(data, path.resolve().parent)


def describe(config: SweepConfig) -> dict[str, Any]:
    """Short JSON-ready description of the design (factors and their levels)."""
    out = {a.name: {"keys": list(a.keys), "levels": list(a.labels or [list(p) if len(p) > 1 else p[0]
                                                                     for p in a.points])}
           for a in config.axes}
    if config.sample:
        out["sample"] = {"method": config.sample.method, "n": config.sample.n,
                         "bounds": {k: [lo, hi] for k, lo, hi in config.sample.bounds}}
    return out
