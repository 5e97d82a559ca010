"""The one schema engine for every configuration file: model presets, sweeps and calibrations.

Contract
--------
``build(cls, data, path)`` turns a nested ``dict`` (parsed TOML) into an instance of the frozen
dataclass ``cls``:

* every key must name a field; an unknown key raises :class:`ConfigError` naming the dotted key and the
  closest known key ("did you mean ...") and listing the allowed keys;
* values are converted by the field annotation: ``float`` accepts ints (not bools), ``int`` rejects
  bools and floats with a fractional part, ``bool`` only booleans, ``str`` only strings,
  ``Literal[...]`` one of its values (with a did-you-mean), ``tuple[X, ...]`` a list of X (a list of
  tables when X is a dataclass: key ``name[i]``), ``dict`` a table taken as it is, ``dict[str, X]`` a
  table whose values are X, ``Path`` a non-empty string (not resolved), ``X | None`` None or X, ``Any``
  anything; nested dataclasses recurse;
* a missing key takes the field default; a field without default is required;
* a field's ``metadata["expected"]`` (e.g. ``"a non-empty string naming the sweep"``) is what type and
  missing-key errors say is allowed;
* the dataclass' own ``__post_init__`` checks ranges (with the ``check_*`` helpers below) and raises
  :class:`ConfigError` itself; a key it names is prefixed with ``path``.

``replace_fields(obj, changes)`` changes dotted fields of a built instance with the same conversions and
checks. ``to_dict(obj)`` is the inverse of ``build`` (plain, JSON-ready). ``read_config`` reads a TOML file and applies
``key=value`` overrides (``parse_value``, ``set_dotted``, ``apply_overrides``). A file that cannot be read,
is not UTF-8 or not TOML, or holds a date or time value (ours take numbers, strings, booleans, lists and
tables; ``check_plain``), and an override giving a date, is a ConfigError naming the file or key. ``resolve_path`` finds a
file a config names relative to the config, absolutely or relative to the working directory.
``suggest`` is the one did-you-mean. Nothing here knows about flocking.

The ``check_*`` helpers raise ConfigError naming the key, the value and what is allowed.
``check_vector3(key, value)`` is the one 3-vector check (a list of 3 finite numbers -> a float tuple) and
``unit_vector3(key, value)`` the one direction (a non-zero 3-vector divided by its length; one already
unit within :data:`UNIT_TOLERANCE` is kept as written, so a canonical form reloads to the same bits).
:data:`FILE_UNIT_TOLERANCE` is the looser test of unit vectors read from data files (state files of
``init.from_file``): vectors stored in single precision must pass.
"""
from __future__ import annotations

import dataclasses
import datetime
import difflib
import functools
import json
import math
import numbers
import os
import stat
import sys
import tomllib
import types
import typing
from collections.abc import Sequence
from pathlib import Path
from typing import Any


class ConfigError(ValueError):
    """A configuration value is wrong. ``key`` is the dotted path, the message says what is allowed."""

    def __init__(self, key: str, message: str):
        self.key = key
        super().__init__(f"{key}: {message}" if key else message)

    @property
    def detail(self) -> str:
        """The message without its key."""
        return str(self).split(": ", 1)[-1] if self.key else str(self)


def suggest(name: str, known) -> str:
    """' (did you mean 'x'?)' for the closest known name, or '' when nothing is close."""
    close = difflib.get_close_matches(str(name), [str(k) for k in known], n=1, cutoff=0.6)
    return f" (did you mean '{close[0]}'?)" if close else ""


def join(path: str, key: str) -> str:
    return f"{path}.{key}" if path else key


# ------------------------------------------------------------------------------------------- checks

def check_choice(key: str, value, allowed) -> None:
    if value not in allowed:
        raise ConfigError(key, f"got {value!r}; allowed: {', '.join(map(repr, allowed))}" + suggest(str(value), allowed))


def check_positive(key: str, value: float) -> None:
    if not (math.isfinite(value) and value > 0):
        raise ConfigError(key, f"got {value!r}; must be a finite number > 0")


def check_non_negative(key: str, value: float) -> None:
    if not (math.isfinite(value) and value >= 0):
        raise ConfigError(key, f"got {value!r}; must be a finite number >= 0")


def check_within(key: str, value: float, lo: float, hi: float, lo_open: bool = False) -> None:
    ok = math.isfinite(value) and (value > lo if lo_open else value >= lo) and value <= hi
    if not ok:
        bracket = "(" if lo_open else "["
        raise ConfigError(key, f"got {value!r}; allowed range {bracket}{lo}, {hi}]")


def check_at_least(key: str, value: int, minimum: int) -> None:
    if value < minimum:
        raise ConfigError(key, f"got {value!r}; expected an integer >= {minimum}")


def check_finite(key: str, value: float) -> None:
    if not math.isfinite(value):
        raise ConfigError(key, f"got {value!r}; expected a finite number")


# a configured direction this close to unit length is kept as written (not divided by its length)
UNIT_TOLERANCE = 1e-12
# unit vectors read from a file must be unit to this: float32 frames (epsilon 1.2e-7, a few roundings) pass
FILE_UNIT_TOLERANCE = 1e-5


def check_vector3(key: str, value) -> tuple[float, float, float]:
    """``value`` (a list, tuple or array of 3 finite real numbers, not booleans) as a tuple of floats."""
    items = None if isinstance(value, (str, bytes, dict)) or not hasattr(value, "__iter__") else list(value)
    if items is None or len(items) != 3 or \
            not all(isinstance(v, numbers.Real) and not isinstance(v, bool) for v in items):
        raise ConfigError(key, f"got {value if items is None else items!r}; must be a list of 3 numbers")
    vec = tuple(float(v) for v in items)
    if not all(math.isfinite(v) for v in vec):
        raise ConfigError(key, f"got {list(vec)!r}; every component must be finite")
    return vec


def unit_vector3(key: str, value) -> tuple[float, float, float]:
    """A non-zero 3-vector divided by its length (kept as written when unit within UNIT_TOLERANCE)."""
    vec = check_vector3(key, value)
    length = math.hypot(*vec)
    if length == 0.0:
        raise ConfigError(key, f"got {list(vec)!r}; must be a non-zero vector (it is normalised on load)")
    if abs(length - 1.0) <= UNIT_TOLERANCE:
        return vec
    return tuple(v / length for v in vec)


# ------------------------------------------------------------------------------------------ building

def _type_name(tp) -> str:
    return getattr(tp, "__name__", str(tp))


def _wrong(key: str, value, expected: str | None, default: str):
    return ConfigError(key, f"expected {expected or default}, got {value!r}")


def _convert(value: Any, tp, key: str, expected: str | None = None):
    origin = typing.get_origin(tp)
    if tp is Any:
        return value
    if origin in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        if value is None:
            return None
        return _convert(value, args[0], key, expected)
    if origin is typing.Literal:
        check_choice(key, value, typing.get_args(tp))
        return value
    if dataclasses.is_dataclass(tp):
        if not isinstance(value, dict):
            raise _wrong(key, value, expected, "a table")
        return build(tp, value, key)
    if tp is dict or origin is dict:
        if not isinstance(value, dict):
            raise _wrong(key, value, expected, "a table")
        args = typing.get_args(tp)
        if not args or args[1] is Any:
            return dict(value)
        return {k: _convert(v, args[1], join(key, k), expected) for k, v in value.items()}
    if origin is tuple:
        (item_tp, _) = typing.get_args(tp)
        if not isinstance(value, (list, tuple)):
            raise _wrong(key, value, expected, "a list")
        return tuple(_convert(v, item_tp, f"{key}[{i}]", expected) for i, v in enumerate(value))
    if tp is bool:
        if not isinstance(value, bool):
            raise _wrong(key, value, expected, "true or false")
        return value
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise _wrong(key, value, expected, "a number")
        return float(value)
    if tp is int:
        if isinstance(value, float) and value.is_integer():
            return int(value)
        if isinstance(value, bool) or not isinstance(value, int):
            raise _wrong(key, value, expected, "an integer")
        return value
    if tp is str:
        if not isinstance(value, str):
            raise _wrong(key, value, expected, "a string")
        return value
    if tp is Path:
        if not isinstance(value, str) or not value:
            raise _wrong(key, value, expected, "a path")
        return Path(value)
    raise TypeError(f"schema: unsupported annotation {_type_name(tp)} at {key}")


@functools.lru_cache(maxsize=None)
def _schema(cls) -> tuple[dict, dict]:
    """(type hints, init fields) of a dataclass, computed once per class."""
    return typing.get_type_hints(cls), {f.name: f for f in dataclasses.fields(cls) if f.init}


def convert_field(cls, name: str, value, path: str = ""):
    """``value`` converted to the type of field ``name`` of dataclass ``cls`` (key ``path.name``)."""
    hints, fields = _schema(cls)
    return _convert(value, hints[name], join(path, name), fields[name].metadata.get("expected"))


def field_names(cls) -> tuple[str, ...]:
    return tuple(_schema(cls)[1])


def unknown_key(key: str, allowed) -> ConfigError:
    allowed = list(allowed)
    name = key.rsplit(".", 1)[-1]
    return ConfigError(key, "unknown key" + suggest(name, allowed) + f"; allowed keys: {', '.join(allowed)}")


def check_table(data, allowed, path: str) -> None:
    """``data`` must be a table whose keys are all in ``allowed``."""
    if not isinstance(data, dict):
        raise ConfigError(path, f"expected a table, got {data!r}")
    for key in data:
        if key not in allowed:
            raise unknown_key(join(path, key), allowed)


def build(cls, data: dict, path: str = ""):
    """Instance of dataclass ``cls`` from ``data``; errors name the dotted key."""
    hints, fields = _schema(cls)
    check_table(data, fields, path)
    for name, spec in fields.items():
        required = spec.default is dataclasses.MISSING and spec.default_factory is dataclasses.MISSING
        if required and name not in data:
            expected = spec.metadata.get("expected")
            raise ConfigError(join(path, name), "missing required key" + (f": expected {expected}" if expected else ""))
    kwargs = {k: convert_field(cls, k, v, path) for k, v in data.items()}
    try:
        return cls(**kwargs)
    except ConfigError as err:
        raise within(err, path) from None


def within(err: ConfigError, path: str) -> ConfigError:
    """``err`` raised by a table's own checks, re-keyed under the table's ``path`` (unchanged when its
    key already starts there; the table itself when it names no key)."""
    if not path or err.key.startswith(path):
        return err
    return ConfigError(join(path, err.key) if err.key else path, err.detail)


def replace_fields(obj, changes, path: str = ""):
    """``obj`` (a frozen dataclass, built by :func:`build`) with ``changes`` [(key parts, value), ...]
    applied: one ``dataclasses.replace`` per table (so the keys of a table change together), each value
    converted by its field's type, each table's own checks run; errors as :func:`build`'s."""
    if not changes:
        return obj
    cls = type(obj)
    names = field_names(cls)
    kwargs, nested = {}, {}
    for parts, value in changes:
        if parts[0] not in names:
            raise unknown_key(join(path, parts[0]), names)
        if len(parts) == 1:
            kwargs[parts[0]] = convert_field(cls, parts[0], value, path)
        else:
            nested.setdefault(parts[0], []).append((parts[1:], value))
    for name, sub in nested.items():
        child = kwargs.get(name, getattr(obj, name))
        if not dataclasses.is_dataclass(child):
            raise ConfigError(join(path, ".".join((name,) + sub[0][0])), f"'{name}' is a value, not a table")
        kwargs[name] = replace_fields(child, sub, join(path, name))
    try:
        return dataclasses.replace(obj, **kwargs)
    except ConfigError as err:
        raise within(err, path) from None


_FIELD_NAMES: dict[type, tuple[str, ...] | None] = {}   # a type's dataclass field names (None: not one)


def _field_names(cls: type) -> tuple[str, ...] | None:
    """The field names of the dataclass ``cls`` in order, None when it is not one (looked up once a type:
    a sweep's design converts every point's preset, thousands of dataclasses each)."""
    try:
        return _FIELD_NAMES[cls]
    except KeyError:
        names = tuple(f.name for f in dataclasses.fields(cls)) if dataclasses.is_dataclass(cls) else None
        _FIELD_NAMES[cls] = names
        return names


def to_dict(obj) -> Any:
    """Plain nested dict/list representation of a (nested) dataclass instance."""
    names = _field_names(type(obj))
    if names is not None:
        return {name: to_dict(getattr(obj, name)) for name in names}
    if isinstance(obj, tuple):
        return [to_dict(v) for v in obj]
    if isinstance(obj, dict):
        return {k: to_dict(v) for k, v in obj.items()}
    if isinstance(obj, Path):
        return str(obj)
    return obj


# ------------------------------------------------------------------------------------- files, overrides

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


def check_plain(value, key: str = "") -> None:
    """ConfigError at ``key`` for a date or time anywhere in ``value`` (a parsed TOML value)."""
    if isinstance(value, (datetime.date, datetime.time)):
        raise ConfigError(key, f"got the date/time {value.isoformat()}; values here are numbers, strings, "
                               "booleans, lists or tables (quote it to make it a string)")
    if isinstance(value, dict):
        for name, item in value.items():
            check_plain(item, join(key, str(name)))
    elif isinstance(value, list):
        for index, item in enumerate(value):
            check_plain(item, f"{key}[{index}]")


TOML_LIMIT = 16 << 20   # bytes: a config file is text a person wrote


def input_file(path, key: str, what: str, limit: int) -> os.stat_result:
    """Check that ``path`` is a regular file of at most ``limit`` bytes before anything reads it:
    ConfigError at ``key`` when it is missing (a NUL in the path, a dangling symlink), a folder, a FIFO,
    a device or a socket (``/dev/zero``), a symlink loop, unreadable, or too large."""
    try:
        info = os.stat(path)
    except ValueError:   # a NUL character in the path
        raise ConfigError(key, f"{what} not found: {str(path)!r} (a path cannot contain a NUL character)") from None
    except FileNotFoundError:
        raise ConfigError(key, f"{what} not found: {path}") from None
    except OSError as err:
        raise ConfigError(key, f"{what} cannot be read: {path}: {err.strerror or err}") from None
    if stat.S_ISDIR(info.st_mode):
        raise ConfigError(key, f"{what} {path} is a folder; expected a file")
    if not stat.S_ISREG(info.st_mode):
        raise ConfigError(key, f"{what} {path} is not a regular file (a FIFO, device or socket); expected a file")
    if info.st_size > limit:
        raise ConfigError(key, f"{what} {path} holds {info.st_size:,} bytes; at most {limit:,} are read here")
    return info


def read_input(path, key: str, what: str, limit: int) -> bytes:
    """The bytes of the input file ``path``, checked by :func:`input_file` and read at most ``limit``."""
    input_file(path, key, what, limit)
    try:
        with open(path, "rb") as handle:
            raw = handle.read(limit + 1)
    except OSError as err:
        raise ConfigError(key, f"{what} cannot be read: {path}: {err.strerror or err}") from None
    if len(raw) > limit:
        raise ConfigError(key, f"{what} {path} holds more than {limit:,} bytes; at most {limit:,} are read here")
    return raw


def read_toml(path, what: str) -> dict:
    """A TOML file as a dict; a missing, unreadable, special (FIFO, device, folder), oversized or
    non-UTF-8 file, bad TOML or a date value is a ConfigError naming the file or key (``what`` says which
    kind of file it is)."""
    path = Path(path)
    raw = read_input(path, "", what, TOML_LIMIT)
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as err:
        raise ConfigError("", f"{path}: not UTF-8 text (byte 0x{raw[err.start]:02x} at offset {err.start}); "
                              "save it as UTF-8") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise ConfigError("", f"{path}: not valid TOML: {err}") from None
    except RecursionError:
        raise ConfigError("", f"{path}: not valid TOML: nested too deeply") from None
    if nesting(data) > MAX_NESTING:
        raise ConfigError("", f"{path}: tables or lists nested more than {MAX_NESTING} levels deep (a dotted key or "
                              "table header of that many parts); no setting is that deep")
    check_plain(data)
    return data


MAX_NESTING = 64   # levels of tables and lists in a config file


def nesting(value) -> int:
    """Levels of nested dicts and lists in ``value`` (counted without recursion)."""
    deepest, todo = 0, [(value, 0)]
    while todo:
        item, level = todo.pop()
        deepest = max(deepest, level)
        if isinstance(item, dict):
            todo += [(v, level + 1) for v in item.values()]
        elif isinstance(item, list):
            todo += [(v, level + 1) for v in item]
    return deepest


def read_config(path, what: str, overrides=()) -> dict:
    """A TOML config file as a dict with ``key=value`` overrides applied (see :func:`read_toml`)."""
    return apply_overrides(read_toml(path, what), overrides)


def apply_overrides(data: dict, overrides) -> dict:
    """Deep copy of ``data`` with each ``key=value`` string of ``overrides`` applied."""
    out = json.loads(json.dumps(data))
    for item in overrides or ():
        if "=" not in item:
            raise ConfigError(item, "an override must look like key=value")
        key, text = item.split("=", 1)
        value = parse_value(text.strip())
        check_plain(value, key.strip())
        set_dotted(out, key.strip(), value)
    return out


def resolve_path(text, base, key: str, what: str, must_exist: bool = True) -> Path:
    """The path a config names: absolute, else relative to ``base`` (the config's folder), else to the
    working directory; the first that exists, resolved (symbolic links followed: the real file, which
    :func:`linked_to` names in messages and the sweep stores). A missing one is a ConfigError at ``key``
    listing where it looked, or (``must_exist=False``) the path relative to ``base``."""
    if not isinstance(text, str) or not text:
        raise ConfigError(key, f"got {text!r}; expected a path to the {what}")
    if "\0" in text:
        raise ConfigError(key, f"got {text!r}; a path cannot contain a NUL character")
    candidates = [Path(text)] if Path(text).is_absolute() else [Path(base) / text, Path.cwd() / text]
    for path in candidates:
        if path.exists():
            return path.resolve()
    if not must_exist:
        return candidates[0]
    tried = ", ".join(str(p) for p in candidates)
    raise ConfigError(key, f"{what} not found: {text!r} (looked at {tried})")


def linked_to(text, base, resolved: Path) -> str:
    """' -> REAL/PATH' when the path a config names (``text``, relative to ``base`` or the working
    directory) reaches ``resolved`` through a symbolic link, else '': messages then say which file was read."""
    written = Path(text) if Path(text).is_absolute() else Path(base) / text
    if not written.exists():
        written = Path.cwd() / text
    return "" if os.path.abspath(written) == str(resolved) else f" -> {resolved}"


class FileConfig:
    """Base of a validated config class read from a TOML file: ``Config.from_toml(path, overrides=())``
    calls the loader function the class names in its module (``class C(FileConfig, loader="load_c")``)."""

    _loader = ""

    def __init_subclass__(cls, loader: str = "", **kwargs):
        super().__init_subclass__(**kwargs)
        cls._loader = loader or cls._loader

    @classmethod
    def from_toml(cls, path, overrides: Sequence[str] = ()):
        """Read the TOML file ``path``, apply ``key=value`` ``overrides`` of its keys, validate.

        Parameters
        ----------
        path : str or pathlib.Path
            The file; relative paths in it start from its folder.
        overrides : sequence of str, optional
            ``key=value`` changes of the file's keys (as the command line's ``--set``).

        Returns
        -------
        FileConfig
            The validated, frozen config, an instance of this class.

        Raises
        ------
        ConfigError
            Naming the dotted key, the bad value and what is allowed.
        """
        return getattr(sys.modules[cls.__module__], cls._loader)(path, overrides)
