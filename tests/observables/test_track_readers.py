"""Track readers that agree or refuse (issue 42): the malformed-input battery's track readers section
(tests/malformed.py TRACK_READERS) refused cleanly, each in one message with exit 2 and nothing written; and
what a reader handles instead of refusing, checked against the truth: decimal commas, tracks across the
antimeridian, Movebank stamps with mixed UTC offsets."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from malformed import TRACK_READERS, attempt
from flocksweep.observables.track_formats import project_wgs84
from flocksweep.observables.tracks import TrackSource, load_tracks


@pytest.mark.parametrize("case", TRACK_READERS, ids=[c.name for c in TRACK_READERS])
def test_each_track_reader_case_is_one_message_and_exit_2_with_nothing_written(case, tmp_path):
    refusal = attempt(case, tmp_path)
    assert refusal.crash == "", refusal.crash
    assert refusal.code == case.code, refusal.stderr
    assert case.expect.lower() in refusal.stderr.lower(), refusal.stderr
    assert refusal.stderr.strip().startswith("flocksweep: ") and "Traceback" not in refusal.stderr
    assert refusal.written == set(), refusal.written


def test_decimal_commas_in_a_semicolon_file_are_read_exactly(tmp_path):
    path = tmp_path / "t.csv"
    path.write_text("id;t;x;y\n1;0;0,125;-1,5\n1;0,5;1,25e1;2\n2;0;3;,5\n2;0,5;4;0,0\n")
    table = load_tracks(path, TrackSource())
    assert table.frame["x"].tolist() == [0.125, 12.5, 3.0, 4.0] and table.frame["y"].tolist() == [-1.5, 2.0, 0.5, 0.0]
    assert table.frame["t"].tolist() == [0.0, 0.5, 0.0, 0.5]
    (note,) = [i for i in table.issues if i.check == "reading"]
    assert note.detail == "decimal commas read as decimal points in column(s) t, x, y"


def test_tracks_across_the_antimeridian_keep_their_distances(tmp_path):
    from pyproj import Geod
    lon = np.array([179.9990, -179.9995, 179.9995, -179.9990])
    lat = np.array([-16.5, -16.5, -16.5005, -16.4995])
    x, y, centre = project_wgs84(lon, lat)
    assert abs(abs(centre[0]) - 180.0) < 0.001            # the middle of the fixes, not the far side of the globe
    geod = Geod(ellps="WGS84")
    for a in range(4):
        for b in range(a + 1, 4):
            metres = geod.inv(lon[a], lat[a], lon[b], lat[b])[2]
            assert np.hypot(x[a] - x[b], y[a] - y[b]) == pytest.approx(metres, rel=1e-7)


def test_movebank_stamps_with_mixed_utc_offsets_are_converted_to_utc(tmp_path):
    path = tmp_path / "gps.csv"
    pd.DataFrame({"timestamp": ["2010-04-01 11:00:00+01:00", "2010-04-01 10:00:01+00:00", "2010-04-01 10:00:02",
                                "2010-04-01 12:00:00+02:00", "2010-04-01 10:00:01.000", "2010-04-01 10:00:02Z"],
                  "location-long": [19.0, 19.0001, 19.0002, 19.0, 19.0001, 19.0002],
                  "location-lat": [47.5] * 3 + [47.5001] * 3,
                  "individual-local-identifier": ["a"] * 3 + ["b"] * 3}).to_csv(path, index=False)
    table = load_tracks(path, TrackSource())
    assert table.frame["t"].tolist() == [0.0, 1.0, 2.0, 0.0, 1.0, 2.0]
    assert any("different UTC offsets converted to UTC" in i.detail for i in table.issues)
