"""Reading and checking measured tracks (observables.tracks, observables.validation)."""
from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from flocksweep.observables.measured import measure_tracks, track_settings
from flocksweep.observables.tracks import TrackSource, load_tracks, raw_flocks, track_source
from flocksweep.observables.validation import TrackError, check_flock, infer_interval, issues_table
from flocksweep.simcore.schema import ConfigError


def straight_tracks(n: int = 4, samples: int = 11, interval: float = 0.5, flocks=("A",), speed=(1.0, 0.0, 0.0)):
    """Long table of individuals flying in a straight line: x = 2 i + speed t."""
    rows = []
    for flock in flocks:
        for k in range(samples):
            t = k * interval
            for i in range(n):
                rows.append({"flock": flock, "id": i, "t": t, "x": 2.0 * i + speed[0] * t, "y": speed[1] * t,
                             "z": 1.0 + speed[2] * t})
    return pd.DataFrame(rows)


def write(frame: pd.DataFrame, path):
    if str(path).endswith(".parquet"):
        frame.to_parquet(path, index=False)
    else:
        frame.to_csv(path, index=False)
    return path


def test_column_map_units_and_body_length_convert_to_body_lengths(tmp_path):
    frame = straight_tracks().rename(columns={"flock": "event", "id": "bird", "t": "time_ms", "x": "X"})
    frame["time_ms"] *= 1000.0
    for axis in ("X", "y", "z"):
        frame[axis] *= 100.0                                   # centimetres
    path = write(frame, tmp_path / "birds.csv")
    source = TrackSource(columns={"flock": "event", "id": "bird", "t": "time_ms", "x": "X"},
                         units={"length": "cm", "time": "ms"}, body_length=0.25)
    table = load_tracks(path, source)
    assert table.unit_label == "BL" and table.dims == 3 and not table.has_velocity
    assert np.allclose(table.frame["t"].unique(), np.arange(11) * 0.5)
    # 1 m/s at 0.25 m per body length is 4 BL/s; z = 1 m is 4 BL
    first = table.frame[table.frame["id"] == 0].sort_values("t")
    assert np.allclose(np.diff(first["x"]) / np.diff(first["t"]), 4.0)
    assert np.allclose(first["z"], 4.0)


def test_two_dimensional_tracks_are_marked_and_get_z_zero(tmp_path):
    path = write(straight_tracks().drop(columns=["z"]), tmp_path / "fish.parquet")
    table = load_tracks(path, TrackSource())
    assert table.dims == 2 and table.unit_label == "m" and table.line_offset is None
    assert (table.frame["z"] == 0).all()
    (flock,), _ = raw_flocks(table)
    assert flock.dims == 2


def test_sidecar_gives_defaults_that_explicit_settings_override(tmp_path):
    path = write(straight_tracks().rename(columns={"id": "bird"}), tmp_path / "tracks.csv")
    (tmp_path / "tracks.json").write_text(json.dumps({"columns": {"id": "bird"}, "units": {"length": "bl"},
                                                      "description": "synthetic"}))
    assert track_source(path, {}).unit_label == "BL"
    source = track_source(path, {"units": {"length": "m"}, "body_length": 0.5})
    assert source.columns == {"id": "bird"} and source.body_length == 0.5 and source.unit_label == "BL"


def test_bad_settings_are_config_errors_naming_the_key():
    with pytest.raises(ConfigError, match=r"columns\.speed: unknown role"):
        TrackSource(columns={"speed": "v"})
    with pytest.raises(ConfigError, match=r"units\.length: got 'feet'"):
        TrackSource(units={"length": "feet"})
    with pytest.raises(ConfigError, match="already in body lengths"):
        TrackSource(units={"length": "bl"}, body_length=0.2)
    with pytest.raises(ConfigError, match="mapped to two roles"):
        TrackSource(columns={"x": "a", "y": "a"})


def test_a_bad_cell_is_named_by_row_line_and_column(tmp_path):
    frame = straight_tracks().astype({"x": object})
    frame.loc[6, "x"] = "abc"
    frame.loc[9, "t"] = np.inf
    frame.loc[2, "flock"] = None
    path = write(frame, tmp_path / "bad.csv")
    with pytest.raises(TrackError) as caught:
        load_tracks(path, TrackSource())
    text = str(caught.value)
    assert "row 7 (line 8), column 'x'" in text and "'abc'" in text
    assert "row 10 (line 11), column 't'" in text
    assert "row 3 (line 4), column 'flock': flock: missing" in text


def test_missing_columns_list_what_the_file_has_with_a_suggestion(tmp_path):
    path = write(straight_tracks().rename(columns={"id": "ids"}), tmp_path / "t.csv")
    with pytest.raises(TrackError, match=r"no column for role 'id'.*did you mean 'ids'.*columns id=NAME"):
        load_tracks(path, TrackSource())
    path = write(straight_tracks().assign(vx=1.0, vy=0.0), tmp_path / "v.csv")
    with pytest.raises(TrackError, match="velocities need all of"):
        load_tracks(path, TrackSource())


def test_empty_positions_are_missed_detections_reported_not_hidden(tmp_path):
    frame = straight_tracks()
    frame.loc[[5, 6], "y"] = np.nan
    table = load_tracks(write(frame, tmp_path / "t.csv"), TrackSource())
    assert len(table.frame) == len(frame) - 2
    (note,) = table.issues
    assert note.check == "missed detection" and note.rows == (6, 7)


def test_duplicates_are_errors_naming_both_rows(tmp_path):
    frame = pd.concat([straight_tracks(), straight_tracks().iloc[[3]]], ignore_index=True)
    table = load_tracks(write(frame, tmp_path / "t.csv"), TrackSource())
    with pytest.raises(TrackError, match=r"duplicate: flock 'A', rows 4, 45 \(lines 5, 46\)"):
        measure_tracks(table, track_settings(5.0))


def test_unsorted_rows_are_sorted_and_reported(tmp_path):
    frame = straight_tracks()
    frame = pd.concat([frame.iloc[20:], frame.iloc[:20]], ignore_index=True)   # later times first
    table = load_tracks(write(frame, tmp_path / "t.csv"), TrackSource())
    (flock,), issues = raw_flocks(table)
    assert [i.check for i in issues] == ["unsorted"]
    bounds = flock.bounds()
    for i in range(len(flock.ids)):
        assert np.all(np.diff(flock.t[bounds[i]:bounds[i + 1]]) > 0)


def test_impossible_speed_flags_the_glitch_only_and_the_policy_decides(tmp_path):
    frame = straight_tracks(samples=21)
    glitch = frame.index[(frame["id"] == 2) & (frame["t"] == 5.0)][0]
    frame.loc[glitch, "x"] += 50.0                     # one sample 50 m off, the track goes on
    path = write(frame, tmp_path / "t.csv")
    table = load_tracks(path, TrackSource())
    (flock,), _ = raw_flocks(table)
    with pytest.raises(TrackError, match=rf"speed: flock 'A', row {glitch + 1} \(line {glitch + 2}\)"):
        measure_tracks(table, track_settings(5.0))
    kept, issues = check_flock(flock, 0.5, 1.25, max_speed=None, bad_speeds="keep")
    assert len(kept.t) == len(flock.t) and [i.level for i in issues] == ["warning"]
    dropped, issues = check_flock(flock, 0.5, 1.25, max_speed=None, bad_speeds="drop")
    assert len(dropped.t) == len(flock.t) - 1 and glitch + 1 not in dropped.rows
    assert "left out" in issues[0].detail and issues[0].rows == (glitch + 1,)
    # an explicit max_speed below the flight speed flags everything after the first sample of each bird
    _, issues = check_flock(flock, 0.5, 1.25, max_speed=0.5, bad_speeds="keep")
    assert len(issues[0].rows) == len(flock.t) - len(flock.ids)


def test_gaps_are_counted_bridged_or_left_missing(tmp_path):
    frame = straight_tracks(samples=21)
    drop = frame.index[(frame["id"] == 1) & frame["t"].isin([2.0])].tolist() + \
        frame.index[(frame["id"] == 3) & frame["t"].isin([6.0, 6.5, 7.0])].tolist()
    table = load_tracks(write(frame.drop(index=drop), tmp_path / "t.csv"), TrackSource())
    (flock,), _ = raw_flocks(table)
    _, issues = check_flock(flock, 0.5, 1.25)
    by_level = {i.level: i for i in issues}
    assert by_level["note"].detail.startswith("1 gap(s) of 1 individual(s) bridged") and by_level["note"].id == "1"
    assert by_level["warning"].detail.startswith("1 gap(s) of 1 individual(s) left missing")
    assert "2 s, from t = 5.5 s to 7.5 s" in by_level["warning"].detail
    table_text = issues_table(issues, 1)
    assert list(table_text["level"]) == ["warning", "note"]


def test_interval_is_inferred_from_the_median_spacing(tmp_path):
    frame = straight_tracks(samples=30, interval=0.1)
    frame["t"] += np.random.default_rng(1).uniform(-0.002, 0.002, len(frame))
    table = load_tracks(write(frame, tmp_path / "t.csv"), TrackSource())
    (flock,), _ = raw_flocks(table)
    assert abs(infer_interval(flock) - 0.1) < 0.002


def test_datetime_times_become_seconds(tmp_path):
    frame = straight_tracks(samples=3)
    frame["t"] = pd.Timestamp("2010-04-08 10:00:00") + pd.to_timedelta(frame["t"], unit="s")
    table = load_tracks(write(frame, tmp_path / "t.parquet"), TrackSource(units={"time": "datetime"}))
    assert np.allclose(sorted(table.frame["t"].unique()), [0.0, 0.5, 1.0])
    assert table.t_origin.startswith("2010-04-08 10:00:00")


def test_pattern_must_stay_constant_per_individual(tmp_path):
    frame = straight_tracks().assign(pattern=0)
    frame.loc[frame.index[-1], "pattern"] = 1
    table = load_tracks(write(frame, tmp_path / "t.csv"), TrackSource())
    with pytest.raises(TrackError, match="pattern changes over time"):
        raw_flocks(table)


def test_a_flock_too_short_for_the_velocity_interval_is_a_failed_row_with_its_reason(tmp_path):
    frame = pd.concat([straight_tracks(flocks=("long",)), straight_tracks(samples=2, flocks=("short",))])
    table = load_tracks(write(frame, tmp_path / "t.csv"), TrackSource())
    measured = measure_tracks(table, track_settings(5.0), 0.5, None, 1.0)
    runs = measured.runs.set_index("flock")
    assert runs.loc["long", "status"] == "ok" and runs.loc["long", "records"] == 9
    assert runs.loc["short", "status"] == "failed" and "too few" in runs.loc["short", "error"]
    assert np.isnan(runs.loc["short", "polarization_mean"]) and len(measured.flocks) == 1
    assert set(measured.timeseries["run_id"]) == {"long"}
    (failed,) = [i for i in measured.issues if i.level == "error"]
    assert failed.check == "not measured" and failed.flock == "short" and "too few" in failed.detail
    # the straight flock: aligned, 2 m apart along a line, flying at 1 m/s
    assert runs.loc["long", "polarization_mean"] == 1.0 and np.isclose(runs.loc["long", "nn_distance_mean"], 2.0)
    assert np.isclose(runs.loc["long", "speed_mean_mean"], 1.0)
    # everyone flies the same heading: correlated 1 at every delay, so no one leads (delay 0, no edge)
    assert runs.loc["long", "dcd_corr_mean"] == 1.0 and runs.loc["long", "dcd_edges"] == 0.0
    assert runs.loc["long", "dcd_delay_mean"] == 0.0


def test_every_missing_column_is_named_at_once(tmp_path):
    path = write(straight_tracks().rename(columns={"id": "bird", "t": "time"}), tmp_path / "t.csv")
    with pytest.raises(TrackError) as caught:
        load_tracks(path, TrackSource())
    text = str(caught.value)
    assert "2 problem(s)" in text and "role 'id'" in text and "role 't'" in text


def test_unmapped_columns_are_listed_with_a_hint(tmp_path):
    frame = straight_tracks().drop(columns=["z"]).assign(vx_ms=1.0, vy_ms=0.0, note="a")
    table = load_tracks(write(frame, tmp_path / "t.csv"), TrackSource())
    (issue,) = table.issues
    assert issue.level == "warning" and issue.check == "unmapped columns"
    assert "3 column(s) not used: vx_ms, vy_ms, note" in issue.detail and "vx_ms (a vx?)" in issue.detail
    mapped = load_tracks(write(frame, tmp_path / "t.csv"), TrackSource(columns={"vx": "vx_ms", "vy": "vy_ms"}))
    assert mapped.has_velocity and "1 column(s) not used: note" in mapped.issues[0].detail


def test_zero_padded_velocities_warn_naming_flock_individual_and_sample(tmp_path):
    frame = straight_tracks(flocks=("F1",)).assign(vx=1.0, vy=0.0, vz=0.0)
    last = (frame["id"] == 2) & (frame["t"] == frame["t"].max())
    frame.loc[last, ["vx", "vy", "vz"]] = 0.0                      # the logger's zero padding
    table = load_tracks(write(frame, tmp_path / "t.csv"), TrackSource())
    measured = measure_tracks(table, track_settings(5.0), velocity_interval="recorded")
    (issue,) = [i for i in measured.issues if i.check == "velocity"]
    assert issue.level == "warning" and issue.flock == "F1" and issue.id == "2"
    assert issue.rows == (int(np.flatnonzero(last)[0]) + 1,) and "1 sample(s) at t = 5 s" in issue.detail
    assert "recorded speed 0, from positions 1" in issue.detail
    # velocities that agree give no warning; differenced velocities are not checked against anything
    clean = load_tracks(write(frame.assign(vx=1.0), tmp_path / "c.csv"), TrackSource())
    assert not [i for i in measure_tracks(clean, track_settings(5.0)).issues if i.check == "velocity"]


def test_tracks_of_which_no_flock_can_be_measured_are_an_error(tmp_path):
    table = load_tracks(write(straight_tracks(), tmp_path / "t.csv"), TrackSource())
    with pytest.raises(TrackError, match=r"not measured: flock 'A'.*no velocities"):
        measure_tracks(table, track_settings(5.0), velocity_interval="recorded")
    with pytest.raises(TrackError, match=r"not measured: flock 'A'.*too few"):
        measure_tracks(table, track_settings(5.0), 0.5, None, 6.0)
