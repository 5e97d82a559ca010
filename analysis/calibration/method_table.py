"""The ``[method]`` table of a calibration file: which method runs, with which settings.

Contract
--------
``method_settings(table, base, dim, k, chosen=None) -> MethodChoice``; ``chosen_kind(table, chosen=None)``

* A ``[method]`` table is either today's flat table (``kind = "emcee"`` and that method's keys), or
  holds settings for several methods in sub-tables named by method (``[method.emcee]``,
  ``[method.optimize]``, ``[method.emulator]``: the registered methods, :mod:`analysis.calibration.methods`), or both:
  the flat keys are then the settings of ``kind`` (the file's own method), and the keys every method
  has (``n_sim``, ``likelihood``: :class:`~analysis.calibration.settings.MethodSettings`) are shared by
  the other methods' sub-tables, whose own keys win. A key given both flat and in ``[method.<kind>]``
  of the file's own kind is an error (which one a ``--set`` meant would be a guess). Without ``kind``,
  flat keys are defaults for every method that has them.
* The method that runs is ``chosen`` (``flocksweep calibrate --method``) if given, else ``kind``, else
  the only sub-table; several sub-tables and no ``kind`` is an error asking for one.
* Every sub-table is validated, whether chosen or not, and so are the flat keys: an unknown key is a
  :class:`~simcore.schema.ConfigError` naming the method (``method.emcee.walkrs: unknown key (did you
  mean 'walkers'?)``); a flat key the file's ``kind`` does not have says how to switch methods
  (``--method``, sub-tables). Cross-checks (``n_sim`` against the ``k`` statistics, then the method's own:
  its ``resolve``, e.g. ``walkers`` against the ``dim`` parameters, the emulator's ``results`` resolved
  against ``base``) are run for each.
* :class:`MethodChoice`: ``settings`` (the chosen method's typed settings), ``kind``, ``own`` (True when
  it is the file's own ``kind``; another method's outputs go to their own folder, ``<name>-<kind>``),
  ``available`` (the methods the file holds settings for).
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

from flocksweep.simcore.schema import ConfigError, build, check_choice, field_names, resolve_path, unknown_key

from .likelihood import min_replicates
from .methods import kinds, method_of, settings_classes
from .settings import MethodSettings

SHARED = field_names(MethodSettings)


@dataclass(frozen=True)
class MethodChoice:
    settings: MethodSettings
    kind: str
    own: bool
    available: tuple[str, ...]


def _switch_hint(owner: str) -> str:
    return (f"; the flat [method] keys are the settings of kind = {owner!r}: to run another method use "
            "flocksweep calibrate FILE --method NAME, and keep settings for several methods in "
            "[method.emcee], [method.optimize], ... tables")


def _checked(cls, data: dict, from_flat, kind: str, base: Path, dim: int, k: int) -> MethodSettings:
    """``cls`` built from ``data``; errors name ``method.<key>`` for the keys ``from_flat`` (the flat table
    gave them), ``method.<kind>.<key>`` for the others (given, or missing, in the method's sub-table)."""
    where = (lambda key: f"method.{key}" if key in from_flat else f"method.{kind}.{key}")
    try:
        settings = build(cls, data, "method")
    except ConfigError as err:
        rest = err.key[len("method."):] if err.key.startswith("method.") else ""
        if not rest:
            raise
        top = re.match(r"[^.\[]+", rest).group(0)
        raise ConfigError(where(top) + rest[len(top):], err.detail) from None
    need = min_replicates(k, settings.likelihood)
    if settings.n_sim < need:
        raise ConfigError(where("n_sim"), f"got {settings.n_sim}; the {settings.likelihood} synthetic likelihood "
                                          f"needs at least {need} replicates for {k} stats (n_sim >= k + {need - k})")
    return method_of(kind).resolve(settings, where, base, dim, k)


def chosen_kind(table: dict, chosen: str | None = None) -> str:
    """The method that runs (see the module docstring)."""
    subs = [name for name in table if name in kinds()]
    if chosen is not None:
        check_choice("--method", chosen, kinds())
        return chosen
    if "kind" in table:
        check_choice("method.kind", table["kind"], kinds())
        return table["kind"]
    if len(subs) == 1:
        return next(iter(subs))
    held = f"this file holds settings for {', '.join(subs)}; " if subs else ""
    raise ConfigError("method.kind", f"missing required key; {held}choose one with kind = \"...\" in [method] or "
                                     f"--method; allowed: {', '.join(kinds())}")


def method_settings(table: dict, base: Path, dim: int, k: int, chosen: str | None = None) -> MethodChoice:
    """The chosen method's validated settings (see the module docstring)."""
    methods = settings_classes()
    subs = {name: value for name, value in table.items() if name in methods}
    for name, value in subs.items():
        if not isinstance(value, dict):
            raise ConfigError(f"method.{name}", f"expected a table of {name}'s settings ([method.{name}]), "
                                                f"got {value!r}")
    kind = chosen_kind(table, chosen)
    owner = table.get("kind")
    flat = {key: value for key, value in table.items() if key != "kind" and key not in methods}
    if owner is None:   # no kind: the flat keys are defaults for every method that has them
        known = list(dict.fromkeys(name for cls in methods.values() for name in field_names(cls)))
        for key in flat:
            if key not in known:
                raise unknown_key(f"method.{key}", known)
    found = {}
    for name in dict.fromkeys([*([owner] if owner else []), *subs, kind]):
        cls = methods[name]
        sub = subs.get(name, {})
        if name == owner:
            allowed = field_names(cls)
            for key in flat:
                if key not in allowed:
                    err = unknown_key(f"method.{key}", allowed)
                    raise ConfigError(err.key, err.detail + _switch_hint(owner))
            for key in sub:
                if key in flat:
                    raise ConfigError(f"method.{name}.{key}", f"also given as method.{key} (the flat [method] keys "
                                                              f"are {owner}'s settings): give it once")
            from_flat = set(flat) if sub else set(flat) | set(field_names(cls))
        else:
            shared = SHARED if owner else field_names(cls)
            from_flat = {key for key in flat if key in shared and key not in sub}
        data = {**{key: flat[key] for key in from_flat if key in flat}, **sub}
        found[name] = _checked(cls, data, from_flat, name, base, dim, k)
    own = "kind" not in table or kind == table["kind"]
    available = tuple(dict.fromkeys([*([owner] if owner else []), *subs]))
    return MethodChoice(settings=found[kind], kind=kind, own=own, available=available)
