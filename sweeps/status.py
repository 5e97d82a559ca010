"""What a results folder holds, read quickly: ``flocksweep status`` and the resume hint after an interrupt.

``status(out_dir) -> dict``: counts of done / failed / missing runs of the stored design, the failures'
reasons, the manifest and the runner holding the folder now (if any). ``resume_hint(sweep_path,
out_dir)``: one line on what was saved and the command that resumes. Reads files only; imports neither
the simulator nor numba, so ``flocksweep status`` starts fast.
"""
from __future__ import annotations

from pathlib import Path

from .store import ResultsStore


def status(out_dir) -> dict:
    """Counts of done / failed / missing runs of the stored design, with the failures' reasons."""
    store = ResultsStore(out_dir)
    design = store.design()
    if design is None:
        raise FileNotFoundError(f"{out_dir}: no sweep stored here (design.parquet missing)")
    latest = store.latest()
    status_of = dict(zip(latest["run_id"], latest["status"])) if len(latest) else {}
    error_of = dict(zip(latest["run_id"], latest["error"])) if len(latest) else {}
    states = [status_of.get(r, "missing") for r in design["run_id"]]
    failures = [(r, error_of[r]) for r, s in zip(design["run_id"], states) if s == "failed"]
    return {"runs": len(design), "ok": states.count("ok"), "failed": states.count("failed"),
            "missing": states.count("missing"), "failures": failures, "manifest": store.manifest(),
            "running": store.holder()}


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
