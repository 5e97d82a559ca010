"""A sweep from ``flocksweep run``'s arguments: a sweep file, or a model with ``--axis`` flags.

Contract
--------
``sweep_from_args(sweep, model, axes, replicates, name, overrides, cwd) -> (SweepConfig, sweep_text)``

* With a sweep file (``sweep``; ``model``, ``axes`` and ``name`` None/empty): :func:`sweeps.config.load_sweep`
  with the overrides and replicates, and the file's text as given.
* With ``model`` (a preset TOML) and ``axes`` (``["KEY=SPEC", ...]``): the sweep a file would hold, as a
  dict, then validated by :func:`sweeps.config.sweep_from_dict` exactly as a file is. ``SPEC`` takes the
  forms of an ``[[axes]]`` table: ``V1,V2,...`` (``values``; each value read as an override value is:
  numbers, booleans, quoted strings, bare words as strings), ``linspace(START,STOP,NUM)`` (``linspace``)
  or ``range(START,STOP,STEP)`` (``range``). ``name`` defaults to ``<model stem>_<last part of each
  axis key>``; ``seed`` is 0 and ``replicates`` 1 unless ``--replicates`` or ``--set seed=...`` say
  otherwise; the preset path is made absolute (the runner stores it relative to the results folder). Overrides (``--set``) apply to that dict as to a file's
  (``model.<preset key>=v`` is ``model.set.<preset key>=v``; ``run.n=...``, ``seed=...``, ...).
* Every axis is checked before anything runs: its key and every value against the preset
  (:meth:`simcore.Preset.replace`), and its form; errors are :class:`~simcore.schema.ConfigError` keyed
  ``--axis`` (or ``--model``) that quote the flag's text and say what is wrong, with a did-you-mean for a
  misspelt key.
* ``sweep_text`` is then the resolved sweep as TOML (overrides and replicates applied; a comment line
  naming the command), which the runner stores as the results' ``sweep.toml``: ``flocksweep run
  RESULTS/sweep.toml`` builds the same sweep, with the same run ids.

``check_run_args(args)``: the run command's counts, workers, output folder and scheduler flags.
"""
from __future__ import annotations

import re
from pathlib import Path

import tomli_w

from flocksweep.simcore.schema import ConfigError, apply_overrides, parse_value

from flocksweep.sweeps.config import SweepConfig, load_sweep, sweep_from_dict
from flocksweep.sweeps.design import base_preset
from flocksweep.sweeps.failures import check_count, check_out, check_workers
from flocksweep.sweeps.model_set import model_overrides

FORMS = "KEY=V1,V2,... or KEY=linspace(START,STOP,NUM) or KEY=range(START,STOP,STEP)"
_CALL = re.compile(r"^(linspace|range)\((.*)\)$")


def _numbers(item: str, text: str, count: int) -> list:
    values = [parse_value(part.strip()) for part in text.split(",")]
    if len(values) != count or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
        raise ConfigError("--axis", f"got {item!r}; expected {count} numbers in the parentheses ({FORMS})")
    return values


def parse_axis_flag(item: str) -> dict:
    """One ``--axis KEY=SPEC`` as an ``[[axes]]`` table (see the module docstring)."""
    key, sep, spec = item.partition("=")
    key, spec = key.strip(), spec.strip()
    if not sep or not key or not spec:
        raise ConfigError("--axis", f"got {item!r}; expected {FORMS}")
    call = _CALL.match(spec)
    if call:
        kind, args = call.groups()
        start, stop, third = _numbers(item, args, 3)
        return {"key": key, kind: {"start": start, "stop": stop, "num" if kind == "linspace" else "step": third}}
    values = [parse_value(part.strip()) for part in spec.split(",")]
    if any(part.strip() == "" for part in spec.split(",")):
        raise ConfigError("--axis", f"got {item!r}; an empty value between commas ({FORMS})")
    return {"key": key, "values": values}


def _rekeyed(err: ConfigError, axes: list[str]) -> ConfigError:
    match = re.match(r"^axes\[(\d+)\]", err.key)
    if match and int(match.group(1)) < len(axes):
        return ConfigError("--axis", f"{axes[int(match.group(1))]!r}: {err.detail}")
    if err.key == "model.preset":
        return ConfigError("--model", err.detail)
    return err


def _check_axes(config: SweepConfig, axes: list[str]) -> None:
    base = base_preset(config)
    for item, axis in zip(axes, config.axes):
        for point in axis.points:
            try:
                base.replace(dict(zip(axis.keys, point)))
            except ConfigError as err:
                raise ConfigError("--axis", f"{item!r}: {err}") from None


def sweep_dict(model: str, axes: list[str], replicates: int | None, name: str | None, overrides) -> dict:
    """The sweep file's dict of a ``--model``/``--axis`` command line, overrides applied."""
    path = Path(model)
    if not path.is_file():
        raise ConfigError("--model", f"got {model!r}; no such file (a model preset TOML, e.g. "
                                     "configs/models/holland.toml)")
    tables = [parse_axis_flag(item) for item in axes]
    default = "_".join([path.stem] + [t["key"].rsplit(".", 1)[-1] for t in tables])
    data = {"name": name or default, "description": f"flocksweep run --model {model} "
                                                    + " ".join(f"--axis {a}" for a in axes),
            "seed": 0, "replicates": replicates or 1, "model": {"preset": str(path.resolve())}, "axes": tables}
    data = apply_overrides(data, model_overrides(overrides))
    if replicates is not None:
        data["replicates"] = replicates
    return data


def sweep_from_args(sweep, model, axes, replicates, name, overrides, cwd=None) -> tuple[SweepConfig, str]:
    """The sweep and the text to store as its ``sweep.toml`` (see the module docstring)."""
    if sweep is not None:
        for flag, value in (("--model", model), ("--axis", axes), ("--name", name)):
            if value:
                raise ConfigError(flag, f"only without a sweep file (got {sweep}); the file names its model, "
                                        "axes and name (change them with --set)")
        return load_sweep(sweep, overrides, replicates), Path(sweep).read_text(encoding="utf-8")
    if model is None:
        raise ConfigError("sweep", "missing: give a sweep TOML, or --model MODEL.toml with --axis " + FORMS)
    if not axes:
        raise ConfigError("--axis", f"missing: give at least one --axis {FORMS}")
    data = sweep_dict(model, list(axes), replicates, name, overrides)
    try:
        config = sweep_from_dict(data, Path(cwd or Path.cwd()))
        _check_axes(config, list(axes))
    except ConfigError as err:
        raise _rekeyed(err, list(axes)) from None
    header = ("# The sweep of a command line, resolved (--set and --replicates applied):\n# "
              f"{data['description']}\n# Run it again (same runs, same run ids): flocksweep run <this file>\n")
    return config, header + tomli_w.dumps(data)


def check_run_args(args) -> None:
    """The run command's numeric and address flags (before anything is read or run)."""
    check_workers(args.workers, args.executor)
    check_count("--replicates", args.replicates, 1)
    check_count("--batch-size", args.batch_size, 1)
    check_count("--max-replicates", args.max_replicates, 1)
    check_out("--out", args.out)
    if args.scheduler is not None and args.executor != "dask":
        raise ConfigError("--scheduler", "only applies with --executor dask")
    if args.workers is not None and args.executor == "cluster":
        raise ConfigError("--workers", "not used with --executor cluster: the cluster's workers are "
                                       "cluster.jobs x cluster.processes (--set cluster.jobs=N)")
    if args.scheduler is not None and not args.scheduler.strip():
        raise ConfigError("--scheduler", "got an empty address; expected tcp://HOST:PORT")
