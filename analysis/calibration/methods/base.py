"""The interface of a calibration method: :class:`CalibrationMethod`, and the :class:`Job` it runs.

A method is an object registered once (:func:`analysis.calibration.methods.register`) under its
``kind``, the name a calibration file's ``[method] kind`` and ``flocksweep calibrate --method`` give.
Everything a calibration does that depends on the method goes through it:

* ``settings``: its settings dataclass (a :class:`~analysis.calibration.settings.MethodSettings`, whose
  ``kind`` is the method's), read from ``[method]`` / ``[method.<kind>]`` by the schema engine;
* ``resolve(settings, where, base, dim, k) -> settings``: the checks of its settings that need the rest of
  the file (``dim`` free parameters, ``k`` statistics, paths resolved against ``base``, the file's folder);
  ``where(key)`` is the dotted key an error names;
* ``check(config)``: the checks that need the whole validated calibration (targets, observation block);
  both run when the file is read, before anything is written;
* ``check_cost(config, yes)``: refuse a calibration too large to run (unless ``yes``), before anything is
  written;
* ``phase_count(config)``: how many numbered progress phases ``run`` starts (the report is one more);
* ``continues(config, folder)``: whether the same command run again continues what ``folder`` holds;
* ``run(job) -> CalibrationRun``: the method itself, its outputs written into ``job.folder``, its
  simulations counted in ``job.cost`` (an :class:`~analysis.calibration.accounting.Accounting`; extra
  entries of the accounting block in ``job.cost_extra``), each phase announced on ``job.phases``;
* ``report_blocks(config, outcome, folder) -> list``: its section of the report (after the verdicts);
* ``resume_hint(command, out_dir) -> str``: one line on what an interrupted run saved and how to go on;
* ``report_file``: the file the run's report (its ``CalibrationRun.report``) is written to;
* ``uses_transforms``: whether it fits the transformed statistics (:mod:`analysis.calibration.transforms`;
  the report records them, or that the method does not use them);
* ``sbc``: True when simulation-based calibration (``flocksweep sbc``, :mod:`analysis.calibration.sbc`)
  checks this method's posterior (it re-runs the method on many synthetic datasets: emcee's BSL);
* ``what``, ``cost``, ``use_when``: its row of the methods table (docs/calibration.md), made from the
  registry (:func:`analysis.calibration.methods.methods_table`).

The driver (:func:`analysis.calibration.run.run_calibration`) does the rest for every method: the output
folder and its lock, the executor, the progress lines, the report, the accounting.
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import ClassVar

from ..settings import MethodSettings


@dataclass
class Job:
    """One calibration run as a method sees it (see the module docstring)."""

    config: object                # CalibrationConfig
    folder: object                # sweeps.store.OutputFolder
    pool: object                  # sweeps.executors.Executor, entered
    phases: object                # sweeps.progress.Phases
    cost: object                  # analysis.calibration.accounting.Accounting
    resume: bool = False
    predictive_draws: int = 100
    executor: tuple = ("serial", None, None)   # the executor asked for: kind, workers, scheduler
    started: float = 0.0
    cost_extra: dict = field(default_factory=dict)
    transforms_record: dict | None = None     # the statistics' transforms as reports record them (None: unused)

    @property
    def progress(self) -> bool:
        return bool(self.phases.enabled)

    @property
    def sweep_executor(self) -> tuple:
        """(kind, workers, scheduler) for work run as a sweep: a sweep's runs are single-threaded, so a
        calibration that runs ``serial`` runs them on the ``local`` pool."""
        kind, workers, scheduler = self.executor
        return ("local" if kind == "serial" else kind), workers, scheduler


class CalibrationMethod(ABC):
    """Base class of a calibration method (see the module docstring); a subclass must define ``run``."""

    kind: ClassVar[str] = ""
    settings: ClassVar[type] = MethodSettings
    report_file: ClassVar[str] = "convergence.json"
    sbc: ClassVar[bool] = False
    uses_transforms: ClassVar[bool] = True
    what: ClassVar[str] = ""
    cost: ClassVar[str] = ""
    use_when: ClassVar[str] = ""

    def resolve(self, settings, where, base, dim: int, k: int):
        return settings

    def check(self, config) -> None:
        return None

    def check_cost(self, config, yes: bool) -> None:
        return None

    def phase_count(self, config) -> int:
        return 1

    def continues(self, config, folder) -> bool:
        return False

    @abstractmethod
    def run(self, job: Job):
        """The method itself (module docstring): its outputs in ``job.folder``, a CalibrationRun."""

    def report_blocks(self, config, outcome, folder) -> list:
        from ..calibration_report import draws_blocks

        return draws_blocks(outcome, folder) if outcome.summary is not None else []

    def resume_hint(self, command: str, out_dir) -> str:
        return f"run the same command again: flocksweep calibrate {command} --out {out_dir}"

    def run_sbc(self, config, **options) -> dict:
        """Simulation-based calibration of this method (``flocksweep sbc``; a method with ``sbc = True``
        writes it): the result of :func:`analysis.calibration.sbc_report.write_report` plus ``wall_s``.
        ``options``: datasets, draws, out_dir, progress, bins, workers, order, resume, alpha, and the
        chain's steps / walkers (None when not given)."""
        from flocksweep.simcore.schema import ConfigError

        raise ConfigError("method.kind", f"got {self.kind!r}, which has no SBC check (flocksweep sbc)")
