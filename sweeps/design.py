"""Design expansion: a :class:`~sweeps.config.SweepConfig` -> validated, frozen :class:`RunSpec` s.

The design is the cartesian product of the axes (a zipped axis is one factor; a ``[sample]`` or
``[design]`` block is one more factor whose levels are its sampled points: :mod:`sweeps.sensitivity`;
rows of a sensitivity sample that coincide after rounding are one point), then the explicit
``[[points]]``, times ``replicates``. Every run's preset is built and validated here, before anything
runs, so a bad value fails with its axis and key named; so does a point whose run would record nothing
to summarise (:func:`sweeps.config.check_window`).

Every point's preset is the base preset (the preset file with ``model.set`` and the ``[run]``
shorthands, which must itself be valid) with the point's values set by :meth:`simcore.Preset.replace`.

Identity (:mod:`sweeps.identity`, :mod:`sweeps.seeds`): a run's seed derives from the sweep seed, the run's parameter point
(the resolved values of the swept keys) and its replicate index, so it does not change when the grid
grows, shrinks or is reordered; with ``common_random_numbers`` it derives from the sweep seed and the
replicate only. The run id is a hash of everything that determines the run's results.

Table columns (:func:`_columns`): an axis' name and every swept key with its resolved value; a value
that is a list or table (an axis over ``world.obstacles``, best labelled) is stored as its canonical
JSON text.

Order: ``RunSpec.index`` = point index x replicates + replicate, with points in the order of the axes'
nested loops (first axis outermost), the explicit points last. Results tables are sorted by it, whatever
order runs finish in.
"""
from __future__ import annotations

import copy
import dataclasses
import functools
import itertools
import json
from dataclasses import dataclass
from typing import NamedTuple

from flocksweep.observables.directional_correlation import DCD_MAX_DELAY
from flocksweep.observables.summary import ENCOUNTER_SETTINGS, MOTION_SETTINGS, MetricSettings
from flocksweep.simcore.params import ModelParams, Preset, preset_from_dict
from flocksweep.simcore.schema import ConfigError, get_dotted, to_dict

from .config import Storage, SweepConfig, check_window
from .external import ExternalRun
from .identity import canonical, point_key, run_id
from .seeds import Tag, generator, run_seed
from .sensitivity import unique_rows


@dataclass(frozen=True)
class RunSpec:
    run_id: str
    index: int
    point_index: int
    replicate: int
    seed: int
    columns: tuple[tuple[str, object], ...]  # swept parameters as (column, value), in factor order
    preset: Preset | None   # None for a run of a command model
    metrics: MetricSettings  # resolved for this run's model
    storage: Storage
    command: ExternalRun | None = None   # a command model's run: the command and the run's parameter values
    timeout_s: float | None = None   # its wall-time limit (run.timeout_s; not part of its id: sweeps.worker)

    @property
    def cost(self) -> float:
        """Relative cost estimate (pairwise perception): steps x N^2; 1 for a command, whose cost is unknown."""
        if self.preset is None:
            return 1.0
        return self.preset.run.n_steps * float(self.preset.init.n) ** 2


class StoredRun(NamedTuple):
    """A run of a stored design known by its row of ``design.parquet`` alone (nothing resolved or built):
    what the plan of a rerun lists when it reuses the stored design and has nothing to compute
    (:mod:`sweeps.design_key`; a named tuple: 100,000 of them are made in a tenth of a second)."""
    run_id: str
    index: int
    point_index: int
    replicate: int
    seed: int


def stored_runs(design) -> list[StoredRun]:
    """The :class:`StoredRun` of every row of a design table, in its order."""
    columns = [design[name].tolist() for name in ("run_id", "index", "point_index", "replicate", "seed")]
    return [StoredRun(str(r), int(i), int(p), int(k), int(s)) for r, i, p, k, s in zip(*columns)]


def base_preset(config: SweepConfig) -> Preset | None:
    """The preset every design point starts from (ConfigError naming the key when it is invalid); None for
    a command model."""
    if config.command is not None:
        return None
    return preset_from_dict(copy.deepcopy(config.preset_data))


def integer_keys(base: Preset, keys) -> list[bool]:
    """Whether each key holds an integer (not a bool) in the base preset: sampled values are rounded."""
    values = base.full_dict()
    return [isinstance(get_dotted(values, key), int) and not isinstance(get_dotted(values, key), bool)
            for key in keys]


def _integer_keys(config: SweepConfig, base: Preset | None, keys) -> list[bool]:
    """:func:`integer_keys` of the base preset, or of a command model's declared parameters."""
    if config.command is not None:
        return [config.command.parameter(key).integer for key in keys]
    return integer_keys(base, keys)


def sample_points(config: SweepConfig, base: Preset | None) -> list[tuple]:
    """The sampled block's points (tuples in bounds order), integer keys rounded; for a ``[design]``
    block the distinct rows of its sensitivity sample."""
    if config.design:
        return unique_rows(config.design.rows(config.seed, _integer_keys(config, base, config.design.keys)))
    from scipy.stats import qmc  # imported here: scipy.stats takes most of a second to import

    sample = config.sample
    rng = generator(config.seed, Tag.DESIGN_SAMPLE)
    d = len(sample.bounds)
    if sample.method == "random":
        unit = rng.random((sample.n, d))
    elif sample.method == "lhs":
        unit = qmc.LatinHypercube(d=d, seed=rng).random(sample.n)
    else:
        unit = qmc.Sobol(d=d, scramble=sample.scramble, seed=rng).random(sample.n)
    lows = [lo for _, lo, _ in sample.bounds]
    highs = [hi for _, _, hi in sample.bounds]
    scaled = qmc.scale(unit, lows, highs) if d else unit
    integer = _integer_keys(config, base, [key for key, _, _ in sample.bounds])
    return [tuple(int(round(v)) if is_int else float(v) for v, is_int in zip(row, integer)) for row in scaled]


def factor_levels(config: SweepConfig, base: Preset) -> list[tuple[tuple[str, ...], list[tuple]]]:
    """Per factor of the product: (keys, points); the sampled block, if any, is the last factor."""
    factors = [(axis.keys, list(axis.points)) for axis in config.axes]
    if config.sample or config.design:
        factors.append((tuple(config.block_keys), sample_points(config, base)))
    return factors


class ResolvedValues:
    """``get_dotted(preset.full_dict(), key)`` for any key (a swept value read back resolved, even from a
    table the run id leaves out; None when the preset has no such key), converting only the tables asked
    for, each once: a design reads a few keys of every point's preset, and the whole preset as a dict
    costs as much as the rest of the point."""

    def __init__(self, preset: Preset):
        self.preset = preset
        self.tables: dict[str, object] = {}

    def _table(self, name: str):
        if name not in self.tables:
            preset, value = self.preset, None
            if name in ("init", "run"):
                value = to_dict(getattr(preset, name))
            elif name in _MODEL_TABLES:
                value = to_dict(getattr(preset.model, name))
                if name == "perception":
                    value["eye_position_deg"] = preset.model.perception.eye_deg
            self.tables[name] = value
        return self.tables[name]

    def __call__(self, key: str):
        head, _, rest = key.partition(".")
        value = self._table(head)
        return value if not rest else get_dotted(value, rest)


_MODEL_TABLES = frozenset(f.name for f in dataclasses.fields(ModelParams))


def _columns(config: SweepConfig, combo, resolved) -> list[tuple[str, object]]:
    """Swept parameters as table columns: an axis' name (label, joined zipped values, or the value when
    renamed) and then every swept key with its resolved value (``resolved(key)``). ``combo``: per axis the
    level index, or (an explicit point) the tuple of the point's values."""
    cols = []
    for axis, level in zip(config.axes, combo):
        values = level if isinstance(level, tuple) else axis.points[level]
        if axis.labels:
            cols.append((axis.name, axis.labels[axis.points.index(values)]))
        elif len(axis.keys) > 1:
            cols.append((axis.name, "|".join(map(str, values))))
        elif axis.name != axis.keys[0]:
            cols.append((axis.name, resolved(axis.keys[0])))
        cols += [(key, _cell(resolved(key))) for key in axis.keys]
    cols += [(key, resolved(key)) for key in config.block_keys]
    return cols


def _cell(value):
    """A swept value as a table cell: scalars as they are, a list or table (e.g. a ``world.obstacles``
    list swept as a labelled axis) as its canonical JSON text, so every factor column is hashable and
    groups, pairs and reads back like any other."""
    return canonical(value) if isinstance(value, (list, tuple, dict)) else value


def _uncell(value):
    """The inverse of :func:`_cell`: the JSON text of a list or table back to the value (no preset key
    takes a string that starts with ``[`` or ``{``)."""
    if isinstance(value, str) and value[:1] in ("[", "{"):
        return json.loads(value)
    return value


def _point_preset(base: Preset, overrides: list[tuple[str, object]], where: str) -> Preset:
    try:
        return base.replace(dict(overrides))
    except ConfigError as err:
        raise ConfigError(err.key, f"{err.detail} (at design point {where})") from None


def rebuild(model_record: dict, row: dict) -> tuple[Preset, MetricSettings]:
    """(preset, resolved metric settings) of a stored run from ``model.json`` and its design/runs row."""
    if "command" in model_record:
        raise ValueError("a run of an external command cannot be rebuilt from model.json: it has no preset, and "
                         "its output was measured and not kept")
    changes = {}
    for key in model_record["swept_keys"]:
        value = row[key]
        changes[key] = _uncell(value.item() if hasattr(value, "item") else value)
    preset = preset_from_dict(copy.deepcopy(model_record["preset"])).replace(changes)
    analysis = model_record["analysis"]
    metrics = MetricSettings(warmup=analysis["warmup"], group_radius=analysis.get("group_radius"),
                             fragmentation_cohesion=analysis["fragmentation_cohesion"],
                             leadership=bool(analysis.get("leadership", False)),
                             dcd="dcd_max_delay" in analysis, dcd_max_delay=analysis.get("dcd_max_delay", DCD_MAX_DELAY),
                             **{key: analysis.get(key, default) for key, default in ENCOUNTER_SETTINGS.items()},
                             **{key: analysis.get(key, default) for key, default in MOTION_SETTINGS.items()})
    return preset, metrics.resolve(preset.model)


def stored_spec(model_record: dict, row: dict) -> RunSpec:
    """The :class:`RunSpec` of a stored run (its ``model.json`` record and its design/runs row), with its
    run id recomputed from the rebuilt spec. A caller that re-simulates a stored run compares that id
    with the stored one: a difference means this code resolves the spec differently from the code that
    ran the sweep."""
    preset, metrics = rebuild(model_record, row)
    analysis = model_record["analysis"]
    storage = Storage(keep=analysis.get("keep", "metrics"), trajectory_every=int(analysis.get("trajectory_every", 6)))
    seed = int(row["seed"])
    return RunSpec(run_id=run_id(preset.to_dict(), metrics, storage, seed), index=int(row.get("index", 0)),
                   point_index=int(row.get("point_index", 0)), replicate=int(row["replicate"]), seed=seed,
                   columns=(), preset=preset, metrics=metrics, storage=storage)


def _design_points(config: SweepConfig, base: Preset):
    """(overrides [(key, value)], column combo, config key) of every design point: the product, then the
    explicit points."""
    factors = factor_levels(config, base)
    for combo in itertools.product(*[range(len(points)) for _, points in factors]):
        overrides = [(k, v) for (keys, points), level in zip(factors, combo) for k, v in zip(keys, points[level])]
        yield overrides, combo, "axes"
    for i, point in enumerate(config.points):
        yield ([(k, point[k]) for k in config.swept_keys],
               tuple(tuple(point[k] for k in axis.keys) for axis in config.axes), f"points[{i}]")


def expand(config: SweepConfig) -> list[RunSpec]:
    """All runs of the sweep, validated, in design order."""
    base = base_preset(config)
    specs = []
    seen: dict[str, str] = {}
    for point_index, (overrides, combo, origin) in enumerate(_design_points(config, base)):
        where = ", ".join(f"{k}={v!r}" for k, v in overrides) or "(the base model)"
        if config.command is None:
            preset = _point_preset(base, overrides, where)
            check_window(config.metrics.warmup, preset.run, f" (at design point {where})" if overrides else "")
            resolved = preset.to_dict()
            values = ResolvedValues(preset)  # swept values read back resolved, even from tables the id leaves out
            metrics, command = config.metrics.resolve(preset.model), None
        else:   # a command model: its declared parameters, each value checked before it is ever substituted
            parameters = config.command.values(dict(overrides), where if overrides else "")
            values = functools.partial(get_dotted, parameters)
            preset, metrics = None, config.metrics
            resolved = {"command": config.command.identity, "parameters": parameters}
            command = ExternalRun(config.command, tuple(parameters.items()))
        point = point_key({k: values(k) for k, _ in overrides})
        if point in seen:
            raise ConfigError(origin, f"design points {seen[point]} and {where} are the same parameters "
                                      "(values that resolve equal, e.g. 60 and 60.0); list each level once")
        seen[point] = where
        columns = tuple(_columns(config, combo, values))
        for replicate in range(config.replicates):
            seed = run_seed(config.seed, None if config.common_random_numbers else point, replicate)
            rid = run_id(resolved, metrics, config.storage, seed)
            specs.append(RunSpec(run_id=rid, index=point_index * config.replicates + replicate,
                                 point_index=point_index, replicate=replicate, seed=seed, columns=columns,
                                 preset=preset, metrics=metrics, storage=config.storage, command=command,
                                 timeout_s=config.timeout_s))
    return specs
