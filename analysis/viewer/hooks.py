"""Viewer pages written by other commands: a report's showcase runs and a calibration's posterior median.

``report_blocks(results_dir, out_dir, cells) -> list`` is called by ``flocksweep report`` with the cells
whose traces it shows ((name, rows) pairs, rows of ``runs.parquet``). For each it takes replicate 0,
re-simulates it and checks it bit for bit (:func:`analysis.viewer.resimulate.reproduce`), writes
``<out_dir>/viewer/<name>.html`` and a still ``<out_dir>/figures/viewer_<name>.png``, and returns the
report's blocks: a heading, a sentence and a :class:`~analysis.document.Gallery` of the stills, each
linked to its page (pages of an earlier build are removed first). A run that does not reproduce gets
no page; the report says so.

``posterior_median_page(config, summary, out_dir) -> Path`` writes
``<out_dir>/viewer_posterior_median.html``: one run of the calibration's model at the posterior median
of every free parameter (integer keys rounded), with the calibration's seed.
"""
from __future__ import annotations

import re
from pathlib import Path

from .page import build_page
from .resimulate import NotReproduced, record_step_for, reproduce
from .track import from_observations

MEDIAN_PAGE = "viewer_posterior_median.html"


def slug(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", str(name)).strip("_") or "run"


def showcase_page(results_dir, out_dir, name: str, row: dict) -> tuple[Path, Path]:
    """(page, still) of one stored run, re-simulated and checked."""
    from .animate import poster

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
    from sweeps.design import rebuild
    from sweeps.store import ResultsStore

    preset, _ = rebuild(ResultsStore(results_dir).model(), row)
    return preset.run.n_steps, preset.init.n


def report_blocks(results_dir, out_dir, cells) -> list:
    from analysis.document import Gallery, Heading, Para

    items, refused = [], []
    for stale in (Path(out_dir) / "viewer").glob("*.html"):
        stale.unlink()  # a rebuilt report holds only the pages of this build
    for name, rows in cells:
        row = rows.sort_values("replicate").iloc[0].to_dict()
        try:
            page, still = showcase_page(results_dir, out_dir, name, row)
        except NotReproduced as err:
            refused.append(f"{name}: {err}")
            continue
        items.append((still, f"{name} (run {row['run_id']})", page.relative_to(Path(out_dir)).as_posix()))
    blocks = [Heading("Watch the showcase runs in 3-D")]
    if items:
        blocks.append(Para("Click a still to open the run's interactive viewer page (beside this report, in "
                           "`viewer/`; works offline): play, pause, scrub, orbit, colour by boid, pattern, leader, "
                           "group or speed, with the frame's metrics. Each run was re-simulated from its seed and "
                           "matches the table bit for bit."))
        blocks.append(Gallery(items))
    for message in refused:
        blocks.append(Para(f"No viewer page for {message}"))
    return blocks


def posterior_median_page(config, summary, out_dir) -> Path:
    """The calibration's model at the posterior median (see the module docstring)."""
    import numpy as np

    from simcore import simulate_preset

    from analysis.calibration.simulator import SummarySimulator

    theta = np.array([float(summary.loc[name, "median"]) for name in config.names])
    simulator = SummarySimulator(config.preset_data, config.keys, config.targets.columns, 1, config.warmup)
    preset = simulator.preset(theta)
    obs = simulate_preset(preset, config.seed, record_step_for(preset.run.n_steps, preset.init.n))
    info = {"calibration": config.name, "seed": config.seed,
            **{f"median {name}": f"{value:.4g}" for name, value in zip(config.names, theta)}}
    track = from_observations(obs, preset, title=f"{config.name}: a run at the posterior median", info=info)
    return build_page(track).save(Path(out_dir) / MEDIAN_PAGE)
