"""Where results live: an output folder (locked, written atomically, stamped) and the sweep's layout.

:class:`OutputFolder` is any result folder (a sweep's, a calibration's, an SBC study's): ``lock()``
holds an exclusive flock on ``<root>/.lock`` while one process writes there (:mod:`sweeps.lock`: a
second one gets :class:`StoreLocked` naming the holder; the lock goes when its process dies, and a
dead holder is recognised), ``holder()`` says who holds it now, every ``write_*`` is atomic
(:mod:`sweeps.files`; a failed write is ``WriteFailed`` naming the file and the errno) and
``provenance()`` is the stamp every result carries (:mod:`sweeps.provenance`).

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

Damaged folders (:mod:`sweeps.quarantine`): a part that cannot be read, or whose schema is not a part's
(a runs part needs ``run_id``, ``status`` in {ok, failed}, ``error`` and ``part`` equal to its file's
number; a time series part ``run_id`` and ``t`` and the series of every ok run of its runs part), is
skipped with a warning by readers and, by ``repair()`` (the runner, holding the lock), moved to
``quarantine/`` with its partner part, so its runs count as missing and are computed again. A garbage
``manifest.json`` is moved aside the same way (a new one is written); a garbage ``runs.parquet`` is
rebuilt from the parts; an unreadable ``design.parquet`` is :class:`~sweeps.files.Unreadable` with how
to rewrite it. Part numbers are never reused, quarantined ones included.

Content checksums: every file the store writes (runs and time series parts, ``runs.parquet``,
``design.parquet``) has the SHA-256 of its bytes recorded in ``manifest.json`` (``checksums``, by path
relative to the folder) *before* it appears under its name: it is written to a temporary file, its
checksum goes into the manifest, then it is renamed into place (a part's two files together, not cut by
signals), and the manifest carries the checksum of its own content (``manifest_checksum``). So a file
whose checksum the manifest does not record was not written by flocksweep, and nothing can switch the
check off. Every reader verifies them: a part is *verified* when the manifest is intact and records the
checksum its bytes have. Any other part is damaged like an unreadable one (skipped by readers with a
warning, quarantined and recomputed by ``repair``): one whose bytes changed since they were written (a
renamed column, values overwritten with valid numbers or NaN), one the manifest does not record, and
every part when ``manifest.json`` is missing, is not a JSON object, changed since it was written or
records no checksums (then one warning says so for all of them: :meth:`ResultsStore.trust`). Nothing
is ever vouched for afresh: ``repair`` records no checksum of a file it did not write, so results can
only be recomputed, never blessed. A changed or unverified ``runs.parquet`` is rebuilt from the parts;
a changed ``design.parquet`` is :class:`Unreadable` (an unverified one is read, as the runner rewrites
it from the sweep file); a damaged manifest is moved aside and written anew. A runs part's schema: at
least one row, the columns ``RUNS_COLUMNS``, its own part number, text run ids, statuses
``ok``/``failed``, numbers (or nothing) in every metric column, and no column that flocksweep never
writes (neither a design column, nor a run's identity, status or timing, nor a summary metric).
"""
from __future__ import annotations

import contextlib
import hashlib
import json
import os
import re
from contextlib import contextmanager
from pathlib import Path

import pandas as pd

from flocksweep.observables.columns import EVERY_METRIC_COLUMN

from .checksums import CHANGED, CHECKSUMS, SELF_CHECKSUM, checksum, content_checksum  # noqa: F401 - also read from here
from .files import (Unreadable, atomic_path, json_ready, read_json, remove_stale_temporaries, write_csv, write_json,
                    write_text)
from .interrupts import deferred
from .lock import StoreLocked, hold, holder
from .provenance import stamp
from .quarantine import FOLDER as QUARANTINE, quarantine, warn

CONSOLIDATED = "consolidated_from"   # manifest.json: what runs.parquet was built from (consolidation_source)
PART = re.compile(r"part-(\d{6})\.parquet$")
NUMBERED = re.compile(r"part-(\d{6})\.parquet")          # also quarantined parts (with a time suffix)
RUNS_COLUMNS = ("run_id", "status", "error", "part")      # every runs part has these
# the runs table's own columns: no axis may be named like one (sweeps.config)
RESERVED_COLUMNS = ("run_id", "index", "point_index", "replicate", "seed", "status", "error", "sim_s", "wall_s",
                    "part", "n", "steps")
LIGHT = ("run_id", "status")   # what repair, plans and status read of a verified part (with RUNS_COLUMNS)
SERIES_COLUMNS = ("run_id", "t")                          # every time series part has these
STATUSES = ("ok", "failed")


__all__ = ["OutputFolder", "ResultsStore", "StoreLocked", "Unreadable"]


class OutputFolder:
    """A result folder: exclusive lock, atomic writes, provenance (see the module docstring)."""

    def __init__(self, root):
        self.root = Path(root)

    @contextmanager
    def lock(self):
        """Exclusive lock on the folder for one writer (released even if the process is killed)."""
        with hold(self.root):
            yield self

    def holder(self) -> str | None:
        """Who holds the folder's lock now, or None."""
        return holder(self.root)

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

    def __init__(self, root):
        super().__init__(root)
        self._reported: set[str] = set()   # damaged files a reader has warned about already
        self._sums: dict[str, str] | None = None   # checksums recorded in the manifest (loaded once)
        self._latest_manifest: dict | None = None   # what write_manifest wrote last (rewritten with new sums)
        self._distrust: str | None = None   # why the manifest vouches for nothing ('' once known to vouch)
        # runs parts read and checked already: path -> (its stat, design columns checked against, frame);
        # one is parsed and verified again only when its stat changed (a runner reads each part once)
        self._parts_read: dict[tuple, tuple[tuple, frozenset | None, pd.DataFrame]] = {}   # by (path, columns)
        self._design_read: dict[tuple | None, tuple[tuple, pd.DataFrame]] = {}   # design.parquet by columns
        self._consolidated: str | None = None   # the consolidation_source runs.parquet was built from
        self._consolidated_loaded = False

    @property
    def damage_reported(self) -> bool:
        """Whether a reader of this store has warned about a damaged file (flocksweep status remembers
        only undamaged folders)."""
        return bool(self._reported)

    # -- checksums -------------------------------------------------------------------------------
    def _relative(self, path: Path) -> str:
        return Path(path).relative_to(self.root).as_posix()

    def checksums(self) -> dict[str, str]:
        """{relative path: SHA-256} of the files whose checksum the manifest records."""
        if self._sums is None:
            sums = self.manifest().get(CHECKSUMS, {})
            self._sums = {str(k): str(v) for k, v in sums.items()} if isinstance(sums, dict) else {}
        return self._sums

    def trust(self) -> str:
        """'' when ``manifest.json`` can vouch for the files (it is intact and records checksums), else why
        not ('manifest.json is missing', 'manifest.json is not valid JSON', ...): then no stored file can
        be verified. Decided once, from the manifest found (before this store writes one)."""
        if self._distrust is None:
            if not (self.root / "manifest.json").exists():
                self._distrust = "manifest.json is missing"
            else:
                data, problem = self._read_manifest()
                if problem:
                    self._distrust = f"manifest.json {problem}"
                elif not isinstance(data.get(CHECKSUMS), dict) or SELF_CHECKSUM not in data:
                    self._distrust = "manifest.json records no checksums"
                else:
                    self._distrust = ""
        return self._distrust

    def unverified(self, path: Path) -> str | None:
        """Why ``path``'s bytes are not vouched for by the manifest (None when they are): the manifest
        cannot vouch (:meth:`trust`), it records no checksum of the file, or the file changed since."""
        why = self.trust()
        if why:
            return f"cannot be verified ({why})"
        name, actual = self._relative(path), checksum(path)
        recorded = self.checksums().get(name)
        if recorded != actual and self._latest_manifest is None:   # written since this reader read the
            data, problem = self._read_manifest()                   # manifest (a runner at work): read it again
            if problem is None and isinstance(data.get(CHECKSUMS), dict):
                self._sums = {str(k): str(v) for k, v in data[CHECKSUMS].items()}
                recorded = self._sums.get(name)
        if recorded is None:
            return ("cannot be verified (manifest.json records no checksum of it: flocksweep did not write it "
                    "here)")
        return CHANGED if recorded != actual else None

    def changed(self, path: Path) -> bool:
        """Whether ``path``'s bytes differ from the checksum recorded when it was written (False when
        none is recorded)."""
        recorded = self.checksums().get(self._relative(path))
        return recorded is not None and recorded != checksum(path)

    def _record(self, *paths: Path) -> None:
        sums = self.checksums()
        for path in paths:
            sums[self._relative(path)] = checksum(path)

    def _record_as(self, path: Path, written: Path) -> None:
        """Record, under ``path``'s name, the checksum of ``written`` (its temporary file, not yet renamed)."""
        self.checksums()[self._relative(path)] = checksum(written)

    def _forget(self, path: Path) -> None:
        self.checksums().pop(self._relative(path), None)

    def _save_checksums(self) -> None:
        """Rewrite the manifest with the checksums as they are now."""
        data = self._latest_manifest if self._latest_manifest is not None else self.manifest()
        self.write_manifest(data)

    def _write_vouched(self, path: Path, frame: pd.DataFrame) -> None:
        """``frame`` as the Parquet file ``path``, its checksum in the manifest before it has its name."""
        with deferred(), atomic_path(path) as tmp:
            frame.to_parquet(tmp, index=False)
            self._record_as(path, tmp)
            self._save_checksums()

    # -- inputs ----------------------------------------------------------------------------------
    def write_inputs(self, sweep_text: str, effective: dict, model: dict, design: pd.DataFrame | None) -> None:
        """The sweep's files and its design (``design`` None: the stored design is kept as it is, a rerun
        that found it to be this sweep's: :mod:`sweeps.design_key`)."""
        write_text(self.root / "sweep.toml", sweep_text)
        write_json(self.root / "sweep.effective.json", effective)
        write_json(self.root / "model.json", model)
        if design is not None:
            self._write_vouched(self.root / "design.parquet", design)

    def model(self) -> dict:
        """The base preset (after the sweep's model.set and run overrides), swept keys and analysis."""
        return self.read_json("model.json", {})

    def design(self, columns: tuple[str, ...] | None = None) -> pd.DataFrame | None:
        """``design.parquet`` (None when missing; Unreadable when it cannot be read or changed since it
        was written), or only its ``columns``; read once while its size, times and inode stay those it
        had."""
        path = self.root / "design.parquet"
        if not path.exists():
            return None
        signature = _signature(path)
        known = self._design_read.get(columns)
        if known is not None and known[0] == signature:
            return known[1]
        rerun = f"running the sweep again (flocksweep run SWEEP.toml --out {self.root}) writes it anew"
        try:
            design = pd.read_parquet(path, columns=None if columns is None else list(columns))
        except Exception as err:  # noqa: BLE001 - any reader failure means the file is damaged
            raise Unreadable(f"{path} cannot be read ({_why(err)}); {rerun}") from None
        if self.changed(path):
            raise Unreadable(f"{path} {CHANGED}; {rerun}")
        self._design_read[columns] = (signature, design)
        return design

    def _design_columns(self) -> set | None:
        """The design's columns (None when there is no readable design)."""
        path = self.root / "design.parquet"
        try:
            if not path.exists() or self.changed(path):
                return None
            return set(_schema(path).names)
        except Exception:  # noqa: BLE001 - an unreadable design has no columns
            return None

    # -- parts -----------------------------------------------------------------------------------
    def _parts(self, kind: str) -> list[Path]:
        folder = self.root / kind
        if not folder.is_dir():
            return []
        return sorted(p for p in folder.iterdir() if PART.search(p.name))

    def next_part(self) -> int:
        numbers = [int(PART.search(p.name).group(1)) for kind in ("runs", "timeseries") for p in self._parts(kind)]
        aside = self.root / QUARANTINE
        if aside.is_dir():
            numbers += [int(NUMBERED.search(p.name).group(1)) for p in aside.rglob("part-*") if NUMBERED.search(p.name)]
        return max(numbers, default=0) + 1

    def write_part(self, number: int, rows: list[dict], timeseries: pd.DataFrame | None) -> None:
        """The batch's time series part, then its runs part (the commit record), not cut by SIGINT/SIGTERM."""
        name = f"part-{number:06d}.parquet"
        table = pd.DataFrame(rows)
        table["part"] = number
        runs, series = self.root / "runs" / name, self.root / "timeseries" / name
        has_series = timeseries is not None and len(timeseries)
        with deferred(), atomic_path(runs) as runs_tmp, \
                (atomic_path(series) if has_series else contextlib.nullcontext()) as series_tmp:
            if has_series:
                timeseries.to_parquet(series_tmp, index=False)
                self._record_as(series, series_tmp)
            table.to_parquet(runs_tmp, index=False)
            self._record_as(runs, runs_tmp)
            self._save_checksums()   # the manifest vouches for both; then the series, then the runs, get their names

    def _runs_part(self, path: Path, design_columns: set | None = None,
                   columns: tuple[str, ...] | None = None) -> pd.DataFrame:
        """A runs part, its checksum and schema checked (Unreadable saying what is wrong; see the module
        docstring); with ``columns``, only those of its columns (and ``RUNS_COLUMNS``) are read, its
        schema checked on the file's. A part this store has read and checked already (against the same
        design columns) is not read again while its size, times and inode are those it had."""
        design_key = None if design_columns is None else frozenset(design_columns)
        signature = _signature(path)
        for read in (columns, None) if columns is not None else (None,):   # the whole part serves any columns
            known = self._parts_read.get((path, read))
            if known is not None and known[0] == signature and known[1] == design_key:
                return known[2] if read == columns else known[2][[c for c in known[2].columns
                                                                  if c in (*RUNS_COLUMNS, *columns)]]
        frame = self._checked_runs_part(path, design_columns, columns)
        self._parts_read[(path, columns)] = (signature, design_key, frame)
        return frame

    def _checked_runs_part(self, path: Path, design_columns: set | None,
                           columns: tuple[str, ...] | None = None) -> pd.DataFrame:
        """:meth:`_runs_part`, read and checked now."""
        try:
            if columns is None:
                frame = pd.read_parquet(path)
                names, numeric = list(frame.columns), None
            else:
                schema = _schema(path)
                names = schema.names
                numeric = {name: _numeric_type(schema.field(name).type) for name in names}
                frame = pd.read_parquet(path, columns=[c for c in dict.fromkeys((*RUNS_COLUMNS, *columns))
                                                       if c in names])
        except Exception as err:  # noqa: BLE001 - any reader failure means the file is damaged
            raise Unreadable(f"cannot be read ({_why(err)})") from None
        problem = self.unverified(path)
        if problem:
            raise Unreadable(problem)
        missing = [c for c in RUNS_COLUMNS if c not in names]
        if missing:
            raise Unreadable(f"is not a part of a sweep (no column {', '.join(map(repr, missing))})")
        if not len(frame):
            raise Unreadable("holds no rows (flocksweep never writes an empty part)")
        number = int(PART.search(path.name).group(1))
        if not (pd.to_numeric(frame["part"], errors="coerce") == number).all():
            raise Unreadable(f"holds rows of another part (its 'part' column is not {number} throughout)")
        if not frame["status"].isin(STATUSES).all() or pd.api.types.infer_dtype(frame["run_id"], skipna=False) != "string":
            raise Unreadable("is not a part of a sweep (run_id must be text, status 'ok' or 'failed')")
        for column in sorted(EVERY_METRIC_COLUMN & set(names)):
            if numeric is not None and numeric[column]:
                continue   # numbers (or nothing) by the file's own schema
            values = frame[column] if column in frame else pd.read_parquet(path, columns=[column])[column]
            if not (pd.api.types.is_numeric_dtype(values) or values.isna().all()):
                raise Unreadable(f"holds non-numbers in its metric column {column!r}")
        known = set(RESERVED_COLUMNS) | EVERY_METRIC_COLUMN | (design_columns or set())
        foreign = sorted(set(names) - known) if design_columns is not None else []
        if foreign:
            raise Unreadable(f"holds a column flocksweep never writes ({', '.join(map(repr, foreign))}): a foreign "
                             "or edited table")
        return frame

    def _damaged(self, path: Path, reason: str, repair: bool, partner: Path | None = None) -> None:
        """Quarantine ``path`` (and ``partner``) when repairing, else warn once that it is skipped."""
        if repair:
            quarantine(self.root, path, f"{reason}; its runs will be computed again")
            self._forget(path)
            if partner is not None and partner.exists():
                quarantine(self.root, partner, f"goes with {path.parent.name}/{path.name}, which was damaged")
                self._forget(partner)
            return
        key = str(path)
        if key not in self._reported:
            self._reported.add(key)
            warn("%s %s; skipped (the next 'flocksweep run' moves it aside and computes its runs again)",
                 path.relative_to(self.root), reason)

    def all_rows(self, repair: bool = False, columns: tuple[str, ...] | None = None) -> pd.DataFrame:
        """Every stored row of every readable, verified part (latest part last); damaged parts are skipped
        with a warning, or quarantined with ``repair``. When the manifest vouches for nothing
        (:meth:`trust`) every part is damaged, and one warning says so for all of them. ``columns``: only
        these (and ``RUNS_COLUMNS``) are read, every part checked as fully (:meth:`_runs_part`)."""
        frames = []
        parts = self._parts("runs")
        if parts and self.trust():
            self._unvouched(parts, repair)
            parts = []
        design_columns = self._design_columns() if parts else None
        for path in parts:
            try:
                frame = self._runs_part(path, design_columns, columns)
            except Unreadable as err:
                self._damaged(path, str(err), repair, self.root / "timeseries" / path.name)
                continue
            frames.append(frame)
        if not frames:
            return pd.DataFrame(columns=list(RUNS_COLUMNS))
        return pd.concat(frames, ignore_index=True).sort_values("part", kind="stable")

    def _unvouched(self, parts: list[Path], repair: bool) -> None:
        """Every runs part (with its time series part) when the manifest vouches for nothing: quarantined
        with one warning, or skipped with one warning."""
        why = self.trust()
        if repair:
            for path in parts:
                for kind in ("runs", "timeseries"):
                    file = self.root / kind / path.name
                    if file.exists():
                        quarantine(self.root, file, "", quiet=True)
                        self._forget(file)
            warn("%s, so %s cannot be verified: moved to quarantine/ with the time series; their runs are "
                 "computed again (results are recomputed, never vouched for afresh)", why, _stored_parts(parts))
            return
        if "unvouched" not in self._reported:
            self._reported.add("unvouched")
            warn("%s, so %s cannot be verified: skipped as damaged (their runs count as missing; the next "
                 "'flocksweep run' moves them aside and computes the runs again)", why, _stored_parts(parts))

    def latest(self, columns: tuple[str, ...] | None = None) -> pd.DataFrame:
        """The latest row per run id (indexed by run_id); ``columns``: only those (and ``RUNS_COLUMNS``)."""
        rows = self.all_rows(columns=columns)
        return rows.drop_duplicates("run_id", keep="last").set_index("run_id", drop=False)

    def statuses(self) -> dict[str, str]:
        """{run id: its latest status} of the readable, verified parts (what a plan needs)."""
        rows = self.all_rows(columns=LIGHT)
        if not len(rows):
            return {}
        return dict(zip(rows["run_id"].tolist(), rows["status"].tolist()))   # later parts overwrite earlier

    def _series_problem(self, path: Path, ok_ids: set) -> str | None:
        """Why the time series part ``path`` cannot serve the ok runs ``ok_ids`` (None when it can). Its
        bytes are checked against their checksum; of its content only the structure and the run ids are
        read (the checksum vouches for the rest)."""
        import pyarrow.parquet as pq

        if not path.exists():
            return f"has no time series part (timeseries/{path.name} is missing)"
        try:
            handle = pq.ParquetFile(path)
            names = handle.schema_arrow.names
            run_ids = handle.read(columns=["run_id"]).column("run_id").to_pylist() if "run_id" in names else []
        except Exception as err:  # noqa: BLE001 - any reader failure means the file is damaged
            return f"has an unreadable time series part timeseries/{path.name} ({_why(err)})"
        problem = self.unverified(path)
        if problem:
            return f"has a time series part timeseries/{path.name} that {problem}"
        if any(c not in names for c in SERIES_COLUMNS):
            return f"has a time series part timeseries/{path.name} without run_id and t columns"
        lacking = ok_ids - set(run_ids)
        if lacking:
            return f"has a time series part timeseries/{path.name} lacking {len(lacking)} of its ok runs"
        return None

    def repair(self) -> list[Path]:
        """For the runner holding the lock: remove temporary files of killed writers, quarantine damaged
        parts (a runs part together with its time series part) and a garbage manifest. Returns what
        was moved aside."""
        for folder in (self.root, self.root / "runs", self.root / "timeseries", self.root / "trajectories"):
            remove_stale_temporaries(folder)
        before = set(self._quarantined())
        self.trust()   # decided on the manifest as found, before it is moved aside
        self.manifest(repair=True)
        self.all_rows(repair=True, columns=LIGHT)   # every part verified in full; its metrics not read
        design_columns = self._design_columns()
        for path in self._parts("runs"):
            frame = self._runs_part(path, design_columns, LIGHT)
            ok_ids = set(frame.loc[frame["status"] == "ok", "run_id"])
            series = self.root / "timeseries" / path.name
            problem = self._series_problem(series, ok_ids) if ok_ids else None
            if problem:
                self._damaged(path, problem, True, series)
        kept = {self._relative(p) for kind in ("runs", "timeseries") for p in self._parts(kind)}
        for name in [n for n in self.checksums() if n.startswith(("runs/", "timeseries/")) and n not in kept]:
            self.checksums().pop(name)   # recorded, then the runner was killed before the rename (or moved aside)
        return sorted(set(self._quarantined()) - before)

    def _quarantined(self) -> list[Path]:
        folder = self.root / QUARANTINE
        return [p for p in folder.rglob("*") if p.is_file()] if folder.is_dir() else []

    # -- consolidation ---------------------------------------------------------------------------
    def consolidation_source(self) -> str | None:
        """A digest of what ``runs.parquet`` is built from: ``design.parquet`` and every runs part, by name
        and recorded checksum (None while the design's checksum is not recorded)."""
        sums = self.checksums()
        if "design.parquet" not in sums:
            return None
        parts = {name: sums.get(name) for name in (self._relative(p) for p in self._parts("runs"))}
        text = json.dumps({"design": sums["design.parquet"], "parts": parts}, sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()

    def _recorded_consolidation(self) -> str | None:
        """The :meth:`consolidation_source` that the manifest found here records for ``runs.parquet``."""
        if not self._consolidated_loaded:
            self._consolidated_loaded = True
            recorded = self.manifest().get(CONSOLIDATED) if not self.trust() else None
            self._consolidated = recorded if isinstance(recorded, str) else None
        return self._consolidated

    def consolidate(self, design: pd.DataFrame) -> pd.DataFrame:
        """Write ``runs.parquet``: the latest row of each run of ``design`` (run_id, index, point_index,
        replicate), in design order; positions come from the current design, not from when a row was
        computed (a run can move when the grid grows or replicates are added). Called after
        :meth:`repair`, which verified every part: when the design and the parts are those the stored
        ``runs.parquet`` was built from (the manifest records their :meth:`consolidation_source`) and it
        still has its recorded checksum, it is read instead (a rerun that computed nothing)."""
        source = self.consolidation_source()
        path = self.root / "runs.parquet"
        if source is not None and source == self._recorded_consolidation() and path.exists() \
                and self.unverified(path) is None:
            try:
                return pd.read_parquet(path)
            except Exception:  # noqa: BLE001 - unreadable after all: built again below
                pass
        latest = self.latest()
        present = design[design["run_id"].isin(latest.index)]
        table = latest.loc[list(present["run_id"])].reset_index(drop=True)
        for column in ("index", "point_index", "replicate"):
            if column in present:
                table[column] = present[column].to_numpy()
        if "index" in table:
            table = table.sort_values("index", kind="stable").reset_index(drop=True)
        self._recorded_consolidation()   # loaded from the manifest found, before this one is written
        self._consolidated = source
        self._write_vouched(path, table)
        return table

    def runs(self) -> pd.DataFrame:
        """``runs.parquet``, or the latest rows of the parts when it is missing, cannot be read or changed
        since it was written."""
        path = self.root / "runs.parquet"
        if path.exists():
            try:
                table = pd.read_parquet(path)
                problem = self.unverified(path)
                if problem:
                    raise Unreadable(problem)
                return table
            except Exception as err:  # noqa: BLE001 - any reader failure means the file is damaged
                problem = str(err) if isinstance(err, Unreadable) else f"cannot be read ({_why(err)})"
                if not (self.trust() and self._parts("runs")):   # else one warning about the parts says it all
                    warn("runs.parquet %s; using the rows of runs/ instead (the next 'flocksweep run' writes it "
                         "anew)", problem)
        return self.latest().reset_index(drop=True)

    def series_intact(self, path: Path) -> bool:
        """Whether the time series part ``path`` may be read (the manifest records its checksum and its
        bytes have it); any other is reported once."""
        problem = self.unverified(path)
        if problem is None:
            return True
        if not self.trust():   # else the one warning about the manifest said it
            self._damaged(path, f"{problem}: the series of its runs are left out", repair=False)
        return False

    def timeseries(self, run_ids=None) -> pd.DataFrame:
        """Time series of the given runs (default: all of runs.parquet), read part by part; a part that
        cannot be read is skipped with a warning."""
        table = self.runs()
        if run_ids is not None:
            table = table[table["run_id"].isin(list(run_ids))]
        frames = []
        for part, group in table[table["status"] == "ok"].groupby("part"):
            path = self.root / "timeseries" / f"part-{int(part):06d}.parquet"
            if not self.series_intact(path):
                continue
            try:
                frame = pd.read_parquet(path, filters=[("run_id", "in", list(group["run_id"]))])
            except Exception as err:  # noqa: BLE001 - any reader failure means the file is damaged
                self._damaged(path, f"cannot be read ({_why(err)}): the series of its "
                                    f"{len(group)} runs are left out", repair=False)
                continue
            frames.append(frame)
        return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()

    # -- manifest --------------------------------------------------------------------------------
    def _read_manifest(self) -> tuple[dict, str | None]:
        """(``manifest.json``, None), or ({}, what is wrong with it); ({}, None) when there is none."""
        try:
            data = self.read_json("manifest.json", {})
        except Unreadable:
            return {}, "is not valid JSON"
        if not isinstance(data, dict):
            return {}, f"is not a JSON object (it holds a {type(data).__name__})"
        if SELF_CHECKSUM in data and data[SELF_CHECKSUM] != content_checksum(data):
            return {}, CHANGED.replace("one recorded in manifest.json", "one it records")
        return data, None

    def manifest(self, repair: bool = False) -> dict:
        """``manifest.json`` ({} when missing); one that is not a JSON object or whose content changed
        since it was written is skipped with a warning, or quarantined."""
        data, problem = self._read_manifest()
        if problem is None:
            return data
        path = self.root / "manifest.json"
        if repair:
            quarantine(self.root, path, f"{problem}; a new manifest is written (the provenance of earlier "
                                        "invocations is in the file moved aside)")
            self._sums = {}   # its checksums vouch for nothing: every part is unverified (trust())
        elif str(path) not in self._reported:
            self._reported.add(str(path))
            warn("manifest.json %s; its provenance and checksums are ignored (the next 'flocksweep run' "
                 "moves it aside and writes a new one)", problem)
        return {}

    def write_manifest(self, data: dict) -> None:
        """Write ``manifest.json``: ``data`` with the checksums recorded so far, what ``runs.parquet`` was
        built from (:meth:`consolidation_source`) and its own checksum."""
        data = {k: v for k, v in data.items() if k not in (CHECKSUMS, SELF_CHECKSUM, CONSOLIDATED)}
        consolidated = self._recorded_consolidation()   # loaded from the manifest found, before it is replaced
        self._latest_manifest = data
        self._distrust = ""   # from now on it records every file this store writes
        record = json_ready({**data, CHECKSUMS: dict(sorted(self.checksums().items())),
                             **({CONSOLIDATED: consolidated} if consolidated else {})})
        write_json(self.root / "manifest.json", {**record, SELF_CHECKSUM: content_checksum(record)})


def _schema(path: Path):
    """The Arrow schema of a Parquet file (its footer only)."""
    import pyarrow.parquet as pq

    return pq.read_schema(path)


def _numeric_type(kind) -> bool:
    """Whether an Arrow type reads as a numeric pandas column (integers, floats, booleans) or holds nothing
    at all (the null type): a metric column's allowed types."""
    import pyarrow as pa

    return pa.types.is_integer(kind) or pa.types.is_floating(kind) or pa.types.is_boolean(kind) or pa.types.is_null(kind)


def _signature(path: Path) -> tuple:
    """A file's size, modification and change times and inode (any rewrite changes one of them)."""
    try:
        st = os.stat(path)
    except OSError:
        return ()
    return (st.st_size, st.st_mtime_ns, st.st_ctime_ns, st.st_ino)


def _stored_parts(parts: list) -> str:
    return f"the {len(parts)} stored part{'s' if len(parts) != 1 else ''} of runs/"


def _why(err: BaseException) -> str:
    """The first line of an exception, with its type."""
    text = str(err).strip().splitlines()
    return f"{type(err).__name__}: {text[0]}" if text else type(err).__name__
