"""A calibration from measured tracks writes viewer_predictive.html: the measured flock and the posterior
predictive run nearest the posterior median as two runs of one page, same clock and colouring; the run is
re-simulated and checked against the predictive check's statistics (analysis.calibration.viewer_page)."""
from __future__ import annotations

import re
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

from flocksweep.analysis.calibration.config import load_calibration
from flocksweep.analysis.calibration.flock_check import flock_columns
from flocksweep.analysis.calibration.run import predictive_runs
from flocksweep.analysis.calibration.viewer_page import (PREDICTIVE_PAGE, NotReproduced, nearest_draw, predictive_page,
                                              predictive_track)
from flocksweep.cli import main
from test_tracks_targets import THETA, calibration_text, runs, tracks, write_config  # noqa: F401 - fixtures

def test_the_draw_nearest_the_median_is_measured_in_units_of_each_parameters_spread():
    draws = np.array([[0.0, 0.0], [10.0, 1.0], [1.0, 10.0], [-10.0, -1.0]])
    # sd of the columns ~7.1 and ~4.2: [10, 1] is nearer (10, 5) than [1, 10] in those units
    assert nearest_draw(draws, np.array([10.0, 5.0])) == 1
    assert nearest_draw(np.array([[3.0, 1.0], [3.0, 2.0]]), np.array([3.0, 2.2])) == 1   # a constant column


@pytest.mark.slow
def test_the_predictive_run_is_reproduced_or_refused(tracks, tmp_path):
    config = load_calibration(write_config(tmp_path, calibration_text(tracks.name)))
    draws = np.array([THETA, (14.0, 5.0)])
    targets, flock = predictive_runs(config, draws)
    track = predictive_track(config, draws[1], 1, np.concatenate([targets[1], flock[1]]))
    assert track.n == 10 and track.info["reproduced"].startswith("bit for bit")
    assert np.allclose(np.diff(track.times), 0.2)            # recorded at the observation's interval
    # on the tracks' clock: the run's 1 s warm-up (the tracks have none) is t = 0, the run's 3 s is 2 s
    assert track.times[0] == 0.0 and track.frames == 11 and track.times[-1] == pytest.approx(2.0, abs=1e-12)
    assert track.info["clock"] == "the tracks' (t = 0 is the run's 1 s: run.warmup 1 s less the tracks' warmup 0 s)"
    changed = np.concatenate([targets[1], flock[1]])
    changed[len(config.targets.columns) + 1] = np.nextafter(changed[len(config.targets.columns) + 1], np.inf)
    with pytest.raises(NotReproduced, match=flock_columns(config)[1]):
        predictive_track(config, draws[1], 1, changed)
    with pytest.raises(NotReproduced):                        # run 0's statistics are not run 1's
        predictive_track(config, draws[1], 0, np.concatenate([targets[1], flock[1]]))


@pytest.mark.slow
def test_no_page_without_tracks_targets(tracks, tmp_path):
    config = load_calibration(write_config(tmp_path, calibration_text(tracks.name)))
    summary = pd.DataFrame({"median": THETA}, index=list(config.names))
    draws, none = np.array([THETA]), np.zeros((1, 20))
    assert len(config.targets.flock_tracks) == 5
    typed = replace(config, targets=replace(config.targets, flock_tracks=()))
    assert predictive_page(typed, summary, draws, none, none, tmp_path) == (None, [])
    assert not (tmp_path / PREDICTIVE_PAGE).exists()


@pytest.mark.slow
def test_a_predictive_run_that_does_not_reproduce_gets_no_page_and_a_warning(tracks, tmp_path):
    config = load_calibration(write_config(tmp_path, calibration_text(tracks.name)))
    summary = pd.DataFrame({"median": THETA}, index=list(config.names))
    draws = np.array([THETA])
    targets, flock = predictive_runs(config, draws)
    page, warnings = predictive_page(config, summary, draws, targets, flock, tmp_path)
    assert page == tmp_path / PREDICTIVE_PAGE and warnings == []
    assert str(tracks.resolve().parent) not in page.read_text()   # no path of the machine it was made on
    page.unlink()
    flock[0, 0] += 1.0                                         # not what run 0 measured
    page, warnings = predictive_page(config, summary, draws, targets, flock, tmp_path)
    column = flock_columns(config)[0]
    assert page is None and warnings == [f"no {PREDICTIVE_PAGE}: predictive run 0 re-simulated differs in {column}"]
    assert not (tmp_path / PREDICTIVE_PAGE).exists()


def _runs_of(page_text: str) -> list[str]:
    return re.findall(r'data-run="([^"]+)"', page_text)


@pytest.mark.slow
def test_a_calibration_from_tracks_shows_the_measured_flock_beside_a_predictive_run(tracks, tmp_path):
    from browser import Browser

    path = write_config(tmp_path, calibration_text(tracks.name))
    out = tmp_path / "out"
    assert main(["calibrate", str(path), "--out", str(out), "--no-progress"]) == 0
    page = out / PREDICTIVE_PAGE
    text = page.read_text()
    assert str(tmp_path) not in text                             # the tracks file by name, no folder of this machine
    ids = _runs_of(text)
    assert ids[0] == "data-flock0" and len(ids) == 2 and ids[1].startswith("predictive-")
    assert re.findall(r'data-label="([^"]+)"', text) == ids     # a measured flock has no parameters to compare
    with Browser() as browser:
        data = browser.open(page)
        assert data.errors == [] and data.blocked == []
        assert data.state("run") == "data-flock0" and data.state("runs") == ids
        assert data.state("n") == 10 and data.state("colorBy") == "group"
        assert data.page.inner_text("#title") == "tracks_test: measured flock flock0"
        assert "10 of 10" in data.page.inner_text("#info")
        data.page.close()
        run = browser.open(page, fragment="run=predictive&t=1.0")
        assert run.errors == [] and run.blocked == []
        assert run.state("run") == ids[1] and run.state("colorBy") == "group"
        assert abs(run.state("time") - 1.0) < 1e-6 and run.state("n") == 10
        assert "predictive run" in run.page.inner_text("#title")
        panel = run.page.inner_text("#info")
        assert "bit for bit" in panel and "t = 0 is the run's 1 s" in panel
        assert run.state("frames") == 11                      # the run's 1-3 s on the tracks' 0-2 s
        run.page.close()
