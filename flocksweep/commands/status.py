"""``flocksweep status``: done / failed / missing runs of a results directory."""
from __future__ import annotations

import sys
from pathlib import Path

from flocksweep.command import Command

HELP = "done / failed / missing runs of a results directory"
DESCRIPTION = ("Count the done, failed and missing runs of a results directory, say whether a runner is working "
               "there now, when its results were computed, and list the failed runs with their reasons. Reads only; "
               "quick (simulates nothing).")


def arguments(p) -> None:
    p.add_argument("dir", type=Path, help="results directory of a sweep")
    p.add_argument("--verify", action="store_true",
                   help="read and verify every file even if none changed since the last full check (status "
                        "otherwise reuses that check's counts while the files' sizes and times are unchanged)")


def handler(args) -> int:
    from flocksweep.sweeps.progress import next_steps
    from flocksweep.sweeps.status import computed, status

    try:
        info = status(args.dir, remember=not args.verify)
    except FileNotFoundError as err:
        print(f"flocksweep: {err}", file=sys.stderr)
        return 2
    manifest = info["manifest"]
    print(f"{manifest.get('sweep', args.dir)}: {info['runs']} runs: {info['ok']} done, {info['failed']} failed, "
          f"{info['missing']} missing")
    if info["running"]:
        print(f"  a runner is working here now ({info['running']}), started {manifest.get('started')}")
    elif manifest.get("finished"):
        print(f"  results computed {computed(manifest)} (git {manifest.get('git_revision')})")
    elif manifest:
        print(f"  last run started {manifest.get('started')} and did not finish (resume with flocksweep run)")
    if info["checked"] != "full":
        print(f"  files {info['checked']} (--verify reads them all again)")
    for run_id, error in info["failures"][:50]:
        print(f"  failed {run_id}: {error}")
    if len(info["failures"]) > 50:
        print(f"  ... and {len(info['failures']) - 50} more")
    next_steps(*after_status(Path(args.dir), info))
    return 0


def after_status(folder: Path, info: dict) -> list[str]:
    """Finish the sweep (missing or failed runs), else its report."""
    if info["running"]:
        return [f"flocksweep status {folder}   (again, once the runner working here has finished)"]
    sweep = folder / "sweep.toml"
    steps = []
    if info["missing"]:
        steps.append(f"flocksweep run {sweep} --out {folder}   (computes the {info['missing']} missing runs only)")
    if info["failed"]:
        steps.append(f"flocksweep run {sweep} --out {folder} --retry-failed   (runs the failed ones again)")
    if info["ok"]:
        steps.append(f"flocksweep report {folder}   (statistics, figures and claims of the finished runs)")
    return steps


COMMAND = Command("status", HELP, DESCRIPTION, arguments, handler)
