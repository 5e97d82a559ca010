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
    set = { "perception.occlusion" = true }  # preset overrides, dotted keys; a nested table merges
                                             # into the preset's (set.perception.range = 30 changes
                                             # only that key), it does not replace it

    # or, for an external simulator run as a command (sweeps.external; docs/sweeps.md):
    # [model]
    # command = ["mysim", "--seed", "{seed}", "--out", "{out}", "{params}"]
    # [model.parameters]
    # noise = { default = 0.3, bounds = [0, 3] }   # axes and bounds then name these parameters

    [run]                           # all optional; defaults from the preset / analysis
    n = 100                         # init.n
    duration = 30.0                 # seconds      (run.duration)
    dt = 0.016666666666666666       #              (run.dt)
    record_interval = 1.0           # seconds between metric records (run.record_interval)
    warmup = 3.0                    # seconds excluded from window summaries
    group_radius = "auto"           # "auto" = the model's perception range, or a number
    fragmentation_cohesion = 0.5    # cohesion below this counts as fragmented
    capture_radius = 1.0            # predator metrics: a boid this close to the predator is captured
    predator_near = 10.0            # predator metrics: the predator is near within this of the flock centre
    prey_reach = 5.0                # prey metrics: the prey is reached within this distance
    keep = "metrics"                # or "trajectories" (positions and velocities per run)
    trajectory_every = 6            # steps between stored trajectory frames when keep = "trajectories"
    leadership_metrics = "auto"     # trigger rate, follow response...: "auto" = when leadership.x is swept or > 0
    dcd_metrics = false             # directional correlation delays (Nagy et al. 2010): dcd_* columns
    dcd_max_delay = 2.0             # seconds: their largest delay (with dcd_metrics = true)
    timeout_s = 600                 # a run still going after this many seconds is stopped and recorded as
                                    # failed (default: no limit; not part of run ids; sweeps.worker)
    k_nearest = 6                   # the k of the knn_* series (neighbours in the focal frame)
    pairwise_metrics = true         # false: no knn_* or corr_length (they rank every pair of every record)
    state_high = 0.65               # state fractions (Tunstrom et al. 2013): an order parameter above this is high
    state_low = 0.35                # ... and below this low

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

    [design]                        # or a sensitivity-analysis block (sweeps.sensitivity; not with [sample])
    kind = "saltelli"               # "saltelli" (Sobol' indices: n = base size, a power of 2) or "morris"
    n = 256                         # (morris: trajectories = 20, levels = 4)
    bounds = { "perception.field_deg" = [30, 180], "perception.range" = [10, 40] }

    [[points]]                      # explicit design points after the product, every swept key given (a
    "perception.field_deg" = 135.0  # labelled axis takes one of its values); the emulator adds points here

    [report]                        # free-form settings for `flocksweep report`

    [cluster]                       # where `flocksweep run --executor cluster` runs it: batch jobs on a
    kind = "slurm"                  # SLURM, PBS, SGE or LSF cluster (sweeps.cluster); never part of a
    jobs = 4                        # run's identity

    include_claims = ["../claims/holland.toml"]   # (top level) shared claims files, tested by the report
    [[claims]]                      # a hypothesis about the results (sweeps/claims.py, docs/claims.md)
    id = "wider-is-aligned"
    statement = "A wider field of vision gives a more aligned flock."
    test = "trend"
    metric = "polarization_mean"
    factor = "perception.field_deg"
    direction = "increasing"

Axis keys are preset keys (``perception.*``, ``steering.*``, ``vehicle.*``, ``world.*``,
``patterns.*``, ``init.*``, ``run.*``) or ``n`` (= ``init.n``). Values are validated by building every
run's preset before anything runs (see :mod:`sweeps.design`); every run must record something to
summarise (:func:`check_window`: ``record_interval <= duration`` and a record at or after ``warmup``).

Overrides (``--set``) change keys of the file; ``model.<preset key>=value`` is short for
``model.set.<preset key>=value``, and either changes that one key of the preset (:mod:`sweeps.model_set`).
``name`` is a plain folder name (no ``/``, ``\\``, control characters or leading dot, <= :data:`NAME_MAX` chars).

A ``[model]`` table with ``command`` (:func:`model_table`) is an external simulator instead of a preset:
:class:`SweepConfig` then has ``command`` (a validated :class:`~sweeps.external.CommandModel`), no preset
(``preset_path`` None), swept keys that are its declared parameters (:func:`check_parameters`) and the
metric settings of measured tracks (:func:`sweeps.external.command_metrics`).

The file is read by the schema engine (:mod:`simcore.schema`) into the tables below; the ``[model]``
and ``[run]`` tables (:class:`ModelTable`, :class:`RunTable`) are shared with calibration files, and
:func:`model_data` applies them to the preset the same way for both. ``warmup``, ``group_radius`` and
``fragmentation_cohesion`` (and the leadership and directional correlation switches, ``dcd_max_delay``) become the run's
:class:`~observables.summary.MetricSettings`; ``keep`` and ``trajectory_every`` what is stored
(:class:`Storage`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace as with_fields
from pathlib import Path
from typing import Any, Literal

from flocksweep.observables.columns import EVERY_METRIC_COLUMN
from flocksweep.observables.directional_correlation import DCD_MAX_DELAY
from flocksweep.observables.metrics import FRAGMENTATION_COHESION, WARMUP_S
from flocksweep.observables.summary import (ENCOUNTER_SETTINGS, MOTION_SETTINGS, MetricSettings, encounter_settings,
                                            motion_settings)
from flocksweep.simcore.params import RUN_SHORTHANDS, canonical_key, read_toml
from flocksweep.simcore.schema import (ConfigError, FileConfig, build, check_at_least, check_finite, check_positive,
                            read_config, resolve_path, set_dotted, suggest)

from .claims import ClaimTable, load_claims, sweep_columns
from .cluster import ClusterSettings, cluster_settings
from .external import CommandModel, CommandTable, command_metrics, command_model
from .store import RESERVED_COLUMNS  # noqa: F401 - the runs table's own columns, declared there
from .model_set import flat_changes, model_overrides
from .sensitivity import DesignTable, SensitivityDesign
from .sweep_toml import sweep_toml

NAME_MAX = 100
METRIC_COLUMNS = EVERY_METRIC_COLUMN   # any run's metric columns (observables.columns)
# the statistics beside the factors in the report's cell tables (analysis.reports.stats.cell_summary)
REPORT_COLUMNS = ("n_missing", "mean", "sd", "ci_halfwidth")


# ----------------------------------------------------------------------------------------- the file

@dataclass(frozen=True)
class ModelTable:
    """``[model]`` of sweep and calibration files: the preset and fixed overrides of its keys."""

    preset: str = field(metadata={"expected": "a path to a model preset TOML"})
    set: dict = field(default_factory=dict)


@dataclass(frozen=True)
class RunTable:
    """``[run]`` of sweep and calibration files: four preset keys by short names (RUN_SHORTHANDS) and
    the metric settings."""

    n: int | None = None
    duration: float | None = None
    dt: float | None = None
    record_interval: float | None = None
    warmup: float = WARMUP_S
    group_radius: Any = field(default="auto", metadata={"expected": '"auto" or a number > 0'})
    fragmentation_cohesion: float = FRAGMENTATION_COHESION
    capture_radius: float = ENCOUNTER_SETTINGS["capture_radius"]
    predator_near: float = ENCOUNTER_SETTINGS["predator_near"]
    prey_reach: float = ENCOUNTER_SETTINGS["prey_reach"]
    dcd_max_delay: float = DCD_MAX_DELAY
    k_nearest: int = MOTION_SETTINGS["k_nearest"]
    pairwise_metrics: bool = MOTION_SETTINGS["pairwise_metrics"]
    state_high: float = MOTION_SETTINGS["state_high"]
    state_low: float = MOTION_SETTINGS["state_low"]

    def __post_init__(self):
        radius = self.group_radius
        if radius != "auto" and (isinstance(radius, bool) or not isinstance(radius, (int, float))):
            raise ConfigError("group_radius", f'got {radius!r}; expected "auto" or a number > 0')
        self.metrics(leadership=False)  # validates the metric settings

    def preset_changes(self) -> dict:
        """{short key: (preset key, value)} of the shorthands given."""
        return {short: (key, getattr(self, short)) for short, key in RUN_SHORTHANDS.items()
                if getattr(self, short) is not None}

    def metrics(self, leadership: bool, dcd: bool = False) -> MetricSettings:
        radius = None if self.group_radius == "auto" else float(self.group_radius)
        return MetricSettings(warmup=self.warmup, group_radius=radius,
                              fragmentation_cohesion=self.fragmentation_cohesion, leadership=leadership,
                              dcd=dcd, dcd_max_delay=self.dcd_max_delay,
                              **{key: getattr(self, key) for key in ENCOUNTER_SETTINGS},
                              **{key: getattr(self, key) for key in MOTION_SETTINGS})


@dataclass(frozen=True)
class SweepRunTable(RunTable):
    """A sweep's ``[run]``: the shared keys, what is stored and whether leadership metrics and directional
    correlation delays are computed."""

    keep: Literal["metrics", "trajectories"] = "metrics"
    trajectory_every: int = 6
    leadership_metrics: Any = "auto"
    dcd_metrics: bool = False
    timeout_s: float | None = field(default=None, metadata={"expected": "seconds > 0: a run still going after "
                                                                        "this long is stopped and recorded as failed"})

    def __post_init__(self):
        super().__post_init__()
        check_at_least("trajectory_every", self.trajectory_every, 1)
        if self.timeout_s is not None:
            check_positive("timeout_s", self.timeout_s)
        if self.leadership_metrics not in ("auto", True, False):
            raise ConfigError("leadership_metrics", f'got {self.leadership_metrics!r}; allowed: "auto", true, false')
        if not self.dcd_metrics and self.dcd_max_delay != DCD_MAX_DELAY:
            raise ConfigError("dcd_max_delay", "sets the directional correlation delays, which a sweep computes only "
                                               "with dcd_metrics = true: add it, or leave dcd_max_delay out")


def model_table(data) -> ModelTable | CommandTable:
    """A sweep file's ``[model]``: a :class:`~sweeps.external.CommandTable` when it gives ``command`` (an
    external simulator), else a :class:`ModelTable` (a preset); never both."""
    if not isinstance(data, dict):
        raise ConfigError("model", f"expected a table, got {data!r}")
    if "command" not in data:
        return build(ModelTable, data, "model")
    if "preset" in data or "set" in data:
        raise ConfigError("model.preset" if "preset" in data else "model.set",
                          "a [model] table names either a preset (a built-in model) or a command (an external "
                          "simulator), not both")
    table = build(CommandTable, data, "model")
    for name in table.parameters:
        if name in RESERVED_COLUMNS or name in METRIC_COLUMNS or name in REPORT_COLUMNS:
            raise ConfigError(f"model.parameters.{name}", f"{name!r} is a column of the results; name the "
                                                          "parameter otherwise (e.g. n_agents for n)")
    return table


MAX_AXIS_VALUES = 1_000_000   # an axis holds at most this many values: counted before any is listed


def _check_axis_size(key: str, count: float) -> None:
    if count > MAX_AXIS_VALUES:
        raise ConfigError(key, f"gives {count:,.0f} values; an axis holds at most {MAX_AXIS_VALUES:,} (the design "
                               "would have at least that many runs): use fewer values or split it into several sweeps")


@dataclass(frozen=True)
class Linspace:
    start: float
    stop: float
    num: int

    def __post_init__(self):
        check_finite("start", self.start)
        check_finite("stop", self.stop)
        check_at_least("num", self.num, 1)
        _check_axis_size("num", self.num)

    def values(self) -> list[float]:
        num, start, stop = self.num, self.start, self.stop
        return [start + (stop - start) * k / (num - 1) if num > 1 else start for k in range(num)]


@dataclass(frozen=True)
class Steps:
    """An axis' ``range = { start, stop, step }``."""

    start: float
    stop: float
    step: float

    def __post_init__(self):
        for name in ("start", "stop", "step"):
            check_finite(name, getattr(self, name))
        if self.step <= 0 or self.stop < self.start:
            raise ConfigError("", "needs step > 0 and stop >= start")
        _check_axis_size("step", (self.stop - self.start) / self.step + 1)

    def values(self) -> list[float]:
        count = int(math.floor((self.stop - self.start) / self.step + 1e-9)) + 1
        return [self.start + k * self.step for k in range(count)]


@dataclass(frozen=True)
class AxisTable:
    """One ``[[axes]]`` table as written (see the module docstring); :func:`parse_axis` checks the rest."""

    name: str | None = None
    key: str | None = None
    keys: tuple[str, ...] | None = None
    values: Any = None
    labels: tuple[str, ...] | None = None
    linspace: Linspace | None = None
    range: Steps | None = None


@dataclass(frozen=True, kw_only=True)
class SampleTable:
    method: Literal["random", "lhs", "sobol"] = "lhs"
    n: int = field(metadata={"expected": "an integer >= 1"})
    bounds: Any = None
    scramble: bool = True

    def __post_init__(self):
        check_at_least("n", self.n, 1)


@dataclass(frozen=True)
class SweepFile:
    """A sweep file's tables, type-checked (see the module docstring)."""

    name: str = field(metadata={"expected": "a non-empty string naming the sweep"})
    model: Any = field(metadata={"expected": 'a table naming a preset ([model] preset = "...") or a command '
                                             '([model] command = [...], sweeps.external)'})
    description: str = ""
    seed: int = 0
    replicates: int = 1
    common_random_numbers: bool = False
    run: SweepRunTable = field(default_factory=SweepRunTable)
    axes: tuple[AxisTable, ...] = field(default=(), metadata={"expected": "an array of tables: [[axes]]"})
    sample: SampleTable | None = None
    design: DesignTable | None = None
    points: tuple[dict, ...] = field(default=(), metadata={"expected": "an array of tables: [[points]]"})
    report: dict = field(default_factory=dict)
    claims: tuple[ClaimTable, ...] = field(default=(), metadata={"expected": "an array of tables: [[claims]]"})
    include_claims: tuple[Any, ...] = field(default=(), metadata={
        "expected": 'a list of claims files, e.g. ["../claims/holland.toml"]'})
    cluster: Any = field(default=None, metadata={"expected": 'a table: [cluster] kind = "slurm", ... (sweeps.cluster)'})

    def __post_init__(self):
        object.__setattr__(self, "model", model_table(self.model))   # ModelTable or external.CommandTable
        check_name(self.name, "the sweep")
        check_at_least("seed", self.seed, 0)
        check_at_least("replicates", self.replicates, 1)


def check_name(name: str, what: str) -> None:
    bad = not name or "/" in name or "\\" in name or name.startswith(".") or len(name) > NAME_MAX or \
        any(ord(c) < 32 or ord(c) == 127 for c in name)
    if bad:
        raise ConfigError("name", f"got {name!r}; expected a plain folder name for {what} (1 to {NAME_MAX} "
                                  "characters, no '/', '\\', control characters or leading '.')")


def check_window(warmup: float, run, where: str = "") -> None:
    """A run of ``run`` (a preset's RunSettings) records something to summarise: ``record_interval <=
    duration`` and a record at or after ``warmup`` (< duration). ``where`` is appended to messages."""
    if run.record_interval > run.duration:
        raise ConfigError("run.record_interval", f"got {run.record_interval!r}; must be at most the run duration "
                                                 f"{run.duration!r} (a run records at 0 s and then every "
                                                 f"record_interval){where}")
    last = (run.n_steps // run.record_every) * run.record_every * run.dt
    if warmup >= run.duration or last < warmup:
        raise ConfigError("run.warmup", f"got {warmup!r}; must be below the run duration {run.duration!r}, with a "
                                        f"record at or after it (the last is at {last:g} s), or every window mean "
                                        f"is undefined{where}")


def model_data(model: ModelTable, run: RunTable, base) -> tuple[Path, dict, dict]:
    """(preset path, the preset dict with ``model.set`` then the ``[run]`` shorthands applied, and for
    every key set that way the key of the file that set it). ``base``: the folder of the file."""
    preset_path = resolve_path(model.preset, base, "model.preset", "model file")
    if not preset_path.is_file():
        raise ConfigError("model.preset", f"not a file: {preset_path}")
    data = read_toml(preset_path)
    origin = {}
    for key, value in flat_changes(model.set).items():
        set_dotted(data, canonical_key(key), value)
        origin[canonical_key(key)] = f"model.set.{key}"
    for short, (key, value) in run.preset_changes().items():
        set_dotted(data, key, value)
        origin[key] = f"run.{short}"
    return preset_path, data, origin


# --------------------------------------------------------------------------------------- the config

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
class Storage:
    """What a run stores beside its row: ``keep = "trajectories"`` adds positions and velocities every
    ``trajectory_every`` steps."""

    keep: str = "metrics"
    trajectory_every: int = 6


@dataclass(frozen=True)
class SweepConfig(FileConfig, loader="load_sweep"):
    """A validated sweep (module docstring); ``SweepConfig.from_toml(path, overrides)`` reads a file (and its text)."""
    name: str
    description: str
    seed: int
    replicates: int
    common_random_numbers: bool
    preset_path: Path | None                                          # None for a command model
    preset_data: dict = field(repr=False, compare=False, hash=False)  # preset TOML with all overrides
    metrics: MetricSettings
    storage: Storage
    axes: tuple[Axis, ...]
    sample: Sample | None
    report: dict = field(repr=False, compare=False, hash=False)
    source: dict = field(repr=False, compare=False, hash=False)  # the sweep file as given (+ --set)
    design: SensitivityDesign | None = None
    points: tuple[dict, ...] = ()   # explicit points {swept key: value}, after the product

    @property
    def block_keys(self) -> list[str]:
        """The keys of the sampled block ([sample] or [design]), in bounds order."""
        block = self.sample or self.design
        return [key for key, _, _ in block.bounds] if block else []
    claims: tuple = field(default=(), repr=False, compare=False, hash=False)  # sweeps.claims.Claim, validated
    text: str | None = field(default=None, repr=False, compare=False, hash=False)  # the file's text, if read from one
    command: CommandModel | None = None   # an external simulator ([model] command, sweeps.external) instead of a preset
    # where the runs may execute (--executor cluster): never part of a run's identity (sweeps.cluster)
    cluster: ClusterSettings | None = field(default=None, repr=False, compare=False, hash=False)
    timeout_s: float | None = None   # run.timeout_s: each run's wall-time limit (not part of any run id)

    @classmethod
    def from_dict(cls, data: dict, base: str | Path | None = None) -> SweepConfig:
        """Validate a sweep given as a dict of a sweep file's tables (:func:`sweep_from_dict`); relative
        paths start from ``base`` (default: the working directory). Running it stores :meth:`to_toml`."""
        return sweep_from_dict(data, Path.cwd() if base is None else Path(base))

    def to_toml(self) -> str:
        """TOML text that reads back as this sweep (same run ids), from any folder (:mod:`sweeps.sweep_toml`)."""
        return sweep_toml(self)

    @property
    def factors(self) -> tuple[str, ...]:
        return tuple([a.name for a in self.axes] + self.block_keys)

    @property
    def swept_keys(self) -> list[str]:
        return [k for axis in self.axes for k in axis.keys] + self.block_keys

    def analysis_record(self) -> dict:
        """The metric and storage settings as stored in ``model.json`` (``analysis``)."""
        m, s = self.metrics, self.storage
        record = {"warmup": m.warmup, "group_radius": m.group_radius, "fragmentation_cohesion": m.fragmentation_cohesion,
                  "keep": s.keep, "trajectory_every": s.trajectory_every, "leadership": m.leadership}
        if m.dcd:   # added later: absent when off, so model.json of earlier sweeps reads the same
            record["dcd_max_delay"] = m.dcd_max_delay
        return record | encounter_settings(m) | motion_settings(m)


# ------------------------------------------------------------- keys and values given by name
# swept keys, the bounds of a sampled or sensitivity block (key = [low, high]) and explicit [[points]]
# (every swept key once): each parser returns canonical keys (simcore.params.canonical_key) and raises
# ConfigError naming the table and key at fault

def canonical_axis_key(key, where: str) -> str:
    if not isinstance(key, str) or not key:
        raise ConfigError(where, f"got {key!r}; expected a dotted preset key such as 'perception.field_deg'")
    return canonical_key(key)


def parse_bounds(bounds, where_table: str) -> tuple[tuple[str, float, float], ...]:
    """A table of key = [low, high] -> ((canonical key, low, high), ...)."""
    if not isinstance(bounds, dict) or not bounds:
        raise ConfigError(where_table, "expected a table of key = [low, high]")
    out = []
    for key, pair in bounds.items():
        where = f"{where_table}.{key}"
        numbers = isinstance(pair, list) and len(pair) == 2 and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in pair)
        if not numbers:
            raise ConfigError(where, f"got {pair!r}; expected [low, high] (finite numbers)")
        low, high = map(float, pair)
        if not low < high:
            raise ConfigError(where, f"got {pair!r}; low must be < high")
        out.append((canonical_axis_key(key, where), low, high))
    return tuple(out)


def parse_points(points: tuple[dict, ...], axes: tuple, keys: list[str]) -> tuple[dict, ...]:
    """``[[points]]``: each a table giving every swept key once (canonical keys); a labelled axis'
    value must be one of its values (it takes that value's label)."""
    out = []
    for i, point in enumerate(points):
        where = f"points[{i}]"
        given = {}
        for key, value in point.items():
            canonical = canonical_axis_key(key, where)
            if canonical not in keys:
                raise ConfigError(f"{where}.{key}", f"not a swept key{suggest(canonical, keys)}; a point gives a "
                                                    f"value to each swept key: {', '.join(keys)}")
            given[canonical] = value
        missing = [k for k in keys if k not in given]
        if missing:
            raise ConfigError(where, f"missing swept key(s) {', '.join(missing)}; a point gives a value to each "
                                     f"swept key: {', '.join(keys)}")
        for axis in axes:
            if axis.labels and tuple(given[k] for k in axis.keys) not in axis.points:
                raise ConfigError(f"{where}.{axis.keys[0]}", f"got {given[axis.keys[0]]!r}; axis {axis.name!r} is "
                                                             f"labelled, so a point takes one of its values "
                                                             f"{[p[0] if len(p) == 1 else list(p) for p in axis.points]}")
        out.append(given)
    return tuple(out)


def _axis_points(axis: AxisTable, where: str, n_keys: int) -> list:
    given = [k for k in ("values", "linspace", "range") if getattr(axis, k) is not None]
    if len(given) != 1:
        raise ConfigError(where, "give exactly one of 'values', 'linspace' or 'range'")
    if axis.values is not None:
        values = axis.values
        if not isinstance(values, list) or not values:
            raise ConfigError(f"{where}.values", f"got {values!r}; expected a non-empty list")
    else:
        values = (axis.linspace or axis.range).values()
    if n_keys == 1:
        return [(v,) for v in values]
    points = []
    for k, value in enumerate(values):
        if not isinstance(value, list) or len(value) != n_keys:
            raise ConfigError(f"{where}.values[{k}]",
                              f"got {value!r}; a zipped axis needs lists of {n_keys} values, one per key")
        points.append(tuple(value))
    return points


def parse_axis(axis: AxisTable, index: int) -> Axis:
    where = f"axes[{index}]"
    if (axis.key is None) == (axis.keys is None):
        raise ConfigError(where, "give exactly one of 'key' (one factor) or 'keys' (zipped factors)")
    if axis.key is not None:
        keys = (canonical_axis_key(axis.key, f"{where}.key"),)
    else:
        if len(axis.keys) < 2:
            raise ConfigError(f"{where}.keys", f"got {list(axis.keys)!r}; a zipped axis needs a list of >= 2 keys")
        keys = tuple(canonical_axis_key(k, f"{where}.keys") for k in axis.keys)
    points = _axis_points(axis, where, len(keys))
    name = axis.name if axis.name is not None else (keys[0] if len(keys) == 1 else "+".join(keys))
    if name in RESERVED_COLUMNS:
        raise ConfigError(f"{where}.name", f"got {name!r}; that name is a results column "
                                           f"({', '.join(RESERVED_COLUMNS)}); choose another")
    if name in METRIC_COLUMNS:
        raise ConfigError(f"{where}.name", f"got {name!r}; that name is a metric column of the results; choose "
                                           "another")
    if name in REPORT_COLUMNS:
        raise ConfigError(f"{where}.name", f"got {name!r}; the report's tables use that name beside the axes "
                                           f"({', '.join(REPORT_COLUMNS)}); choose another")
    if not isinstance(name, str) or not name.strip():
        raise ConfigError(f"{where}.name", f"got {name!r}; expected a non-empty name for the axis' column")
    if axis.labels is not None and len(axis.labels) != len(points):
        raise ConfigError(f"{where}.labels", f"got {list(axis.labels)!r}; expected {len(points)} strings, one per value")
    if axis.labels is not None and len(set(axis.labels)) != len(axis.labels):
        raise ConfigError(f"{where}.labels", f"got {list(axis.labels)!r}; labels repeat: each value needs its own")
    if len(set(map(repr, points))) != len(points):
        raise ConfigError(f"{where}.values", "values repeat; use 'replicates' for repeated runs")
    return Axis(name=name, keys=keys, points=tuple(points), labels=axis.labels)


def parse_sample(sample: SampleTable) -> Sample:
    return Sample(method=sample.method, n=sample.n, bounds=parse_bounds(sample.bounds, "sample.bounds"),
                  scramble=sample.scramble)


def parse_design(design: DesignTable) -> SensitivityDesign:
    return SensitivityDesign(kind=design.kind, bounds=parse_bounds(design.bounds, "design.bounds"), n=design.n,
                             second_order=design.second_order, scramble=design.scramble,
                             trajectories=design.trajectories, levels=design.levels)


def _leadership_on(setting, preset_data: dict, swept: list[str]) -> bool:
    """``leadership_metrics``: true/false as given; "auto" when leadership is swept or switched on."""
    if setting != "auto":
        return bool(setting)
    x = preset_data.get("leadership", {}).get("x", 0)
    return "leadership.x" in swept or (isinstance(x, (int, float)) and x > 0)


def sweep_from_dict(data: dict, base: Path) -> SweepConfig:
    """Validated sweep from a parsed TOML dict; ``base`` is the folder relative paths start from."""
    table = build(SweepFile, data)
    command = command_model(table.model, base) if isinstance(table.model, CommandTable) else None
    preset_path, preset_data, _ = model_data(table.model, table.run, base) if command is None else (None, {}, {})
    axes = tuple(parse_axis(a, k) for k, a in enumerate(table.axes))
    sample = parse_sample(table.sample) if table.sample else None
    design = parse_design(table.design) if table.design else None
    if sample and design:
        raise ConfigError("design", "a sweep has one sampled block: give [sample] (random, lhs, sobol) or [design] "
                                    "(saltelli, morris), not both")
    block = [k for k, _, _ in (sample or design).bounds] if (sample or design) else []
    names = [a.name for a in axes] + block
    keys = [k for a in axes for k in a.keys] + block
    for label, items in (("axis name", names), ("key", keys)):
        dupes = sorted({x for x in items if items.count(x) > 1})
        if dupes:
            raise ConfigError("axes", f"{label} {dupes[0]!r} is swept twice")
    if command is None:
        metrics = table.run.metrics(_leadership_on(table.run.leadership_metrics, preset_data, keys),
                                    table.run.dcd_metrics)
    else:
        check_parameters(command, axes, sample or design)
        metrics = command_metrics(table.run)
    claims = load_claims(table.claims, table.include_claims, base,
                         sweep_columns(axes, sample or design, metrics.leadership, metrics.dcd))
    return SweepConfig(name=table.name, description=table.description, seed=table.seed,
                       replicates=table.replicates, common_random_numbers=table.common_random_numbers,
                       preset_path=preset_path, preset_data=preset_data, metrics=metrics,
                       storage=Storage(table.run.keep, table.run.trajectory_every), axes=axes, sample=sample,
                       report=table.report, source=data, design=design,
                       points=parse_points(table.points, axes, keys), claims=claims, command=command,
                       cluster=cluster_settings(table.cluster),
                       timeout_s=None if table.run.timeout_s is None else float(table.run.timeout_s))


def check_parameters(command: CommandModel, axes: tuple[Axis, ...], block) -> None:
    """Every key a command model's design sweeps is one of its declared parameters."""
    swept = [(f"axes[{i}].key{'s' if len(axis.keys) > 1 else ''}", key) for i, axis in enumerate(axes)
             for key in axis.keys]
    if block is not None:
        table = "sample" if isinstance(block, Sample) else "design"
        swept += [(f"{table}.bounds.{key}", key) for key, _, _ in block.bounds]
    for where, key in swept:
        if key not in command.names:
            raise ConfigError(where, f"got {key!r}; not a parameter of the command{suggest(key, command.names)}: "
                                     f"declared in [model.parameters]: {', '.join(command.names) or 'none'}")


def load_sweep(path, overrides=(), replicates: int | None = None) -> SweepConfig:
    """Read a sweep TOML, apply ``key=value`` overrides (of the sweep file's own keys), validate."""
    path = Path(path)
    data = read_config(path, "sweep file", model_overrides(overrides))
    if replicates is not None:
        data["replicates"] = replicates
    return with_fields(sweep_from_dict(data, path.resolve().parent), text=path.read_text(encoding="utf-8"))


def describe(config: SweepConfig) -> dict[str, Any]:
    """Short JSON-ready description of the design (factors and their levels)."""
    out = {a.name: {"keys": list(a.keys), "levels": list(a.labels or [list(p) if len(p) > 1 else p[0]
                                                                     for p in a.points])}
           for a in config.axes}
    if config.sample:
        out["sample"] = {"method": config.sample.method, "n": config.sample.n,
                         "bounds": {k: [lo, hi] for k, lo, hi in config.sample.bounds}}
    if config.design:
        out["design"] = config.design.record()
    if config.points:
        out["points"] = len(config.points)
    return out
