"""Strict conversion of plain dicts (parsed TOML) into frozen dataclasses.

Contract
--------
``build(cls, data, path)`` turns a nested ``dict`` into an instance of the frozen dataclass ``cls``:

* every key must name a field; an unknown key raises :class:`ConfigError` naming the dotted key and the
  closest known key ("did you mean ...");
* values are type-checked against the field annotation (``float`` accepts ints, ``int`` rejects floats
  with a fractional part and bools, ``bool`` accepts only booleans, ``str`` only strings); nested
  dataclasses recurse; ``tuple[X, ...]`` accepts lists;
* missing keys take the field default;
* the dataclass' own ``__post_init__`` checks ranges and raises :class:`ConfigError` itself.

``to_dict(obj)`` is the inverse (plain, JSON-ready); ``parse_value``/``set_dotted``/``apply_overrides``
handle ``a.b.c=value`` override strings. Nothing here knows about flocking; sweeps and calibration reuse it.
"""
from __future__ import annotations

import dataclasses
import difflib
import functools
import json
import tomllib
import types
import typing
from typing import Any


class ConfigError(ValueError):
    """A configuration value is wrong. ``key`` is the dotted path, the message says what is allowed."""

    def __init__(self, key: str, message: str):
        self.key = key
        super().__init__(f"{key}: {message}" if key else message)


def suggest(name: str, known) -> str:
    """' (did you mean 'x'?)' for the closest known name, or '' when nothing is close."""
    close = difflib.get_close_matches(name, list(known), n=1, cutoff=0.6)
    return f" (did you mean '{close[0]}'?)" if close else ""


def join(path: str, key: str) -> str:
    return f"{path}.{key}" if path else key


def _type_name(tp) -> str:
    return getattr(tp, "__name__", str(tp))


def _convert(value: Any, tp, key: str):
    origin = typing.get_origin(tp)
    if origin in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        if value is None:
            return None
        return _convert(value, args[0], key)
    if dataclasses.is_dataclass(tp):
        if not isinstance(value, dict):
            raise ConfigError(key, f"expected a table, got {value!r}")
        return build(tp, value, key)
    if origin is tuple:
        (item_tp, _) = typing.get_args(tp)
        if not isinstance(value, (list, tuple)):
            raise ConfigError(key, f"expected a list, got {value!r}")
        return tuple(_convert(v, item_tp, f"{key}[{i}]") for i, v in enumerate(value))
    if tp is bool:
        if not isinstance(value, bool):
            raise ConfigError(key, f"expected true or false, got {value!r}")
        return value
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(key, f"expected a number, got {value!r}")
        return float(value)
    if tp is int:
        if isinstance(value, bool):
            raise ConfigError(key, f"expected an integer, got {value!r}")
        if isinstance(value, float) and value.is_integer():
            return int(value)
        if not isinstance(value, int):
            raise ConfigError(key, f"expected an integer, got {value!r}")
        return value
    if tp is str:
        if not isinstance(value, str):
            raise ConfigError(key, f"expected a string, got {value!r}")
        return value
    raise TypeError(f"schema: unsupported annotation {_type_name(tp)} at {key}")


@functools.lru_cache(maxsize=None)
def _schema(cls) -> tuple[dict, dict]:
    """(type hints, init fields) of a dataclass, computed once per class."""
    return typing.get_type_hints(cls), {f.name: f for f in dataclasses.fields(cls) if f.init}


def build(cls, data: dict, path: str = ""):
    """Instance of dataclass ``cls`` from ``data``; errors name the dotted key."""
    hints, fields = _schema(cls)
    for key in data:
        if key not in fields:
            raise ConfigError(join(path, key), "unknown key" + suggest(key, fields) +
                              f"; allowed keys: {', '.join(sorted(fields))}")
    for name, spec in fields.items():
        required = spec.default is dataclasses.MISSING and spec.default_factory is dataclasses.MISSING
        if required and name not in data:
            raise ConfigError(join(path, name), "missing required key")
    kwargs = {k: _convert(v, hints[k], join(path, k)) for k, v in data.items()}
    try:
        return cls(**kwargs)
    except ConfigError as err:
        if path and not err.key.startswith(path):
            raise ConfigError(join(path, err.key), str(err).split(": ", 1)[-1]) from None
        raise


def to_dict(obj) -> Any:
    """Plain nested dict/list representation of a (nested) dataclass."""
    if dataclasses.is_dataclass(obj):
        return {f.name: to_dict(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, tuple):
        return [to_dict(v) for v in obj]
    return obj


def parse_value(text: str):
    """Value of an override string: TOML syntax when it parses (numbers, booleans, lists, quoted
    strings), otherwise the bare text as a string (so ``kind=binocular`` works)."""
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text


def set_dotted(data: dict, dotted: str, value) -> None:
    """Set ``data['a']['b']['c'] = value`` for ``dotted == 'a.b.c'``, creating tables as needed."""
    parts = dotted.split(".")
    if not all(parts):
        raise ConfigError(dotted, "an override key must be dotted names like perception.field_deg")
    node = data
    for part in parts[:-1]:
        child = node.setdefault(part, {})
        if not isinstance(child, dict):
            raise ConfigError(dotted, f"'{part}' is a value, not a table")
        node = child
    node[parts[-1]] = value


def get_dotted(data: dict, dotted: str):
    """``data['a']['b']['c']`` for ``dotted == 'a.b.c'``, or None when any part is missing."""
    node = data
    for part in dotted.split("."):
        if not isinstance(node, dict) or part not in node:
            return None
        node = node[part]
    return node


def read_config(path, what: str, overrides=()) -> dict:
    """A TOML config file as a dict with ``key=value`` overrides applied; a missing file or bad TOML is
    a ConfigError naming the file (``what`` says which kind of file it is)."""
    from pathlib import Path

    path = Path(path)
    if not path.is_file():
        raise ConfigError("", f"{what} not found: {path}")
    try:
        with path.open("rb") as handle:
            data = tomllib.load(handle)
    except tomllib.TOMLDecodeError as err:
        raise ConfigError("", f"{path}: not valid TOML: {err}") from None
    return apply_overrides(data, overrides)


def apply_overrides(data: dict, overrides) -> dict:
    """Deep copy of ``data`` with each ``key=value`` string of ``overrides`` applied."""
    out = json.loads(json.dumps(data))
    for item in overrides or ():
        if "=" not in item:
            raise ConfigError(item, "an override must look like key=value")
        key, text = item.split("=", 1)
        set_dotted(out, key.strip(), parse_value(text.strip()))
    return out
