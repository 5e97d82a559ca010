"""The Python entry point of a sweep: run a :class:`~sweeps.config.SweepConfig` into a results folder.

``run_sweep(sweep, out, executor="local", workers=None, ...) -> SweepResult`` is what ``flocksweep run``
does, from Python: a sweep read from a file (``Sweep.from_toml``) stores that file's text as
``sweep.toml``, a sweep built from a dict (``Sweep.from_dict``) its faithful TOML
(:meth:`~sweeps.config.SweepConfig.to_toml`), so every results folder can be run again from its
``sweep.toml``. The work is :func:`sweeps.runner.run_sweep` (resume, failures, atomic parts, lock).
"""
from __future__ import annotations

from pathlib import Path

from .config import SweepConfig
from .runner import SweepResult, run_sweep as _run


def run_sweep(sweep: SweepConfig, out: str | Path, executor: str = "local", workers: int | None = None, *,
              scheduler: str | None = None, force: bool = False, retry_failed: bool = False,
              dry_run: bool = False, progress: bool = True, batch_size: int | None = None,
              yes: bool = False) -> SweepResult:
    """Run (or resume) a sweep and store its results in ``out``.

    Parameters
    ----------
    sweep : SweepConfig
        The sweep, from :meth:`Sweep.from_toml <sweeps.config.SweepConfig.from_toml>` or
        :meth:`Sweep.from_dict <sweeps.config.SweepConfig.from_dict>`.
    out : str or pathlib.Path
        The results folder. Runs already stored there are skipped (resume).
    executor : {"local", "serial", "dask"}, default "local"
        A local process pool, this process, or a Dask cluster (:class:`sweeps.executors.Executor`).
        The results do not depend on it.
    workers : int, optional
        Worker processes (default: every core).
    scheduler : str, optional
        Dask scheduler address (``tcp://HOST:PORT``); without it a local Dask cluster starts.
    force : bool, default False
        Compute every run again, finished or not.
    retry_failed : bool, default False
        Compute the runs stored as failed again.
    dry_run : bool, default False
        Count the runs and estimate their cost; run nothing, write nothing.
    progress : bool, default True
        Show a progress bar with the time left.
    batch_size : int, optional
        Runs per task (default: automatic).
    yes : bool, default False
        Allow a design of more than 100,000 runs.

    Returns
    -------
    SweepResult
        ``table`` (the runs table, one row per run), ``plan`` (done, failed and computed runs),
        ``wall_s``, ``lost`` (runs whose worker process died, left missing) and ``estimate`` (dry run).

    Raises
    ------
    simcore.ConfigError
        A bad design, naming the key, before anything is written.
    sweeps.store.StoreLocked
        Another runner is working in ``out``.
    """
    return _run(sweep, None, out, executor, workers, scheduler, force, retry_failed, dry_run, progress,
                batch_size, yes=yes)
