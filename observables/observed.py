"""A flock as an observer sees it: positions and velocities on a regular record grid, with who was seen.

:class:`ObservedFlock` is what a tracking system delivers once resampled (:mod:`.resample`): measured
tracks of a real flock, or a simulated run seen through an observation model (:mod:`.observation`).
It quacks like a simulator ``Observations`` where the metrics look (``times``, ``pos``, ``vel``,
``pattern``; ``visible`` and ``binocular`` are None, so ``visible_mean``, ``visible_sd`` and ``binocular_share`` are nan:
nobody measures what a bird perceives), and adds ``present`` (R, N) bool: individual i counts at record
r when its position and velocity there are known. Missing entries of ``pos`` and ``vel`` are nan.

``present_metrics(flock, group_radius, box=None, k_nearest=6, pairwise=True)`` is
:func:`~observables.metrics.frame_metrics` record by record over the individuals present: at record r
the metrics are those of the flock made of the ``present[r]`` individuals, in index order (so with
everyone present it is exactly ``frame_metrics`` of the whole arrays). Records are batched into one compiled call per distinct set
of present individuals (or per number of them, when patterns do not matter); a record with nobody
present gets nan for every metric. ``overtake_rate`` compares consecutive records, so it is computed
(with ``interval``, the grid's spacing) when every individual is present at every record, and is nan
otherwise. :func:`observables.summary.measure_run` calls it for any
observations with a ``present`` mask, so measured and simulated flocks share one definition of every
metric and of the summary row.

``dims`` is 3, or 2 for planar tracks (their third coordinate is 0). ``ids`` names the individuals (as in
the track file) and ``name`` the flock.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .metrics import K_NEAREST, METRIC_NAMES, frame_metrics


@dataclass(frozen=True, eq=False)
class ObservedFlock:
    name: str
    ids: np.ndarray            # (N,) the individuals' ids as in the track file
    times: np.ndarray          # (R,) seconds since the flock's first sample
    pos: np.ndarray            # (R, N, 3) float64, nan where unknown
    vel: np.ndarray            # (R, N, 3) float64, nan where unknown
    present: np.ndarray        # (R, N) bool: position and velocity known
    dims: int = 3
    pattern: np.ndarray | None = None   # (N,) int, each individual's pattern (None: one for all)
    t_start: float = 0.0       # the source clock's time at t = 0 (s)
    interval: float | None = None   # seconds between records (the resampling grid's), for overtake_rate
    visible = None             # not observable: the perception metrics are nan
    binocular = None

    @property
    def n(self) -> int:
        return self.pos.shape[1]

    @property
    def tracked(self) -> np.ndarray:
        """(R,) float64: individuals present at each record."""
        return self.present.sum(axis=1).astype(np.float64)


def _groups(present: np.ndarray, by_members: bool) -> dict:
    """Records grouped by their set of present individuals (``by_members``) or by how many there are."""
    groups: dict = {}
    for r, row in enumerate(present):
        key = row.tobytes() if by_members else int(row.sum())
        groups.setdefault(key, []).append(r)
    return groups


def present_metrics(flock, group_radius: float, box: float | None = None, k_nearest: int = K_NEAREST,
                    pairwise: bool = True) -> dict[str, np.ndarray]:
    """Every metric of METRIC_NAMES per record over the individuals present (see the module docstring;
    ``k_nearest`` and ``pairwise`` as for :func:`~observables.metrics.frame_metrics`)."""
    present = np.asarray(flock.present, dtype=bool)
    n_records, n = present.shape
    pattern = None if flock.pattern is None else np.asarray(flock.pattern)
    if present.all():   # everyone at every record: the simulator's definition, overtakes included
        return frame_metrics(flock.pos, flock.vel, None, None, pattern, group_radius, box, flock.interval,
                             k_nearest, pairwise)
    out = {name: np.full(n_records, np.nan) for name in METRIC_NAMES}
    by_members = pattern is not None and np.unique(pattern).size > 1
    for records in _groups(present, by_members).values():
        records = np.asarray(records)
        members = present[records]                     # (B, N), equal counts in a group
        count = int(members[0].sum())
        if count == 0:
            continue
        if members.all():
            pos, vel = flock.pos[records], flock.vel[records]
        else:
            pos = flock.pos[records][members].reshape(len(records), count, 3)
            vel = flock.vel[records][members].reshape(len(records), count, 3)
        group_pattern = None if pattern is None else (pattern[members[0]] if by_members else pattern[:count])
        series = frame_metrics(pos, vel, None, None, group_pattern, group_radius, box, None, k_nearest, pairwise)
        for name in METRIC_NAMES:
            out[name][records] = series[name]
    return out
