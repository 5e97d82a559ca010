"""External simulators run as commands: a sweep's ``[model] command``, measured as tracks.

A sweep whose ``[model]`` table gives ``command`` instead of ``preset`` runs that program once per run and
measures the long-format tracks it writes with the measured-tracks path (:func:`observables.tracks.load_tracks`,
:func:`observables.measured.measure_tracks`: the same checks, resampling and metrics as ``flocksweep
measure``)::

    [model]
    command = ["python", "vicsek_sim.py", "--seed", "{seed}", "--out", "{out}", "{params}"]
    output = "tracks.csv"        # the file {out} names, in the run's scratch folder (.csv, .csv.gz, .parquet)
    timeout_s = 60               # a run still going after this many seconds is killed and recorded as failed
    workdir = "."                # the folder the command runs in (relative to the sweep file)
    [model.parameters]           # every parameter the command takes: its default and its allowed values
    noise = { default = 0.3, bounds = [0.0, 3.0] }
    n_agents = { default = 20, bounds = [2, 500], integer = true }
    rule = { default = "metric", choices = ["metric", "topological"] }
    [model.tracks]               # how to read the output: the columns, units ... of observables.tracks, and
    units = { length = "bl" }    # interval, velocity_interval, max_gap of the resampling

**The command** is a list of arguments (a string is split with :func:`shlex.split`); it never goes through a
shell. Its first argument, the program, is a file (a path with a ``/``, relative to ``workdir``) or a name
found on ``PATH``; either must exist when the sweep is read. Placeholders, each a whole ``{name}`` inside an
argument (``{{`` and ``}}`` are literal braces): ``{seed}`` the run's seed, ``{out}`` the output file's path,
``{scratch}`` the run's scratch folder, ``{params_json}`` / ``{params_toml}`` the path of a JSON / TOML file
of every parameter's value written there before the command starts, ``{<parameter>}`` one parameter's value,
and ``{params}``, which must be a whole argument, expanding to ``--name value`` for every parameter in the
order they are declared. ``{out}`` must appear somewhere (the program must learn where to write). An unknown
placeholder, a format spec or a missing program is a :class:`~simcore.schema.ConfigError` before any run.

**Parameters** are numbers (finite; within ``bounds`` when given; whole with ``integer = true``) or one of
their ``choices`` (strings, numbers or booleans); ``n`` and the other results columns are not parameter
names (:data:`sweeps.config.RESERVED_COLUMNS`). Every value a run gets (a default or a design point's) is
checked before it is substituted: :meth:`CommandModel.values`. Numbers are written as Python writes them
(``repr``: the shortest text that reads back as the same float), booleans as ``true``/``false``.

**Identity.** A run's id hashes :attr:`CommandModel.identity` (the template as given, the SHA-256 of the
program file and of every literal argument that names a file in ``workdir``, the output's name and how
it is read) with the run's parameter values, metric settings and seed; the absolute folders are left out,
so a moved repository keeps its run ids and a changed script or program file changes them.

**A run** (:func:`run_external`): a fresh scratch folder, the parameter files, the command with stdin
closed, in its own process group. Its stdout and stderr are pipes read as it writes them, each through a
:class:`Tail` that keeps only the last :data:`TAIL_BYTES` (a command that writes gigabytes costs no
memory and no disk). When the run ends, whatever the command's exit status, its whole process group is
killed (a background child the command left behind goes with it): at once when the command exits, after
``timeout_s`` (or the run's ``run.timeout_s``, whichever is shorter) when it does not, and when the run is
interrupted; on Linux the kernel kills the command too when its worker dies. The group is killed before
the command is reaped, so its id cannot have been reused. A timeout, a non-zero exit status (with the
last lines of stderr, or of stdout when stderr is empty), a missing output or an
output that is not long-format tracks of one flock (:class:`CommandFailed`, :class:`MalformedOutput`) is
the run's failure: the worker records it as failed with that reason (the scratch folder's path written
``{scratch}``, so a reason does not depend on where it ran) and the sweep goes on. The scratch folder is
removed afterwards.
"""
from __future__ import annotations

import dataclasses
import errno
import hashlib
import json
import math
import os
import re
import selectors
import shlex
import shutil
import signal
import string
import subprocess
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from flocksweep.observables.measured import measure_tracks, track_settings
from flocksweep.observables.resample import RECORDED
from flocksweep.observables.summary import MOTION_SETTINGS, MetricSettings, summary_columns
from flocksweep.observables.tracks import TrackSource, load_tracks
from flocksweep.simcore.schema import ConfigError, suggest

from .sandbox import dies_with_parent

PLACEHOLDERS = ("seed", "out", "scratch", "params", "params_json", "params_toml")
NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")
OUTPUT_SUFFIXES = (".csv", ".csv.gz", ".parquet")
STDERR_LINES = 12          # the last lines of stderr kept in a failed run's reason
STDERR_CHARS = 2000
TAIL_BYTES = 64 * 1024     # of stdout and of stderr, the most kept in memory while a command runs
READ_BYTES = 64 * 1024     # one read from a pipe
POLL_S = 0.1               # where the kernel gives no pidfd: how often to look whether the command exited


class CommandFailed(RuntimeError):
    """The command timed out, exited with a non-zero status or wrote no output."""


class MalformedOutput(RuntimeError):
    """The command's output is not long-format tracks of one flock that can be measured."""


# ----------------------------------------------------------------------------------------- the tables

@dataclass(frozen=True)
class Parameter:
    """One ``[model.parameters]`` entry: a number (``bounds``, ``integer``) or one of ``choices``."""

    default: Any = field(metadata={"expected": "the value a run gets when the design does not set it"})
    bounds: tuple[float, ...] | None = None
    integer: bool = False
    choices: tuple[Any, ...] | None = None
    description: str = ""

    def __post_init__(self):
        if self.choices is not None:
            if self.bounds is not None or self.integer:
                raise ConfigError("choices", "give either choices or bounds / integer, not both")
            if not self.choices or not all(_plain(c) for c in self.choices):
                raise ConfigError("choices", f"got {list(self.choices)!r}; expected a non-empty list of strings, "
                                             "numbers or booleans")
        if self.bounds is not None:
            low_high = len(self.bounds) == 2 and all(_number(v) and math.isfinite(v) for v in self.bounds)
            if not low_high or not self.bounds[0] < self.bounds[1]:
                raise ConfigError("bounds", f"got {list(self.bounds)!r}; expected [low, high], finite numbers, "
                                            "low < high")
        self.check(self.default, "default")

    def check(self, value, key: str):
        """``value`` if this parameter allows it (an integer parameter's whole float becomes an int), else a
        ConfigError at ``key`` saying what is allowed."""
        if self.choices is not None:
            for choice in self.choices:   # the declared choice: 2.0 given for a choice 2 is 2, never True
                if (type(choice) is type(value) or (_number(choice) and _number(value))) and choice == value:
                    return choice
            raise ConfigError(key, f"got {value!r}; allowed: {', '.join(map(repr, self.choices))}")
        if not _number(value) or not math.isfinite(value):
            raise ConfigError(key, f"got {value!r}; expected a finite number")
        if self.integer:
            if float(value) != round(value):
                raise ConfigError(key, f"got {value!r}; expected a whole number (integer = true)")
            value = int(value)
        if self.bounds is not None and not self.bounds[0] <= value <= self.bounds[1]:
            raise ConfigError(key, f"got {value!r}; allowed: {self.bounds[0]:g} to {self.bounds[1]:g} (bounds)")
        return value


def _number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _plain(value) -> bool:
    return isinstance(value, (str, bool)) or (_number(value) and math.isfinite(value))


@dataclass(frozen=True)
class OutputTracks(TrackSource):
    """``[model.tracks]``: how the output is read (:class:`~observables.tracks.TrackSource`: columns, units,
    body length, the speed check; a long format only) and resampled (``interval``: None, the output's own
    sampling interval; ``velocity_interval``: None, the recorded velocities when the output has them, else
    positions differenced over one interval; ``max_gap``: None, 2.5 intervals)."""

    interval: float | None = None
    velocity_interval: Any = None
    max_gap: float | None = None

    def __post_init__(self):
        super().__post_init__()
        if self.format not in ("auto", "csv", "parquet"):
            raise ConfigError("format", f"got {self.format!r}; a command's output is long-format tracks: "
                                        '"auto", "csv" or "parquet"')
        for key in ("interval", "max_gap"):
            value = getattr(self, key)
            if value is not None and not (math.isfinite(value) and value > 0):
                raise ConfigError(key, f"got {value!r}; expected seconds > 0")
        velocity = self.velocity_interval
        if velocity is not None and velocity != RECORDED and not (_number(velocity) and math.isfinite(velocity)
                                                                  and velocity > 0):
            raise ConfigError("velocity_interval", f'got {velocity!r}; expected seconds > 0 or "recorded"')


@dataclass(frozen=True)
class CommandTable:
    """A sweep's ``[model]`` table naming a command (see the module docstring)."""

    command: Any = field(metadata={"expected": 'a list of arguments, e.g. ["mysim", "--seed", "{seed}", '
                                               '"--out", "{out}", "{params}"]'})
    parameters: dict[str, Parameter] = field(default_factory=dict)
    output: str = "tracks.csv"
    timeout_s: float = 600.0
    workdir: str = "."
    tracks: OutputTracks = field(default_factory=OutputTracks)

    def __post_init__(self):
        if not (math.isfinite(self.timeout_s) and self.timeout_s > 0):
            raise ConfigError("timeout_s", f"got {self.timeout_s!r}; expected seconds > 0")
        if Path(self.output).name != self.output or not self.output.endswith(OUTPUT_SUFFIXES):
            raise ConfigError("output", f"got {self.output!r}; expected a file name (no folder) ending in "
                                        f"{', '.join(OUTPUT_SUFFIXES)}")
        for name in self.parameters:
            if not NAME.match(name) or name in PLACEHOLDERS:
                raise ConfigError(f"parameters.{name}", "a parameter name is letters, digits and _ (not first "
                                                        f"a digit) and none of {', '.join(PLACEHOLDERS)}")


# ------------------------------------------------------------------------------------------ the model

@dataclass(frozen=True)
class CommandModel:
    """A validated command model: what runs, where, and how its output is read (module docstring)."""

    template: tuple[str, ...]
    program: Path                               # the executable, resolved
    workdir: Path
    files: tuple[tuple[int, str], ...]          # (argument index, SHA-256) of every argument naming a file
    parameters: tuple[tuple[str, Parameter], ...]
    output: str
    timeout_s: float
    tracks: OutputTracks

    @property
    def names(self) -> list[str]:
        return [name for name, _ in self.parameters]

    def parameter(self, name: str) -> Parameter:
        return dict(self.parameters)[name]

    @property
    def identity(self) -> dict:
        """What a run's id hashes of the command (see the module docstring)."""
        return {"command": list(self.template), "files": {str(i): digest for i, digest in self.files},
                "output": self.output, "tracks": _tracks_record(self.tracks)}

    def record(self, workdir: str | None = None) -> dict:
        """The model as stored in ``model.json`` (``workdir``: as the results folder should name it)."""
        return {**self.identity, "program": str(self.program),
                "workdir": str(self.workdir) if workdir is None else workdir, "timeout_s": self.timeout_s,
                "parameters": {name: _record(p) for name, p in self.parameters}}

    def values(self, given: dict, where: str = "") -> dict:
        """Every parameter's value, declaration order: the defaults with ``given`` applied, each checked
        (a ConfigError naming the key and ``where``)."""
        out = {}
        for name, spec in self.parameters:
            value = given.get(name, spec.default)
            try:
                out[name] = spec.check(value, name)
            except ConfigError as err:
                raise ConfigError(err.key, err.detail + (f" (at design point {where})" if where else "")) from None
        unknown = [k for k in given if k not in out]
        if unknown:
            raise ConfigError(unknown[0], f"not a parameter of the command{suggest(unknown[0], self.names)}; "
                                          f"declared in [model.parameters]: {', '.join(self.names) or 'none'}")
        return out

    def arguments(self, values: dict, seed: int, out: Path, scratch: Path) -> list[str]:
        """The argument list of one run: the template with its placeholders substituted."""
        fields = {"seed": str(int(seed)), "out": str(out), "scratch": str(scratch),
                  "params_json": str(scratch / "params.json"), "params_toml": str(scratch / "params.toml"),
                  **{name: value_text(value) for name, value in values.items()}}
        argv = []
        for arg in self.template:
            if arg == "{params}":
                for name, value in values.items():
                    argv += [f"--{name}", value_text(value)]
            else:
                argv.append(arg.format_map(fields))
        argv[0] = str(self.program)
        return argv

    @property
    def label(self) -> str:
        """The name of the first file the command names after the program (the script an interpreter runs),
        else the program's."""
        return Path(self.template[self.files[min(1, len(self.files) - 1)][0]]).name

    def uses(self, placeholder: str) -> bool:
        return any(placeholder in _fields(arg) for arg in self.template)


def value_text(value) -> str:
    """A parameter value as one argument: ``repr`` of a float, ``true``/``false``, strings as they are."""
    if isinstance(value, bool):
        return "true" if value else "false"
    return value if isinstance(value, str) else repr(value)


def _record(table) -> dict:
    return {f.name: (list(v) if isinstance(v := getattr(table, f.name), tuple) else v)
            for f in dataclasses.fields(table)}


# reading settings added to TrackSource after run ids were first stored: in a run's identity only when
# set (so earlier run ids stay as they were); ``origins`` says where settings came from and never is
LATER_TRACK_SETTINGS = {"keep_padding": False, "trim": None, "burst_share": 0.5, "burst_frames": 5.0,
                        "burst_jump": 3.0, "arena": None}


def _tracks_record(tracks) -> dict:
    out = _record(tracks)
    out.pop("origins", None)
    return {k: v for k, v in out.items() if not (k in LATER_TRACK_SETTINGS and v == LATER_TRACK_SETTINGS[k])}


def _fields(arg: str) -> list[str]:
    """The placeholders of one argument; ConfigError on a malformed one or a format spec."""
    try:
        parsed = list(string.Formatter().parse(arg))
    except ValueError as err:
        raise ConfigError("model.command", f"argument {arg!r}: {err} (write {{{{ and }}}} for literal braces)") from None
    names = []
    for _, name, spec, conversion in parsed:
        if name is None:
            continue
        if spec or conversion or not name:
            raise ConfigError("model.command", f"argument {arg!r}: placeholders are plain {{name}}, without "
                                               "conversions or format specs")
        names.append(name)
    return names


def _argument_list(command) -> tuple[str, ...]:
    if isinstance(command, str):
        try:
            command = shlex.split(command)
        except ValueError as err:
            raise ConfigError("model.command", f"got {command!r}: {err}") from None
    if not isinstance(command, list) or not command or not all(isinstance(a, str) and a for a in command):
        raise ConfigError("model.command", f"got {command!r}; expected a non-empty list of non-empty strings")
    if any("\0" in a for a in command):
        raise ConfigError("model.command", "an argument cannot contain a NUL character")
    return tuple(command)


def _program(name: str, workdir: Path) -> Path:
    """The executable the first argument names: a file (relative to ``workdir``) or a name on PATH."""
    if _fields(name):
        raise ConfigError("model.command[0]", f"got {name!r}; the program is named as it is, without placeholders")
    if "/" in name or os.sep in name:   # not resolved: a venv's python is a link that must be run as itself
        path = Path(os.path.abspath(workdir / name))
        if not path.is_file():
            raise ConfigError("model.command[0]", f"program not found: {name!r} (looked at {path})")
        if not os.access(path, os.X_OK):
            raise ConfigError("model.command[0]", f"{path} is not executable (chmod +x it, or run it through its "
                                                  "interpreter, e.g. [\"python\", \"script.py\", ...])")
        return path
    found = shutil.which(name)
    if found is None:
        raise ConfigError("model.command[0]", f"program not found: {name!r} is not a file name on PATH (give a "
                                              "path with a / for a file, relative to the sweep file's folder)")
    return Path(os.path.abspath(found))


def file_digest(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def command_model(table: CommandTable, base: Path) -> CommandModel:
    """Validate a :class:`CommandTable` (relative paths from ``base``, the sweep file's folder)."""
    template = _argument_list(table.command)
    workdir = (Path(base) / table.workdir).resolve()
    if not workdir.is_dir():
        raise ConfigError("model.workdir", f"not a folder: {workdir}")
    names = list(table.parameters)
    known = list(PLACEHOLDERS) + names
    for i, arg in enumerate(template):
        for name in _fields(arg):
            if name not in known:
                raise ConfigError(f"model.command[{i}]", f"unknown placeholder {{{name}}}{suggest(name, known)}; "
                                                         f"known: {', '.join('{' + k + '}' for k in known)}")
            if name == "params" and arg != "{params}":
                raise ConfigError(f"model.command[{i}]", f"got {arg!r}; {{params}} expands to several arguments "
                                                         "(--name value ...) and must be a whole argument")
    if not any("out" in _fields(arg) for arg in template):
        raise ConfigError("model.command", "never names {out}: the program must be told where to write its tracks "
                                           '(e.g. "--out", "{out}")')
    program = _program(template[0], workdir)
    files = [(0, file_digest(program))]
    for i, arg in enumerate(template[1:], start=1):
        if not _fields(arg) and "{" not in arg and (workdir / arg).is_file():
            files.append((i, file_digest(workdir / arg)))
    return CommandModel(template=template, program=program, workdir=workdir, files=tuple(files),
                        parameters=tuple(table.parameters.items()), output=table.output,
                        timeout_s=float(table.timeout_s), tracks=table.tracks)


def command_metrics(run_table, where: str = "run") -> MetricSettings:
    """The metric settings of a command model's runs from a sweep's ``[run]`` table: a group radius (a number:
    there is no model perception range), no leadership metrics, no preset keys, nothing stored beside the row."""
    for short in ("n", "duration", "dt", "record_interval"):
        if getattr(run_table, short) is not None:
            raise ConfigError(f"{where}.{short}", "sets a key of a model preset; a command model has none: declare "
                                                  "the simulator's own settings in [model.parameters]")
    if run_table.group_radius == "auto":
        raise ConfigError(f"{where}.group_radius", 'got "auto"; a command model has no perception range to default '
                                                   "to: give the linking radius in the output's length units")
    if run_table.leadership_metrics is True:
        raise ConfigError(f"{where}.leadership_metrics", "needs the simulator's leader records; a command's tracks "
                                                         "have none")
    if run_table.keep != "metrics":
        raise ConfigError(f"{where}.keep", f"got {run_table.keep!r}; a command model's runs keep their metrics only "
                                           "(the output is measured, then its scratch folder removed)")
    settings = track_settings(run_table.group_radius, run_table.warmup, run_table.fragmentation_cohesion,
                              run_table.dcd_max_delay)
    return dataclasses.replace(settings, dcd=run_table.dcd_metrics,
                               **{key: getattr(run_table, key) for key in MOTION_SETTINGS})


# ------------------------------------------------------------------------------------------ one run

@dataclass(frozen=True)
class ExternalRun:
    """What a :class:`~sweeps.design.RunSpec` of a command model carries: the model and the run's values."""

    model: CommandModel
    values: tuple[tuple[str, Any], ...]


class Tail:
    """The last ``limit`` bytes written to a stream, however much is written: memory stays below twice
    ``limit`` plus one read. ``total`` counts every byte seen."""

    def __init__(self, limit: int = TAIL_BYTES):
        self.limit = limit
        self.data = bytearray()
        self.total = 0

    def add(self, data: bytes) -> None:
        self.total += len(data)
        self.data += data
        if len(self.data) > 2 * self.limit:
            del self.data[:-self.limit]

    def lines(self) -> str:
        """Its last :data:`STDERR_LINES` non-empty lines, at most :data:`STDERR_CHARS` characters."""
        kept = bytes(self.data[-self.limit:])
        if self.total > len(kept) and b"\n" in kept:   # cut: its first line is a piece of one
            kept = kept[kept.index(b"\n") + 1:]
        text = kept.decode(errors="replace")
        lines = [line for line in text.strip().splitlines() if line.strip()][-STDERR_LINES:]
        return "\n".join(lines)[-STDERR_CHARS:]

    def said(self, name: str) -> str:
        """'; NAME ends:\n...' (with how much was written when that was more than was kept), or ''."""
        tail = self.lines()
        if not tail:
            return ""
        size = f" (of {self.total:,} bytes)" if self.total > self.limit else ""
        return f"; {name} ends{size}:\n{tail}"


def _write_params(model: CommandModel, values: dict, scratch: Path) -> None:
    if model.uses("params_json"):
        (scratch / "params.json").write_text(json.dumps(values, indent=1) + "\n")
    if model.uses("params_toml"):
        import tomli_w
        (scratch / "params.toml").write_text(tomli_w.dumps(values))


def _end_group(process: subprocess.Popen) -> None:
    """Kill the command's whole process group (it and everything it started, also after it exited), then
    reap the command. Its process is not reaped before the group is killed, so the group's id is still
    its own."""
    try:
        os.killpg(process.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
    process.wait()


def _exited(pid: int) -> bool:
    """Whether the child ``pid`` has exited, without reaping it (its group id stays reserved)."""
    try:
        return os.waitid(os.P_PID, pid, os.WEXITED | os.WNOHANG | os.WNOWAIT) is not None
    except ChildProcessError:
        return True


def _pidfd(pid: int):
    """A file descriptor that becomes readable when ``pid`` exits (Linux 5.3 and later), or None."""
    try:
        return os.pidfd_open(pid)
    except (AttributeError, OSError):
        return None


def _read(selector, key, tail: Tail) -> None:
    try:
        data = os.read(key.fd, READ_BYTES)
    except BlockingIOError:
        return
    if data:
        tail.add(data)
    else:
        selector.unregister(key.fileobj)


def _follow(process: subprocess.Popen, outputs: dict, timeout_s: float) -> bool:
    """Read the command's pipes (``outputs``: pipe -> :class:`Tail`) until it exits (True) or ``timeout_s``
    passes (False). The command is not reaped."""
    deadline = time.monotonic() + timeout_s
    pidfd = _pidfd(process.pid)
    with selectors.DefaultSelector() as selector:
        for pipe, tail in outputs.items():
            os.set_blocking(pipe.fileno(), False)
            selector.register(pipe, selectors.EVENT_READ, tail)
        if pidfd is not None:
            selector.register(pidfd, selectors.EVENT_READ, None)
        try:
            while not _exited(process.pid):
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return False
                for key, _ in selector.select(remaining if pidfd is not None else min(remaining, POLL_S)):
                    if key.data is not None:
                        _read(selector, key, key.data)
            return True
        finally:
            if pidfd is not None:
                os.close(pidfd)


def _drain(outputs: dict) -> None:
    """What the (now killed) command group wrote before it died, without waiting for an end of file that
    a process outside the group holding the pipe would keep back."""
    for pipe, tail in outputs.items():
        while True:
            try:
                data = os.read(pipe.fileno(), READ_BYTES)
            except (BlockingIOError, OSError) as err:
                if isinstance(err, BlockingIOError) or err.errno == errno.EAGAIN:
                    break
                raise
            if not data:
                break
            tail.add(data)


def run_command(model: CommandModel, values: dict, seed: int, scratch: Path, timeout_s: float | None = None) -> Path:
    """Run the command for one run in ``scratch``; the output's path, or :class:`CommandFailed`. The limit
    is ``model.timeout_s``, or ``timeout_s`` (the run's ``run.timeout_s``) when that is shorter."""
    out = scratch / model.output
    _write_params(model, values, scratch)
    argv = model.arguments(values, seed, out, scratch)
    limit, which = model.timeout_s, "model.timeout_s"
    if timeout_s is not None and timeout_s < limit:
        limit, which = timeout_s, "run.timeout_s"
    process = subprocess.Popen(argv, cwd=model.workdir, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, start_new_session=True, preexec_fn=dies_with_parent())
    stdout, stderr = Tail(), Tail()
    outputs = {process.stdout: stdout, process.stderr: stderr}
    try:
        finished = _follow(process, outputs, limit)
    finally:   # finished, timed out or interrupted: the command's whole group goes with the run
        _end_group(process)
        _drain(outputs)
        process.stdout.close()
        process.stderr.close()
    if not finished:
        raise CommandFailed(f"timed out after {limit:g} s ({which}); killed" + stderr.said("stderr"))
    status = process.returncode
    if status != 0:
        how = f"killed by signal {-status}" if status < 0 else f"exit status {status}"
        said = stderr.said("stderr") or "; nothing on stderr" + stdout.said("stdout")
        raise CommandFailed(f"{model.label} failed: {how}{said}")
    if not out.is_file():
        raise CommandFailed(f"{model.label} exited 0 but wrote no output: {model.output} ({{out}}) is missing")
    return out


def measure_output(path: Path, model: CommandModel, settings: MetricSettings) -> tuple[np.ndarray, dict, dict]:
    """(record times, per-record series, summary row) of a command's output, through the measured-tracks
    path; :class:`MalformedOutput` with the reason when it cannot be read or measured as one flock."""
    try:
        table = load_tracks(path, model.tracks)
        velocity = model.tracks.velocity_interval
        if velocity is None:
            velocity = RECORDED if table.has_velocity else None
        measured = measure_tracks(table, settings, model.tracks.interval, model.tracks.max_gap, velocity)
    except Exception as err:  # noqa: BLE001 - whatever the reader makes of a bad file is the output's fault
        raise MalformedOutput(f"the output {model.output} is not tracks that can be measured: "
                              f"{type(err).__name__}: {err}") from None
    flocks = list(measured.runs["flock"])
    if len(flocks) != 1:
        raise MalformedOutput(f"the output {model.output} holds {len(flocks)} flocks ({', '.join(flocks[:5])}); a "
                              "run writes one")
    row = measured.runs.iloc[0]
    columns = summary_columns(leadership=False, dcd=settings.dcd)
    summary = {column: row[column] for column in columns}
    series = measured.timeseries.drop(columns=["run_id"])
    times = series.pop("t").to_numpy()
    return times, {name: series[name].to_numpy() for name in series.columns}, summary


def run_external(run: ExternalRun, seed: int, settings: MetricSettings, label: str = "",
                 timeout_s: float | None = None) -> tuple:
    """One run of a command model: (record times, series, summary row, seconds the command took); raises
    :class:`CommandFailed` or :class:`MalformedOutput` with the reason. ``timeout_s``: the run's
    ``run.timeout_s`` (the command's limit when shorter than ``model.timeout_s``)."""
    with tempfile.TemporaryDirectory(prefix=f"flocksweep-{label[:12]}-" if label else "flocksweep-") as folder:
        scratch = Path(folder)
        start = time.perf_counter()
        try:
            out = run_command(run.model, dict(run.values), seed, scratch, timeout_s)
            seconds = time.perf_counter() - start
            times, series, summary = measure_output(out, run.model, settings)
        except (CommandFailed, MalformedOutput) as err:   # the same reason wherever the scratch folder was
            raise type(err)(str(err).replace(str(scratch), "{scratch}")) from None
    return times, series, summary, seconds
