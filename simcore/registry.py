"""The one registry of dynamics: every built-in listed once, plug-ins loaded through the same path.

A dynamics is described by a numba-free **descriptor** module and run by a compiled **hooks** module
(:mod:`simcore.hooks` states the hooks' contract). A built-in is a plug-in that ships: its descriptor is a
module of ``simcore`` named in :data:`BUILTINS` (one line per dynamics), a plug-in's is the user's own
module (:mod:`simcore.plugin`). :func:`describe` reads either into a :class:`Dynamics`, and everything
above the compiled hooks (validation and the canonical form of a preset in :mod:`simcore.params`, the
units of :mod:`simcore.units`, the packed slots of :mod:`simcore.layout`, :mod:`simcore.simulate`, the
metrics' settings, ``flocksweep compile``) asks it, never a dynamics' name. Importing this module imports
no descriptor and no numba.

What a descriptor module defines (every name optional unless said; the defaults are a plug-in's):

* ``Params``: the class of its preset table (a frozen dataclass; its fields declared with
  :func:`simcore.plugin.parameter`: default, unit, power of length, bounds, doc) and ``TABLE``, the
  table's name in a preset (``"vicsek"``; a plug-in's is always ``plugin``). Required of a built-in that
  has parameters of its own;
* ``HOOKS``: the module of its compiled hooks (relative to ``simcore``, or a full module path; a plug-in's
  is itself, or :mod:`simcore.plugin_hooks` when it defines only the convenience ``steer``);
* capability flags: ``PLANAR`` (runs with ``world.dimensions = 2``), ``OBSTACLES`` (reads
  ``world.obstacles``), ``HEADING`` (a constant-speed heading model), ``PERCEPTION`` (the perception kind
  it requires, or None for any), ``AGENTS`` (records agents besides the boids: a predator, a prey),
  ``LEADERSHIP`` (has the change of leadership), ``PATTERNS`` (has the pattern mode), ``SHARED_NOISE``
  (``[noise]`` and ``[cruise]`` act on it), ``THREADS`` (a synchronous run may split over threads);
* ``STREAMS``: its random streams, name -> stream number of :mod:`simcore.rng` (unique across the
  built-ins and the shared streams; a test checks);
* ``USES``: the shared tables its canonical form keeps (``vehicle``, ``patterns``, another dynamics'
  table such as ``steering``); the shared feature tables ``leadership``, ``noise`` and ``cruise`` are kept
  when on, or always when listed here;
* functions of a validated model: ``check(model)`` (its own cross-table checks, ConfigError naming the
  key), ``sphere_radius(model)`` (the perception sphere's radius when the dynamics derives it from its
  own table; its canonical form then records only ``perception.kind``), ``canonical(table) -> dict`` (its
  table's run-identity form; default every key), ``body_radius(model)`` (the body radius collisions are
  measured with; default ``perception.body_radius``), ``migration(model)`` (a migratory direction, or
  None), ``agent_observations(model, rec_agents, capture_step) -> dict`` (with ``AGENTS``: the agents'
  fields of the run's observations).
"""
from __future__ import annotations

import dataclasses
import importlib
from dataclasses import dataclass, field
from types import ModuleType
from typing import Callable

PACKAGE = __name__.rsplit(".", 1)[0]

# name presets give -> its descriptor module (relative to simcore, or a full module path); the position is
# the dynamics' number in the run loop (a compile-time literal), so a new built-in goes at the end
BUILTINS: dict[str, str] = {
    "opensteer": ".opensteer_params",
    "hartman_benes": ".hartman_benes_params",
    "reynolds87": ".reynolds_params",
    "boidspp": ".boidspp_params",
    "couzin2002": ".couzin_params",
    "vicsek": ".vicsek_params",
}

FEATURE_TABLES = ("leadership", "noise", "cruise")   # shared tables kept in the canonical form when on


def _nothing(model) -> None:
    return None


def _body_radius(model) -> float:
    return float(model.perception.body_radius)


@dataclass(frozen=True)
class Dynamics:
    """A dynamics as the registry describes it (module docstring): its name, run-loop number,
    descriptor module, table and class, capabilities and functions."""

    name: str
    number: int
    descriptor: ModuleType
    hooks_module: str
    table: str | None = None
    params: type | None = None
    builtin: bool = True
    planar: bool = False
    obstacles: bool = False
    heading: bool = False
    perception: str | None = None
    agents: bool = False
    leadership: bool = False
    patterns: bool = True
    shared_noise: bool = True
    threads: bool = True
    streams: dict = field(default_factory=dict)
    uses: tuple[str, ...] = ()
    check: Callable = _nothing
    sphere_radius: Callable | None = None
    canonical: Callable | None = None
    body_radius: Callable = _body_radius
    migration: Callable = _nothing
    agent_observations: Callable | None = None

    def hooks(self) -> ModuleType:
        """The compiled hooks module (imports numba)."""
        return importlib.import_module(self.hooks_module, PACKAGE)

    def keeps(self, table: str, on: bool) -> bool:
        """Whether the canonical form of a model of this dynamics keeps shared ``table`` (``on``: whether
        the table's feature is on; tables without a feature pass True)."""
        if table in FEATURE_TABLES:
            return on or table in self.uses
        return table == self.table or table in self.uses


FLAGS = {"PLANAR": "planar", "OBSTACLES": "obstacles", "HEADING": "heading", "PERCEPTION": "perception",
         "AGENTS": "agents", "LEADERSHIP": "leadership", "PATTERNS": "patterns", "SHARED_NOISE": "shared_noise",
         "THREADS": "threads", "STREAMS": "streams", "USES": "uses"}
FUNCTIONS = ("check", "sphere_radius", "canonical", "body_radius", "migration", "agent_observations")


def from_module(name: str, number: int, module: ModuleType, *, hooks_module: str, table: str | None,
                builtin: bool, defaults: dict | None = None) -> Dynamics:
    """The :class:`Dynamics` a descriptor module declares (module docstring), with ``defaults`` for the
    flags it leaves out."""
    values = dict(defaults or {})
    values.update({attr: getattr(module, flag) for flag, attr in FLAGS.items() if hasattr(module, flag)})
    values.update({fn: getattr(module, fn) for fn in FUNCTIONS if callable(getattr(module, fn, None))})
    values["uses"] = tuple(values.get("uses", ()))
    values["streams"] = dict(values.get("streams", {}))
    return Dynamics(name=name, number=number, descriptor=module, hooks_module=hooks_module, table=table,
                    params=getattr(module, "Params", None) if table else None, builtin=builtin, **values)


_BUILTIN: dict[str, Dynamics] = {}


def builtin_names() -> tuple[str, ...]:
    """The built-in dynamics, in run-loop number order."""
    return tuple(BUILTINS)


def _builtin(name: str) -> Dynamics:
    if name not in _BUILTIN:
        number = list(BUILTINS).index(name)
        module = importlib.import_module(BUILTINS[name], PACKAGE)
        table = getattr(module, "TABLE", None)
        if table is not None and not dataclasses.is_dataclass(getattr(module, "Params", None)):
            raise TypeError(f"dynamics {name!r}: its descriptor {module.__name__} names TABLE = {table!r} but "
                            "defines no Params dataclass")
        _BUILTIN[name] = from_module(name, number, module, hooks_module=getattr(module, "HOOKS", ""),
                                     table=table, builtin=True)
    return _BUILTIN[name]


def builtins() -> tuple[Dynamics, ...]:
    """Every built-in dynamics, described."""
    return tuple(_builtin(name) for name in BUILTINS)


def builtin_tables() -> dict[str, type]:
    """The preset tables the built-ins declare: table name -> its class (in BUILTINS order; a table two
    dynamics share is listed once)."""
    return {d.table: d.params for d in builtins() if d.table is not None}


def is_builtin(name: str) -> bool:
    """Whether a preset's ``dynamics`` names a built-in (else a plug-in module's dotted path)."""
    return name in BUILTINS


def describe(name: str) -> Dynamics:
    """The dynamics a preset names: a built-in, or a plug-in (loaded, checked and registered on first use:
    :func:`simcore.plugin.load`; ConfigError at ``dynamics`` when it is neither)."""
    if name in BUILTINS:
        return _builtin(name)
    from .plugin import load

    return _plugin(load(name, builtin_names()))


def by_number(number: int) -> Dynamics:
    """The dynamics of run-loop literal ``number`` (a built-in's position, or a loaded plug-in's number;
    KeyError for any other)."""
    names = builtin_names()
    if 0 <= number < len(names):
        return _builtin(names[number])
    from .plugin import BY_NUMBER

    return _plugin(BY_NUMBER[number])


_PLUGIN: dict[int, Dynamics] = {}


def _plugin(plugin) -> Dynamics:
    """A loaded plug-in (:class:`simcore.plugin.Plugin`) described as a built-in is: its module is its
    descriptor and, with the full hook set, its hooks; otherwise :mod:`simcore.plugin_hooks` runs its
    ``steer``. Flags it leaves out take a plug-in's defaults (:data:`simcore.plugin.DEFAULTS`)."""
    if plugin.number not in _PLUGIN:
        from .plugin import DEFAULTS, TABLE

        hooks = plugin.module.__name__ if plugin.full_hooks else f"{PACKAGE}.plugin_hooks"
        _PLUGIN[plugin.number] = from_module(plugin.name, plugin.number, plugin.module, hooks_module=hooks,
                                             table=TABLE, builtin=False,
                                             defaults={**DEFAULTS, "threads": not plugin.full_hooks})
    return _PLUGIN[plugin.number]
