"""``flocksweep init TRACKS --model PRESET``: a ready calibration file from a tracks file and a preset (the
targets from the tracks, an [observation] block that matches them, the run sized to them, priors sized from
the measured speed and spacing, every line commented), on messy files: metres with a sidecar, a glitch, 2-D
tracks with a spare channel, a periodic model, no body length."""
from __future__ import annotations

import importlib.util
import shutil
import tomllib

import pytest

from flocksweep.analysis.calibration.config import load_calibration
from flocksweep.cli import main
from paths import ROOT

TRACKS = ROOT / "configs" / "tracks"
HOLLAND = ROOT / "configs" / "models" / "holland.toml"


def copy(name: str, folder):
    for suffix in (".csv.gz", ".json"):
        shutil.copy(TRACKS / f"{name}{suffix}", folder / f"{name}{suffix}")
    return folder / f"{name}.csv.gz"


def test_a_3d_tracks_file_in_metres_gives_a_file_that_calibrates(tmp_path, capsys):
    tracks = copy("synthetic_holland", tmp_path)      # 8 flocks, metres, 5 Hz with jitter, a glitch dropped
    assert main(["init", str(tracks), "--model", str(HOLLAND), "--out", str(tmp_path / "fit.toml")]) == 0
    printed = capsys.readouterr().out
    assert "measured 8 flock(s): 20 individuals" in printed and "next: edit its priors" in printed
    text = (tmp_path / "fit.toml").read_text()
    data = tomllib.loads(text)
    assert data["observation"] == {"interval": 0.2, "velocity_interval": 0.4, "detection_probability": 0.95,
                                   "position_sd": 0.0, "projection": "none"}
    assert data["run"]["n"] == 20 and data["targets"]["from_tracks"] == "synthetic_holland.csv.gz"
    assert set(data["parameters"]) == {"max_speed", "range", "separation_weight"}
    speed = data["parameters"]["max_speed"]["prior"]
    assert speed["low"] < 7.0 < speed["high"]                 # sized from the measured speed; the truth inside
    assert speed["low"] == pytest.approx(2.11, abs=0.01)
    assert all(line.startswith("#") or "#" in line or not line.strip() or line.startswith(("[", "key", "prior",
               "stats", "summary", "name", "seed", "kind", "from_tracks", "preset"))
               for line in text.splitlines())                 # every setting says why
    config = load_calibration(tmp_path / "fit.toml")          # it validates: targets measured, ready to run
    assert config.targets.observed.shape == (8, 4) and config.observation.interval == 0.2
    assert main(["init", str(tracks), "--model", str(HOLLAND), "--out", str(tmp_path / "fit.toml")]) == 2
    assert "--force" in capsys.readouterr().err


def test_2d_tracks_are_seen_from_above_and_a_planar_periodic_model_gets_an_open_world(tmp_path):
    spec = importlib.util.spec_from_file_location("make_flight_2d", TRACKS / "make_flight_2d.py")
    flight = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(flight)
    tracks = flight.write(tmp_path, count=2, last=12.0)       # 2-D, metres, a spare `confidence` column
    assert main(["init", str(tracks), "--model", str(HOLLAND), "--out", str(tmp_path / "h.toml")]) == 0
    holland = tomllib.loads((tmp_path / "h.toml").read_text())
    assert holland["observation"]["projection"] == "xz"       # a 3-D model seen from above
    assert holland["observation"]["detection_probability"] == pytest.approx(0.9, abs=0.02)
    vicsek = ROOT / "configs" / "models" / "vicsek.toml"      # planar, in a periodic box
    assert main(["init", str(tracks), "--model", str(vicsek), "--out", str(tmp_path / "v.toml"),
                 "--stats", "polarization,nn_distance"]) == 0
    data = tomllib.loads((tmp_path / "v.toml").read_text())
    assert data["observation"]["projection"] == "xy" and data["model"]["set"]["world.boundary"] == "open"
    assert set(data["parameters"]) == {"speed", "radius", "noise"}
    assert data["targets"]["stats"] == ["polarization", "nn_distance"]
    load_calibration(tmp_path / "v.toml")


def test_tracks_in_metres_without_a_body_length_are_refused_naming_the_option(tmp_path, capsys):
    tracks = copy("synthetic_holland", tmp_path)
    sidecar = tmp_path / "synthetic_holland.json"
    sidecar.write_text(sidecar.read_text().replace('"body_length": 0.3,', ""))
    assert main(["init", str(tracks), "--model", str(HOLLAND), "--out", str(tmp_path / "fit.toml")]) == 2
    assert "--body-length" in capsys.readouterr().err and not (tmp_path / "fit.toml").exists()
    assert main(["init", str(tracks), "--model", str(HOLLAND), "--out", str(tmp_path / "fit.toml"),
                 "--body-length", "0.3"]) == 0
    assert tomllib.loads((tmp_path / "fit.toml").read_text())["targets"]["tracks"]["body_length"] == 0.3
