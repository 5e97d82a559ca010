"""The repository stands alone, and docs/model.md documents every configuration key.

* No tracked ``.md``, ``.toml`` or ``.py`` file points outside the repository: not to the
  sibling folder of shared material (``..`` + ``/shared``), the external specification ``MODEL.md`` (upper case; ``docs/model.md`` is ours)
  or the papers' text files. Docs and configs must pass today. Code must pass too, but its docstrings
  still cite the external specification, so that test is an expected failure (``strict``): it turns
  into a failure the day the last such docstring is fixed, and then its marker must go.
* Every key of simcore's parameter dataclasses (``ModelParams`` and its tables, ``InitParams``,
  ``RunSettings``, ``Units``) has a row in section 9 of docs/model.md, with its true default and, for keys with a
  fixed set of values, exactly those values; and no row documents a key that does not exist.
  Keys inside a list of tables are written ``list[k].field`` (``patterns.set[k].bits``).
"""
from __future__ import annotations

import dataclasses
import re
import subprocess
import tomllib
import typing
from pathlib import Path

import pytest

from flocksweep.simcore import arena, boidspp_params, params, reynolds_params
from flocksweep.simcore.params import InitParams, ModelParams, RunSettings
from flocksweep.simcore.units import Units
from paths import ROOT

MODEL_DOC = ROOT / "docs" / "model.md"
THIS_FILE = Path(__file__).resolve()

# Pointers to files outside the repository. Case-sensitive: "docs/model.md" is ours and allowed.
SHARED = "sha" + "red"   # spelt in two parts so that this file does not itself point outside the repository
OUTSIDE_REFERENCES = re.compile(rf"\.\./{SHARED}|/work/{SHARED}|{SHARED}/MODEL\.md|{SHARED}/seeds|MODEL\.md")


def tracked_files(*suffixes: str) -> list[Path]:
    """Tracked files of the repository with one of the suffixes (git's view, so results/ etc. are out)."""
    patterns = [f"*{suffix}" for suffix in suffixes]
    done = subprocess.run(["git", "-C", str(ROOT), "ls-files", "-z", "--", *patterns],
                          capture_output=True, text=True, check=False)
    assert done.returncode == 0, f"git ls-files failed: {done.stderr}"
    paths = [ROOT / name for name in done.stdout.split("\0") if name]
    return [path for path in paths if path.is_file() and path.resolve() != THIS_FILE]


def outside_references(paths: list[Path]) -> list[str]:
    hits = []
    for path in paths:
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            if OUTSIDE_REFERENCES.search(line):
                hits.append(f"{path.relative_to(ROOT)}:{number}: {line.strip()}")
    return hits


@pytest.mark.parametrize("text, outside", [
    (f"see ../{SHARED}/MODEL.md section 5", True),
    ("(MODEL.md section 3)", True),
    (f"the paper in /work/{SHARED}/seeds/000.txt", True),
    (f"{SHARED}/seeds/003_x.txt", True),
    ("docs/model.md section 5.4", False),
    ("[model.md](model.md) section 8", False),
    ("on the shared 2-core development machine", False),
])
def test_the_scanner_tells_outside_references_from_ours(text, outside):
    assert bool(OUTSIDE_REFERENCES.search(text)) is outside


def test_docs_and_configs_point_nowhere_outside_the_repository():
    paths = tracked_files(".md", ".toml")
    names = {path.relative_to(ROOT).as_posix() for path in paths}
    assert {"README.md", "docs/model.md", "pyproject.toml", "configs/models/holland.toml"} <= names
    hits = outside_references(paths)
    assert not hits, "references to files outside the repository:\n" + "\n".join(hits)


def test_code_points_nowhere_outside_the_repository():
    paths = tracked_files(".py")
    assert any(path.relative_to(ROOT).as_posix() == "simcore/params.py" for path in paths)
    hits = outside_references(paths)
    assert not hits, "references to files outside the repository:\n" + "\n".join(hits)


# --- every configuration key documented -------------------------------------------------------------

def _list_item_type(tp):
    """X for tuple[X, ...], else None."""
    if typing.get_origin(tp) is tuple:
        args = typing.get_args(tp)
        if len(args) == 2 and args[1] is Ellipsis:
            return args[0]
    return None


def _keys_of(cls, prefix: str):
    hints = typing.get_type_hints(cls)
    for field in dataclasses.fields(cls):
        key = prefix + field.name
        tp = hints[field.name]
        if dataclasses.is_dataclass(tp):
            yield from _keys_of(tp, key + ".")
            continue
        yield key, field
        item = _list_item_type(tp)
        if item is not None and dataclasses.is_dataclass(item):
            yield from _keys_of(item, key + "[k].")


def config_keys() -> dict[str, dataclasses.Field]:
    keys = {}
    for cls, prefix in ((ModelParams, ""), (InitParams, "init."), (RunSettings, "run."), (Units, "units.")):
        for key, field in _keys_of(cls, prefix):
            assert key not in keys, f"key {key} defined twice"
            keys[key] = field
    return keys


def documented_rows() -> dict[str, list[str]]:
    """{key: [default, allowed, meaning]} of the key tables in section 9 of docs/model.md."""
    text = MODEL_DOC.read_text(encoding="utf-8")
    start = re.search(r"^## 9\. ", text, re.M)
    end = re.search(r"^## 10\. ", text, re.M)
    assert start and end and start.start() < end.start(), "docs/model.md needs sections 9 and 10"
    rows = {}
    for line in text[start.start():end.start()].splitlines():
        cells = [cell.strip() for cell in line.strip().strip("|").split("|")]
        if not line.startswith("|") or len(cells) != 4:
            continue
        match = re.fullmatch(r"`([a-z_][a-z0-9_]*(?:\[k\])?(?:\.[a-z_][a-z0-9_]*(?:\[k\])?)*)`", cells[0])
        if match is None:
            continue
        assert match.group(1) not in rows, f"key {match.group(1)} documented twice"
        rows[match.group(1)] = cells[1:]
    return rows


def _default(field: dataclasses.Field):
    if field.default is not dataclasses.MISSING:
        return field.default
    if field.default_factory is not dataclasses.MISSING:
        return field.default_factory()
    return dataclasses.MISSING


def _literal(cell: str):
    """The TOML value written in a default cell like `9`, `"open"`, `true` or `1/60`; None if not one."""
    match = re.fullmatch(r"`([^`]+)`", cell)
    if match is None:
        return None
    text = match.group(1)
    fraction = re.fullmatch(r"(\d+(?:\.\d+)?)/(\d+(?:\.\d+)?)", text)
    if fraction:
        return float(fraction.group(1)) / float(fraction.group(2))
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return None


def test_the_key_walk_finds_the_tables_and_list_entries():
    keys = config_keys()
    for key in ("name", "perception.field_deg", "leadership.slow_speed", "patterns.set",
                "patterns.set[k].bits", "init.n", "run.record_interval"):
        assert key in keys
    assert "perception" not in keys  # tables are walked into, not listed as keys


def test_every_configuration_key_is_documented_and_every_documented_key_exists():
    keys, rows = config_keys(), documented_rows()
    missing = sorted(set(keys) - set(rows))
    stale = sorted(set(rows) - set(keys))
    assert not missing, f"keys with no row in docs/model.md section 9: {missing}"
    assert not stale, f"rows in docs/model.md section 9 for keys that do not exist: {stale}"


def test_documented_defaults_are_the_true_defaults():
    keys, rows = config_keys(), documented_rows()
    wrong = []
    for key, field in keys.items():
        if key not in rows:
            continue  # reported by the test above
        default, cell = _default(field), rows[key][0]
        literal = _literal(cell)
        if default is None or default is dataclasses.MISSING or isinstance(default, tuple):
            # unset / required / list defaults are described in words, not as a TOML value
            if literal is not None:
                wrong.append(f"{key}: documented {cell}, but its default is not a single value")
        elif literal is None:
            wrong.append(f"{key}: default cell {cell!r} is not a TOML value (true default {default!r})")
        elif isinstance(default, bool) or isinstance(literal, bool):
            if literal is not default:
                wrong.append(f"{key}: documented {cell}, true default {default!r}")
        elif literal != default:
            wrong.append(f"{key}: documented {cell}, true default {default!r}")
    assert not wrong, "\n".join(wrong)


CHOICES = {
    "dynamics": params.DYNAMICS,
    "perception.kind": params.PERCEPTION_KINDS,
    "world.boundary": params.BOUNDARIES,
    "world.update_order": params.UPDATE_ORDERS,
    "patterns.separation_weight": params.SEPARATION_WEIGHTS,
    "leadership.front_gate": params.FRONT_GATES,
    "arena.kind": arena.ARENA_KINDS,
    "reynolds.allocation": reynolds_params.ALLOCATIONS,
    "reynolds.migration_who": reynolds_params.MIGRATION_WHO,
    "boidspp.separation.form": boidspp_params.SEPARATION_FORMS,
    "boidspp.alignment.scope": boidspp_params.SCOPES,
    "boidspp.cohesion.scope": boidspp_params.SCOPES,
    "boidspp.predator.target": boidspp_params.PREDATOR_TARGETS,
}


@pytest.mark.parametrize("key", sorted(CHOICES))
def test_documented_choices_are_exactly_the_allowed_values(key):
    allowed_cell = documented_rows()[key][1]
    assert set(re.findall(r"`([^`]+)`", allowed_cell)) == set(CHOICES[key])
