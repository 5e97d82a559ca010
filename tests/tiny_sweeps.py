"""A tiny Holland sweep as a dict, and its run ids (tests of a sweep's [run] metric settings)."""
from __future__ import annotations

from flocksweep.sweeps.config import sweep_from_dict
from flocksweep.sweeps.design import expand
from paths import ROOT

HOLLAND = ROOT / "configs" / "models" / "holland.toml"


def sweep(**run) -> dict:
    return {"name": "tiny", "seed": 7, "model": {"preset": str(HOLLAND)},
            "run": {"n": 8, "duration": 1.0, "record_interval": 0.5, "warmup": 0.25, **run}, "axes": []}


def run_ids(data: dict) -> list[str]:
    return [spec.run_id for spec in expand(sweep_from_dict(data, ROOT))]
