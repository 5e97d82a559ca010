"""An independent check of a sweep's results folder, for benchmarks at scale (issue 43 point 4).

    python bench/check_sweep_folder.py RESULTS_DIR

Reads the files with pyarrow and hashlib only (not through ``sweeps.store``) and checks what the store
promises: ``manifest.json`` carries its own valid checksum; every file in ``runs/`` and ``timeseries/``,
``design.parquet`` and ``runs.parquet`` has the SHA-256 the manifest records, and the manifest records no
file that is not there; every run of the design has exactly one row in ``runs.parquet``, in design order,
with the latest status of the parts; every ok run has its time series in the part its row names; and
the manifest's counts are the table's. Prints one line per check; exit status 1 when any fails.
"""
from __future__ import annotations

import hashlib
import json
import sys
from collections import Counter
from pathlib import Path

import pyarrow.parquet as pq


def sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def main(root: Path) -> int:
    failures = []

    def check(ok: bool, what: str) -> None:
        print(f"  {'ok  ' if ok else 'FAIL'} {what}")
        if not ok:
            failures.append(what)

    manifest = json.loads((root / "manifest.json").read_text())
    body = {k: v for k, v in manifest.items() if k != "manifest_checksum"}
    own = hashlib.sha256(json.dumps(body, sort_keys=True, allow_nan=False).encode()).hexdigest()
    check(own == manifest.get("manifest_checksum"), "manifest.json carries its own valid checksum")
    sums = manifest.get("checksums", {})
    files = [p for kind in ("runs", "timeseries") for p in sorted((root / kind).glob("part-*.parquet"))]
    files += [root / "design.parquet", root / "runs.parquet"]
    wrong = [p.relative_to(root).as_posix() for p in files if sums.get(p.relative_to(root).as_posix()) != sha256(p)]
    check(not wrong, f"{len(files)} files have the checksums the manifest records{': not ' + ', '.join(wrong[:5]) if wrong else ''}")
    absent = [name for name in sums if not (root / name).exists()]
    check(not absent, f"the manifest records no absent file{': ' + ', '.join(absent[:5]) if absent else ''}")
    design = pq.read_table(root / "design.parquet", columns=["run_id", "index"]).to_pydict()
    table = pq.read_table(root / "runs.parquet", columns=["run_id", "index", "status", "part"]).to_pydict()
    check(table["run_id"] == design["run_id"] and table["index"] == design["index"],
          f"runs.parquet holds the design's {len(design['run_id']):,} runs once each, in design order")
    latest = {}
    for path in sorted((root / "runs").glob("part-*.parquet")):
        part = pq.read_table(path, columns=["run_id", "status", "part"]).to_pydict()
        latest.update({r: (s, p) for r, s, p in zip(part["run_id"], part["status"], part["part"])})
    check(all(latest.get(r) == (s, p) for r, s, p in zip(table["run_id"], table["status"], table["part"])),
          "every row of runs.parquet is its run's latest row in the parts")
    by_part: dict[int, set] = {}
    for r, s, p in zip(table["run_id"], table["status"], table["part"]):
        if s == "ok":
            by_part.setdefault(int(p), set()).add(r)
    lacking = 0
    for number, ids in by_part.items():
        series = pq.read_table(root / "timeseries" / f"part-{number:06d}.parquet", columns=["run_id"])
        lacking += len(ids - set(series.column("run_id").to_pylist()))
    check(lacking == 0, f"every ok run has its time series in its part ({lacking} lacking)")
    counts = Counter(table["status"])
    recorded = manifest.get("counts", {})
    check(recorded.get("ok") == counts["ok"] and recorded.get("failed") == counts["failed"]
          and recorded.get("runs") == len(design["run_id"]),
          f"the manifest's counts are the table's ({counts['ok']:,} ok, {counts['failed']:,} failed)")
    return 1 if failures else 0


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    sys.exit(main(Path(sys.argv[1])))
