"""Trackers' and loggers' files (observables.track_formats): each format written by the test from a
simulated run and measured back gives the simulator's own metrics (or, for 2-D formats and formats
without velocities, exactly what the observation model makes of the run)."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from flocksweep.observables.columns import PERCEPTION_SERIES
from flocksweep.observables.measured import measure_tracks, track_settings
from flocksweep.observables.observation import Observation, observe_run
from flocksweep.observables.summary import MetricSettings, measure_run, summarize_run
from flocksweep.observables.track_formats import detect_format, project_wgs84
from flocksweep.observables.tracks import TrackSource, load_tracks, track_source
from flocksweep.simcore import load_preset, simulate_preset
from flocksweep.simcore.schema import ConfigError
from paths import ROOT

RADIUS = 4.0
FPS = 8.0          # records every 0.125 s: frame / 8 is the simulator's record time exactly


@pytest.fixture(scope="module")
def run():
    preset = load_preset(ROOT / "configs/models/holland.toml",
                         ["init.n=8", "run.duration=3.0", "run.dt=0.0625", "run.record_interval=0.125",
                          "init.radius=5.0"])
    obs = simulate_preset(preset, 3)
    assert np.array_equal(obs.times, np.arange(len(obs.times)) / FPS)
    return preset, obs


def own_row(preset, obs) -> dict:
    return measure_run(obs, MetricSettings(warmup=0.0, group_radius=RADIUS).resolve(preset.model))[1]


def observed_row(obs, velocity_interval, projection) -> dict:
    observation = Observation(interval=1 / FPS, velocity_interval=velocity_interval, projection=projection)
    return summarize_run(observe_run(obs, observation, 0), track_settings(RADIUS))


def measure(path, velocity_interval="recorded", **given):
    table = load_tracks(path, track_source(path, given))
    measured = measure_tracks(table, track_settings(RADIUS), velocity_interval=velocity_interval)
    (row,) = measured.runs.to_dict("records")
    assert row["status"] == "ok"
    return table, row


def assert_same(got: dict, expected: dict, rtol: float = 0.0):
    for column, value in expected.items():
        if column.startswith(PERCEPTION_SERIES):
            continue
        if rtol:   # a turning rate of 0 (boids flying straight) comes back as ~1e-5 degrees/s after rounding
            atol = 1e-4 if column.startswith("turn_rate") else 1e-12
            assert np.allclose(got[column], value, rtol=rtol, atol=atol, equal_nan=True), column
        else:
            assert np.array_equal(got[column], value, equal_nan=True), column


# ------------------------------------------------------------------------------------------- writers

def cube(obs, channels) -> np.ndarray:
    """(individuals, channels, samples) of the run's records."""
    parts = {**{a: obs.pos[:, :, k] for k, a in enumerate("xyz")}, **{f"v{a}": obs.vel[:, :, k] for k, a in enumerate("xyz")}}
    return np.stack([parts[c].T for c in channels], axis=1)


def write_mat_v73(path, name: str, array: np.ndarray):
    """An HDF5 .mat file as MATLAB 7.3 writes one: a 512-byte header, the array's dimensions reversed."""
    import h5py
    with h5py.File(path, "w", userblock_size=512) as handle:
        handle.create_dataset(name, data=array.T)
    header = b"MATLAB 7.3 MAT-file, written by the flocksweep tests".ljust(116) + bytes(8) + b"\x00\x02IM"
    with open(path, "r+b") as handle:
        handle.write(header.ljust(512, b"\x00"))
    return path


def write_idtracker(path, obs, body_px: float):
    traj = obs.pos[:, :, :2] * body_px                    # frames x individuals x 2, pixels
    np.save(path, {"trajectories": traj, "frames_per_second": FPS, "body_length": body_px, "version": "5"},
            allow_pickle=True)
    return path


def write_trex(folder, obs):
    folder.mkdir()
    for i in range(obs.n):
        np.savez(folder / f"video_fish{i}.npz", X=obs.pos[:, i, 0], Y=obs.pos[:, i, 1], VX=obs.vel[:, i, 0],
                 VY=obs.vel[:, i, 1], time=obs.times, frame=np.arange(len(obs.times)),
                 missing=np.zeros(len(obs.times)))
    return folder


def write_trajr(folder, obs):
    folder.mkdir()
    for i in range(obs.n):
        pd.DataFrame({"time": obs.times, **{a: obs.pos[:, i, k] for k, a in enumerate("xyz")},
                      **{f"v{a}": obs.vel[:, i, k] for k, a in enumerate("xyz")}}).to_csv(folder / f"bird{i}.csv",
                                                                                          index=False)
    return folder


def write_movebank(path, obs, body_m: float, centre=(19.05, 47.47)):
    from pyproj import CRS, Transformer
    plane = CRS.from_dict({"proj": "aeqd", "lon_0": centre[0], "lat_0": centre[1], "datum": "WGS84", "units": "m"})
    back = Transformer.from_crs(plane, "EPSG:4326", always_xy=True)
    x, y = (obs.pos[:, :, 0] * body_m).reshape(-1), (obs.pos[:, :, 1] * body_m).reshape(-1)
    lon, lat = back.transform(x, y)
    stamps = pd.Timestamp("2010-04-01 10:00:00") + pd.to_timedelta(np.repeat(obs.times, obs.n), unit="s")
    pd.DataFrame({"event-id": np.arange(len(x)), "timestamp": stamps.strftime("%Y-%m-%d %H:%M:%S.%f"),
                  "location-long": lon, "location-lat": lat, "sensor-type": "gps",
                  "individual-local-identifier": np.tile([f"P{i}" for i in range(obs.n)], len(obs.times))}
                 ).to_csv(path, index=False)
    return path


# ------------------------------------------------------------------------------------------ round trips

@pytest.mark.parametrize("version", ["v5", "v7.3"])
def test_matlab_files_give_the_simulators_own_metrics(run, tmp_path, version):
    import scipy.io
    preset, obs = run
    channels = ("x", "y", "z", "vx", "vy", "vz")
    array = np.transpose(cube(obs, channels), (2, 0, 1))          # samples x individuals x channels
    path = tmp_path / "flight.mat"
    if version == "v5":
        scipy.io.savemat(path, {"tracks": array, "note": np.array([[1.0]])})
    else:
        write_mat_v73(path, "tracks", array)
    assert detect_format(path) == "mat"
    table, row = measure(path, units={"length": "bl"}, fps=FPS,
                         layout={"axes": "sample,individual,channel", "channels": ",".join(channels)})
    assert table.dims == 3 and table.has_velocity and table.source.format == "mat"
    assert_same(row, own_row(preset, obs))


def test_idtracker_trajectories_take_frame_rate_and_body_length_from_the_file(run, tmp_path):
    preset, obs = run
    path = write_idtracker(tmp_path / "trajectories.npy", obs, body_px=4.0)
    assert detect_format(path) == "idtracker"
    table, row = measure(path, velocity_interval=None)
    assert table.dims == 2 and table.unit_label == "BL" and table.source.fps == FPS
    assert table.source.body_length_px == 4.0
    assert_same(row, observed_row(obs, 1 / FPS, "xy"))


def test_trex_folders_give_the_projected_run_with_its_velocities(run, tmp_path):
    preset, obs = run
    folder = write_trex(tmp_path / "data", obs)
    assert detect_format(folder) == "trex"
    table, row = measure(folder, units={"length": "bl"})
    assert table.dims == 2 and table.has_velocity and sorted(table.frame["id"].unique()) == [str(i) for i in range(8)]
    assert_same(row, observed_row(obs, "recorded", "xy"))


def test_trajr_folders_of_one_csv_per_individual_give_the_simulators_own_metrics(run, tmp_path):
    preset, obs = run
    folder = write_trajr(tmp_path / "tracks", obs)
    assert detect_format(folder) == "trajr"
    table, row = measure(folder, units={"length": "bl"}, columns={"t": "time"})
    assert table.dims == 3 and list(table.frame["flock"].unique()) == ["tracks"]   # the folder is the flock
    assert_same(row, own_row(preset, obs))


def test_movebank_gps_is_projected_to_metres(run, tmp_path):
    preset, obs = run
    path = write_movebank(tmp_path / "pigeons.csv", obs, body_m=0.5)
    assert detect_format(path) == "movebank"
    table, row = measure(path, velocity_interval=None, body_length=0.5)
    assert table.dims == 2 and table.t_origin.startswith("2010-04-01 10:00:00")
    # through latitude and longitude and back: equal to rounding (the projection is not exact arithmetic)
    assert_same(row, observed_row(obs, 1 / FPS, "xy"), rtol=1e-6)


def test_the_local_projection_keeps_distances():
    lon = np.array([19.0, 19.0 + 1e-3, 19.0])
    lat = np.array([47.5, 47.5, 47.5 + 1e-3])
    x, y, centre = project_wgs84(lon, lat)
    from pyproj import Geod
    geod = Geod(ellps="WGS84")
    for a, b in ((0, 1), (0, 2), (1, 2)):
        _, _, metres = geod.inv(lon[a], lat[a], lon[b], lat[b])
        assert np.isclose(np.hypot(x[a] - x[b], y[a] - y[b]), metres, rtol=1e-7)
    assert x[1] > x[0] and y[2] > y[0]                    # x east, y north


# ---------------------------------------------------------------------------------------- bad variants

def test_bad_files_of_each_format_are_one_clear_config_error(run, tmp_path):
    preset, obs = run
    import scipy.io
    path = tmp_path / "f.mat"
    scipy.io.savemat(path, {"tracks": np.zeros((3, 4, 5))})
    with pytest.raises(ConfigError, match="layout.channels: missing"):
        load_tracks(path, TrackSource(fps=8.0))
    with pytest.raises(ConfigError, match=r"layout.channels: names 2 channels, the array has 4 \(name the others - to "
                                          r"skip them: x,y,-,-\)"):
        load_tracks(path, TrackSource(fps=8.0, layout={"channels": "x,y"}))
    with pytest.raises(ConfigError, match="fps: the times are frame numbers"):
        load_tracks(path, TrackSource(layout={"channels": "x,y,vx,vy"}))
    (tmp_path / "junk.mat").write_bytes(b"not a mat file at all")
    with pytest.raises(ConfigError, match="cannot read it as a MATLAB .mat file"):
        load_tracks(tmp_path / "junk.mat", TrackSource())
    np.savez(tmp_path / "t.npz", trajectories=np.zeros((4, 2, 3)))
    with pytest.raises(ConfigError, match=r"trajectories has shape \(4, 2, 3\); expected \(frames, individuals, 2\)"):
        load_tracks(tmp_path / "t.npz", TrackSource())
    folder = tmp_path / "trex"
    folder.mkdir()
    np.savez(folder / "v_fish0.npz", X=np.zeros(3), time=np.arange(3.0))
    with pytest.raises(ConfigError, match="not a TRex export: no Y"):
        load_tracks(folder, TrackSource())
    gps = tmp_path / "gps.csv"
    gps.write_text("timestamp,location-long,location-lat,individual-local-identifier\n"
                   "2010-01-01 00:00:00,19.0,147.5,a\n")
    with pytest.raises(ConfigError, match=r"latitude/longitude outside .* at rows 1"):
        load_tracks(gps, TrackSource())
