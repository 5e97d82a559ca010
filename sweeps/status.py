"""What a results folder holds, read quickly: ``flocksweep status`` and the resume hint after an interrupt.

``status(out_dir, remember=False) -> dict``: counts of done / failed / missing runs of the stored
design, the failures' reasons, the manifest and the runner holding the folder now (if any).
``resume_hint(sweep_path, out_dir)``: one line on what was saved and the command that resumes. Reads
files only; imports neither the simulator nor numba, so ``flocksweep status`` starts fast.

Unchanged folders are not checked twice (``remember=True``, what ``flocksweep status`` does): a full
check verifies the checksums and schemas of the design and of every runs part, reading of their contents
only the run ids, statuses and errors (:class:`sweeps.store.ResultsStore`; never the metrics, nor any
time series). When it finds nothing damaged, its counts are remembered in the
user's cache (:func:`cache_path`: ``$FLOCKSWEEP_CACHE_DIR/status/``, else
``$XDG_CACHE_HOME/flocksweep/status/``, else ``~/.cache/flocksweep/status/``; never in the results folder,
which ``status`` only reads) together with the folder's *fingerprint*: size, modification and
change time (``st_ctime_ns``, which no user can set back) and inode of ``design.parquet``,
``manifest.json`` and every file in ``runs/``, plus those of the checking code (``CODE``). The
next ``status`` whose fingerprint is equal reuses the counts without importing pandas (the manifest and
the lock holder are read anew each time); any difference (a new, removed, rewritten or touched part, an
edited manifest, new flocksweep code) means a full check again, and a folder with a damaged file is
never remembered, so it is reported as damaged every time. ``remember=False`` (the default, and
``flocksweep status --verify``) always checks in full.
"""
from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

from .files import read_json, user_cache, write_json
from .lock import holder

CACHE_FORMAT = 1
# the checking code: a change in any of these invalidates what was remembered
CODE = (Path(__file__), Path(__file__).with_name("store.py"), Path(__file__).with_name("files.py"),
        Path(__file__).with_name("checksums.py"),
        Path(__file__).resolve().parent.parent / "observables" / "columns.py")


def status(out_dir, remember: bool = False) -> dict:
    """Counts of done / failed / missing runs of the stored design, with the failures' reasons;
    ``checked`` says whether the files were read now ("full") or were unchanged since a full check."""
    root = Path(out_dir)
    if not (root / "design.parquet").exists():
        raise FileNotFoundError(f"{out_dir}: no sweep stored here (design.parquet missing)")
    fingerprint = _fingerprint(root) if remember else None
    counts = _remembered(root, fingerprint) if remember else None
    if counts is None:
        counts, clean = _full_check(root)
        if remember and clean:
            _remember(root, fingerprint, counts)
        checked = "full"
    else:
        checked = f"unchanged since the full check at {counts.pop('checked_at')}"
    manifest = read_json(root / "manifest.json", {}) if counts.get("manifest") is None else counts["manifest"]
    return {**{k: v for k, v in counts.items() if k != "manifest"}, "manifest": manifest if isinstance(manifest, dict)
            else {}, "running": holder(root), "checked": checked}


def _full_check(root: Path) -> tuple[dict, bool]:
    """The counts from reading and verifying every file (sweeps.store), and whether nothing was damaged."""
    from .store import ResultsStore

    store = ResultsStore(root)
    design = store.design(columns=("run_id",))
    if design is None:
        raise FileNotFoundError(f"{root}: no sweep stored here (design.parquet missing)")
    latest = store.latest(columns=("run_id", "status", "error"))   # every part verified; its metrics not read
    manifest = store.manifest()
    ids = design["run_id"]
    states = ids.map(dict(zip(latest["run_id"].tolist(), latest["status"].tolist()))).astype(object)
    states[states.isna()] = "missing"
    failed = ids[states == "failed"].tolist()
    error_of = dict(zip(latest["run_id"].tolist(), latest["error"].tolist()))
    tally = states.value_counts()
    counts = {"runs": len(design), **{state: int(tally.get(state, 0)) for state in ("ok", "failed", "missing")},
              "failures": [(r, str(error_of[r])) for r in failed], "manifest": manifest}
    return counts, not store.damage_reported


def _stat(path: Path) -> list[int] | None:
    try:
        s = path.stat()
    except OSError:
        return None
    return [s.st_size, s.st_mtime_ns, s.st_ctime_ns, s.st_ino]


def _fingerprint(root: Path) -> dict:
    """What a full check's result depends on: the stats of the files it reads and of the checking code."""
    files = {name: _stat(root / name) for name in ("design.parquet", "manifest.json")}
    runs = root / "runs"
    if runs.is_dir():
        files.update({f"runs/{entry.name}": _stat(runs / entry.name) for entry in sorted(os.scandir(runs),
                                                                                        key=lambda e: e.name)})
    return {"format": CACHE_FORMAT, "folder": str(root.resolve()), "files": files,
            "code": {str(p): _stat(p) for p in CODE}}


def cache_path(root: Path) -> Path:
    """Where the remembered counts of the folder ``root`` live: the user's cache (``$FLOCKSWEEP_CACHE_DIR``,
    else ``$XDG_CACHE_HOME/flocksweep``, else ``~/.cache/flocksweep``), never the folder itself."""
    key = hashlib.sha256(str(Path(root).resolve()).encode()).hexdigest()[:32]
    return user_cache() / "status" / f"{key}.json"


def _remembered(root: Path, fingerprint: dict) -> dict | None:
    """The remembered counts when the folder's fingerprint is the one recorded with them, else None."""
    try:
        record = json.loads(cache_path(root).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(record, dict) or record.get("fingerprint") != fingerprint:
        return None
    counts = record.get("counts")
    if not isinstance(counts, dict) or not {"runs", "ok", "failed", "missing", "failures"} <= set(counts):
        return None
    return {**counts, "failures": [tuple(f) for f in counts["failures"]], "manifest": None,
            "checked_at": record.get("checked_at", "?")}


def _remember(root: Path, fingerprint: dict, counts: dict) -> None:
    """Record the counts of a clean full check (a cache: a folder where it cannot be written is skipped)."""
    import time

    record = {"fingerprint": fingerprint, "checked_at": time.strftime("%Y-%m-%d %H:%M:%S"),
              "counts": {k: v for k, v in counts.items() if k != "manifest"}}
    try:
        write_json(cache_path(root), record)
    except Exception:  # noqa: BLE001 - only a cache: the next status checks in full again
        pass


def resume_hint(sweep_path, out_dir) -> str:
    """One line on what an interrupted sweep saved and how to resume it."""
    if not (Path(out_dir) / "design.parquet").exists():
        return "nothing was saved yet: run the same command again"
    info = status(out_dir)
    return (f"saved: {info['ok']} ok and {info['failed']} failed of {info['runs']} runs in {out_dir}; resume with: "
            f"flocksweep run {sweep_path} --out {out_dir}")


def computed(manifest: dict) -> str:
    """When the stored runs were computed, from the manifest's invocations that computed runs (a rerun
    that found everything done is not one): 'START to FINISH', and with several 'first computed START to
    FINISH; last extended START to FINISH (K invocations computed runs)'. Older manifests without
    invocations: their own start and finish."""
    history = [h for h in manifest.get("invocations", []) if h.get("computed")]
    if not history:
        if not manifest.get("started"):
            return "unknown"
        return f"{manifest.get('started')} to {manifest.get('finished') or 'unfinished'}"

    def span(h: dict) -> str:
        return f"{h.get('started')} to {h.get('finished') or 'interrupted'} ({h['computed']} runs)"
    if len(history) == 1:
        return span(history[0])
    return (f"first computed {span(history[0])}; last extended {span(history[-1])} "
            f"({len(history)} invocations computed runs)")
