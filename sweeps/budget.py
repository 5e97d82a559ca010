"""What a design costs before anything is built or run: how many runs, and the memory of one.

Checked on the configuration alone (no run is built, nothing is simulated), so a design of 10^9 runs
or a flock of 10^12 boids is refused in milliseconds, before any file is written.

* ``count_runs(config) -> int``: the runs of a sweep (the product of its axes' levels and the sampled
  block's ``n``, times ``replicates``).
* ``run_bytes(n, n_steps, record_every) -> int``: an estimate (from above) of the peak memory of one run
  of ``n`` boids: its recorded observations (positions and velocities in float64, the two neighbour
  counts in int32 and the leader flags, per record and boid), the per-record metric work arrays, the
  compiled step's per-boid state and work space, and the metrics' ``n x n`` neighbour table (int32).
* ``worst_run(config) -> Worst``: the largest ``init.n`` and ``run.duration`` and the smallest
  ``run.dt`` and record interval any run of the design can have (from the base preset and every value an
  axis or the sampled block gives those keys), with the key that sets each; with ``keep =
  "trajectories"`` the record step is the one the worker simulates with (gcd with ``trajectory_every``).
* ``check_sweep(config, workers, yes=False, available=None)``: :class:`BudgetError` (a ConfigError
  naming the key) when one run needs more memory than the machine has available, when ``workers`` runs
  at once do (saying how many fit), when the design has more than :data:`MAX_RUNS` runs and ``yes`` is
  not given, or when even building its list of runs would not fit in memory (for a command model,
  :mod:`sweeps.external`, only the last two: what its runs need is the command's business).
* ``check_runs(key, n, n_steps, record_every, copies=1, available=None)``: the same memory check for
  ``copies`` runs at once of a single configuration (``flocksweep simulate``, a calibration's batch of
  ``n_sim`` replicates).
* ``available_memory() -> int | None``: ``MemAvailable`` of /proc/meminfo, else the physical memory.
* ``human(bytes) -> str``: 21 TiB, 512 MiB, ...
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

from flocksweep.simcore.schema import ConfigError, get_dotted

MAX_RUNS = 100_000            # a larger design needs --yes
SPEC_BYTES = 4096             # memory per run while the design is built (spec + design row), from above
RECORD_BYTES = 128            # per record and boid: observations (57) + metric work arrays (44) + copies
BOID_BYTES = 512              # per boid: state (~180) + the compiled step's work space (~200) + slack
PAIR_BYTES = 4                # the metrics' n x n int32 neighbour table
KEYS = {"n": "init.n", "duration": "run.duration", "dt": "run.dt", "record_interval": "run.record_interval"}


class BudgetError(ConfigError):
    """The design or a run is too large for this machine (or needs --yes)."""


def human(count: float) -> str:
    """Bytes as '21 TiB', '512 MiB', ..."""
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"):
        if abs(count) < 1024 or unit == "EiB":
            return f"{count:.0f} {unit}" if unit == "B" else f"{count:.3g} {unit}"
        count /= 1024
    return f"{count:.3g} EiB"


def available_memory() -> int | None:
    """Memory available to new processes, in bytes (None when it cannot be told)."""
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return None


def run_bytes(n: float, n_steps: float, record_every: float) -> float:
    """Estimated peak memory of one run (see the module docstring); floats, so 10^12 boids do not overflow."""
    records = math.floor(n_steps / max(record_every, 1)) + 1
    return n * (records * RECORD_BYTES + BOID_BYTES) + PAIR_BYTES * float(n) ** 2


def count_runs(config) -> int:
    """Runs of the sweep ``config`` (a SweepConfig), without building them."""
    points = math.prod(len(axis.points) for axis in config.axes)
    if config.sample:
        points *= config.sample.n
    return points * config.replicates


@dataclass(frozen=True)
class Worst:
    """The extreme values a design's runs can have, and the key (and where) each comes from."""

    n: float
    duration: float
    dt: float
    record_interval: float
    origin: dict   # short name -> "init.n (axes[0])" or "init.n (the base model)"
    trajectory_every: int | None = None   # with keep = "trajectories": frames are recorded this often too

    @property
    def n_steps(self) -> float:
        return self.duration / self.dt

    @property
    def record_every(self) -> float:
        every = max(1.0, self.record_interval / self.dt)
        if self.trajectory_every:
            every = float(math.gcd(max(1, round(every)), self.trajectory_every))
        return every


def _numbers(values) -> list[float]:
    """The finite positive numbers among ``values`` (other values are the validation's to refuse)."""
    return [float(v) for v in values
            if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and v > 0]


def worst_run(config) -> Worst:
    """The largest n and duration, the smallest dt and record interval of any run of ``config``."""
    base = config.preset_data
    defaults = {"n": 100, "duration": 30.0, "dt": 1.0 / 60.0, "record_interval": 1.0}
    values = {short: _numbers([get_dotted(base, key)]) or [defaults[short]] for short, key in KEYS.items()}
    origin = {short: f"{key} (the base model)" for short, key in KEYS.items()}
    swept = []
    for i, axis in enumerate(config.axes):
        for j, key in enumerate(axis.keys):
            swept.append((f"axes[{i}]", key, [point[j] for point in axis.points]))
    if config.sample:
        swept += [(f"sample.bounds.{key}", key, [low, high]) for key, low, high in config.sample.bounds]
    pick = {"n": max, "duration": max, "dt": min, "record_interval": min}
    for where, key, level_values in swept:
        for short, preset_key in KEYS.items():
            if key == preset_key:
                numbers = _numbers(level_values)
                if numbers and pick[short](numbers + values[short]) != pick[short](values[short]):
                    origin[short] = f"{preset_key} ({where})"
                values[short] = values[short] + numbers
    chosen = {short: pick[short](values[short]) for short in KEYS}
    return Worst(origin=origin, trajectory_every=config.storage.trajectory_every
                 if config.storage.keep == "trajectories" else None, **chosen)


def _memory_error(key: str, what: str, need: float, available: int) -> BudgetError:
    return BudgetError(key, f"{what} would need about {human(need)} of memory; this machine has "
                            f"{human(available)} available")


def check_runs(key: str, n: float, n_steps: float, record_every: float, copies: int = 1,
               available: int | None = None, what: str | None = None) -> float:
    """BudgetError at ``key`` when ``copies`` runs of ``n`` boids at once do not fit; returns one run's bytes."""
    available = available_memory() if available is None else available
    one = run_bytes(n, n_steps, record_every)
    if available is None:
        return one
    label = what or f"a run of {n:,.0f} boids over {n_steps:,.0f} steps"
    if one > available:
        raise _memory_error(key, label, one, available)
    if one * copies > available:
        raise _memory_error(key, f"{copies:,} such runs at once ({label})", one * copies, available)
    return one


def check_sweep(config, workers: int, yes: bool = False, available: int | None = None) -> int:
    """Refuse a design too large to build or a run too large to fit (see the module docstring); returns
    the number of runs."""
    available = available_memory() if available is None else available
    runs = count_runs(config)
    if available is not None and runs * SPEC_BYTES > available / 2:
        raise BudgetError("axes", f"the design has {runs:,} runs; listing them alone would need about "
                                  f"{human(runs * SPEC_BYTES)} of memory ({human(available)} available): "
                                  "split it into several sweeps")
    if runs > MAX_RUNS and not yes:
        raise BudgetError("axes", f"the design has {runs:,} runs (more than {MAX_RUNS:,}); building and running "
                                  "them takes long and a large results folder: pass --yes to go ahead")
    if getattr(config, "command", None) is not None:
        return runs   # a command's memory is its own: only the design's size is checked
    worst = worst_run(config)
    key = worst.origin["n"]
    one = check_runs(key, worst.n, worst.n_steps, worst.record_every, 1, available,
                     what=f"a run of {worst.n:,.0f} boids ({key}) over {worst.n_steps:,.0f} steps")
    if available is not None and workers > 1 and one * workers > available:
        fit = max(1, int(available // one))
        raise BudgetError("--workers", f"{workers} runs at once of {worst.n:,.0f} boids ({key}) would need about "
                                       f"{human(one * workers)} of memory ({human(available)} available); "
                                       f"use --workers {fit} or fewer")
    return runs
