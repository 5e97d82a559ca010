"""A sweep written back as a TOML file: what a sweep built in Python stores as ``sweep.toml``.

``sweep_toml(config) -> str`` writes the sweep's tables as given (``config.source``, the dict it was
built from, with ``--set`` overrides and ``replicates`` applied) so that
``SweepConfig.from_toml`` of the text gives the same sweep: the same design and run ids. Two things
change so the file runs from any folder: ``model.preset`` becomes the absolute path of the preset that
was read (stored in a results folder, :func:`relocated` makes it relative to that folder; a command
model's ``model.workdir`` likewise, :func:`relocated_workdir`), and ``include_claims`` are written out as ``[[claims]]`` tables (as in
``sweep.effective.json``). Values TOML cannot hold (``None``, objects) raise
:class:`~simcore.schema.ConfigError` naming the dotted key. The writer is ``tomli_w``.
"""
from __future__ import annotations

import math
import os
import re
import tomllib
from pathlib import Path, PurePath

import numpy as np
import tomli_w

from flocksweep.simcore.schema import ConfigError

from .claims import with_claims

HEADER = "# The sweep as run, written by flocksweep (sweeps/sweep_toml.py); reads back as the same sweep.\n"


def toml_value(value, key: str):
    """``value`` as a type TOML holds (numpy scalars and arrays, tuples and paths converted)."""
    if isinstance(value, dict):
        return {str(k): toml_value(v, f"{key}.{k}" if key else str(k)) for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [toml_value(v, f"{key}[{i}]") for i, v in enumerate(list(value))]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, PurePath):
        return str(value)
    if isinstance(value, float) and not math.isfinite(value):
        return value   # TOML has nan and inf; the schema decides whether they are allowed
    if value is None or not isinstance(value, (bool, int, float, str)):
        raise ConfigError(key, f"got {value!r}; a sweep file holds only numbers, booleans, strings, lists "
                               "and tables")
    return value


def sweep_toml(config) -> str:
    """TOML text of the sweep ``config`` (a :class:`sweeps.config.SweepConfig`); see the module docstring."""
    data = with_claims({**config.source, "replicates": config.replicates}, config.claims)
    if config.command is not None:   # a command model: the folder it runs in (and its files are found from)
        data["model"] = {**data.get("model", {}), "workdir": str(config.command.workdir)}
    else:
        data["model"] = {**data.get("model", {}), "preset": str(config.preset_path)}
    return HEADER + tomli_w.dumps(toml_value(data, ""))


def portable(path, folder) -> str:
    """``path`` relative to ``folder`` (POSIX separators), for files stored in ``folder``."""
    return Path(os.path.relpath(Path(path).resolve(), Path(folder).resolve())).as_posix()


def relocated(text: str, preset_path, folder) -> str:
    """``text`` with ``model.preset`` relative to ``folder`` (see the module docstring). A preset that is
    not a plain ``preset = "..."`` line of the ``[model]`` table is left as it is."""
    try:
        given = tomllib.loads(text).get("model", {}).get("preset")
    except tomllib.TOMLDecodeError:
        return text
    if not isinstance(given, str):
        return text
    line = re.compile(r"^(\s*preset\s*=\s*)(" + re.escape(tomli_w.dumps({"p": given})[4:].strip())
                      + "|'" + re.escape(given) + "')(.*)$", re.M)
    new = tomli_w.dumps({"p": portable(preset_path, folder)})[4:].strip()
    changed, count = line.subn(lambda m: m.group(1) + new + m.group(3), text)
    if count != 1 or tomllib.loads(changed).get("model", {}).get("preset") != portable(preset_path, folder):
        return text
    return changed


def relocated_workdir(text: str, workdir, folder) -> str:
    """A command model's sweep ``text`` with ``model.workdir`` (the folder its command runs in) relative to
    ``folder``: a line added under ``[model]`` when the file has none, else the file written anew (its
    comments lost). The stored sweep then runs the same command, with the same run ids, from ``folder``."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError:
        return text
    if not isinstance(data.get("model"), dict):
        return text
    new = portable(workdir, folder)
    wanted = {**data, "model": {**data["model"], "workdir": new}}
    line = "workdir = " + tomli_w.dumps({"p": new})[4:].strip()
    changed, count = re.compile(r"^(\[model\][ \t]*(#.*)?)$", re.M).subn(lambda m: m.group(1) + "\n" + line, text)
    if "workdir" not in data["model"] and count == 1:
        try:
            if tomllib.loads(changed) == wanted:
                return changed
        except tomllib.TOMLDecodeError:
            pass
    return HEADER + tomli_w.dumps(toml_value(wanted, ""))
