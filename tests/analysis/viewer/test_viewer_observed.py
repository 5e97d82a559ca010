"""An observed flock (measured tracks) as a viewer Track, gaps interpolated (analysis.viewer.track.from_observed),
and a Track's frames from a time on (Track.since)."""
from __future__ import annotations

import numpy as np
import pytest

from flocksweep.analysis.viewer.track import from_arrays, from_observed
from flocksweep.observables.observed import ObservedFlock


def _flock(present: np.ndarray) -> ObservedFlock:
    records, n = present.shape
    rng = np.random.default_rng(4)
    pos, vel = rng.normal(size=(records, n, 3)), rng.normal(size=(records, n, 3))
    pos[~present], vel[~present] = np.nan, np.nan
    return ObservedFlock(name="f1", ids=np.arange(n), times=0.2 * np.arange(records), pos=pos, vel=vel,
                         present=present, interval=0.2)


def test_every_individual_seen_is_drawn_with_its_gaps_interpolated_and_the_page_says_so():
    present = np.ones((6, 4), dtype=bool)
    present[2, 1] = False                                   # individual 1 missed once
    present[:2, 3] = present[5, 3] = False                  # individual 3 seen late and lost at the end
    flock = _flock(present)
    track = from_observed(flock, info={"flock": "f1"}, group_radius=5.0)
    assert track.n == 4 and np.array_equal(track.times, flock.times)
    assert np.array_equal(track.pos[present], flock.pos[present])          # what was measured is kept
    assert np.array_equal(track.vel[present], flock.vel[present])
    np.testing.assert_allclose(track.pos[2, 1], (flock.pos[1, 1] + flock.pos[3, 1]) / 2, rtol=1e-12)
    np.testing.assert_allclose(track.vel[2, 1], (flock.vel[1, 1] + flock.vel[3, 1]) / 2, rtol=1e-12)
    assert np.array_equal(track.pos[:2, 3], flock.pos[[2, 2], 3]) and np.array_equal(track.pos[5, 3], flock.pos[4, 3])
    assert track.info == {"flock": "f1", "individuals shown": "4 of 4",
                          "filled in": "4 of 24 positions (16.7%), interpolated between detections"}
    assert track.group_radius == 5.0 and track.title == "flock f1"


def test_an_individual_never_present_is_left_out_and_a_flock_of_nobody_is_refused():
    present = np.ones((6, 3), dtype=bool)
    present[:, 1] = False
    track = from_observed(_flock(present))
    assert track.n == 2 and track.info["individuals shown"] == "2 of 3 (the others are never present)"
    assert track.info["filled in"] == "0 of 12 positions (0.0%), interpolated between detections"
    with pytest.raises(ValueError, match="flock 'f1': no individual is present at any record"):
        from_observed(_flock(np.zeros((6, 2), dtype=bool)))


def test_since_keeps_the_frames_from_a_time_on_on_a_shifted_clock():
    times = 0.2 * np.arange(10)
    pos = np.random.default_rng(1).normal(size=(10, 3, 3))
    leader = np.zeros((10, 3), dtype=bool)
    leader[7, 1] = True
    track = from_arrays(times, pos, leader=leader)
    later = track.since(0.6, 0.6)                          # 0.6 is 3 x 0.2 only to rounding: still kept
    assert later.frames == 7 and np.array_equal(later.pos, pos[3:]) and np.array_equal(later.leader, leader[3:])
    np.testing.assert_allclose(later.times, times[3:] - 0.6, atol=1e-15)
    assert track.since(5.0).frames == 1 and track.since(-1.0, -1.0).times[0] == 1.0
