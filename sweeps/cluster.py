"""A batch-scheduled cluster (SLURM, PBS, SGE, LSF) as the sweep's executor: Dask workers started as batch
jobs by dask-jobqueue, the sweep's tasks sent to them, the results written by this process.

A sweep file declares its cluster in a ``[cluster]`` table (any key may also be set or changed on the
command line, ``--set cluster.jobs=8``); ``flocksweep run SWEEP --executor cluster`` then submits the
jobs, runs the sweep on their workers and cancels the jobs when it ends (finished, failed or
interrupted)::

    [cluster]
    kind = "slurm"            # slurm | pbs | sge | lsf
    queue = "short"           # the partition / queue (default: the scheduler's own)
    account = "proj42"        # the project charged (optional)
    jobs = 4                  # batch jobs to submit
    cores = 8                 # cores of one job
    processes = 8             # worker processes in one job (default: cores; each runs one task at a time)
    memory = "16GB"           # memory of one job
    walltime = "02:00:00"     # the wall time a job asks for
    directives = ["--constraint=cpu"]                # more scheduler lines (#SBATCH ..., #PBS ...)
    prologue = ["module load python/3.11", "source ~/flocksweep/.venv/bin/activate"]  # before the worker
    python = "/home/me/flocksweep/.venv/bin/python"  # the workers' interpreter (default: this one)
    interface = "ib0"         # the network interface workers reach this process on (default: dask's choice)
    log_directory = "cluster-logs"                   # the jobs' stdout/stderr (default: the scheduler's)

The cluster is execution only: it never enters a run's identity, so a sweep run on a cluster has the
same run ids and bit-identical results as on this machine, and a sweep interrupted on one resumes on
the other. The workers need flocksweep installed (the same version) and, when the sweep keeps
trajectories, the results folder on a shared file system; numba's cache of compiled kernels is best
filled once ahead (``flocksweep compile``) on that file system, so the jobs load rather than compile.

:class:`ClusterSettings` is the validated table; :func:`start_cluster` submits its jobs (dask-jobqueue is
the ``hpc`` extra: ``pip install 'flocksweep[hpc]'``); :func:`job_script` is the script one job runs, for
``--dry-run`` and the docs.
"""
from __future__ import annotations

import re
import sys
from dataclasses import dataclass, field

from flocksweep.simcore.schema import ConfigError, build, check_choice

KINDS = {"slurm": "SLURMCluster", "pbs": "PBSCluster", "sge": "SGECluster", "lsf": "LSFCluster"}
MEMORY = re.compile(r"^\s*\d+(\.\d+)?\s*(B|[KMGTP]i?B)\s*$", re.I)
WALLTIME = re.compile(r"^(\d+-)?\d{1,3}(:\d{2}){1,2}$")
DEATH_TIMEOUT = 120   # seconds a job's workers wait for this process before they exit on their own
INSTALL = "the cluster executor needs dask-jobqueue: pip install 'flocksweep[hpc]'"


@dataclass(frozen=True)
class ClusterSettings:
    """A sweep file's ``[cluster]`` table (see the module docstring)."""

    kind: str = field(metadata={"expected": f"the batch scheduler: one of {', '.join(KINDS)}"})
    jobs: int = 1
    cores: int = 1
    processes: int | None = None
    memory: str = "4GB"
    walltime: str = "01:00:00"
    queue: str | None = None
    account: str | None = None
    directives: tuple[str, ...] = ()
    prologue: tuple[str, ...] = ()
    python: str | None = None
    interface: str | None = None
    log_directory: str | None = None

    def __post_init__(self):
        check_choice("cluster.kind", self.kind, tuple(KINDS))
        for key in ("jobs", "cores"):
            value = getattr(self, key)
            if isinstance(value, bool) or value < 1:
                raise ConfigError(f"cluster.{key}", f"got {value!r}; expected an integer >= 1")
        if self.processes is not None and not (1 <= self.processes <= self.cores):
            raise ConfigError("cluster.processes", f"got {self.processes!r}; expected an integer from 1 to "
                                                   f"cluster.cores ({self.cores})")
        if not MEMORY.match(self.memory):
            raise ConfigError("cluster.memory", f"got {self.memory!r}; expected an amount with its unit, "
                                                "e.g. \"4GB\" or \"1500MB\"")
        if not WALLTIME.match(self.walltime):
            raise ConfigError("cluster.walltime", f"got {self.walltime!r}; expected HH:MM:SS (or D-HH:MM:SS), "
                                                  "e.g. \"02:00:00\"")
        for key in ("directives", "prologue"):
            lines = getattr(self, key)
            bad = [line for line in lines if "\n" in line or not line.strip()]
            if bad:
                raise ConfigError(f"cluster.{key}", f"got {bad[0]!r}; expected one non-empty line per item")

    @property
    def workers(self) -> int:
        """Worker processes in all: jobs x processes per job."""
        return self.jobs * self.per_job

    @property
    def per_job(self) -> int:
        return self.processes or self.cores

    def describe(self) -> str:
        return (f"{self.kind} cluster: {self.jobs} job(s) x {self.per_job} worker(s), {self.cores} core(s), "
                f"{self.memory}, {self.walltime} each" + (f", queue {self.queue}" if self.queue else ""))


def cluster_settings(table) -> ClusterSettings | None:
    """The validated ``[cluster]`` table of a sweep file (None when it has none)."""
    if table is None:
        return None
    if not isinstance(table, dict):
        raise ConfigError("cluster", f"expected a table, got {table!r}")
    return build(ClusterSettings, table, "cluster")


def _jobqueue_class(kind: str):
    return getattr(_import_jobqueue(), KINDS[kind])


def _import_jobqueue():
    """dask_jobqueue, imported without its side effect: importing it replaces the process's SIGINT handler
    (its runner module makes Ctrl-C a bare ``sys.exit()``), which would take Ctrl-C away from the command's
    own handling (docs/errors.md); the handler in place before is put back."""
    import signal
    import threading

    main = threading.current_thread() is threading.main_thread()
    before = signal.getsignal(signal.SIGINT) if main else None
    try:
        import dask_jobqueue
    except ImportError:
        raise ConfigError("--executor", INSTALL) from None
    finally:
        if main and before is not None and signal.getsignal(signal.SIGINT) is not before:
            signal.signal(signal.SIGINT, before)
    return dask_jobqueue


def _arguments(settings: ClusterSettings) -> dict:
    """dask-jobqueue's arguments for ``settings``: single-threaded worker processes, no dashboard."""
    arguments = {"cores": settings.cores, "processes": settings.per_job, "memory": settings.memory,
                 "walltime": settings.walltime, "queue": settings.queue, "account": settings.account,
                 "job_extra_directives": list(settings.directives), "job_script_prologue": list(settings.prologue),
                 "python": settings.python or sys.executable, "death_timeout": DEATH_TIMEOUT,
                 "log_directory": settings.log_directory, "name": "flocksweep-worker",
                 "scheduler_options": {"dashboard_address": None}}
    if settings.interface:
        arguments["interface"] = settings.interface
    return {key: value for key, value in arguments.items() if value is not None}


def start_cluster(settings: ClusterSettings):
    """A dask-jobqueue cluster for ``settings`` with its jobs submitted (``scale(jobs=...)``); closing it
    cancels them."""
    cluster = _jobqueue_class(settings.kind)(**_arguments(settings))
    try:
        cluster.scale(jobs=settings.jobs)
    except BaseException:
        cluster.close()
        raise
    return cluster


def job_script(settings: ClusterSettings) -> str:
    """The batch script one job runs (the scheduler's address as it would be now)."""
    cluster = _jobqueue_class(settings.kind)(**_arguments(settings))
    try:
        return cluster.job_script()
    finally:
        cluster.close()
