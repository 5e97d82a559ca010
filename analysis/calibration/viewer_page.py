"""A calibration's viewer page: one run of the model at the posterior median.

``posterior_median_page(config, summary, out_dir) -> Path`` writes ``<out_dir>/viewer_posterior_median.html``:
one run of the calibration's model at the posterior median of every free parameter (integer keys rounded,
as the summary simulator does), with the calibration's seed.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from analysis.viewer.hooks import preset_page

from .simulator import SummarySimulator

MEDIAN_PAGE = "viewer_posterior_median.html"


def posterior_median_page(config, summary, out_dir) -> Path:
    """The calibration's model at the posterior median (see the module docstring)."""
    theta = np.array([float(summary.loc[name, "median"]) for name in config.names])
    simulator = SummarySimulator(config.preset_data, config.keys, config.targets.columns, 1, config.metrics.warmup)
    preset = simulator.preset(theta)
    info = {"calibration": config.name, "seed": config.seed,
            **{f"median {name}": f"{value:.4g}" for name, value in zip(config.names, theta)}}
    return preset_page(preset, config.seed, Path(out_dir) / MEDIAN_PAGE,
                       title=f"{config.name}: a run at the posterior median", info=info)
