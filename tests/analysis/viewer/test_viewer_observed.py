"""An observed flock (measured tracks) as a viewer Track: the individuals present at every record
(analysis.viewer.track.from_observed)."""
from __future__ import annotations

import numpy as np
import pytest

from analysis.viewer.track import from_observed
from observables.observed import ObservedFlock


def _flock(present: np.ndarray) -> ObservedFlock:
    records, n = present.shape
    rng = np.random.default_rng(4)
    pos, vel = rng.normal(size=(records, n, 3)), rng.normal(size=(records, n, 3))
    pos[~present], vel[~present] = np.nan, np.nan
    return ObservedFlock(name="f1", ids=np.arange(n), times=0.2 * np.arange(records), pos=pos, vel=vel,
                         present=present, interval=0.2)


def test_the_individuals_present_at_every_record_are_shown_and_the_page_says_how_many():
    present = np.ones((6, 4), dtype=bool)
    present[2, 1] = False                                   # individual 1 missed once
    flock = _flock(present)
    track = from_observed(flock, info={"flock": "f1"}, group_radius=5.0)
    assert track.n == 3 and np.array_equal(track.pos, flock.pos[:, [0, 2, 3]])
    assert np.array_equal(track.vel, flock.vel[:, [0, 2, 3]]) and np.array_equal(track.times, flock.times)
    assert track.info == {"flock": "f1", "individuals shown": "3 of 4 (those present at every record)"}
    assert track.group_radius == 5.0 and track.title == "flock f1"
    assert from_observed(_flock(np.ones((6, 4), dtype=bool))).info["individuals shown"] == "4 of 4"


def test_a_flock_with_nobody_present_throughout_is_refused_by_name():
    present = np.ones((6, 2), dtype=bool)
    present[1, 0] = present[4, 1] = False
    with pytest.raises(ValueError, match="flock 'f1': no individual is present at every record"):
        from_observed(_flock(present))
