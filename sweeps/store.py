"""Where results live: an output folder (locked, written atomically, stamped) and the sweep's layout.

:class:`OutputFolder` is any result folder (a sweep's, a calibration's, an SBC study's): ``lock()``
holds an exclusive flock on ``<root>/.lock`` while one process writes there (a second one gets
:class:`StoreLocked` naming the holder; the lock goes when its process dies), every ``write_*`` is atomic
(:mod:`sweeps.files`) and ``provenance()`` is the stamp every result carries (:mod:`sweeps.provenance`).

:class:`ResultsStore` is a sweep's folder, ``results/<sweep name>/``::

    sweep.toml            the sweep file as given
    sweep.effective.json  the sweep as run (after --set / --replicates)
    model.json            the base preset the design varies, the swept keys and the analysis settings
    design.parquet        the resolved design: one row per run (id, index, replicate, seed, parameters)
    manifest.json         provenance (versions, git revision, machine), times, counts, executor
    runs/part-NNNNNN.parquet        result rows, one part per finished batch
    timeseries/part-NNNNNN.parquet  metric time series of the same batch (run_id, t, metrics...)
    runs.parquet          consolidated table: the latest row of every run of the design, in design order
    trajectories/<run_id>.npz       only with keep = "trajectories"
    .lock                 held (flock) while a runner works here

A batch's time series part is written before its runs part, so a runs part is the commit record: a
crash can leave an unreferenced time series part (ignored) but never a row without its data. Parts are
never rewritten; a recomputed run (``--force``, ``--retry-failed``) appears in a later part and the
latest part wins. Nothing here holds more than one batch's time series in memory.
"""
from __future__ import annotations

import fcntl
import os
import re
import socket
import time
from contextlib import contextmanager
from pathlib import Path

import pandas as pd

from .files import read_json, write_csv, write_json, write_parquet, write_text
from .provenance import stamp

PART = re.compile(r"part-(\d{6})\.parquet$")


class StoreLocked(RuntimeError):
    pass


class OutputFolder:
    """A result folder: exclusive lock, atomic writes, provenance (see the module docstring)."""

    def __init__(self, root):
        self.root = Path(root)

    @contextmanager
    def lock(self):
        """Exclusive lock on the folder for one writer (released even if the process is killed)."""
        self.root.mkdir(parents=True, exist_ok=True)
        path = self.root / ".lock"
        handle = open(path, "a+")
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            handle.seek(0)
            holder = handle.read().strip() or "unknown process"
            handle.close()
            raise StoreLocked(f"{self.root} is in use by another flocksweep runner ({holder}); wait for it "
                              "to finish or stop it, then run again (finished runs are kept)") from None
        handle.seek(0)
        handle.truncate()
        handle.write(f"pid {os.getpid()} on {socket.gethostname()} since {time.strftime('%Y-%m-%d %H:%M:%S')}")
        handle.flush()
        try:
            yield self
        finally:
            handle.truncate(0)
            fcntl.flock(handle, fcntl.LOCK_UN)
            handle.close()

    def path(self, name: str) -> Path:
        return self.root / name

    def write_json(self, name: str, data) -> Path:
        write_json(self.root / name, data)
        return self.root / name

    def write_text(self, name: str, text: str) -> Path:
        write_text(self.root / name, text)
        return self.root / name

    def write_csv(self, name: str, frame, **options) -> Path:
        write_csv(self.root / name, frame, **options)
        return self.root / name

    def read_json(self, name: str, missing=None):
        return read_json(self.root / name, missing)

    @staticmethod
    def provenance() -> dict:
        return stamp()


class ResultsStore(OutputFolder):
    """A sweep's results folder (layout in the module docstring)."""

    # -- inputs ----------------------------------------------------------------------------------
    def write_inputs(self, sweep_text: str, effective: dict, model: dict, design: pd.DataFrame) -> None:
        write_text(self.root / "sweep.toml", sweep_text)
        write_json(self.root / "sweep.effective.json", effective)
        write_json(self.root / "model.json", model)
        write_parquet(self.root / "design.parquet", design)

    def model(self) -> dict:
        """The base preset (after the sweep's model.set and run overrides), swept keys and analysis."""
        return self.read_json("model.json", {})

    def design(self) -> pd.DataFrame | None:
        path = self.root / "design.parquet"
        return pd.read_parquet(path) if path.exists() else None

    # -- parts -----------------------------------------------------------------------------------
    def _parts(self, kind: str) -> list[Path]:
        folder = self.root / kind
        if not folder.is_dir():
            return []
        return sorted(p for p in folder.iterdir() if PART.search(p.name))

    def next_part(self) -> int:
        numbers = [int(PART.search(p.name).group(1)) for kind in ("runs", "timeseries") for p in self._parts(kind)]
        return max(numbers, default=0) + 1

    def write_part(self, number: int, rows: list[dict], timeseries: pd.DataFrame | None) -> None:
        name = f"part-{number:06d}.parquet"
        if timeseries is not None and len(timeseries):
            write_parquet(self.root / "timeseries" / name, timeseries)
        table = pd.DataFrame(rows)
        table["part"] = number
        write_parquet(self.root / "runs" / name, table)

    def all_rows(self) -> pd.DataFrame:
        """Every stored row of every part (latest part last)."""
        frames = [pd.read_parquet(p) for p in self._parts("runs")]
        frames = [f for f in frames if len(f)]
        if not frames:
            return pd.DataFrame(columns=["run_id", "status", "error", "part"])
        return pd.concat(frames, ignore_index=True).sort_values("part", kind="stable")

    def latest(self) -> pd.DataFrame:
        """The latest row per run id (indexed by run_id)."""
        rows = self.all_rows()
        return rows.drop_duplicates("run_id", keep="last").set_index("run_id", drop=False)

    # -- consolidation ---------------------------------------------------------------------------
    def consolidate(self, design: pd.DataFrame) -> pd.DataFrame:
        """Write ``runs.parquet``: the latest row of each run of ``design`` (run_id, index, point_index,
        replicate), in design order; positions come from the current design, not from when a row was
        computed (a run can move when the grid grows or replicates are added)."""
        latest = self.latest()
        present = design[design["run_id"].isin(latest.index)]
        table = latest.loc[list(present["run_id"])].reset_index(drop=True)
        for column in ("index", "point_index", "replicate"):
            if column in present:
                table[column] = present[column].to_numpy()
        if "index" in table:
            table = table.sort_values("index", kind="stable").reset_index(drop=True)
        write_parquet(self.root / "runs.parquet", table)
        return table

    def runs(self) -> pd.DataFrame:
        path = self.root / "runs.parquet"
        return pd.read_parquet(path) if path.exists() else self.latest().reset_index(drop=True)

    def timeseries(self, run_ids=None) -> pd.DataFrame:
        """Time series of the given runs (default: all of runs.parquet), read part by part."""
        table = self.runs()
        if run_ids is not None:
            table = table[table["run_id"].isin(list(run_ids))]
        frames = []
        for part, group in table[table["status"] == "ok"].groupby("part"):
            path = self.root / "timeseries" / f"part-{int(part):06d}.parquet"
            frame = pd.read_parquet(path, filters=[("run_id", "in", list(group["run_id"]))])
            frames.append(frame)
        return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()

    # -- manifest --------------------------------------------------------------------------------
    def manifest(self) -> dict:
        return self.read_json("manifest.json", {})

    def write_manifest(self, data: dict) -> None:
        write_json(self.root / "manifest.json", data)
