"""The registry of calibration methods: every method is a :class:`~.base.CalibrationMethod` registered
once, under its ``kind``; nothing else in flocksweep names a method.

Contract
--------
``register(method, replace=False)``: add a method object (its ``kind`` a plain name, its ``settings`` a
:class:`~analysis.calibration.settings.MethodSettings` subclass of the same ``kind``; a kind registered
already is a ValueError unless ``replace``). ``unregister(kind)`` removes one (tests).

``method_of(kind) -> CalibrationMethod`` (a :class:`~simcore.schema.ConfigError` at ``method.kind`` naming
the registered kinds for an unknown one); ``kinds() -> tuple`` in registration order (the built-ins:
emcee, optimize, npe, emulator); ``settings_classes() -> {kind: settings class}``; ``sbc_kinds()``: the
methods simulation-based calibration checks (``flocksweep sbc``: their ``sbc`` flag);
``check_sbc(config)``: a ConfigError at ``method.kind`` naming those for any other method;
``run_sbc(config, **options) -> dict``: the config's method object's ``run_sbc`` (emcee: BSL's,
:func:`analysis.calibration.sbc.run_sbc`; emulator: the same on
:func:`analysis.calibration.sbc_emulator.emulator_problem`, its chain on the surrogate; npe:
:func:`analysis.calibration.sbc_npe.run_npe_sbc`). optimize has none: it gives a point, not a posterior.

``methods_table() -> str``: the Markdown table of the methods (what each does, its cost, when to use it),
the table at the top of docs/calibration.md (a test keeps the two equal).

The calibration file's ``[method]`` table (:mod:`analysis.calibration.method_table`) and ``flocksweep
calibrate --method`` take their choices from here; :func:`analysis.calibration.run.run_calibration` runs
the method ``method_of(config.method.kind)``. A new method: its settings dataclass, a
``CalibrationMethod`` subclass, and ``register(TheMethod())`` (in this module for a built-in; anywhere,
before the calibration file is read, for a user's: docs/calibration.md, "A method of your own").
"""
from __future__ import annotations

import re

from flocksweep.simcore.schema import ConfigError

from .base import CalibrationMethod, Job
from .emcee import Emcee
from .emulator import Emulator
from .npe import Npe
from .optimize import Optimize

__all__ = ["CalibrationMethod", "Job", "register", "unregister", "method_of", "kinds", "sbc_kinds", "check_sbc", "run_sbc",
           "settings_classes", "methods_table"]

_REGISTERED: dict[str, CalibrationMethod] = {}
KIND = re.compile(r"[a-z][a-z0-9_]*\Z")


def register(method: CalibrationMethod, replace: bool = False) -> CalibrationMethod:
    """Register ``method`` under its kind (see the module docstring); returns it."""
    if not isinstance(method, CalibrationMethod):
        raise TypeError(f"expected a CalibrationMethod instance, got {method!r}")
    kind = method.kind
    if not isinstance(kind, str) or not KIND.match(kind):
        raise ValueError(f"method kind {kind!r}: expected a plain lower-case name (letters, digits, _)")
    if getattr(method.settings, "kind", None) != kind:
        raise ValueError(f"method {kind!r}: its settings class {method.settings.__name__} has kind "
                         f"{getattr(method.settings, 'kind', None)!r}; give it kind: ClassVar[str] = {kind!r}")
    if kind in _REGISTERED and not replace:
        raise ValueError(f"method {kind!r} is registered already (register(..., replace=True) to replace it)")
    _REGISTERED[kind] = method
    return method


def unregister(kind: str) -> None:
    _REGISTERED.pop(kind, None)


def kinds() -> tuple[str, ...]:
    return tuple(_REGISTERED)


def method_of(kind: str) -> CalibrationMethod:
    try:
        return _REGISTERED[kind]
    except KeyError:
        raise ConfigError("method.kind", f"got {kind!r}; allowed: {', '.join(_REGISTERED)}") from None


def sbc_kinds() -> tuple[str, ...]:
    """The methods simulation-based calibration checks (their ``sbc`` flag)."""
    return tuple(kind for kind, method in _REGISTERED.items() if method.sbc)


def check_sbc(config) -> None:
    """ConfigError at ``method.kind`` unless the config's method has an SBC check (its ``sbc`` flag)."""
    if not method_of(config.method.kind).sbc:
        raise ConfigError("method.kind", f"got {config.method.kind!r}, which has no SBC check yet; allowed: "
                                         f"{', '.join(sbc_kinds())} (SBC re-fits many synthetic datasets drawn "
                                         "from the prior; --set method.kind=... to check another method)")


def run_sbc(config, **options) -> dict:
    """Simulation-based calibration of ``config`` by its method's own check (module docstring)."""
    check_sbc(config)
    return method_of(config.method.kind).run_sbc(config, **options)


def settings_classes() -> dict:
    return {kind: method.settings for kind, method in _REGISTERED.items()}


def methods_table() -> str:
    """The methods as a Markdown table (see the module docstring)."""
    lines = ["| method | what it does | cost | use it when |", "|---|---|---|---|"]
    lines += [f"| `{kind}` | {m.what} | {m.cost} | {m.use_when} |" for kind, m in _REGISTERED.items()]
    return "\n".join(lines)


for _method in (Emcee(), Optimize(), Npe(), Emulator()):
    register(_method)
