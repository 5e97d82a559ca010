"""Leadership metrics of a run with the Hartman-Benes change of leadership (docs/model.md).

Computed from the recorded observations, never inside the simulator. Inputs (an ``Observations`` or
the same arrays given explicitly, see :func:`leadership_input`):

* ``times`` (R,) record times (s), evenly spaced by the record interval dr = ``record_every`` x ``dt``;
* ``pos``, ``vel`` (R, N, 3); ``leader`` (R, N) bool, the leaders at each record;
* ``triggers`` (E, 2) int, trigger events (step, boid) in order; ``dt`` the step length (s).

Notation. An event e = (step, b) happens at t0 = step x dt; its record is the one nearest t0,
r0 = round((t0 - times[0]) / dr) clipped to [0, R - 1] (the simulator decides a trigger at step s
from the state it records at step s, so r0 is exact when s is a multiple of ``record_every``).
v_hat = v/|v| is a unit heading; a stopped boid (|v| = 0) has none and is left out of every term
below. D is ``escape_duration``; the escape window holds the records r0, r0 + 1, ..., r0 + L with
L = floor(D / dr) (so it spans [t0, t0 + D]). The group of an event, G_e, is the connected component
holding b of the graph linking boids closer than ``group_radius`` at record r0 (``groups.py``;
minimum image in a periodic ``box``); its followers are F_e = G_e without b.

Per-run scalars of :func:`leadership_metrics` (LEADERSHIP_METRIC_NAMES):

* ``trigger_rate`` = E / N / (T / 60), trigger events per boid per minute, with T = times[-1] - times[0]
  the recorded span of the run (s). 0 when E = 0; nan when E > 0 and T = 0.
* ``leader_time_fraction`` = mean over records of [at least one leader], in [0, 1].
* ``leaders_mean`` = mean over records of the number of leaders, in [0, N].
* Follow response, after Nagy et al. 2010 (Nature 464: 890, "Hierarchical group dynamics
  in pigeon flocks"), who correlate one bird's heading with another's at a time lag. At lag tau = j dr,
  j = 0, 1, ..., J = floor(max_lag / dr):

      c_ef(tau) = mean over s = 0 .. L - j (records r0 + s + j past the last record are skipped)
                  of v_hat_b(r0 + s) . v_hat_f(r0 + s + j),       i.e. s in the window [t0, t0 + D - tau]
      C(tau)    = mean of c_ef(tau) over every (event e, follower f in F_e) pair that has a term,

  so an event weighs as many times as it has followers. Events without a follower (a stray leader)
  contribute nothing. ``follow_corr_lag0`` = C(0); ``follow_corr_max`` = max over tau of C(tau);
  ``follow_lag_max`` = the lag (s) of that maximum (the smallest such lag on ties); all nan when no
  event has a term. C is in [-1, 1]: 1 when every follower flies exactly as the leader flew tau
  earlier, about 0 for unrelated headings. A maximum at tau > 0 means the group turns after the leader.
* ``follow_corr_before`` = the same lag-0 correlation over the window before the trigger, records
  r0 - L .. r0 (i.e. [t0 - D, t0]; records before the first are skipped), with the same followers:
  the baseline to compare ``follow_corr_lag0`` and ``follow_corr_max`` with.
* ``heading_change_deg`` = mean over events of the angle (degrees, in [0, 180]) between
  h(r0) and h(r0 + L), h(r) = sum of the unit headings of the boids of G_e (leader included, the
  group fixed at r0) at record r: how far the leader's group turns over one escape. Only events whose
  window fits in the run (r0 + L <= R - 1) and whose two sums are non-zero (|h| > 1e-12 x |G_e|)
  count; nan when none does.
* ``escape_gain`` = mean over events of max_{s=0..L} |v_b(r0 + s)| / |v_b(r0)|: the leader's peak
  speed over the escape window relative to its speed at the trigger. Only events whose window fits in
  the run and whose leader moves at r0 count; nan when none does.

:func:`follow_curve` gives C(tau) for every lag (a DataFrame: lag, corr, pairs, events) for figures.
:func:`observables.summary.observation_leadership` ties the metrics to a model.

Cost: the correlation is one compiled pass (numba, ``cache=True``) over events x followers x lags x
window, O(E N J L); the groups cost one neighbour-graph pass over the distinct trigger records.
"""
from __future__ import annotations

from collections.abc import Mapping
from typing import Any, NamedTuple, TYPE_CHECKING

import numba as nb
import numpy as np

from .columns import LEADERSHIP_METRIC_NAMES  # noqa: F401 - declared there, part of this module's face
from .groups import check_radius, kernel_box, neighbour_graph
from .metrics import unit_headings

if TYPE_CHECKING:  # pandas is imported where it is used: importing this module stays light
    import pandas as pd

_FIELDS = ("times", "pos", "vel", "leader", "triggers", "dt", "record_every")
_EPS = 1e-9  # slack when a duration is divided into record intervals (3.0 / 0.1 = 29.999...)


class LeadershipInput(NamedTuple):
    """The observations the leadership metrics read (checked shapes and dtypes)."""

    times: np.ndarray     # float64 (R,)
    pos: np.ndarray       # float64 (R, N, 3)
    vel: np.ndarray       # float64 (R, N, 3)
    leader: np.ndarray    # bool (R, N)
    triggers: np.ndarray  # int64 (E, 2): (step, boid)
    dt: float
    record_every: int

    @property
    def record_interval(self) -> float:
        return self.dt * self.record_every


def leadership_input(obs_like: Any = None, **arrays) -> LeadershipInput:
    """The inputs from an ``Observations`` (or any object with the attributes times, pos, vel, leader,
    triggers, dt, record_every), a mapping with those keys, or the same given as keywords."""
    if obs_like is None:
        source = arrays
    elif isinstance(obs_like, LeadershipInput):
        return obs_like
    elif isinstance(obs_like, Mapping):
        source = obs_like
    else:
        source = {f: getattr(obs_like, f) for f in _FIELDS if hasattr(obs_like, f)}
    missing = [f for f in _FIELDS if f not in source]
    if missing:
        raise ValueError(f"leadership inputs: missing {', '.join(missing)}")
    times = np.asarray(source["times"], dtype=np.float64)
    pos = np.asarray(source["pos"], dtype=np.float64)
    vel = np.asarray(source["vel"], dtype=np.float64)
    leader = np.asarray(source["leader"], dtype=bool)
    triggers = np.asarray(source["triggers"], dtype=np.int64).reshape(-1, 2)
    dt = float(source["dt"])
    record_every = source["record_every"]
    if times.ndim != 1 or times.size == 0:
        raise ValueError(f"times: expected a non-empty 1-D array, got shape {times.shape}")
    n_rec = times.size
    if pos.ndim != 3 or pos.shape[0] != n_rec or pos.shape[2] != 3 or pos.shape[1] < 1:
        raise ValueError(f"pos: expected shape ({n_rec}, N, 3) with N >= 1, got {pos.shape}")
    if vel.shape != pos.shape:
        raise ValueError(f"vel: expected shape {pos.shape}, got {vel.shape}")
    if leader.shape != pos.shape[:2]:
        raise ValueError(f"leader: expected shape {pos.shape[:2]}, got {leader.shape}")
    if not (np.isfinite(dt) and dt > 0):
        raise ValueError(f"dt: got {dt!r}; must be a finite number > 0")
    if isinstance(record_every, bool) or int(record_every) != record_every or record_every < 1:
        raise ValueError(f"record_every: got {record_every!r}; must be an integer >= 1 (steps)")
    record_every = int(record_every)
    interval = dt * record_every
    if n_rec > 1 and not np.allclose(np.diff(times), interval, rtol=1e-6, atol=1e-9 * interval):
        raise ValueError(f"times: records must be evenly spaced by dt x record_every = {interval!r}")
    n = pos.shape[1]
    if triggers.size and (triggers[:, 0].min() < 0 or triggers[:, 1].min() < 0 or triggers[:, 1].max() >= n):
        raise ValueError(f"triggers: steps must be >= 0 and boids in [0, {n})")
    return LeadershipInput(times, pos, vel, leader, triggers, dt, record_every)


# ---------------------------------------------------------------------------------------------------
# compiled follow correlation


@nb.njit(cache=True)
def _pair_mean(head, moving, b, f, r_lead, r_foll, n_terms):
    """Mean of v_hat_b(r_lead + s) . v_hat_f(r_foll + s), s = 0 .. n_terms - 1, over the records that
    exist and where both move; (mean, terms) with terms = 0 when there is none."""
    n_rec = moving.shape[0]
    total = 0.0
    count = 0
    for s in range(n_terms):
        r = r_lead + s
        rf = r_foll + s
        if r < 0 or rf < 0:
            continue
        if r >= n_rec or rf >= n_rec:
            break
        if moving[r, b] and moving[rf, f]:
            total += head[r, b, 0] * head[rf, f, 0] + head[r, b, 1] * head[rf, f, 1] + head[r, b, 2] * head[rf, f, 2]
            count += 1
    if count == 0:
        return 0.0, 0
    return total / count, count


@nb.njit(cache=True)
def _follow_kernel(head, moving, ev_rec, ev_boid, ev_frame, labels, window, n_lags,
                   acc, pairs, events, before):
    """Accumulate the follow correlation of every event.

    ``acc[j]``, ``pairs[j]``, ``events[j]``: sum of the pair means c_ef(j dr), number of (event, follower)
    pairs with a term and number of events with such a pair, for j = 0 .. n_lags - 1; ``before`` (3,)
    the same three numbers for the lag-0 window before the trigger."""
    n = moving.shape[1]
    for e in range(ev_rec.shape[0]):
        r0 = ev_rec[e]
        b = ev_boid[e]
        frame = ev_frame[e]
        group = labels[frame, b]
        used = np.zeros(n_lags + 1, np.bool_)
        for f in range(n):
            if f == b or labels[frame, f] != group:
                continue
            for j in range(n_lags):
                if window - j < 0:
                    break
                c, terms = _pair_mean(head, moving, b, f, r0, r0 + j, window - j + 1)
                if terms > 0:
                    acc[j] += c
                    pairs[j] += 1.0
                    used[j] = True
            c, terms = _pair_mean(head, moving, b, f, r0 - window, r0 - window, window + 1)
            if terms > 0:
                before[0] += c
                before[1] += 1.0
                used[n_lags] = True
        for j in range(n_lags):
            if used[j]:
                events[j] += 1.0
        if used[n_lags]:
            before[2] += 1.0


# ---------------------------------------------------------------------------------------------------
# the metrics


class _Events(NamedTuple):
    rec: np.ndarray     # int64 (E,) record nearest each trigger
    boid: np.ndarray    # int64 (E,) the leader
    frame: np.ndarray   # int64 (E,) row of ``labels`` for each event
    labels: np.ndarray  # int32 (U, N) group labels at the distinct trigger records
    window: int         # L: records in the escape window after r0
    n_lags: int         # J + 1


def _events(inp: LeadershipInput, group_radius: float, escape_duration: float, box: float | None,
            max_lag: float) -> _Events:
    check_radius(group_radius)
    kernel_box(box)
    if not (np.isfinite(escape_duration) and escape_duration > 0):
        raise ValueError(f"escape_duration: got {escape_duration!r}; must be a finite number > 0")
    if not (np.isfinite(max_lag) and max_lag >= 0):
        raise ValueError(f"max_lag: got {max_lag!r}; must be a finite number >= 0")
    interval = inp.record_interval
    n_rec = inp.times.size
    t0 = inp.triggers[:, 0] * inp.dt
    rec = np.clip(np.floor((t0 - inp.times[0]) / interval + 0.5), 0, n_rec - 1).astype(np.int64)
    distinct, frame = np.unique(rec, return_inverse=True)
    if distinct.size:
        labels = neighbour_graph(inp.pos[distinct], group_radius, box).labels
    else:
        labels = np.zeros((0, inp.pos.shape[1]), np.int32)
    window = int(np.floor(escape_duration / interval + _EPS))
    n_lags = int(np.floor(max_lag / interval + _EPS)) + 1
    return _Events(rec, inp.triggers[:, 1].copy(), frame.reshape(-1).astype(np.int64), labels, window, n_lags)


def _follow(inp: LeadershipInput, ev: _Events):
    """(acc, pairs, events, before) of :func:`_follow_kernel`."""
    head, moving = unit_headings(inp.vel)
    acc = np.zeros(ev.n_lags)
    pairs = np.zeros(ev.n_lags)
    events = np.zeros(ev.n_lags)
    before = np.zeros(3)
    if ev.rec.size:
        _follow_kernel(np.ascontiguousarray(head), np.ascontiguousarray(moving), ev.rec, ev.boid, ev.frame,
                       np.ascontiguousarray(ev.labels), ev.window, ev.n_lags, acc, pairs, events, before)
    return acc, pairs, events, before


def _ratio(total: float, count: float) -> float:
    return float(min(max(total / count, -1.0), 1.0)) if count > 0 else float("nan")


def _curve(acc: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """C(tau) = acc / pairs clipped to [-1, 1] (rounding), nan where no pair has a term."""
    corr = np.full(acc.shape, np.nan)
    np.divide(acc, pairs, out=corr, where=pairs > 0)
    return np.clip(corr, -1.0, 1.0)


def follow_curve(obs_like, group_radius: float, escape_duration: float, box: float | None = None,
                 max_lag: float = 2.0) -> pd.DataFrame:
    """C(tau) for tau = 0, dr, ..., max_lag (see the module docstring), one row per lag:
    ``lag`` (s), ``corr`` (nan without a term), ``pairs`` ((event, follower) pairs averaged) and
    ``events`` (events with at least one such pair)."""
    import pandas as pd
    inp = leadership_input(obs_like)
    ev = _events(inp, group_radius, escape_duration, box, max_lag)
    acc, pairs, events, _ = _follow(inp, ev)
    corr = _curve(acc, pairs)
    return pd.DataFrame({"lag": np.arange(ev.n_lags) * inp.record_interval, "corr": corr,
                         "pairs": pairs.astype(np.int64), "events": events.astype(np.int64)})


def _group_turn_and_gain(inp: LeadershipInput, ev: _Events) -> tuple[float, float]:
    """(heading_change_deg, escape_gain) means over the events whose escape window fits in the run."""
    n_rec = inp.times.size
    fits = ev.rec + ev.window <= n_rec - 1
    if not fits.any():
        return float("nan"), float("nan")
    rec, boid, frame = ev.rec[fits], ev.boid[fits], ev.frame[fits]
    labels = ev.labels[frame]                                        # (F, N)
    member = labels == labels[np.arange(rec.size), boid][:, None]    # the leader's group, leader included
    head, _ = unit_headings(inp.vel)
    start = np.einsum("en,enk->ek", member, head[rec])
    end = np.einsum("en,enk->ek", member, head[rec + ev.window])
    size = member.sum(axis=1)
    len_start = np.linalg.norm(start, axis=1)
    len_end = np.linalg.norm(end, axis=1)
    ok = (len_start > 1e-12 * size) & (len_end > 1e-12 * size)
    cross = np.linalg.norm(np.cross(start[ok], end[ok]), axis=1)
    dot = np.einsum("ek,ek->e", start[ok], end[ok])
    turn = float(np.degrees(np.arctan2(cross, dot)).mean()) if ok.any() else float("nan")

    speed = np.linalg.norm(inp.vel, axis=-1)                          # (R, N)
    span = rec[:, None] + np.arange(ev.window + 1)                    # (F, L + 1)
    peak = speed[span, boid[:, None]].max(axis=1)
    first = speed[rec, boid]
    moving = first > 0
    gain = float((peak[moving] / first[moving]).mean()) if moving.any() else float("nan")
    return turn, gain


def leadership_metrics(obs_like, group_radius: float, escape_duration: float, box: float | None = None,
                       max_lag: float = 2.0) -> dict[str, float]:
    """Per-run leadership scalars (LEADERSHIP_METRIC_NAMES; formulas in the module docstring).

    ``obs_like``: an ``Observations``, a mapping or a :class:`LeadershipInput` (see
    :func:`leadership_input`); ``group_radius`` links boids into groups (strictly closer); ``escape_duration``
    is the model's ``leadership.duration`` (s); ``box`` the periodic box side or None; ``max_lag`` (s) the
    largest lag of the follow correlation."""
    inp = leadership_input(obs_like)
    n_rec, n = inp.leader.shape
    n_events = inp.triggers.shape[0]
    span = float(inp.times[-1] - inp.times[0])
    if n_events == 0:
        rate = 0.0
    else:
        rate = n_events / n / (span / 60.0) if span > 0 else float("nan")
    out = {
        "trigger_rate": float(rate),
        "leader_time_fraction": float(inp.leader.any(axis=1).mean()),
        "leaders_mean": float(inp.leader.sum(axis=1).mean()),
    }
    ev = _events(inp, group_radius, escape_duration, box, max_lag)
    acc, pairs, _, before = _follow(inp, ev)
    corr = _curve(acc, pairs)
    out["follow_corr_lag0"] = float(corr[0])
    if np.isfinite(corr).any():
        best = int(np.nanargmax(corr))
        out["follow_corr_max"] = float(corr[best])
        out["follow_lag_max"] = float(best * inp.record_interval)
    else:
        out["follow_corr_max"] = out["follow_lag_max"] = float("nan")
    out["follow_corr_before"] = _ratio(before[0], before[1])
    out["heading_change_deg"], out["escape_gain"] = _group_turn_and_gain(inp, ev)
    return {name: out[name] for name in LEADERSHIP_METRIC_NAMES}
