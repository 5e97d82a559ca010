"""Simulated statistics of a design of parameter vectors, saved as they finish and found again: the npe
method's training and held-out simulations.

Every row is the calibration's own data model (:class:`~analysis.calibration.simulator.SummarySimulator`:
a built-in or plug-in dynamics, or an external command, measured through the ``[observation]`` block
exactly as the tracks were), so an estimator learns from what every other method simulates.

Shapes: N design rows, d parameters, k statistics.

Contract
--------
``design_rows(simulator, theta (N, d), keys, folder, pool, tick=None, save_every=10.0) -> DesignRows``:
row i is the bare statistics (no measurement noise) of the simulator's ``n_sim`` runs at ``theta[i]``
(their mean; one run with ``n_sim = 1``; a simulator with a ``pool(runs) -> row`` method, a learned summary's
:class:`~analysis.calibration.learned_inputs.LearnedSimulator`, makes the row of its runs itself), the run seeds drawn from ``generator(*keys[i])``
(:func:`analysis.calibration.bsl.simulate_keyed`): a deterministic function of the row, whatever the
executor ``pool`` or the finishing order. The rows are
stored in ``folder`` under the design's digest (:func:`design_digest`: the simulator's identity, theta and
the seed keys): ``<digest>.npz`` (``index``, ``rows``: numbers only, read without pickle) and
``<digest>.json`` (``label``, the identity and every failed row's reason), both written atomically every
``save_every`` seconds while the work goes on and at the end, also when it is interrupted or fails. The
same call again computes only the rows not stored yet; a stored file that cannot be read is set aside
(renamed ``.unreadable``) and its rows computed again. A row whose run raised or whose statistics are not
finite is NaN, with its reason in ``DesignRows.failed``; the work goes on.

:class:`DesignRows`: ``rows`` (N, k) float (NaN where failed), ``failed`` {index: reason}, ``new`` (N,) bool
(the rows simulated by this call; ``computed`` their count), ``reused`` (rows found stored). With
``subset`` only those rows are simulated when missing (a reused estimator needs its held-out rows only).
"""
from __future__ import annotations

import functools
import hashlib
import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from flocksweep.sweeps.executors import Executor
from flocksweep.sweeps.files import atomic_path, json_ready

from flocksweep.sweeps.seeds import generator, seeds_for

from .bsl import simulate_keyed

NOT_FINITE = "statistics not finite (a run whose trajectory or requested summaries are nan or infinite)"


@dataclass
class DesignRows:
    rows: np.ndarray
    failed: dict = field(default_factory=dict)
    new: np.ndarray | None = None       # (N,) bool: the rows this call simulated
    reused: int = 0

    @property
    def computed(self) -> int:
        return int(self.new.sum()) if self.new is not None else 0

    @property
    def usable(self) -> np.ndarray:
        """(N,) bool: the rows with finite statistics."""
        return np.isfinite(self.rows).all(axis=1)


def design_digest(simulator, theta: np.ndarray, keys) -> tuple[str, dict]:
    """(digest, identity) of a design: what its rows depend on."""
    identity = {"simulator": simulator.identity(),
                "theta_sha256": hashlib.sha256(np.ascontiguousarray(theta, dtype=np.float64).tobytes()).hexdigest(),
                "keys_sha256": hashlib.sha256(json.dumps([list(map(int, k)) for k in keys]).encode()).hexdigest(),
                "rows": int(len(theta))}
    text = json.dumps(json_ready(identity), sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:20], identity


def _one_row(simulator, task) -> np.ndarray:
    """A design row: the mean statistics of the simulator's ``n_sim`` runs with the seeds of the row's key
    (NaN when any failed); a failure's reason, when the simulator gives one, is raised for the caller to
    record."""
    reasons = getattr(simulator, "rows_and_reasons", None)
    pool = getattr(simulator, "pool", None)       # a learned summary's simulator pools its runs its own way
    if pool is not None:
        return pool(simulate_keyed(simulator, task))
    if reasons is None:
        return simulate_keyed(simulator, task).mean(axis=0)
    theta, key = task
    rows, why = reasons(np.array(theta, dtype=float), seeds_for(generator(*key), simulator.n_sim))
    failed = [reason for reason in why if reason]
    if failed:
        raise RunFailed(failed[0])
    return rows.mean(axis=0)


class RunFailed(RuntimeError):
    """A design row's run failed (its reason)."""


def _load(path_npz: Path, path_json: Path, n: int, k: int) -> tuple[np.ndarray, np.ndarray, dict]:
    """(rows, done mask, failed reasons) stored for this design; nothing when absent or unreadable."""
    rows, done, failed = np.full((n, k), np.nan), np.zeros(n, dtype=bool), {}
    if not path_npz.is_file():
        return rows, done, failed
    try:
        with np.load(path_npz, allow_pickle=False) as data:
            index, stored = np.asarray(data["index"], dtype=np.int64), np.asarray(data["rows"], dtype=np.float64)
        if stored.shape != (len(index), k) or (len(index) and (index.min() < 0 or index.max() >= n)):
            raise ValueError(f"rows of shape {stored.shape} for {len(index)} indices")
        info = json.loads(path_json.read_text()) if path_json.is_file() else {}
        failed = {int(i): str(reason) for i, reason in info.get("failed", {}).items()}
    except Exception:  # noqa: BLE001 - a damaged store is recomputed, never trusted
        path_npz.replace(path_npz.with_suffix(".npz.unreadable"))
        return np.full((n, k), np.nan), np.zeros(n, dtype=bool), {}
    rows[index] = stored
    done[index] = True
    return rows, done, {i: r for i, r in failed.items() if done[i]}


def _save(path_npz: Path, path_json: Path, identity: dict, rows: np.ndarray, done: np.ndarray, failed: dict,
          label: str) -> None:
    with atomic_path(path_json) as tmp:
        Path(tmp).write_text(json.dumps(json_ready({"label": label, "identity": identity, "done": int(done.sum()),
                                                    "failed": {str(i): r for i, r in sorted(failed.items())}}),
                                        indent=1))
    index = np.flatnonzero(done)
    with atomic_path(path_npz) as tmp:
        with open(tmp, "wb") as handle:
            np.savez(handle, index=index, rows=rows[index])


def design_rows(simulator, theta: np.ndarray, keys, folder, pool: Executor, tick=None,
                save_every: float = 10.0, subset=None, label: str = "") -> DesignRows:
    """The statistics of every design row, stored ones found (see the module docstring); with ``subset``
    (indices or a boolean mask) only those rows are simulated when missing (the others stay NaN unless
    stored)."""
    theta = np.asarray(theta, dtype=float)
    keys = [tuple(int(w) for w in key) for key in keys]
    digest, identity = design_digest(simulator, theta, keys)
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    path_npz, path_json = folder / f"{digest}.npz", folder / f"{digest}.json"
    k = getattr(simulator, "row_width", len(simulator.columns))
    rows, done, failed = _load(path_npz, path_json, len(theta), k)
    wanted = np.ones(len(theta), dtype=bool) if subset is None else np.zeros(len(theta), dtype=bool)
    if subset is not None:
        wanted[subset] = True
    reused = int((done & wanted).sum())
    if tick is not None:
        for _ in range(reused):
            tick()
    todo = np.flatnonzero(~done & wanted)
    new = np.zeros(len(theta), dtype=bool)
    fn = functools.partial(_one_row, simulator)
    last_save, computed = time.monotonic(), 0
    try:
        for outcome in pool.as_completed(fn, [(theta[i], keys[i]) for i in todo], idle=save_every):
            if outcome is not None:
                i = int(todo[outcome.index])
                if outcome.error is not None:
                    failed[i] = outcome.reason
                else:
                    rows[i] = outcome.value
                    if not np.isfinite(rows[i]).all():
                        rows[i] = np.nan
                        failed[i] = NOT_FINITE
                done[i] = new[i] = True
                computed += 1
                if tick is not None:
                    tick()
            if time.monotonic() - last_save >= save_every:
                _save(path_npz, path_json, identity, rows, done, failed, label)
                last_save = time.monotonic()
    finally:
        if computed:
            _save(path_npz, path_json, identity, rows, done, failed, label)
    return DesignRows(rows=rows, failed={i: r for i, r in failed.items() if wanted[i]}, new=new, reused=reused)
