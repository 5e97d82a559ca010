"""Plug-in dynamics: a model a user writes in a Python module, named in a preset (docs/plugins.md).

A preset's ``dynamics`` is either a built-in dynamics (:data:`simcore.params.DYNAMICS`) or a plug-in:
the name of an entry point in the group ``flocksweep.dynamics`` (its value a module path), or an
importable module path (``dynamics = "examples.couzin_like"``). :func:`load` imports that one module,
and only it, checks its interface and registers it; :mod:`simcore.registry` then describes it as it does a
built-in (the module's capability flags, with :data:`DEFAULTS` for those it leaves out). The module
defines ``Params`` and either the full hook set of a dynamics (``scratch``, ``sense``, ``move`` and the
optional ones, :mod:`simcore.hooks`; run through the adapters of :mod:`simcore.plugin_hooks`) or the
convenience ``steer``:

* ``Params``: a frozen dataclass subclassing :class:`PluginParams`, one field per parameter (``float``,
  ``int`` or ``bool``), each declared with :func:`parameter` (default, unit, bounds). The preset's
  ``[plugin]`` table sets them; the schema engine (:mod:`simcore.schema`) converts and checks them like
  every built-in key (errors name ``plugin.<key>``), so sweeps and calibrations address them as
  ``plugin.<key>``;
* ``steer(i, step, m, nbrs, state, fp, ip, p, key) -> (fx, fy, fz)``: boid i's raw steering force from its m
  perceived neighbours (``nbrs.idx[a]``, offsets ``nbrs.off[a]`` = p_j - p_i, a < m), the run-loop groups
  of :mod:`simcore.hooks` (``state``, the shared slots ``fp``, ``ip`` of :mod:`simcore.layout`), ``p`` its
  parameters as float64 in field order (index it with ``slots(Params)``) and the run's ``key`` for
  counter-based draws (:func:`simcore.rng.normal` with ``STREAM_PLUGIN``). A plain Python function that
  numba can compile as a leaf (:mod:`simcore.jit`): it reads, never allocates, and writes nothing.
  The force moves the boid through the OpenSteer vehicle physics of ``[vehicle]``
  (:func:`simcore.dynamics.apply_steering`; :mod:`simcore.plugin_hooks` holds the hooks).

Identity. A plug-in's ``sha256`` is the SHA-256 of its module file; a validated model records it
(``plugin_sha256``), so it enters the run id and a changed module gives new run ids (a stored spec
whose plug-in changed is refused, as ``init.from_file``). Its dynamics ``number`` (the run loop's
compile-time literal, ``ip[I.DYNAMICS]``) is ``PLUGIN_BASE`` plus 40 bits of the hash of its module path
and source: the run loop compiled for it, which numba caches on disk, is never served for another
version of the module. The module's own function is compiled without a cache of its own (it lives on in
the run loop's cached code). Code the module imports from other files is not part of either hash: keep
the model in its one module.

Nothing here imports numba: validating a preset stays cheap.
"""
from __future__ import annotations

import dataclasses
import hashlib
import importlib
import importlib.metadata
import math
import typing
from dataclasses import dataclass, field
from enum import IntEnum
from types import ModuleType

from .schema import ConfigError, build, suggest

ENTRY_POINT_GROUP = "flocksweep.dynamics"
PLUGIN_BASE = 1 << 40   # plug-in dynamics numbers start here; built-ins are 0, 1, ...
TABLE = "plugin"        # the preset table of a plug-in's parameters
PARAM_TYPES = (float, int, bool)
REQUIRED = ("Params",)
HOOK_SET = ("scratch", "sense", "move")   # the full hook set (simcore.hooks), or else ``steer``
# a plug-in's capabilities when its module declares none (simcore.registry)
DEFAULTS = {"planar": False, "obstacles": False, "leadership": False, "patterns": True, "shared_noise": True,
            "uses": ("steering", "gains", "vehicle", "patterns")}   # a plug-in's hooks receive every shared slot


def parameter(default, *, unit: str = "", low: float | None = None, high: float | None = None,
              low_open: bool = False, high_open: bool = False, length=None, doc: str = ""):
    """A model parameter (a plug-in's, or a built-in table's): a dataclass field with its default, unit and
    bounds ``[low, high]`` (``(low`` with ``low_open``, ``high)`` with ``high_open``; None: unbounded on
    that side), checked by :class:`PluginParams`. ``length``: the power of length the value carries, for a
    preset written in metres (:mod:`simcore.units`: 0 for none, 1 for a length, a speed or an acceleration,
    or a function of the preset's data); None: not declared (such a table is not converted from metres)."""
    return field(default=default, metadata={"unit": unit, "low": low, "high": high, "low_open": low_open,
                                            "high_open": high_open, "length": length, "doc": doc})


@dataclass(frozen=True)
class PluginParams:
    """Base of a model's parameter table (a plug-in's ``Params``, a built-in's table): checks every field
    against the bounds :func:`parameter` declared (a float must also be finite), raising ConfigError
    naming the key (under the table ``TABLE`` when the class sets one), the value, its unit and the
    range."""

    TABLE: typing.ClassVar[str] = ""

    def __post_init__(self):
        for spec in dataclasses.fields(self):
            check_bounds(spec, getattr(self, spec.name), self.TABLE)


def check_bounds(spec: dataclasses.Field, value, table: str = "") -> None:
    meta = spec.metadata
    low, high = meta.get("low"), meta.get("high")
    low_open, high_open = meta.get("low_open", False), meta.get("high_open", False)
    unit = f" {meta['unit']}" if meta.get("unit") else ""
    key = f"{table}.{spec.name}" if table else spec.name
    if isinstance(value, float) and not math.isfinite(value):
        raise ConfigError(key, f"got {value!r}; expected a finite number")
    below = low is not None and (value <= low if low_open else value < low)
    above = high is not None and (value >= high if high_open else value > high)
    if below or above:
        left = "-inf" if low is None else low
        right = "inf" if high is None else high
        raise ConfigError(key, f"got {value!r}{unit}; allowed range {'(' if low_open or low is None else '['}"
                               f"{left}, {right}{')' if high is None or high_open else ']'}{unit}")


def slots(params_class) -> IntEnum:
    """Named positions of a plug-in's parameters in ``p`` (``p[P.zor]``; numba folds them to constants)."""
    return IntEnum(f"{params_class.__name__}Slot", [f.name for f in dataclasses.fields(params_class)], start=0)


@dataclass(frozen=True)
class Plugin:
    """A loaded plug-in: the name the preset gives, its module, parameters class, source hash and number
    (:mod:`simcore.registry` describes it as it does a built-in)."""

    name: str
    module: ModuleType
    params: type
    sha256: str
    number: int

    @property
    def full_hooks(self) -> bool:
        """Whether the module defines the full hook set (else its ``steer`` runs through OpenSteer's vehicle)."""
        return all(callable(getattr(self.module, hook, None)) for hook in HOOK_SET)

    def values(self, params) -> list[float]:
        """The parameters as ``p`` holds them (field order, as floats)."""
        return [float(getattr(params, f.name)) for f in dataclasses.fields(self.params)]


LOADED: dict[str, Plugin] = {}       # by the name presets give
BY_NUMBER: dict[int, Plugin] = {}    # by dynamics number (the run loop's literal)


def module_path(name: str) -> str:
    """The module a plug-in name stands for: an entry point's module, or the name itself."""
    for point in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP):
        if point.name == name:
            return point.value.split(":", 1)[0].strip()
    return name


def load(name: str, builtins: tuple[str, ...] = ()) -> Plugin:
    """The plug-in named ``name`` (imported, checked and registered once per process); ConfigError at
    ``dynamics`` when it is not an importable module with the plug-in interface (``builtins``: the
    built-in names, for the message)."""
    if name in LOADED:
        return LOADED[name]
    path = module_path(name)
    module = _import(name, path, builtins)
    missing = [attr for attr in REQUIRED if not hasattr(module, attr)]
    if not hasattr(module, "steer") and not any(hasattr(module, hook) for hook in HOOK_SET):
        missing.append("steer")
    if missing:
        raise ConfigError("dynamics", f"got {name!r}: module {path!r} is not a plug-in dynamics: it defines no "
                                      f"{', '.join(missing)} (a plug-in defines Params and steer, or Params and the "
                                      f"full hook set {', '.join(HOOK_SET)}; docs/plugins.md)")
    params = _check_params(path, module.Params)
    _check_hooks(name, path, module)
    sha = source_sha256(module)
    tag = hashlib.sha256(f"{path}\0{sha}".encode()).hexdigest()
    number = PLUGIN_BASE + int(tag[:10], 16)
    plugin = Plugin(name, module, params, sha, number)
    LOADED[name] = BY_NUMBER[plugin.number] = plugin
    return plugin


def _check_hooks(name: str, path: str, module: ModuleType) -> None:
    """The module defines the full hook set (``scratch``, ``sense``, ``move``) or ``steer``."""
    defined = [hook for hook in HOOK_SET if hasattr(module, hook)]
    if defined and len(defined) < len(HOOK_SET):
        missing = [hook for hook in HOOK_SET if hook not in defined]
        raise ConfigError("dynamics", f"got {name!r}: module {path!r} defines {', '.join(defined)} but not "
                                      f"{', '.join(missing)}: a plug-in defines the full hook set "
                                      f"({', '.join(HOOK_SET)}) or only steer (docs/plugins.md)")
    for hook in HOOK_SET if defined else ("steer",):
        if not callable(getattr(module, hook)):
            raise ConfigError("dynamics", f"got {name!r}: {path}.{hook} is not a function (docs/plugins.md)")


def _import(name: str, path: str, builtins) -> ModuleType:
    try:
        return importlib.import_module(path)
    except ModuleNotFoundError as err:
        if err.name and path.startswith(err.name):
            allowed = f"allowed: {', '.join(map(repr, builtins))}{suggest(name, builtins)}, or " if builtins else ""
            raise ConfigError("dynamics", f"got {name!r}; {allowed}a plug-in module on the Python path (PYTHONPATH, "
                                          f"or installed): no module {err.name!r} can be imported") from None
        raise ConfigError("dynamics", f"importing plug-in module {path!r} failed: {err}") from None
    except Exception as err:   # the module's own code failed: say so, with what it raised
        raise ConfigError("dynamics", f"importing plug-in module {path!r} failed: {type(err).__name__}: "
                                      f"{err}") from None


def _check_params(path: str, params) -> type:
    if not (isinstance(params, type) and issubclass(params, PluginParams) and dataclasses.is_dataclass(params)
            and params.__dataclass_params__.frozen):
        raise ConfigError("dynamics", f"{path}.Params must be a frozen dataclass subclassing "
                                      "simcore.plugin.PluginParams (docs/plugins.md)")
    hints = typing.get_type_hints(params)
    for spec in dataclasses.fields(params):
        if hints[spec.name] not in PARAM_TYPES:
            raise ConfigError("dynamics", f"{path}.Params.{spec.name}: a parameter is a float, int or bool, not "
                                          f"{hints[spec.name]!r}")
        if spec.default is dataclasses.MISSING:
            raise ConfigError("dynamics", f"{path}.Params.{spec.name} has no default (declare it with "
                                          "simcore.plugin.parameter)")
    return params


def source_sha256(module: ModuleType) -> str:
    """SHA-256 of a plug-in module's source file."""
    source = getattr(module, "__file__", None)
    if not source or not source.endswith(".py"):
        raise ConfigError("dynamics", f"plug-in module {module.__name__!r} has no Python source file ({source!r}); "
                                      "its source hash is part of every run id")
    with open(source, "rb") as handle:
        return hashlib.sha256(handle.read()).hexdigest()


def validate(model, builtins: tuple[str, ...]) -> tuple[object, str]:
    """(parameters, sha256) of a plug-in model (``ModelParams`` whose dynamics is not built in): its
    ``[plugin]`` table built by the schema engine, and the module's hash, checked against the one a
    stored spec gives (``builtins``: the built-in names, for messages)."""
    plugin = load(model.dynamics, builtins)
    table = model.plugin
    if table is None:
        table = {}
    if isinstance(table, dict):
        values = build(plugin.params, table, TABLE)
    elif isinstance(table, plugin.params):
        values = table
    else:
        raise ConfigError(TABLE, f"holds the parameters of another dynamics ({type(table).__name__}); "
                                 f"expected those of {model.dynamics!r}")
    if model.plugin_sha256 is not None and model.plugin_sha256 != plugin.sha256:
        raise ConfigError("dynamics", f"plug-in module {module_path(model.dynamics)!r} changed since this spec was "
                                      f"made (its SHA-256 is {plugin.sha256}, the spec says {model.plugin_sha256})")
    return values, plugin.sha256
