"""The Python entry point of a sweep: run a :class:`~sweeps.config.SweepConfig` into a results folder.

``run_sweep(sweep, out, executor="local", workers=None, ...) -> SweepResult`` is what ``flocksweep run``
does, from Python: a sweep read from a file (``Sweep.from_toml``) stores that file's text as
``sweep.toml``, a sweep built from a dict (``Sweep.from_dict``) its faithful TOML
(:meth:`~sweeps.config.SweepConfig.to_toml`), so every results folder can be run again from its
``sweep.toml``. The work is :func:`sweeps.runner.run_sweep` (resume, failures, atomic parts, lock).

Never silent: runs left missing because their worker processes died raise :class:`RunsLost` (its
``result`` holds what was saved; running the sweep again computes the missing runs), and a script that
runs a sweep on worker processes from its top level, outside ``if __name__ == "__main__":``, raises
:class:`~sweeps.main_guard.UnguardedScript` before anything is written (:mod:`sweeps.main_guard`).
"""
from __future__ import annotations

from pathlib import Path

from .config import SweepConfig
from .runner import SweepResult, run_sweep as _run


class RunsLost(RuntimeError):
    """Runs were left missing: their worker processes died on every attempt. ``result`` is the
    :class:`SweepResult` (what was saved); the message gives the count and the cause."""

    def __init__(self, result: SweepResult):
        self.result = result
        causes = "; ".join(result.lost_reasons) or "cause unknown"
        super().__init__(f"{len(result.lost)} of {len(result.plan.specs)} runs were left missing in "
                         f"{result.out_dir}: {causes}. Run the sweep again to compute them")


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
    executor : {"local", "serial", "dask", "cluster"}, default "local"
        A local process pool, this process, a Dask cluster, or batch jobs on a SLURM/PBS/SGE/LSF cluster
        as the sweep's ``[cluster]`` table declares them (:class:`sweeps.executors.Executor`,
        :mod:`sweeps.cluster`).
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
    RunsLost
        Runs were left missing because their worker processes died (``err.result`` is the result).
    sweeps.main_guard.UnguardedScript
        The calling script starts worker processes from its top level: guard it with
        ``if __name__ == "__main__":``.
    simcore.ConfigError
        A bad design, naming the key, before anything is written.
    sweeps.store.StoreLocked
        Another runner is working in ``out``.
    """
    result = _run(sweep, None, out, executor, workers, scheduler, force, retry_failed, dry_run, progress,
                  batch_size, yes=yes)
    if result.lost:
        raise RunsLost(result)
    return result
