"""End-to-end: `flocksweep simulate --tracks` and `flocksweep measure` (analysis.reports.measured)."""
from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from flocksweep.observables.metrics import frame_metrics, summarize
from flocksweep.observables.summary import summary_columns
from flocksweep.cli import main
from paths import ROOT

HOLLAND = str(ROOT / "configs/models/holland.toml")
EXAMPLE = ROOT / "configs/tracks/synthetic_holland.csv.gz"


def test_simulated_tracks_measure_back_to_the_simulators_metrics_through_the_cli(tmp_path, capsys):
    run = tmp_path / "run"
    assert main(["simulate", HOLLAND, "--n", "10", "--duration", "2", "--seed", "5", "--record-every", "6",
                 "--set", "init.radius=5", "--out", str(run), "--tracks", "parquet"]) == 0
    assert json.loads((run / "tracks.json").read_text())["units"] == {"length": "bl", "time": "s"}
    out = tmp_path / "measured"
    assert main(["measure", str(run / "tracks.parquet"), "--group-radius", "6", "--warmup", "0.5",
                 "--out", str(out), "--no-figures"]) == 0
    printed = capsys.readouterr().out
    assert "1 flock(s), 1 measured, 3-D, lengths in BL" in printed
    data = np.load(run / "trajectory.npz")
    series = frame_metrics(data["pos"], data["vel"], None, None, data["pattern"], 6.0,
                           record_interval=0.1)   # 6 steps of 1/60 s: the interval measure infers
    expected = summarize(series, data["times"], warmup=0.5)
    runs = pd.read_parquet(out / "runs.parquet")
    assert runs.loc[0, "flock"] == "holland-seed5" and runs.loc[0, "velocity_interval"] == "recorded"
    for column, value in expected.items():
        assert np.array_equal(runs.loc[0, column], value, equal_nan=True), column
    assert set(summary_columns(leadership=False)) <= set(runs.columns)
    ts = pd.read_parquet(out / "timeseries.parquet")
    assert np.array_equal(ts["t"].to_numpy(), data["times"]) and np.array_equal(ts["polarization"], series["polarization"])
    for name in ("report.md", "report.html", "validation.csv", "measure.json", "runs.csv"):
        assert (out / name).stat().st_size > 0, name
    assert "Measured flocks: tracks.parquet" in (out / "report.md").read_text()
    assert not (out / "figures").exists()


def test_bad_tracks_exit_2_naming_row_and_column_and_keep_the_validation_table(tmp_path, capsys):
    frame = pd.DataFrame({"bird": [1, 1, 2, 2], "time": [0.0, 0.1, 0.0, 0.1], "x": [0.0, 0.1, 1.0, "oops"],
                          "y": [0.0, 0.0, 0.0, 0.0]})
    path = tmp_path / "bad.csv"
    frame.to_csv(path, index=False)
    out = tmp_path / "out"
    code = main(["measure", str(path), "--group-radius", "2", "--columns", "id=bird", "t=time", "--out", str(out)])
    assert code == 2
    err = capsys.readouterr().err
    assert "row 4 (line 5), column 'x'" in err and "'oops'" in err
    table = pd.read_csv(out / "validation.csv")
    assert list(table["level"]) == ["error"] and table.loc[0, "column"] == "x"
    # an unknown unit is a config error naming the key
    assert main(["measure", str(path), "--group-radius", "2", "--units", "furlong"]) == 2
    assert "units.length: got 'furlong'" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["measure", str(path)])                         # --group-radius is required


@pytest.mark.slow
def test_the_shipped_synthetic_example_measures_with_its_glitch_reported(tmp_path, capsys):
    out = tmp_path / "example"
    assert main(["measure", str(EXAMPLE), "--group-radius", "20", "--velocity-interval", "0.4", "--out", str(out)]) == 0
    runs = pd.read_parquet(out / "runs.parquet")
    assert list(runs["flock"]) == [f"F{k}" for k in range(1, 9)] and (runs["status"] == "ok").all()
    assert (runs["length_unit"] == "BL").all() and (runs["interval"] == 0.2).all()
    validation = pd.read_csv(out / "validation.csv")
    speed = validation[validation["check"] == "speed"]
    assert len(speed) == 1 and speed.iloc[0]["flock"] == "F3" and "left out" in speed.iloc[0]["detail"]
    report = (out / "report.md").read_text()
    assert "SYNTHETIC" in report and len(list((out / "figures").glob("flock_F*.png"))) == 8
    assert "figures/metrics_over_time.png" in report and "Flock F8" in report
    assert (out / "figures/metrics_over_time.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_two_dimensional_tracks_with_velocities_measure(tmp_path, capsys):
    path = tmp_path / "t.csv"
    path.write_text("id,t,x,y,vx,vy\n1,0,0,0,1,0\n1,1,1,0,1,0\n2,0,0,1,1,0\n2,1,1,1,1,0\n")
    out = tmp_path / "out"
    assert main(["measure", str(path), "--group-radius", "5", "--out", str(out), "--no-figures"]) == 0
    assert "2-D" in capsys.readouterr().out
    runs = pd.read_parquet(out / "runs.parquet")
    assert runs.loc[0, "dims"] == 2 and runs.loc[0, "polarization_mean"] == 1.0
    assert runs.loc[0, "speed_mean_mean"] == 1.0 and runs.loc[0, "nn_distance_mean"] == 1.0


def test_zero_padding_warns_and_no_measurable_flock_exits_2(tmp_path, capsys):
    path = tmp_path / "t.csv"
    rows = [f"{i},{k * 0.1:g},{k * 0.1:g},{i},{0 if k == 9 and i == 2 else 1},0" for i in (1, 2) for k in range(10)]
    path.write_text("id,t,x,y,vx,vy\n" + "\n".join(rows) + "\n")
    assert main(["measure", str(path), "--group-radius", "5", "--out", str(tmp_path / "a"), "--no-figures"]) == 0
    err = capsys.readouterr().err
    assert "warning: velocity: flock 't', id 2, row 20 (line 21): 1 sample(s) at t = 0.9 s" in err
    code = main(["measure", str(path), "--group-radius", "5", "--velocity-interval", "1.5", "--out",
                 str(tmp_path / "b"), "--no-figures"])
    err = capsys.readouterr().err
    assert code == 2 and "not measured: flock 't'" in err and "too few" in err
    assert pd.read_csv(tmp_path / "b" / "validation.csv")["check"].tolist() == ["not measured"]


def test_a_matlab_file_of_birds_channels_samples_measures_from_the_command_line(tmp_path, capsys):
    import scipy.io
    t = np.arange(20) / 10.0                                    # 10 Hz, frame numbers in the file
    birds = np.stack([np.stack([t * 15.0, np.full(20, 3.0 * b), np.full(20, 15.0), np.zeros(20)])
                      for b in range(3)])                       # birds x (x, y, vx, vy) x samples, metres
    path = tmp_path / "flight.mat"
    scipy.io.savemat(path, {"data": birds})
    out = tmp_path / "out"
    assert main(["measure", str(path), "--group-radius", "5", "--fps", "10", "--layout", "channels=x,y,vx,vy",
                 "--out", str(out), "--no-figures"]) == 0
    assert "1 flock(s), 1 measured, 2-D" in capsys.readouterr().out
    runs = pd.read_parquet(out / "runs.parquet")
    assert runs.loc[0, "interval"] == 0.1 and runs.loc[0, "speed_mean_mean"] == 15.0
    assert runs.loc[0, "polarization_mean"] == 1.0 and runs.loc[0, "nn_distance_mean"] == 3.0


@pytest.mark.parametrize("name, content, args, message", [
    ("a.mat", None, ["--fps", "10"], "layout.channels: missing"),
    ("b.mat", None, ["--layout", "channels=x,y,vx,vy"], "fps: the times are frame numbers"),
    ("c.mat", b"MATLAB 5.0 MAT-file, but cut short", [], "cannot read it as a MATLAB .mat file"),
    ("d.csv", b"timestamp,location-long,location-lat,individual-local-identifier\n2010-01-01,190.0,47.0,a\n", [],
     "latitude/longitude outside"),
    ("e.csv", b"bird,time,x\n1,0,0\n", [], "no column for role 'id'"),
])
def test_bad_files_exit_2_with_one_message(tmp_path, capsys, name, content, args, message):
    import scipy.io
    path = tmp_path / name
    if content is None:
        scipy.io.savemat(path, {"data": np.zeros((3, 4, 5))})
    else:
        path.write_bytes(content)
    assert main(["measure", str(path), "--group-radius", "5", "--out", str(tmp_path / "out"), *args]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    if "no column for role 'id'" in message:
        assert "no column for role 't'" in err and "no column for role 'y'" in err   # all at once


@pytest.mark.slow   # over half a second of CPU: out of the quick loop (CI runs it)
def test_the_report_draws_each_flocks_leader_follower_hierarchy(tmp_path, capsys):
    from PIL import Image

    from planted_flocks import write_planted_tracks
    planted = [0, 2, 4, 7, 3]                   # individual 0 leads; 3 follows everyone, 7 records late
    write_planted_tracks(tmp_path / "planted.parquet", planted, 120, 0.2)
    out = tmp_path / "out"
    assert main(["measure", str(tmp_path / "planted.parquet"), "--group-radius", "50", "--out", str(out),
                 "--no-progress"]) == 0
    path = out / "figures/hierarchy_planted.png"
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    width, height = Image.open(path).size
    assert width >= 1400 and height >= 600      # 11 x 5 inches at 150 dpi: readable at a report's width
    report = (out / "report.md").read_text()
    assert "## Leader-follower hierarchy" in report and "figures/hierarchy_planted.png" in report
    runs = pd.read_parquet(out / "runs.parquet")
    assert runs.loc[0, "dcd_edges"] * 5 == 10    # every pair correlates: 10 edges, from the earlier copier
    # without figures there is none
    assert main(["measure", str(tmp_path / "planted.parquet"), "--group-radius", "50", "--out", str(tmp_path / "b"),
                 "--no-figures", "--no-progress"]) == 0
    assert not (tmp_path / "b/figures").exists()


def test_measure_json_and_the_report_state_the_units_and_the_clock_with_where_each_came_from(tmp_path, capsys):
    traj = np.zeros((30, 3, 2))
    traj[:, :, 0] = np.arange(30)[:, None] * 2.0                   # 2 px per frame
    traj[:, :, 1] = np.arange(3)[None, :] * 40.0
    traj[10:15, 1] = np.nan                                        # missed detections: overtake_rate undefined
    path = tmp_path / "fish.npy"
    np.save(path, {"trajectories": traj, "frames_per_second": 25.0, "body_length": 20.0}, allow_pickle=True)
    out = tmp_path / "out"
    assert main(["measure", str(path), "--group-radius", "3", "--body-length-px", "40", "--out", str(out),
                 "--no-figures", "--no-progress"]) == 0
    printed = capsys.readouterr().out
    assert "units: length unit px (file), time unit frame (file), fps 25.0 (file), body length (px) 40.0 (given)" \
           in printed and "records every 0.04 s: frame numbers at 25 frames per second (fps: file)" in printed
    info = json.loads((out / "measure.json").read_text())
    assert info["scales"]["body length (px)"] == {"value": 40.0, "from": "given"}
    assert info["scales"]["fps"] == {"value": 25.0, "from": "file"}
    assert info["interval"] == 0.04 and info["interval_found"].startswith("frame numbers at 25 frames per second")
    runs = pd.read_parquet(out / "runs.parquet")
    assert runs.loc[0, "speed_mean_mean"] == pytest.approx(2.0 * 25 / 40)      # BL/s with the given body length
    report = (out / "report.md").read_text()
    assert "| fps | 25.0 | file |" in report and "| body length (px) | 40.0 | given |" in report
    assert "`overtake_rate` compares who is where at consecutive records" in report and "flock(s) fish have missed" in report
    assert "None" not in report.split("## Validation")[1].split("## Flocks")[0]


def test_a_file_that_cannot_be_read_leaves_no_output_folder(tmp_path, capsys):
    path = tmp_path / "t.csv"
    path.write_text("id,t,x,y\n1,0,0,0\n")
    assert main(["measure", str(path), "--group-radius", "3", "--layout", "channels=x,y", "--out",
                 str(tmp_path / "out"), "--no-progress"]) == 2
    assert "layout: the csv format has no array layout" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()
