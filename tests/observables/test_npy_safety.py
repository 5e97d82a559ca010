"""A track file is data, never code (observables.npy_file): a pickled idtracker.ai file whose pickle would
create a file is refused by every route that reads tracks (measure, format auto-detection, a raw pickle
renamed .npy, a calibration file's targets.from_tracks through `targets` and `calibrate`), and the file is
never created; idtracker.ai's own dictionaries, as numpy pickles them with every protocol, still read."""
from __future__ import annotations

import collections
import io
import pathlib
import pickle

import numpy as np
import pytest

from flocksweep.cli import main
from flocksweep.observables.npy_file import NotData, read_npy
from flocksweep.observables.track_formats import detect_format
from flocksweep.observables.tracks import load_tracks, track_source
from flocksweep.simcore.schema import ConfigError
from paths import ROOT


class Payload:
    """Unpickling this creates the file ``marker`` (what a malicious track file would do)."""

    def __init__(self, marker):
        self.marker = str(marker)

    def __reduce__(self):
        return (open, (self.marker, "w"))


def trajectories() -> np.ndarray:
    t = np.arange(40, dtype=np.float64)
    return np.stack([np.stack([10 * t + 5 * i, 3 * t + 7 * i], axis=1) for i in range(4)], axis=1)  # (40, 4, 2)


def idtracker_dict(**extra) -> dict:
    return {"trajectories": trajectories(), "frames_per_second": 10.0, "body_length": 20.0, "version": "5",
            **extra}


def save_pickled(path: pathlib.Path, obj, protocol: int = 3) -> pathlib.Path:
    """``np.save`` of an object array, with the pickle protocol given."""
    array = np.empty((), dtype=object)
    array[()] = obj
    with open(path, "wb") as handle:            # as np.save writes it, with the protocol given
        np.lib.format.write_array_header_1_0(handle, np.lib.format.header_data_from_array_1_0(array))
        pickle.dump(array, handle, protocol=protocol)
    return path


@pytest.fixture()
def marker(tmp_path):
    return tmp_path / "payload_ran"


@pytest.fixture()
def poisoned(tmp_path, marker):
    return save_pickled(tmp_path / "trajectories.npy", idtracker_dict(note=Payload(marker)))


def test_a_pickled_payload_is_refused_by_the_reader_before_it_runs(poisoned, marker):
    with pytest.raises(NotData, match=r"io\.open, which is not array data"):
        read_npy(poisoned)
    assert not marker.exists()


def test_measure_refuses_it_naming_the_way_to_convert_a_trusted_file(poisoned, marker, tmp_path, capsys):
    assert detect_format(poisoned) == "idtracker"          # auto-detection reads the name, not the pickle
    code = main(["measure", str(poisoned), "--group-radius", "4", "--out", str(tmp_path / "m")])
    err = capsys.readouterr().err
    assert code == 2 and "not opened" in err and "np.savez" in err
    assert not marker.exists()
    code = main(["measure", str(poisoned), "--format", "idtracker", "--group-radius", "4", "--out",
                 str(tmp_path / "m2")])
    assert code == 2 and not marker.exists()


def test_a_raw_pickle_renamed_npy_is_never_unpickled(tmp_path, marker):
    path = tmp_path / "trajectories.npy"
    path.write_bytes(pickle.dumps(idtracker_dict(note=Payload(marker))))
    with pytest.raises(ConfigError, match="not a .npy file"):
        load_tracks(path, track_source(path, {}))
    assert not marker.exists()
    harmless = tmp_path / "plain.npy"
    harmless.write_bytes(pickle.dumps(idtracker_dict()))
    with pytest.raises(ConfigError, match="raw pickle is never opened"):
        load_tracks(harmless, track_source(harmless, {}))


def test_an_object_array_in_an_npz_is_refused_without_unpickling(tmp_path, marker):
    path = tmp_path / "trajectories.npz"
    payload = np.empty(1, dtype=object)
    payload[0] = Payload(marker)
    np.savez(path, trajectories=trajectories(), note=payload)
    with pytest.raises(ConfigError):
        load_tracks(path, track_source(path, {}))
    assert not marker.exists()


CALIBRATION = '''
name = "poisoned"
seed = 3
[model]
preset = "{preset}"
[run]
n = 4
duration = 6.0
warmup = 1.0
[observation]
interval = 0.1
[parameters.separation]
key = "steering.separation_weight"
prior = {{ dist = "uniform", low = 6, high = 18 }}
[targets]
stats = ["polarization"]
from_tracks = "{tracks}"
[method]
kind = "emcee"
n_sim = 4
walkers = 4
steps = 2
'''


@pytest.mark.parametrize("command", ["targets", "calibrate"])
def test_a_calibration_file_cannot_make_it_run_either(poisoned, marker, tmp_path, capsys, command):
    path = tmp_path / "cal.toml"
    path.write_text(CALIBRATION.format(preset=ROOT / "configs/models/holland.toml", tracks=poisoned))
    args = [command, str(path)] + (["--from-tracks"] if command == "targets" else ["--out", str(tmp_path / "c")])
    assert main(args) == 2
    assert "not opened" in capsys.readouterr().err
    assert not marker.exists()


@pytest.mark.parametrize("protocol", [2, 3, 4, 5])
def test_idtracker_dictionaries_as_numpy_pickles_them_still_read(tmp_path, protocol):
    extra = {"setup_points": collections.OrderedDict(border=np.zeros((3, 2))), "video_path": pathlib.Path("/v.avi"),
             "id_probabilities": np.ones((40, 4, 1), dtype=np.float32), "stats": None,
             "frames_per_second": np.float64(10.0), "body_length": np.float32(20.0)}
    path = save_pickled(tmp_path / "trajectories.npy", idtracker_dict(**extra), protocol)
    data = read_npy(path).item()
    assert np.array_equal(data["trajectories"], trajectories()) and data["video_path"] == "/v.avi"
    table = load_tracks(path, track_source(path, {}))
    assert table.source.fps == 10.0 and table.source.body_length_px == 20.0
    assert sorted(table.frame["id"].unique()) == [1, 2, 3, 4]


def test_a_truncated_file_is_refused_before_its_declared_shape_is_allocated(tmp_path):
    path = tmp_path / "huge.npy"
    buffer = io.BytesIO()
    header = {"descr": "<f8", "fortran_order": False, "shape": (10**9, 10**4, 2)}
    np.lib.format.write_array_header_1_0(buffer, header)
    path.write_bytes(buffer.getvalue() + bytes(64))
    with pytest.raises(ValueError, match="truncated or damaged"):
        read_npy(path)
    with pytest.raises(ConfigError, match="truncated or damaged"):
        load_tracks(path, track_source(path, {}))
