"""A calibration's viewer pages: a run at the posterior median, and the measured flock beside a predictive run.

``posterior_median_page(config, summary, out_dir) -> Path`` writes ``<out_dir>/viewer_posterior_median.html``:
one run of the calibration's model at the posterior median of every free parameter (integer keys rounded,
as the summary simulator does), with the calibration's seed.

``predictive_page(config, summary, draws, predictive, flock, out_dir) -> (Path | None, warnings)`` writes
``<out_dir>/viewer_predictive.html`` when the targets come from measured tracks (None otherwise): one page of
two runs with a run menu (:func:`analysis.viewer.page.build_runs_page`), the same colouring (by group) and
the same clock, the tracks' (seconds since the start of a measured flock's records; switching keeps the
time): the predictive run's records from ``run.warmup - tracks.warmup`` seconds on, shifted by that, so
the windows the statistics compare (the run from its warm-up, the flock from its own) start at the same
time in both:

* ``data-<flock>``: the first measured flock as resampled for the targets (its records; an individual's
  records where it was not detected interpolated between those where it was:
  :func:`analysis.viewer.track.from_observed`);
* ``predictive-<i>``: posterior predictive run i, the one whose draw is closest to the posterior median
  (``summary['median']``; distance in units of the draws' sd per parameter), re-simulated from its draw
  ``draws[i]`` and its seed (the seed key ``(config.seed, Tag.PREDICTIVE, i)`` of
  :func:`analysis.calibration.data_model.predictive_runs`) and checked: its bare statistics (the flock
  columns, and the targets when no noise is added to them) must equal row i of ``predictive``/``flock`` bit
  for bit (:func:`predictive_track` raises :class:`NotReproduced`; the page is then not written and the
  warning names the differing columns). It is shown as simulated (before the observation model's
  projection, missed detections and noise), recorded at the observation's interval.

Both use the calibration's fixed group radius, so the groups drawn are the groups the flock check counts.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from flocksweep.analysis.viewer.hooks import preset_page
from flocksweep.analysis.viewer.page import build_page, build_runs_page
from flocksweep.analysis.viewer.track import from_observations, from_observed
from flocksweep.sweeps.seeds import Tag, generator, seeds_for

from .emulated import observation_covariance
from .flock_check import flock_columns
from .simulator import SummarySimulator, summary_simulator

MEDIAN_PAGE = "viewer_posterior_median.html"
PREDICTIVE_PAGE = "viewer_predictive.html"
COLOR_BY = "group"


class NotReproduced(RuntimeError):
    """The re-simulated predictive run's statistics differ from the predictive check's."""


def posterior_median_page(config, summary, out_dir) -> Path:
    """The calibration's model at the posterior median (see the module docstring)."""
    theta = median_theta(config, summary)
    info = {"calibration": config.name, "seed": config.seed,
            **{f"median {name}": f"{value:.4g}" for name, value in zip(config.names, theta)}}
    if config.command is not None:      # an external simulator: its tracks, as measured
        flock, _ = summary_simulator(config, n_sim=1).run(theta, config.seed)
        track = from_observed(flock, title=f"{config.name}: a run at the posterior median", info=info,
                              group_radius=config.metrics.group_radius)
        return build_page(track, color_by=COLOR_BY).save(Path(out_dir) / MEDIAN_PAGE)
    simulator = SummarySimulator(config.preset_data, config.keys, config.targets.columns, 1, config.metrics.warmup)
    preset = simulator.preset(theta)
    return preset_page(preset, config.seed, Path(out_dir) / MEDIAN_PAGE,
                       title=f"{config.name}: a run at the posterior median", info=info)


def median_theta(config, summary) -> np.ndarray:
    return np.array([float(summary.loc[name, "median"]) for name in config.names])


def nearest_draw(draws: np.ndarray, centre: np.ndarray) -> int:
    """Index of the draw closest to ``centre``, each parameter in units of the draws' sd (1 where it is 0)."""
    sd = draws.std(axis=0)
    scaled = (draws - centre) / np.where(sd > 0, sd, 1.0)
    return int(np.argmin((scaled ** 2).sum(axis=1)))


def predictive_page(config, summary, draws, predictive, flock, out_dir) -> tuple[Path | None, list[str]]:
    """(the page, warnings): the measured flock beside a posterior predictive run (see the module docstring);
    no page and no warning without tracks targets, no page and a warning when the run does not reproduce."""
    targets = config.targets
    if not targets.flock_tracks:
        return None, []
    shown = targets.flock_tracks[0]
    i = nearest_draw(np.asarray(draws, dtype=float), median_theta(config, summary))
    data = from_observed(shown, title=f"{config.name}: measured flock {shown.name}",
                         info={"source": Path(targets.tracks_path).name, "flock": shown.name},   # no folder: a page is shared
                         group_radius=config.metrics.group_radius, tank=targets.tank)
    try:
        run = predictive_track(config, draws[i], i, np.concatenate([predictive[i], flock[i]]))
    except NotReproduced as err:
        return None, [f"no {PREDICTIVE_PAGE}: {err}"]
    page = build_runs_page([data, run], [f"data-{shown.name}", f"predictive-{i}"], color_by=COLOR_BY)
    return page.save(Path(out_dir) / PREDICTIVE_PAGE), []


def predictive_track(config, theta, i: int, stored_row: np.ndarray):
    """Predictive run ``i`` (draw ``theta``) re-simulated, checked against ``stored_row``, as a Track."""
    simulator = summary_simulator(config, n_sim=1, extra_columns=flock_columns(config))
    seed = seeds_for(generator(config.seed, Tag.PREDICTIVE, i), 1)[0]   # as predictive_runs seeds run i
    obs, row = simulator.run(np.asarray(theta, dtype=float), seed)
    k = len(config.targets.columns)
    bare = np.arange(len(row)) >= (k if observation_covariance(config) is not None else 0)
    differing = [c for c, a, b, same in zip(simulator.columns, row, stored_row, bare)
                 if same and not (a == b or (np.isnan(a) and np.isnan(b)))]
    if differing:
        raise NotReproduced(f"predictive run {i} re-simulated differs in {', '.join(differing)}")
    values = {name: f"{value:.4g}" for name, value in zip(config.names, np.asarray(theta, dtype=float))}
    shift = config.metrics.warmup - config.targets.tracks_warmup
    title = f"{config.name}: predictive run {i} (nearest the posterior median)"
    info = {"calibration": config.name, "predictive run": f"{i} (its draw nearest the posterior median)",
            "seed": seed, **values,
            "reproduced": f"bit for bit ({int(bare.sum())} statistics of the predictive check)",
            "clock": f"the tracks' (t = 0 is the run's {shift:g} s: run.warmup {config.metrics.warmup:g} s less "
                     f"the tracks' warmup {config.targets.tracks_warmup:g} s)"}
    if config.command is not None:   # an external simulator's run: its tracks as measured
        track = from_observed(obs, title=title, info={**info, "shown": "as measured (the command's tracks)"},
                              group_radius=config.metrics.group_radius)
    else:
        track = from_observations(obs, simulator.preset(theta), title=title,
                                  info={**info, "shown": "as simulated, before the observation model"},
                                  group_radius=config.metrics.group_radius)
    return track.since(shift, shift)
