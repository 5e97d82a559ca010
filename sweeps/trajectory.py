"""The trajectory file: one run's records as a compressed numpy ``.npz``, one format for every writer.

``write_trajectory(path, obs, seed)`` writes it atomically (:func:`sweeps.files.atomic_path`; a failed
write raises :class:`~sweeps.files.WriteFailed`); ``read_trajectory(path) -> dict`` reads it back. Both
``flocksweep simulate --out`` (``trajectory.npz``, every record) and a sweep with ``keep =
"trajectories"`` (``trajectories/<run_id>.npz``, every ``trajectory_every`` steps: pass the
observations at that interval, :func:`observables.summary.every_nth`) write it; the viewer reads it
(:func:`analysis.viewer.track.from_npz`). For R records of N boids it holds:

* ``times`` float64 (R,) seconds; ``pos``, ``vel`` float64 (R, N, 3);
* ``visible``, ``binocular`` int (R, N): neighbours seen, of them binocularly; ``leader`` bool (R, N);
* ``pattern`` uint32 (N,);
* ``seed``: the run's seed (an integer, or integers for a tuple seed; left out when it does not fit 64 bits);
* ``predator``, ``prey`` float64 (R, 3): the Boids++ agents' positions (NaN while absent), only when the
  run has them (:data:`observables.encounters.AGENTS`).

Files written before this format are read alike: a sweep's ``trajectories/<run_id>.npz`` of earlier
versions lacks ``visible``, ``binocular`` and ``leader``, a ``trajectory.npz`` of ``flocksweep
simulate`` lacks ``seed`` and ``leader``: :func:`read_trajectory` gives None for any optional field a
file does not hold (``REQUIRED`` must be there). A file that is not such an ``.npz`` (garbage, truncated,
arrays of other shapes) is a ValueError naming it. A state file read by ``init.from_file``
(:mod:`simcore.initfile`) may be a trajectory: its last record is used.
"""
from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np

from flocksweep.observables.encounters import AGENTS, agent_positions

from .files import atomic_path

REQUIRED = ("times", "pos", "vel")
OPTIONAL = ("visible", "binocular", "leader", "pattern", "seed") + AGENTS


def write_trajectory(path, obs, seed=None) -> Path:
    """Write the records of ``obs`` (an ``Observations``) and ``seed`` to ``path``; returns ``path``."""
    path = Path(path)
    seed_array = {} if seed is None else {"seed": np.asarray(seed)}
    if seed_array and seed_array["seed"].dtype.kind not in "iu":
        seed_array = {}   # not a plain integer seed (e.g. one beyond 64 bits): not stored
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as handle:
            np.savez_compressed(handle, times=obs.times, pos=obs.pos, vel=obs.vel, visible=obs.visible,
                                binocular=obs.binocular, leader=obs.leader, pattern=obs.pattern,
                                **seed_array, **agent_positions(obs))
    return path


def read_trajectory(path) -> dict:
    """{field: array or None} of every field of the format (see the module docstring); FileNotFoundError
    when ``path`` is not a file, ValueError naming the missing fields when it is not a trajectory."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such trajectory file")
    if not zipfile.is_zipfile(path):
        raise ValueError(f"{path}: not a trajectory .npz (not a zip archive of arrays); expected a file written by "
                         f"flocksweep (simulate --out, or a sweep's trajectories/)")
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {key: data[key] for key in data.files} if hasattr(data, "files") else {}
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile) as err:
        raise ValueError(f"{path}: cannot be read as a trajectory .npz ({type(err).__name__}: {err}); expected "
                         f"a file written by flocksweep (simulate --out, or a sweep's trajectories/)") from None
    missing = [key for key in REQUIRED if key not in arrays]
    if missing:
        raise ValueError(f"{path}: not a flocksweep trajectory (missing {', '.join(missing)}; expected "
                         f"{', '.join(REQUIRED)} and optionally {', '.join(OPTIONAL)})")
    _check_shapes(path, arrays)
    return {key: arrays.get(key) for key in REQUIRED + OPTIONAL}


def _check_shapes(path: Path, arrays: dict) -> None:
    """times (R,) and pos, vel (R, N, 3) of numbers, R >= 1: else ValueError naming the file and field."""
    times, pos = arrays["times"], arrays["pos"]
    expected = {"times": "(records,)", "pos": "(records, boids, 3)", "vel": "(records, boids, 3)"}
    for key in REQUIRED:
        value = arrays[key]
        shape_ok = value.ndim == 1 if key == "times" else (value.ndim == 3 and value.shape[2] == 3
                                                          and value.shape[:2] == pos.shape[:2])
        if value.dtype.kind not in "fiu" or not shape_ok or len(value) != len(times) or not len(times):
            raise ValueError(f"{path}: {key} holds a {value.dtype} array of shape {value.shape}; a trajectory's "
                             f"{key} is numbers of shape {expected[key]} with at least one record")
