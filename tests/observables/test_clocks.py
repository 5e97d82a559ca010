"""Exact clocks (observables.clock): tracks sampled at 60 and 120 fps over more than 10,000 records, with
staggered starts and ends, given as frame numbers, as double-precision seconds and as single-precision
seconds, give exactly the records and detections of their frames, and every per-record figure computed
here from the frames (forward differences over one frame), to 1e-9 (the stamps' rounding only)."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from flocksweep.observables.clock import sampling_clock
from flocksweep.observables.measured import measure_tracks, track_settings
from flocksweep.observables.tracks import TrackSource, load_tracks

FRAMES = 10_002                                   # frames 0 .. 10,001: 10,001 records of forward differences
SPANS = ((0, FRAMES - 1), (13, FRAMES - 40), (250, FRAMES - 1), (0, FRAMES - 7))   # staggered starts and ends


def position(i: int, frame: np.ndarray, fps: float) -> np.ndarray:
    t = frame / fps
    return np.stack([2.0 * i + (1.0 + 0.1 * i) * t, 3.0 * i + 0.5 * np.sin(0.7 * t + i), 0.2 * np.cos(0.3 * t)], -1)


def tracks(fps: float) -> pd.DataFrame:
    parts = []
    for i, (first, last) in enumerate(SPANS):
        frame = np.arange(first, last + 1)
        pos = position(i, frame, fps)
        parts.append(pd.DataFrame({"id": i, "frame": frame, "x": pos[:, 0], "y": pos[:, 1], "z": pos[:, 2]}))
    return pd.concat(parts, ignore_index=True)


def expected(fps: float) -> dict:
    """Records k = 0 .. FRAMES - 2 (the last frame only ends a difference): who is present, their mean speed
    and mean nearest-neighbour distance, from the frames."""
    records = FRAMES - 1
    present = np.zeros((records, len(SPANS)), dtype=bool)
    speed = np.full((records, len(SPANS)), np.nan)
    pos = np.full((records, len(SPANS), 3), np.nan)
    k = np.arange(records)
    for i, (first, last) in enumerate(SPANS):
        here = (k >= first) & (k + 1 <= last)
        present[:, i] = here
        step = position(i, k + 1, fps) - position(i, k, fps)
        speed[here, i] = np.linalg.norm(step[here], axis=1) * fps
        pos[here, i] = position(i, k[here], fps)
    distance = np.linalg.norm(pos[:, :, None] - pos[:, None, :], axis=-1)
    distance[:, np.arange(len(SPANS)), np.arange(len(SPANS))] = np.inf
    nearest = np.where(present, np.nanmin(np.where(np.isnan(distance), np.inf, distance), axis=2), np.nan)
    return {"records": records, "tracked": present.sum(axis=1).astype(float),
            "speed_mean": np.nanmean(speed, axis=1), "nn_distance": np.nanmean(nearest, axis=1)}


@pytest.fixture(scope="module", params=[60.0, 120.0], ids=["60fps", "120fps"])
def case(request):
    return request.param, tracks(request.param), expected(request.param)


def _measure(path, source):
    table = load_tracks(path, source)
    measured = measure_tracks(table, track_settings(50.0, dcd_max_delay=0.0), velocity_interval=None)   # no DCD: time
    return measured.runs.iloc[0], measured.timeseries


@pytest.mark.parametrize("clock", ["frames", "double seconds", "single seconds", "single seconds in a CSV"])
def test_every_record_and_detection_is_kept_and_the_figures_are_the_frames_own(case, clock, tmp_path):
    fps, frame, truth = case
    frame = frame.copy()
    if clock == "frames":
        frame["t"], source = frame.pop("frame").astype(float), TrackSource(units={"time": "frame"}, fps=fps)
    else:
        seconds = frame.pop("frame") / fps
        frame["t"] = seconds.astype(np.float32) if clock.startswith("single") else seconds
        source = TrackSource()
    path = tmp_path / ("t.csv" if clock.endswith("CSV") else "t.parquet")
    frame.to_csv(path, index=False) if path.suffix == ".csv" else frame.to_parquet(path, index=False)
    if clock.endswith("CSV"):
        assert "0.016666668" in path.read_text() or "0.008333334" in path.read_text()   # float32 as printed
    row, series = _measure(path, source)
    assert row["records"] == truth["records"] == len(series)
    assert np.array_equal(series["tracked"].to_numpy(), truth["tracked"])
    assert row["tracked_mean"] == truth["tracked"].mean()
    np.testing.assert_allclose(series["speed_mean"].to_numpy(), truth["speed_mean"], rtol=1e-9)
    np.testing.assert_allclose(series["nn_distance"].to_numpy(), truth["nn_distance"], rtol=1e-9)
    np.testing.assert_allclose(series["t"].to_numpy(), np.arange(truth["records"]) / fps, rtol=0, atol=1e-9)
    assert row["interval"] == 1 / fps
    words = {"frames": f"frame numbers at {fps:g} frames per second", "double seconds": "(double precision)",
             "single seconds": "single precision", "single seconds in a CSV": "single precision"}[clock]
    assert words in row["clock"]


def test_the_interval_of_frame_numbers_is_exact_and_of_stamps_is_found_without_rounding():
    t = np.arange(5000) / 60.0
    ind = np.zeros(5000, dtype=np.int64)
    assert sampling_clock(t * 60.0 * (1 / 60.0), ind, frame_seconds=1 / 60.0).interval == 1 / 60.0
    stamps = sampling_clock(t, ind)
    assert stamps.precision == "exact" and stamps.interval == 1 / 60.0          # the rate 60, not 0.0166666667
    single = sampling_clock(t.astype(np.float32).astype(np.float64), ind)
    assert single.precision == "single" and single.interval == 1 / 60.0
    jittered = t + np.random.default_rng(1).uniform(-0.003, 0.003, len(t))
    loose = sampling_clock(jittered, ind)
    assert loose.precision == "irregular" and abs(loose.interval - 1 / 60.0) < 1e-3
    tenths = sampling_clock(np.arange(31) * 0.1, np.zeros(31, dtype=np.int64))
    assert tenths.interval == 0.1 and tenths.precision == "exact"     # the shortest decimal that fits
