"""A calibration's simulator for other tools: theta (or a parameter dict) -> the summary statistics the
calibration compares with its targets, observation noise included.

``summary_simulator(calibration, n_sim=1, threads=None) -> CalibrationSimulator`` is the simulator and
data model a calibration file defines, for another inference library (pyABC, sbi, ELFI, a hand-written
rejection ABC). It is exactly the calibration's own: its calls run
:func:`analysis.calibration.data_model.simulate_fn` (fresh seeds from a generator, as the emcee BSL chain and
SBC draw them) and :func:`~analysis.calibration.data_model.seeded_fn` (a deterministic function of given seeds,
as the optimiser's common random numbers), on :func:`analysis.calibration.simulator.summary_simulator`
(the fixed preset, the free keys, the target columns, the metric settings and the ``[observation]``
block). So the same theta and the same generator state give the same numbers, bit for bit, inside a
calibration and here, in this process or another.

The data model: each row is one simulated flock (``n_sim`` rows per call), summarised by the target
columns; with mean/sd targets (or a covariance) Gaussian observation noise N(0, cov) of the targets is
added to each row, drawn from the same generator after the seeds (docs/calibration.md). Targets from
``samples`` add no noise. A run whose state or summaries are not finite is a row of NaN.

Threads: the simulations of one call run their ``n_sim`` replicates in parallel on
numba's threads (:func:`simcore.simulate_batch`), all of the machine's cores by default. Inside another
library's worker processes that oversubscribes the cores (each worker spins as many threads). Pass
``threads=1`` (each call then sets ``numba.set_num_threads(1)`` and restores the previous count), or set
``NUMBA_NUM_THREADS=1`` in the environment before the workers start, or call
``numba.set_num_threads(1)`` in each worker. The count changes no result.

A :class:`CalibrationSimulator` pickles small (the calibration's validated config; the simulator is
rebuilt on first use in the receiving process), so it can be sent to spawned worker processes.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from flocksweep.sweeps.seeds import generator

from .config import CalibrationConfig, load_calibration
from .data_model import seeded_fn, simulate_fn
from .simulator import summary_simulator as _bare_simulator

__all__ = ["CalibrationSimulator", "summary_simulator"]


@contextmanager
def _numba_threads(threads: int | None):
    """Run the block with numba's thread count set to ``threads`` (None: unchanged)."""
    if threads is None:
        yield
        return
    import numba

    previous = numba.get_num_threads()
    numba.set_num_threads(max(1, min(int(threads), numba.config.NUMBA_NUM_THREADS)))
    try:
        yield
    finally:
        numba.set_num_threads(previous)


class CalibrationSimulator:
    """The simulator and observation model of one calibration (see the module docstring).

    Attributes
    ----------
    config : CalibrationConfig
        The calibration it simulates.
    n_sim : int
        Rows (simulated flocks) per call.
    threads : int or None
        numba threads per call (None: numba's current count).
    names : tuple of str
        The free parameters' names, in theta's order.
    keys : tuple of str
        Their dotted preset keys.
    columns : tuple of str
        The summary columns, in the rows' order.
    observed : numpy.ndarray
        The targets, shape (m, k): one row per observed dataset (m = 1 for mean/sd targets).
    """

    def __init__(self, config: CalibrationConfig, n_sim: int = 1, threads: int | None = None):
        if isinstance(n_sim, bool) or not isinstance(n_sim, (int, np.integer)) or n_sim < 1:
            raise ValueError(f"n_sim: got {n_sim!r}; must be an integer >= 1")
        if threads is not None and (isinstance(threads, bool) or not isinstance(threads, (int, np.integer))
                                    or threads < 1):
            raise ValueError(f"threads: got {threads!r}; must be an integer >= 1 or None")
        self.config = config
        self.n_sim = int(n_sim)
        self.threads = None if threads is None else int(threads)
        self.names = tuple(config.names)
        self.keys = tuple(config.keys)
        self.columns = tuple(config.targets.columns)
        self.observed = np.asarray(config.targets.observed, dtype=float)
        self._functions = None

    def __getstate__(self) -> dict:
        return {**self.__dict__, "_functions": None}   # the compiled simulator is rebuilt where it is used

    def _fns(self):
        if self._functions is None:
            bare = _bare_simulator(self.config, n_sim=self.n_sim)
            self._functions = (simulate_fn(self.config, bare), seeded_fn(self.config, bare))
        return self._functions

    def theta(self, parameters: Mapping[str, float]) -> np.ndarray:
        """theta, shape (p,), from a dict of parameter values by name (or by dotted key).

        Parameters
        ----------
        parameters : Mapping[str, float]
            One value per free parameter, e.g. ``{"field_deg": 120.0}`` (pyABC's ``Parameter``).

        Returns
        -------
        numpy.ndarray
            float64 (p,), in the order of :attr:`names`.
        """
        values = []
        for name, key in zip(self.names, self.keys):
            if name in parameters:
                values.append(float(parameters[name]))
            elif key in parameters:
                values.append(float(parameters[key]))
            else:
                raise KeyError(f"parameters: no value for {name!r} (key {key!r}); got {sorted(parameters)}")
        return np.array(values, dtype=np.float64)

    def __call__(self, theta, rng: np.random.Generator) -> np.ndarray:
        """Summaries at ``theta`` with fresh seeds drawn from ``rng`` (as the BSL chain and SBC call it).

        Parameters
        ----------
        theta : array_like
            Shape (p,), one value per free parameter (:attr:`names`).
        rng : numpy.random.Generator
            Source of the run seeds and the observation noise; advanced by the call.

        Returns
        -------
        numpy.ndarray
            float64 (n_sim, k): one row per simulated flock, columns :attr:`columns`.
        """
        with _numba_threads(self.threads):
            return self._fns()[0](np.asarray(theta, dtype=float), rng)

    def simulate(self, theta, seeds) -> np.ndarray:
        """Summaries at ``theta`` as a deterministic function of ``seeds`` (as the optimiser calls it).

        Parameters
        ----------
        theta : array_like
            Shape (p,).
        seeds : sequence
            ``n_sim`` run seeds (ints >= 0, tuples of them or ``numpy.random.SeedSequence``); the noise is
            drawn from ``sweeps.seeds.generator(*seeds)``.

        Returns
        -------
        numpy.ndarray
            float64 (n_sim, k).
        """
        with _numba_threads(self.threads):
            return self._fns()[1](np.asarray(theta, dtype=float), list(seeds))

    def summaries(self, parameters: Mapping[str, float], seed=None) -> dict[str, float]:
        """A model function for pyABC-style libraries: {column: value}, the mean of the ``n_sim`` rows.

        Parameters
        ----------
        parameters : Mapping[str, float]
            Free parameter values by name (or dotted key).
        seed : int or tuple of int, optional
            The call's randomness is ``sweeps.seeds.generator(seed)`` (``generator(*seed)`` for a tuple),
            so a given seed always gives the same statistics. None: fresh entropy from the OS (not
            reproducible, as pyABC's own models are).

        Returns
        -------
        dict[str, float]
            One value per summary column; NaN when every row was NaN.
        """
        if seed is None:
            rng = np.random.default_rng()
        else:
            rng = generator(*seed) if isinstance(seed, tuple) else generator(seed)
        rows = self(self.theta(parameters), rng)
        finite = rows[np.isfinite(rows).all(axis=1)]
        means = finite.mean(axis=0) if len(finite) else np.full(len(self.columns), math.nan)
        return {column: float(value) for column, value in zip(self.columns, means)}

    def sample_prior(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """``n`` draws of theta from the calibration's prior, shape (n, p)."""
        return np.asarray(self.config.prior.sample(rng, n), dtype=float).reshape(n, len(self.names))

    def log_prior(self, theta) -> float:
        """The calibration's log prior density at ``theta`` (-inf outside its support)."""
        return float(self.config.prior.logpdf(np.asarray(theta, dtype=float)))


def summary_simulator(calibration: CalibrationConfig | str | Path, n_sim: int = 1,
                      threads: int | None = None) -> CalibrationSimulator:
    """The exact simulator and observation/noise model of a calibration, for other inference tools.

    Parameters
    ----------
    calibration : CalibrationConfig or str or pathlib.Path
        A validated calibration (``Calibration.from_toml(path)``) or the path of its TOML file.
    n_sim : int, default 1
        Simulated flocks (rows) per call. One row is one simulated dataset, as the targets are one
        observed dataset; the calibration's own BSL likelihood uses ``method.n_sim`` rows.
    threads : int, optional
        numba threads each call uses (set for the call, then restored). In another library's worker
        processes pass 1 (or set ``NUMBA_NUM_THREADS=1``), so the workers do not oversubscribe the cores.

    Returns
    -------
    CalibrationSimulator
        Callable as ``sim(theta, rng)`` (fresh seeds from ``rng``), ``sim.simulate(theta, seeds)``
        (deterministic in the seeds) or ``sim.summaries(parameters_dict, seed)`` (a pyABC model); it
        pickles and works in spawned worker processes.

    Examples
    --------
    >>> sim = summary_simulator("configs/calibration/recover_holland.toml", threads=1)  # doctest: +SKIP
    >>> sim.summaries({"field_deg": 120.0}, seed=1)                                      # doctest: +SKIP
    """
    config = calibration if isinstance(calibration, CalibrationConfig) else load_calibration(calibration)
    return CalibrationSimulator(config, n_sim, threads)
