"""Viewer pages of stored sweep runs, for the commands that write them beside their own output.

``showcase_page(results_dir, out_dir, name, row) -> (page, still)`` re-simulates one stored run and checks
it bit for bit (:func:`analysis.viewer.resimulate.reproduce`; :class:`~analysis.viewer.resimulate.NotReproduced`
when it does not reproduce), then writes ``<out_dir>/viewer/<name>.html`` and a still
``<out_dir>/figures/viewer_<name>.png``. ``flocksweep report`` calls it for its showcase runs
(:mod:`analysis.reports.viewer_pages`); calibration writes its posterior-median page with
:func:`preset_page` (:mod:`analysis.calibration.viewer_page`).

``preset_page(preset, seed, path, title, info) -> Path`` simulates one run of a preset and writes its page.
"""
from __future__ import annotations

import re
from pathlib import Path

from flocksweep.simcore import simulate_preset
from flocksweep.sweeps.design import rebuild
from flocksweep.sweeps.store import ResultsStore

from .animation import poster
from .page import build_page
from .resimulate import record_step_for, reproduce
from .track import from_observations


def slug(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", str(name)).strip("_") or "run"


def showcase_page(results_dir, out_dir, name: str, row: dict) -> tuple[Path, Path]:
    """(page, still) of one stored run, re-simulated and checked."""
    run = run_steps(results_dir, row)
    reproduced = reproduce(results_dir, row, record_step_for(*run))
    info = {"sweep": Path(results_dir).resolve().name, "showcase": name, "run id": row["run_id"],
            "replicate": int(row["replicate"]), "seed": int(row["seed"]),
            "reproduced": f"bit for bit ({int(reproduced.checks['identical'].sum())} checks)"}
    track = from_observations(reproduced.obs, reproduced.preset, title=f"{name}: run {row['run_id']}", info=info,
                              group_radius=reproduced.group_radius)
    out = Path(out_dir)
    page = build_page(track).save(out / "viewer" / f"{slug(name)}.html")
    still = poster(track, out / "figures" / f"viewer_{slug(name)}.png", title=name)
    return page, still


def run_steps(results_dir, row: dict) -> tuple[int, int]:
    """(steps, boids) of a stored run."""
    preset, _ = rebuild(ResultsStore(results_dir).model(), row)
    return preset.run.n_steps, preset.init.n


def preset_page(preset, seed: int, path, title: str, info: dict) -> Path:
    """Simulate one run of ``preset`` with ``seed`` and write its viewer page to ``path``."""
    obs = simulate_preset(preset, seed, record_step_for(preset.run.n_steps, preset.init.n))
    track = from_observations(obs, preset, title=title, info=info)
    return build_page(track).save(Path(path))
