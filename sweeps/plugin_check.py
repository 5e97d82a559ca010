"""A plug-in's ``steer`` compiled on its own before any run: a compile error is one message naming its file and line.

``check_plugin(model)`` (a validated ``ModelParams`` whose dynamics is a plug-in, :mod:`simcore.plugin`)
compiles the module's ``steer`` alone, with numba's options for it (:data:`simcore.plugin_hooks.STEER_OPTIONS`)
and the argument types the run loop calls it with (found from the values the run loop builds: the
neighbour buffers of :func:`simcore.neighbours.new_neighbours`, the state group of an initial state of 3
boids, the packed parameters, a key), and checks that it returns three numbers. That takes a second or
two, where the first compile of the whole run loop takes a minute before numba reports an error in steer,
buried in a page of its traceback. A failure is a :class:`~simcore.schema.ConfigError` at ``dynamics`` (exit
status 2, before anything is written)::

    dynamics: plug-in 'mymodels.zones' does not compile: mymodels/zones.py, line 14 (x = nbrs.nonexistent[0]):
    Unknown attribute 'nonexistent' of type Neighbours(...); steer is compiled by numba in nopython mode
    (docs/plugins.md says what it may use)

The place is the first line of the plug-in's file numba names (steer's first line when it names none, as
for a name that is not defined). Should the run loop's argument types ever be unknown to this check, it is
skipped, and the run loop's own compile fails each run with its reason. Each module is checked
once per process (by its name and source hash). The runner calls it before a sweep is written
(:func:`check_specs`), ``flocksweep simulate`` before it simulates.
"""
from __future__ import annotations

import os
import re

from flocksweep.simcore.schema import ConfigError

ANSI = re.compile(r"\x1b\[[0-9;]*m")
WHERE = re.compile(r'File "(?P<file>[^"]+)", line (?P<line>\d+)')
LISTING = re.compile(r"\b([A-Za-z]\w*)\((?:[^()]|\((?:[^()]|\([^()]*\))*\))*\)")   # Name(... two levels ...)
DETAIL_CHARS = 300
ALLOCATES = "Only accept returning of array passed into the function as argument"   # numba, when _nrt=False
_CHECKED: set[tuple[str, str]] = set()   # (dynamics name, module sha256) checked in this process


def check_specs(specs) -> None:
    """:func:`check_plugin` for every plug-in dynamics the runs of ``specs`` use (once each)."""
    from flocksweep.simcore.registry import is_builtin

    models = {}
    for spec in specs:
        if spec.preset is not None and not is_builtin(spec.preset.model.dynamics):
            models.setdefault(spec.preset.model.dynamics, spec.preset.model)
    for model in models.values():
        check_plugin(model)


def _arguments(model):
    """Values of the types the run loop passes to steer (i, step, m, nbrs, state, fp, ip, p, key)."""
    import numpy as np

    from flocksweep.simcore import hooks
    from flocksweep.simcore.neighbours import new_neighbours
    from flocksweep.simcore.params import InitParams
    from flocksweep.simcore.rng import run_streams
    from flocksweep.simcore.state import FIELDS, initial_state

    rng, key = run_streams(0)
    state = initial_state(InitParams(n=3), model.patterns, rng, model.world.dimensions)
    group = tuple(getattr(state, f) for f in FIELDS) + (state.agents,)
    fp, ip, dyn = hooks.pack(model, 0.01)
    return (np.int64(0), np.int64(0), np.int64(0), new_neighbours(3), group, fp, ip, dyn[0], np.uint64(key))


def check_plugin(model) -> None:
    """Compile the plug-in's steer alone (module docstring); ConfigError at ``dynamics`` when numba
    refuses it at a line of the plug-in's file, or when it does not return three numbers."""
    from flocksweep.simcore.plugin import load, module_path

    plugin = load(model.dynamics)
    if (model.dynamics, plugin.sha256) in _CHECKED:
        return
    import numba
    from numba.core import types
    from numba.core.errors import NumbaError

    from flocksweep.simcore.plugin_hooks import STEER_OPTIONS

    try:
        signature = tuple(numba.typeof(value) for value in _arguments(model))
    except Exception:  # noqa: BLE001 - the run loop's arguments changed shape: leave it to the loop's compile
        return
    source = os.path.realpath(plugin.module.__file__)
    name = f"plug-in {module_path(model.dynamics)!r}"
    steer = numba.njit(**STEER_OPTIONS)(plugin.module.steer)
    try:
        steer.compile(signature)
    except NumbaError as err:
        where = _where(str(err), source) or _unplaced(str(err), plugin.module.steer, source)
        raise ConfigError("dynamics", f"{name} does not compile: {where}; steer is compiled by numba in nopython "
                                      "mode (docs/plugins.md says what it may use)") from None
    returned = steer.overloads[signature].signature.return_type
    if not (isinstance(returned, types.BaseTuple) and len(returned) == 3
            and all(isinstance(t, (types.Number, types.Boolean)) for t in returned)):
        raise ConfigError("dynamics", f"{name}: steer returns {returned}; it must return three numbers, the force "
                                      f"(fx, fy, fz) ({source})")
    _CHECKED.add((model.dynamics, plugin.sha256))


def _where(message: str, source: str) -> str | None:
    """'FILE, line N (source text): what numba says' for the first place of ``message`` in the file
    ``source``, or None when numba names no line of it."""
    text = ANSI.sub("", message)
    lines = text.splitlines()
    for number, line in enumerate(lines):
        found = WHERE.search(line)
        if not found or os.path.realpath(found.group("file")) != source:
            continue
        code = _code_at(lines, number)
        what = _what(lines)
        return f"{_shown(source)}, line {found.group('line')}" + (f" ({code})" if code else "") + f": {what}"
    return None


def _unplaced(message: str, steer, source: str) -> str:
    """'FILE, steer from line N: what numba says' for an error numba gives no line for (a name not
    defined, ...)."""
    import inspect

    try:
        first = inspect.getsourcelines(steer)[1]
    except (OSError, TypeError):
        first = "?"
    return f"{_shown(source)}, steer (from line {first}): {_what(ANSI.sub('', message).splitlines())}"


def _shown(source: str) -> str:
    """The plug-in's file as the user knows it: relative to the working directory when below it."""
    relative = os.path.relpath(source)
    return source if relative.startswith("..") else relative


def _code_at(lines: list[str], number: int) -> str:
    """The source line numba marks (the one above its caret ``^``) after the 'File ...' line ``number``."""
    for k in range(number + 1, min(number + 12, len(lines))):
        if lines[k].strip() == "^" and k > number + 1:
            return lines[k - 1].strip()
    return ""


def _what(lines: list[str]) -> str:
    """Numba's own words: its first line that is not a pipeline heading, long type listings shortened
    (``Neighbours(array(int64, 1d, C), ...)`` -> ``Neighbours(...)``), at most DETAIL_CHARS characters."""
    for k, line in enumerate(lines):
        line = line.strip()
        if line and not line.startswith(("Failed in ", "- Resolution failure", "During:")):
            call = next((x.strip()[4:] for x in lines[k + 1:k + 4] if x.strip().startswith(">>> ")), None)
            if line.endswith(":") and call:   # 'No implementation of function ... found for signature:' and the call
                line = f"{line} {call}"
            line = LISTING.sub(lambda m: m.group(0) if len(m.group(0)) <= 40 else f"{m.group(1)}(...)", line)
            line = line if len(line) <= DETAIL_CHARS else line[:DETAIL_CHARS] + "..."
            if any(ALLOCATES in x for x in lines):
                line += " (steer cannot allocate arrays: it is compiled without reference counting)"
            return line
    return "numba could not compile it"
