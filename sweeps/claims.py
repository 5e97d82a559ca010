"""Claims: hypotheses about a sweep's results, declared as data and validated like every config.

A sweep file lists its claims as ``[[claims]]`` tables and may include shared claims files
(``include_claims = ["../claims/holland.toml"]``, or ``[{ file = "...", only = ["a", "b"] }]`` for some
of a file's claims); a claims file holds ``description`` and ``[[claims]]`` only. One claim::

    [[claims]]
    id = "d"                                   # unique in the sweep
    statement = "Narrow fields of vision give faster, elongated flocks (the leapfrog effect)."
    source = { paper = "Holland & Semwal", section = "7 Results", quote = "..." }
    condition = "perception.direction_deg <= 20"   # where the claim is tested (sweeps.expressions)
    family = "holland"                         # Holm's correction runs over a family's tests
    alpha = 0.05
    test = "all_of"                            # trend | compare | sign | all_of | any_of
      [[claims.parts]]
      id = "faster"
      test = "trend"
      metric = "speed_mean_mean"               # a summary column, or arithmetic on columns
      factor = "perception.field_deg"
      direction = "decreasing"

Test kinds and their keys (every other key of a test is an error naming it):

* ``trend``: ``metric``, ``factor`` (a numeric factor), ``direction`` increasing | decreasing,
  ``method`` spearman, ``effect``;
* ``compare``: ``metric``, ``lower`` and ``higher`` (conditions selecting the group claimed lower and
  the group claimed higher), ``paired`` (pair runs equal in every other factor and the replicate, and
  test the differences: ``method`` wilcoxon | sign | t), ``method`` mann-whitney | welch, ``effect``;
* ``sign``: ``metric``, ``direction`` positive | negative | zero (of metric - ``value``, default 0;
  zero means every run within ``tolerance`` of ``value``), ``method`` wilcoxon | sign | t, ``effect``;
* ``all_of`` / ``any_of``: ``parts``, a list of tests (nested compositions allowed).

Every test may also have ``id``, ``label`` (what the part says) and ``condition``: a part's condition
applies on top of its parents'. ``effect`` is the smallest effect of interest in the metric's units (a
trend's change of the mean over the factor's range, a comparison's difference of means, a sign test's
distance of the mean from ``value``); without it, half the spread of the metric around its level means.
``power = { target = 0.8, simulations = 200, max_replicates = 200 }`` sets the power analysis.

``load_claims(tables, includes, base, columns)`` validates and resolves: every name a claim uses must be
a factor (conditions, ``factor``, ``lower``, ``higher``) or a metric (``metric``) of the sweep, with a
did-you-mean; every condition must select at least one design point, a trend at least two levels of
its factor, and the two groups of a comparison must be non-empty and disjoint. :class:`Columns` says
what a sweep has: :func:`sweep_columns` before it runs, :func:`table_columns` from a results table.
The result is a tuple of :class:`Claim` whose :class:`Test` trees hold parsed expressions (the tables
and the tree are in :mod:`sweeps.claim_schema`, re-exported here).
``claims_record(claims)`` is what a results folder stores (``sweep.effective.json["claims"]``, includes
expanded); ``claims_from_records`` reads it back. Statistics are not here (analysis/reports/claims).
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass, field, fields
from pathlib import Path

import numpy as np
import pandas as pd

from flocksweep.observables.directional_correlation import DCD_METRIC_NAMES
from flocksweep.observables.leadership import LEADERSHIP_METRIC_NAMES
from flocksweep.observables.summary import ENCOUNTER_FAMILIES, summary_columns
from flocksweep.simcore.schema import ConfigError, build, linked_to, read_toml, resolve_path, suggest, to_dict

from .claim_schema import (COMMON, DIRECTIONS, ID, KEYS, KINDS, METHODS, REQUIRED, Claim, ClaimsFile,  # noqa: F401
                           ClaimTable, IncludeTable, PowerTable, Source, Test, TestTable)
from .expressions import Expression, ExpressionError, parse

DESIGN_CHECK_MAX = 200_000   # design points enumerated to check conditions; larger designs skip the check


# ------------------------------------------------------------------------------- what a sweep can name

@dataclass(frozen=True)
class Columns:
    """The columns claims may name: factors (with their levels when known), numeric factors, metrics,
    metrics that exist but are off (with the reason), and the design's points (None: not checked)."""

    factors: tuple[str, ...]
    numeric: frozenset
    metrics: frozenset
    unavailable: dict = field(default_factory=dict)
    design: pd.DataFrame | None = None


def _is_number(value) -> bool:
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))


def _axis_columns(axis) -> list[tuple[str, list]]:
    """(column, value per level) of one axis as the design writes them (sweeps.design._columns)."""
    out = []
    if axis.labels:
        out.append((axis.name, list(axis.labels)))
    elif len(axis.keys) > 1:
        out.append((axis.name, ["|".join(map(str, point)) for point in axis.points]))
    elif axis.name != axis.keys[0]:
        out.append((axis.name, [point[0] for point in axis.points]))
    out += [(key, [point[k] for point in axis.points]) for k, key in enumerate(axis.keys)]
    return out


def sweep_columns(axes, sample, leadership: bool, dcd: bool = False) -> Columns:
    """What a sweep's claims may name, from its axes and sampled block (before anything runs)."""
    factors, numeric = [], set()
    per_axis = []
    for axis in axes:
        columns = _axis_columns(axis)
        per_axis.append(columns)
        for name, values in columns:
            if name not in factors:
                factors.append(name)
            if all(_is_number(v) for v in values):
                numeric.add(name)
    sampled = [key for key, _, _ in sample.bounds] if sample else []
    factors += [k for k in sampled if k not in factors]
    numeric |= set(sampled)
    design = None
    sizes = [len(axis.points) for axis in axes]
    if int(np.prod(sizes, dtype=float)) <= DESIGN_CHECK_MAX:
        rows = []
        for combo in itertools.product(*[range(s) for s in sizes]):
            row = {}
            for columns, level in zip(per_axis, combo):
                row.update({name: values[level] for name, values in columns})
            rows.append(row)
        design = pd.DataFrame(rows) if rows else None
    metrics = frozenset(summary_columns(leadership=leadership, encounters=ENCOUNTER_FAMILIES, migration=True, dcd=dcd,
                                        walls=True))
    off = {} if leadership else {m: "leadership metrics are computed only with run.leadership_metrics = true "
                                    "(or leadership.x swept)" for m in LEADERSHIP_METRIC_NAMES}
    off |= {} if dcd else {m: "directional correlation delays are computed only with run.dcd_metrics = true"
                           for m in DCD_METRIC_NAMES}
    return Columns(tuple(factors), frozenset(numeric), metrics, off, design)


def table_columns(design: pd.DataFrame, metrics, reserved) -> Columns:
    """What claims may name in a stored sweep: the design's parameter columns and the metric columns."""
    factors = [c for c in design.columns if c not in reserved]
    numeric = {c for c in factors if pd.api.types.is_numeric_dtype(design[c]) and not pd.api.types.is_bool_dtype(design[c])}
    points = design[factors].drop_duplicates().reset_index(drop=True) if factors else None
    return Columns(tuple(factors), frozenset(numeric), frozenset(metrics), {}, points)


# ------------------------------------------------------------------------------------------ validation

def _given(table: TestTable) -> set[str]:
    """The keys of a test table that differ from their defaults (i.e. that were written)."""
    defaults = TestTable()
    return {f.name for f in fields(TestTable) if getattr(table, f.name) != getattr(defaults, f.name)}


def _check_name(name: str, allowed, key: str, what: str, columns: Columns) -> None:
    if name in allowed:
        return
    if name in columns.unavailable:
        raise ConfigError(key, f"{name!r} is not computed in this sweep: {columns.unavailable[name]}")
    listed = sorted(allowed)
    shown = ", ".join(listed[:40]) + (" ..." if len(listed) > 40 else "")
    raise ConfigError(key, f"{name!r} is not {what} of this sweep{suggest(name, listed)}; available: {shown}")


def _expression(text, key: str, kind: str, columns: Columns) -> Expression:
    expression = parse(text, key, kind)
    allowed, what = (columns.factors, "a factor") if kind == "condition" else (columns.metrics, "a metric")
    for name in expression.names:
        _check_name(name, allowed, key, what, columns)
    return expression


def _check_kind(table: TestTable, key: str) -> None:
    kind = table.test
    if kind is None:
        raise ConfigError(f"{key}.test", f"missing required key: expected one of {', '.join(KINDS)}")
    extra = sorted(_given(table) - set(COMMON) - set(KEYS[kind]) - {"statement", "source", "family", "alpha", "power"})
    if extra:
        raise ConfigError(f"{key}.{extra[0]}", f"not a key of a {kind} test; a {kind} test takes "
                                               f"{', '.join(KEYS[kind])} (and id, label, condition)")
    for name in REQUIRED[kind]:
        if not getattr(table, name):
            raise ConfigError(f"{key}.{name}", f"missing required key of a {kind} test (it takes {', '.join(KEYS[kind])})")
    if kind in DIRECTIONS and table.direction not in DIRECTIONS[kind]:
        raise ConfigError(f"{key}.direction", f"got {table.direction!r}; a {kind} test allows "
                                              + ", ".join(DIRECTIONS[kind]) + suggest(str(table.direction), DIRECTIONS[kind]))
    methods = METHODS["sign"] if kind == "compare" and table.paired else METHODS.get(kind, ())
    if kind in METHODS and table.method is not None and table.method not in methods:
        what = "a paired compare test (a one-sample test of the differences)" if table.paired else f"a {kind} test"
        raise ConfigError(f"{key}.method", f"got {table.method!r}; {what} allows "
                                           + ", ".join(methods) + suggest(str(table.method), methods))
    if table.effect is not None and not (np.isfinite(table.effect) and table.effect > 0):
        raise ConfigError(f"{key}.effect", f"got {table.effect!r}; expected the smallest effect of interest, a number > 0")
    if not (np.isfinite(table.tolerance) and table.tolerance >= 0):
        raise ConfigError(f"{key}.tolerance", f"got {table.tolerance!r}; expected a number >= 0")
    if table.id is not None and not ID.match(table.id):
        raise ConfigError(f"{key}.id", f"got {table.id!r}; expected letters, digits, '_', '-' or '.'")


def _resolve(table: TestTable, key: str, path: str, inherited: tuple, columns: Columns) -> Test:
    _check_kind(table, key)
    conditions = inherited
    if table.condition is not None:
        conditions = inherited + (_expression(table.condition, f"{key}.condition", "condition", columns),)
    default_label = path.rsplit(".", 1)[-1] if "." in path or table.metric is None else table.metric
    common = {"kind": table.test, "path": path, "label": table.label or default_label, "key": key,
              "conditions": conditions}
    if table.test in ("all_of", "any_of"):
        parts, seen = [], set()
        for k, part in enumerate(table.parts):
            part_id = part.id or str(k + 1)
            if part_id in seen:
                raise ConfigError(f"{key}.parts[{k}].id", f"got {part_id!r}; part ids repeat within {path!r}")
            seen.add(part_id)
            parts.append(_resolve(part, f"{key}.parts[{k}]", f"{path}.{part_id}", conditions, columns))
        return Test(**common, parts=tuple(parts))
    metric = _expression(table.metric, f"{key}.metric", "metric", columns)
    extra = {}
    if table.test == "trend":
        _check_name(table.factor, columns.factors, f"{key}.factor", "a factor", columns)
        if table.factor not in columns.numeric:
            raise ConfigError(f"{key}.factor", f"{table.factor!r} is not numeric; a trend needs a numeric factor "
                                               "(compare groups of a categorical one)")
        extra["factor"] = table.factor
    if table.test == "compare":
        extra["lower"] = _expression(table.lower, f"{key}.lower", "condition", columns)
        extra["higher"] = _expression(table.higher, f"{key}.higher", "condition", columns)
    default_method = {"trend": "spearman", "compare": "wilcoxon" if table.paired else "mann-whitney",
                      "sign": "wilcoxon"}[table.test]
    test = Test(**common, metric=metric, direction=table.direction, paired=table.paired, value=table.value,
                tolerance=table.tolerance, method=table.method or default_method, effect=table.effect, **extra)
    _check_design(test, columns)
    return test


def _levels_text(design: pd.DataFrame, names) -> str:
    return "; ".join(f"{n}: {', '.join(map(str, sorted(design[n].unique(), key=str)))}" for n in names
                     if n in design)


def _check_design(test: Test, columns: Columns) -> None:
    """Evaluate the test's conditions on the design's points: each must select some point."""
    design = columns.design
    names = {n for c in test.conditions for n in c.names} | {test.factor} - {None}
    for group in (test.lower, test.higher):
        if group is not None:
            names |= set(group.names)
    if design is None or not names <= set(design.columns):
        return
    key = f"{test.key}.condition" if test.conditions else test.key
    try:
        inside = test.select(design)
    except ExpressionError as err:
        raise ConfigError(key, str(err)) from None
    if not inside.any():
        raise ConfigError(key, "selects no design point of this sweep; its levels: "
                               + _levels_text(design, sorted({n for c in test.conditions for n in c.names})))
    if test.kind == "trend" and design.loc[inside, test.factor].nunique() < 2:
        raise ConfigError(key, f"leaves fewer than two levels of {test.factor!r}: no trend to test")
    if test.kind == "compare":
        masks = []
        for name, group in (("lower", test.lower), ("higher", test.higher)):
            try:
                mask = group.evaluate(design) & inside
            except ExpressionError as err:
                raise ConfigError(f"{test.key}.{name}", str(err)) from None
            if not mask.any():
                raise ConfigError(f"{test.key}.{name}", "selects no design point (within the condition); levels: "
                                                        + _levels_text(design, group.names))
            masks.append(mask)
        if (masks[0] & masks[1]).any():
            raise ConfigError(f"{test.key}.higher", "the two groups share design points; they must be disjoint")


def resolve_claim(table: ClaimTable, key: str, columns: Columns, origin: str = "") -> Claim:
    """A validated :class:`Claim` from its table (``key`` names it in messages)."""
    if not table.id:
        raise ConfigError(f"{key}.id", "missing required key: expected a short id, e.g. \"d\"")
    if not table.statement:
        raise ConfigError(f"{key}.statement", "missing required key: expected the claim as one sentence")
    if not 0 < table.alpha < 1:
        raise ConfigError(f"{key}.alpha", f"got {table.alpha!r}; expected a number in (0, 1)")
    test = _resolve(table, key, table.id, (), columns)
    return Claim(table.id, table.statement, table.source, table.family, table.alpha, table.power, test, table, origin)


def _included(item, k: int, base) -> tuple[list[ClaimTable], str, str]:
    """(claim tables, the key prefix for messages, the file) of one ``include_claims`` entry."""
    key = f"include_claims[{k}]"
    spec = build(IncludeTable, item, key) if isinstance(item, dict) else IncludeTable(file=item)
    if not isinstance(spec.file, str):
        raise ConfigError(key, f"got {item!r}; expected a path to a claims file or {{ file = ..., only = [...] }}")
    path = resolve_path(spec.file, base, f"{key}.file" if isinstance(item, dict) else key, "claims file")
    shown = f"{key} ({spec.file}{linked_to(spec.file, base, path)})"
    try:
        data = build(ClaimsFile, read_toml(path, "claims file"))
    except ConfigError as err:
        raise ConfigError(f"{shown} {err.key}".strip(), err.detail) from None
    tables = list(data.claims)
    if spec.only is not None:
        ids = [t.id for t in tables]
        for name in spec.only:
            if name not in ids:
                raise ConfigError(f"{key}.only", f"{name!r} is not a claim of {spec.file}{suggest(name, ids)}; "
                                                  f"its claims: {', '.join(map(str, ids))}")
        tables = [t for t in tables if t.id in spec.only]
    return tables, shown, str(spec.file)


def load_claims(tables, includes, base, columns: Columns) -> tuple[Claim, ...]:
    """Every claim of a sweep: its own ``[[claims]]`` then each included file's, validated (see the
    module docstring); ids must be unique."""
    entries = [(t, f"claims[{k}]", "") for k, t in enumerate(tables)]
    for k, item in enumerate(includes):
        included, shown, file = _included(item, k, Path(base))
        entries += [(t, f"{shown} claims[{i}]", file) for i, t in enumerate(included)]
    claims, seen = [], {}
    for table, key, origin in entries:
        claim = resolve_claim(table, key, columns, origin)
        if claim.id in seen:
            raise ConfigError(f"{key}.id", f"got {claim.id!r}; claim ids must be unique (also at {seen[claim.id]})")
        seen[claim.id] = key
        claims.append(claim)
    return tuple(claims)


def claims_record(claims) -> list[dict]:
    """The claims as stored in a results folder: every table written out, includes expanded."""
    return [_plain(to_dict(claim.table)) for claim in claims]


def _plain(node):
    """A dict without None values (TOML has no null), recursively."""
    if isinstance(node, dict):
        return {k: _plain(v) for k, v in node.items() if v is not None}
    if isinstance(node, list):
        return [_plain(v) for v in node]
    return node


def with_claims(effective: dict, claims) -> dict:
    """A sweep's effective configuration with its claims written out (``include_claims`` expanded)."""
    out = {k: v for k, v in effective.items() if k not in ("claims", "include_claims")}
    if claims:
        out["claims"] = claims_record(claims)
    return out


def claims_from_records(records, columns: Columns) -> tuple[Claim, ...]:
    """Claims stored by :func:`claims_record` (or any list of claim tables), validated against ``columns``."""
    tables = [build(ClaimTable, dict(record), f"claims[{k}]") for k, record in enumerate(records)]
    return load_claims(tables, (), ".", columns)


def read_claims_file(path, columns: Columns) -> tuple[Claim, ...]:
    """The claims of a claims file, or of a sweep file (its ``[[claims]]`` and ``include_claims``, paths
    relative to it), validated against ``columns``."""
    path = Path(path)
    data = read_toml(path, "claims file")
    try:
        if "name" in data and "model" in data:  # a sweep file
            tables = [build(ClaimTable, dict(t), f"claims[{k}]") for k, t in enumerate(data.get("claims", []))]
            includes = data.get("include_claims", [])
            if not isinstance(includes, list):
                raise ConfigError("include_claims", f"got {includes!r}; expected a list of claims files")
            return load_claims(tables, includes, path.resolve().parent, columns)
        return load_claims(build(ClaimsFile, data).claims, (), path.resolve().parent, columns)
    except ConfigError as err:
        raise ConfigError(f"{path}: {err.key}", err.detail) from None
