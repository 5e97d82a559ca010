"""Flocks with planted leader-follower delays (directional correlation tests: observables, the measure
report)."""
from __future__ import annotations

import numpy as np
import pandas as pd


def turning_flock(delays, records=200, seed=0, noise=0.0):
    """A leader whose heading wanders in the plane; individual k copies it delays[k] records later."""
    rng = np.random.default_rng(seed)
    angle = np.cumsum(rng.normal(0.0, 0.25, records + max(delays)))
    vel = np.zeros((records, len(delays), 3))
    for k, d in enumerate(delays):
        a = angle[max(delays) - d: max(delays) - d + records] + rng.normal(0.0, noise, records)
        vel[:, k, 0], vel[:, k, 1] = np.cos(a) * 2.0, np.sin(a) * 2.0
    return vel


def write_planted_tracks(path, delays, records: int, interval: float):
    """A turning flock (ids 0..N-1, 3 apart) as a long parquet track file with recorded velocities; returns
    the velocities (records, N, 3)."""
    vel = turning_flock(delays, records=records)
    n = len(delays)
    pos = np.cumsum(vel, axis=0) * interval + np.arange(n)[None, :, None] * 3.0
    t = np.arange(records) * interval
    frame = pd.DataFrame({"id": np.tile(np.arange(n), records), "t": np.repeat(t, n),
                          **{a: pos[:, :, k].reshape(-1) for k, a in enumerate("xyz")},
                          **{f"v{a}": vel[:, :, k].reshape(-1) for k, a in enumerate("xyz")}})
    frame.to_parquet(path, index=False)
    return vel
