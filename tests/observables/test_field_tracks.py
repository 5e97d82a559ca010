"""Tracks as they come from the field (issue 44): arrays with extra channels, detection tables in array
files, zero padding and trims, units a format implies merged before they are checked, and a speed check
that tells a group's burst from one tracker glitch. Every fixture is built here, small."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import scipy.io

from flocksweep.observables.measured import measure_tracks, track_settings
from flocksweep.observables.tracks import TrackSource, load_tracks, raw_flocks, track_source
from flocksweep.observables.validation import TrackError, check_flock
from flocksweep.simcore.schema import ConfigError

RADIUS = 5.0


def flight(n: int = 5, samples: int = 30, fps: float = 10.0, seed: int = 1) -> dict:
    """A 2-D flight: (n, samples) positions and velocities (m, m/s), a slow turn plus a little wobble."""
    rng = np.random.default_rng(seed)
    t = np.arange(samples) / fps
    heading = 0.3 * t[None, :] + rng.normal(0, 0.05, (n, samples))
    vel = np.stack([np.cos(heading), np.sin(heading)], -1) * (2.0 + 0.1 * np.arange(n))[:, None, None]
    pos = np.cumsum(vel, axis=1) / fps + np.stack([np.arange(n) * 1.5, np.zeros(n)], -1)[:, None, :]
    return {"t": t, "pos": pos, "vel": vel, "fps": fps}


def long_csv(data: dict, path, extra_columns: bool = False):
    n, s = data["pos"].shape[:2]
    frame = pd.DataFrame({"id": np.repeat(np.arange(1, n + 1), s), "t": np.tile(data["t"], n),
                          "x": data["pos"][..., 0].reshape(-1), "y": data["pos"][..., 1].reshape(-1),
                          "vx": data["vel"][..., 0].reshape(-1), "vy": data["vel"][..., 1].reshape(-1)})
    frame.to_csv(path, index=False)
    return path


def measured(path, velocity="recorded", **given):
    table = load_tracks(path, track_source(path, given))
    result = measure_tracks(table, track_settings(RADIUS, dcd_max_delay=0.0), velocity_interval=velocity)
    return table, result


def same_rows(a, b, columns=("records", "tracked_mean", "polarization_mean", "nn_distance_mean", "speed_mean_mean")):
    for column in columns:
        assert a[column].tolist() == b[column].tolist(), column


# ------------------------------------------------------------------------------------- channels (point 2)

def seven_channels(data: dict) -> np.ndarray:
    """(birds, channels, samples): x, y, vx, vy, then two accelerations and a quality score."""
    pos, vel = data["pos"], data["vel"]
    acc = np.gradient(vel, axis=1) * data["fps"]
    quality = np.full(pos.shape[:2], 0.9)
    return np.stack([pos[..., 0], pos[..., 1], vel[..., 0], vel[..., 1], acc[..., 0], acc[..., 1], quality], axis=1)


def test_a_mat_array_with_more_channels_than_positions_and_velocities_is_read_by_skipping_them(tmp_path):
    data = flight()
    path = tmp_path / "flight.mat"
    scipy.io.savemat(path, {"birds": seven_channels(data)})
    reference = long_csv(data, tmp_path / "flight.csv")
    _, expected = measured(reference, fps=None)
    for channels in ("x,y,vx,vy,-,-,-", "x:0,y:1,vx:2,vy:3"):
        table, got = measured(path, layout={"channels": channels}, fps=data["fps"], units={"length": "m"})
        assert table.has_velocity and table.dims == 2
        same_rows(got.runs, expected.runs)
        notes = [i.detail for i in table.issues if i.check == "reading"]
        assert notes == ["channels 4, 5, 6 of 'birds' skipped"]
    with pytest.raises(ConfigError, match=r"layout.channels: names 4 channels, the array has 7 \(name the others - "
                                          r"to skip them: x,y,vx,vy,-,-,-\)"):
        load_tracks(path, TrackSource(layout={"channels": "x,y,vx,vy"}, fps=10.0))
    with pytest.raises(ConfigError, match=r"layout.chanels: unknown layout key \(did you mean 'channels'\?\)"):
        load_tracks(path, TrackSource(layout={"chanels": "x,y,vx,vy,-,-,-"}, fps=10.0))


def test_a_numpy_cube_reads_like_the_mat_one(tmp_path):
    data = flight()
    np.save(tmp_path / "birds.npy", np.transpose(seven_channels(data), (2, 0, 1)))   # samples, birds, channels
    _, expected = measured(long_csv(data, tmp_path / "f.csv"))
    table, got = measured(tmp_path / "birds.npy", layout={"channels": "x,y,vx,vy,-,-,-",
                                                          "axes": "sample,individual,channel"}, fps=10.0)
    assert table.source.format == "npy"
    same_rows(got.runs, expected.runs)


# ------------------------------------------------------------------------------ detection tables (point 1)

def detection_table(data: dict, frames: bool = False) -> np.ndarray:
    """One row per bird per sample: id, x, y, z, time (s, or frame), vx, vy, vz, then two more columns."""
    n, s = data["pos"].shape[:2]
    rows = []
    for i in range(n):
        for k in range(s):
            rows.append([i + 1, *data["pos"][i, k], 0.0, k if frames else data["t"][k], *data["vel"][i, k], 0.0,
                         7.0, -1.0])
    return np.array(rows)


def test_a_mat_detection_table_is_read_by_naming_its_columns(tmp_path):
    data = flight()
    path = tmp_path / "detections.mat"
    scipy.io.savemat(path, {"det": detection_table(data), "fps": 10.0, "label": "flight 3"})
    _, expected = measured(long_csv(data, tmp_path / "f.csv"))
    table, got = measured(path, layout={"columns": "id,x,y,z,t,vx,vy,vz,-,-"})
    assert table.dims == 3 and table.has_velocity and sorted(table.frame["id"].unique()) == [1, 2, 3, 4, 5]
    same_rows(got.runs, expected.runs)
    frames = tmp_path / "frames.mat"
    scipy.io.savemat(frames, {"det": detection_table(data, frames=True).T})      # stored one column per detection
    _, by_frame = measured(frames, layout={"columns": "id:0,x:1,y:2,z:3,frame:4,vx:5,vy:6,vz:7",
                                           "axes": "column,detection"}, fps=10.0)
    same_rows(by_frame.runs, expected.runs)


def test_an_array_file_no_layout_fits_is_refused_naming_its_arrays_and_the_routes(tmp_path):
    path = tmp_path / "detections.mat"
    scipy.io.savemat(path, {"det": detection_table(flight()), "fps": 10.0, "label": "flight 3"})
    with pytest.raises(ConfigError) as caught:
        load_tracks(path, TrackSource())
    text = str(caught.value)
    assert "it holds: det (150 x 10), fps (1 x 1), label (1, char)" in text
    assert "columns=id,t,x,y,z" in text and "channels=x,y,vx,vy" in text and "long CSV" in text
    np.save(tmp_path / "table.npy", detection_table(flight()))
    _, got = measured(tmp_path / "table.npy", layout={"columns": "id,x,y,z,t,vx,vy,vz,-,-"})
    assert got.runs["records"].tolist() == [30]


# ------------------------------------------------------------------------------- padding and trim (point 3)

def padded(data: dict) -> dict:
    """The logger's padding: one more sample for everyone, velocities exactly zero, positions repeated."""
    pos = np.concatenate([data["pos"], data["pos"][:, -1:]], axis=1)
    vel = np.concatenate([data["vel"], np.zeros_like(data["vel"][:, -1:])], axis=1)
    return {**data, "pos": pos, "vel": vel, "t": np.arange(pos.shape[1]) / data["fps"]}


def test_zero_padding_is_dropped_by_default_with_one_warning_and_kept_on_request(tmp_path):
    data = flight()
    _, clean = measured(long_csv(data, tmp_path / "clean.csv"))
    path = long_csv(padded(data), tmp_path / "padded.csv")
    _, got = measured(path)
    same_rows(got.runs, clean.runs)
    (warning,) = [i for i in got.issues if i.check == "padding"]
    assert warning.level == "warning" and "1 trailing sample time(s) (t = 3 s)" in warning.detail
    assert "left out" in warning.detail and len(warning.rows) == 5
    assert not [i for i in got.issues if i.check == "velocity"]        # no velocity warning per individual
    _, kept = measured(path, keep_padding=True)
    assert kept.runs["records"].tolist() == [31]
    assert [i.detail.endswith("kept (keep_padding)") for i in kept.issues if i.check == "padding"] == [True]
    _, trimmed = measured(path, keep_padding=True, trim="0:-1")     # the same by a trim of the last sample
    same_rows(trimmed.runs, clean.runs)
    _, seconds = measured(path, keep_padding=True, trim=":-0.05s")
    same_rows(seconds.runs, clean.runs)


def test_trims_count_samples_or_seconds_from_either_end_and_a_bad_trim_is_named():
    from flocksweep.observables.clock import sampling_clock
    from flocksweep.observables.trimming import parse_trim, trim_flock
    from flocksweep.observables.tracks import RawFlock
    t = np.tile(np.arange(20) * 0.1, 2)
    raw = RawFlock("A", np.arange(2), t, np.repeat([0, 1], 20), np.zeros((40, 3)))
    clock = sampling_clock(raw.t, raw.ind)
    for text, kept in (("5:", (0.5, 1.9)), (":-5", (0.0, 1.4)), ("2:4", (0.2, 0.3)), ("0.5s:", (0.5, 1.9)),
                       (":1s", (0.0, 0.9)), ("-0.35s:", (1.6, 1.9))):
        cut, _ = trim_flock(raw, parse_trim(text), clock)
        assert (cut.t.min(), cut.t.max()) == pytest.approx(kept), text
    _, (issue,) = trim_flock(raw, parse_trim("30:"), clock)
    assert issue.level == "error" and "leaves no sample" in issue.detail
    for bad in ("5", "a:b", "1.5:", "1:2:3"):
        with pytest.raises(ConfigError, match=r"^trim: got"):
            TrackSource(trim=bad)


# --------------------------------------------------------------------------------------- units (point 4)

def test_a_formats_pixel_unit_is_merged_before_the_body_length_in_pixels_is_checked(tmp_path):
    traj = np.transpose(flight()["pos"], (1, 0, 2)) * 30.0                      # frames x fish x 2, pixels
    np.save(tmp_path / "fish.npy", {"trajectories": traj, "frames_per_second": 10.0, "body_length": 30.0},
            allow_pickle=True)
    table, got = measured(tmp_path / "fish.npy", velocity=None, body_length_px=60.0)   # once refused
    assert table.source.body_length_px == 60.0 and table.unit_label == "BL"
    scales = table.source.scales()
    assert scales["body length (px)"] == {"value": 60.0, "from": "given"}
    assert scales["fps"] == {"value": 10.0, "from": "file"} and scales["length unit"]["from"] == "file"
    np.save(tmp_path / "bare.npy", traj)                                        # no stored rate or body length
    with pytest.raises(ConfigError, match="fps: the times are frame numbers"):
        load_tracks(tmp_path / "bare.npy", TrackSource())
    with pytest.raises(ConfigError, match=r"body_length_px: the positions are in pixels \(units.length = \"px\", "
                                          r"from the file\)"):
        load_tracks(tmp_path / "bare.npy", TrackSource(fps=10.0))
    bare, _ = measured(tmp_path / "bare.npy", velocity=None, fps=10.0, body_length_px=30.0)
    assert bare.unit_label == "BL" and bare.source.scales()["fps"]["from"] == "given"


def test_a_calibration_tracks_table_takes_the_same_settings(tmp_path):
    from flocksweep.analysis.calibration.tracks_targets import TracksTable
    traj = np.transpose(flight()["pos"], (1, 0, 2)) * 30.0
    np.save(tmp_path / "fish.npy", {"trajectories": traj, "frames_per_second": 10.0}, allow_pickle=True)
    source = track_source(tmp_path / "fish.npy", {"body_length_px": 30.0, "trim": "2:", "keep_padding": True},
                          "targets.tracks", cls=TracksTable)
    table = load_tracks(tmp_path / "fish.npy", source)
    assert table.unit_label == "BL" and isinstance(table.source, TracksTable) and table.source.trim == "2:"
    with pytest.raises(ConfigError, match="targets.tracks.origins: unknown key"):
        track_source(tmp_path / "fish.npy", {"origins": {}}, "targets.tracks", cls=TracksTable)


# ------------------------------------------------------------------------------- bursts and glitches (point 6)

def startle(tmp_path, glitch: bool = True):
    """20 fish swimming straight at 1 m/s; at t = 5 s the whole school bolts (15 m/s for 0.5 s, the fish
    starting within the same five frames), and one tracker glitch: fish 7 jumps 25 m for one sample at 12 s."""
    fps, rows = 10.0, []
    for i in range(20):
        x, start = 0.0, 50 + (i % 5)
        for k in range(200):
            speed = 15.0 if start <= k < start + 5 else 1.0
            x += speed / fps
            rows.append({"id": i, "t": k / fps, "x": x + (25.0 if glitch and i == 7 and k == 120 else 0.0),
                         "y": 2.0 * i})
    path = tmp_path / "school.csv"
    pd.DataFrame(rows).to_csv(path, index=False)
    return path, rows


def test_a_group_burst_is_kept_and_one_glitch_is_refused_naming_the_rule(tmp_path):
    path, rows = startle(tmp_path)
    table = load_tracks(path, TrackSource())
    with pytest.raises(TrackError) as caught:
        measure_tracks(table, track_settings(RADIUS, dcd_max_delay=0.0))
    (error,) = caught.value.issues
    glitch_row = next(r for r, row in enumerate(rows, 1) if row["id"] == 7 and row["t"] == 12.0)
    assert error.rule == "glitch" and error.rows == (glitch_row,) and error.detail.startswith("glitch: 1 samples")
    dropped = measure_tracks(load_tracks(path, TrackSource(bad_speeds="drop")), track_settings(RADIUS, dcd_max_delay=0.0))
    (burst,) = [i for i in dropped.issues if i.rule == "burst"]
    assert burst.level == "note" and "a burst of the group, kept as motion" in burst.detail
    assert "individuals 0, 1, 10, 11, 12, 13, 14, 15, 16, 17 ..." in burst.detail
    assert [i.rule for i in dropped.issues if i.check == "speed"] == ["burst", "glitch"]
    series = dropped.timeseries.set_index(np.round(dropped.timeseries["t"], 6))
    for k in range(48, 58):       # the bolt is measured: record k differences samples k and k + 1
        fast = [50 + i % 5 <= k + 1 < 55 + i % 5 for i in range(20)]
        assert series.loc[round(k / 10, 6), "speed_mean"] == pytest.approx(np.mean(np.where(fast, 15.0, 1.0)))
    # the rule is settable: demand a jump of 20 times the usual speed (the bolt is 15) and it is refused too
    strict = load_tracks(path, TrackSource(burst_jump=20.0))
    with pytest.raises(TrackError) as refused:
        measure_tracks(strict, track_settings(RADIUS, dcd_max_delay=0.0))
    assert sum(i.rule == "glitch" for i in refused.value.issues) == 1 and "20 individuals" not in str(refused.value)
    assert len(refused.value.issues[0].rows) > 50


def test_the_impossible_speed_rows_are_listed_in_file_order(tmp_path):
    rows = [{"id": i, "t": k * 0.1, "x": k * 0.1 + (30.0 if k == 25 - 10 * i else 0.0), "y": 3.0 * i}
            for k in range(30) for i in range(3)]                     # time-major: file order is not id order
    path = tmp_path / "t.csv"
    pd.DataFrame(rows).to_csv(path, index=False)
    (flock,), _ = raw_flocks(load_tracks(path, TrackSource()))
    _, issues = check_flock(flock, 0.1, 0.25)
    (issue,) = [i for i in issues if i.check == "speed"]
    assert list(issue.rows) == sorted(issue.rows) and len(issue.rows) == 3


# --------------------------------------------------------------------------------------- smaller (point 8)

def test_the_velocity_warning_gives_the_vector_difference_it_fired_on(tmp_path):
    data = flight(samples=12)
    data["vel"][2, 6] = data["vel"][2, 6][::-1]                      # a velocity pointing the wrong way
    _, got = measured(long_csv(data, tmp_path / "t.csv"))
    (issue,) = [i for i in got.issues if i.check == "velocity"]
    assert "|recorded - from positions| = " in issue.detail and "x the speed" in issue.detail


# ------------------------------------------------------------------------------- projections (point 5)

def planar_run(records: int = 30, n: int = 6):
    """A run of a 2-D model: motion in the x-y plane, z = 0."""
    from types import SimpleNamespace
    t = np.arange(records) * 0.1
    angle = 0.5 * t[:, None] + np.arange(n)[None, :]
    pos = np.stack([4 * np.cos(angle), 4 * np.sin(angle), np.zeros_like(angle)], -1)
    vel = np.stack([-2 * np.sin(angle), 2 * np.cos(angle), np.zeros_like(angle)], -1)
    return SimpleNamespace(times=t, pos=pos, vel=vel, pattern=np.zeros(n, dtype=np.int64), dt=0.1, record_every=1)


def test_a_projection_that_drops_the_plane_a_2d_world_moves_in_is_refused():
    from flocksweep.analysis.calibration.tracks_targets import check_observation
    from flocksweep.observables.observation import Observation, check_projection, observe_run
    from flocksweep.simcore import load_preset
    from flocksweep.sweeps.config import RunTable
    from paths import ROOT
    preset = load_preset(ROOT / "configs/models/vicsek.toml")
    assert preset.model.world.dimensions == 2
    with pytest.raises(ConfigError, match=r"observation.projection: got 'xz', which drops y; the model's 2-D world "
                                          r"moves in the x-y plane"):
        check_observation(Observation(interval=preset.run.dt, projection="xz"), preset, RunTable(), ["polarization"])
    check_projection(Observation(interval=0.1, projection="xy"), 2)
    check_projection(Observation(interval=0.1, projection="xz"), 3)           # a 3-D flock seen from above
    run = planar_run()
    with pytest.raises(ValueError, match=r"projection 'yz' drops x, along which the run moves: it moves in the x-y "
                                         r"plane \(z is constant\)"):
        observe_run(run, Observation(interval=0.1, projection="yz"), 0)
    flat = observe_run(run, Observation(interval=0.1), 0)
    assert flat.dims == 2                                                       # a 2-D run is seen as 2-D tracks


def test_a_2d_runs_own_tracks_read_back_as_2d(tmp_path):
    from flocksweep.observables.tracks import tracks_frame
    frame = tracks_frame(planar_run(), "flat")
    assert "z" not in frame.columns and "vz" not in frame.columns
    frame.to_csv(tmp_path / "tracks.csv", index=False)
    table = load_tracks(tmp_path / "tracks.csv", TrackSource(units={"length": "bl"}))
    assert table.dims == 2 and table.has_velocity
