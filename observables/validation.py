"""Checking measured tracks: every problem named by flock, individual, row and column; nothing dropped
without saying so.

An :class:`Issue` is one finding: ``level`` "error" (the tracks cannot be used as they are), "warning"
(used, but look) or "note" (how the data were handled); ``check`` says which check found it. A
:class:`TrackError` carries the errors and says where they are (rows numbered from 1 in file order; a
CSV's line is the row + 1).

The checks on one flock (:func:`check_flock`), after reading (:mod:`.tracks`):

* **duplicates**: two samples of one individual at the same time: an error (which one is right?);
* **impossible speeds**: a sample reached from the individual's previous good sample faster than
  ``max_speed`` (default: 10 x the flock's median step speed) is judged against the group
  (:class:`BurstRule`): it is a **burst** when at least ``share`` (0.5) of the other individuals present
  within ``frames`` (5) sampling intervals of it each make a jump there (a step faster than ``jump`` (3)
  times that individual's own recent speed, the median of its previous 10 steps, the flock's median
  step speed standing in for steps before its first), and kept as motion
  with a note (``rule = "burst"``); otherwise it is a **glitch** (``rule = "glitch"``), which then shows
  as one flagged sample while the track continues from the last good one. ``bad_speeds`` says what
  happens to glitches: "error" (the default: stop and list them, rows in file order), "keep" (a warning,
  the samples are used) or "drop" (a warning listing the samples left out);
* **recorded velocities** (tracks with velocity columns): each sample's recorded velocity is compared with
  its velocity from position differences (centred over its neighbours, one-sided at an individual's
  first and last sample, :func:`difference_velocities`); a sample where they differ by more than
  ``VELOCITY_TOLERANCE`` (0.5) x the larger of the difference speed and the flock's median difference
  speed gets a warning, one per individual, naming the flock, the individual, the samples' times and
  rows, the size of the vector difference it fired on and both speeds (zero padding of one individual,
  velocities in other units or of other individuals show up this way; padding of every individual is
  dropped before, :mod:`.trimming`);
* **gaps**: consecutive samples of an individual more than 1.5 sampling intervals apart. Gaps up to
  ``max_gap`` are bridged by linear interpolation when resampling (a note), longer ones stay missing (a
  warning); one issue of each kind per flock, counting them and naming the longest gap, its individual
  and rows;
* **the tank** (tracks that declare their arena, :meth:`~observables.tracks.TrackSource.tank`): every
  sample must lie inside the declared walls. A sample beyond a wall by more than ``TANK_TOLERANCE`` (5%)
  of the tank's inner extent (its radius, or half its shortest side) is an error (a wrong centre, radius or
  unit is far more likely than an animal outside its tank), naming the farthest sample and the rows; samples
  outside by less (a centroid on the wall, tracker noise, a tank measured a little small) get a warning and
  are used (:func:`check_tank`). 2-D tracks are checked in their plane.

An issue's ``rule`` says which rule of its check fired; ``issues_table`` lists issues with empty text where
an issue names no flock, individual or column. ``infer_interval(flock)`` is the sampling interval of tracks that do not state it, from their time stamps
without rounding (:mod:`.clock`). ``issues_table`` lists issues as
a DataFrame (level, check, flock, id, column, rows, detail).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # pandas is imported where it is used: importing this module stays light
    import pandas as pd

VELOCITY_TOLERANCE = 0.5  # recorded and position-difference velocities disagree beyond this share of the speed
GAP_FACTOR = 1.5          # consecutive samples further apart than this many intervals make a gap
SPEED_FACTOR = 10.0       # default max_speed: this many times the flock's median step speed
BURST_SHARE = 0.5         # a fast sample is a burst when at least this share of the others present ...
BURST_FRAMES = 5.0        # ... within this many sampling intervals of it ...
BURST_JUMP = 3.0          # ... each move faster than this many times their own recent speed
RECENT_STEPS = 10         # an individual's recent speed: the median of its last this many steps
LEVELS = ("error", "warning", "note")
TANK_TOLERANCE = 0.05     # a sample beyond the declared tank's wall by more than this share of its inner extent


@dataclass(frozen=True)
class Issue:
    level: str
    check: str
    detail: str
    flock: str | None = None
    id: str | None = None
    rows: tuple = ()
    column: str | None = None
    rule: str = ""          # which rule of the check fired (the speed check: "glitch" or "burst")


def rows_text(rows, line_offset: int | None = None, limit: int = 8) -> str:
    """'row 12' / 'rows 12, 13, 40 (+5 more)', with the file lines when ``line_offset`` is given."""
    rows = [int(r) for r in rows]
    if not rows:
        return ""
    shown = ", ".join(map(str, rows[:limit])) + (f" (+{len(rows) - limit} more)" if len(rows) > limit else "")
    text = f"row{'s' if len(rows) > 1 else ''} {shown}"
    if line_offset is not None:
        lines = ", ".join(str(r + line_offset) for r in rows[:limit])
        text += f" (line{'s' if len(rows) > 1 else ''} {lines}{', ...' if len(rows) > limit else ''})"
    return text


def describe(issue: Issue, line_offset: int | None = None) -> str:
    where = [f"flock {issue.flock!r}" if issue.flock is not None else "",
             f"id {issue.id}" if issue.id is not None else "", rows_text(issue.rows, line_offset),
             f"column {issue.column!r}" if issue.column else ""]
    where = ", ".join(w for w in where if w)
    return f"{issue.level}: {issue.check}: {where + ': ' if where else ''}{issue.detail}"


class TrackError(ValueError):
    """Tracks that cannot be used as they are; ``issues`` lists every error found."""

    def __init__(self, issues, path=None, line_offset: int | None = None):
        self.issues = list(issues)
        self.path = path
        self.line_offset = line_offset
        errors = [i for i in self.issues if i.level == "error"] or self.issues
        head = f"{path}: " if path else ""
        lines = [describe(i, line_offset) for i in errors[:20]]
        more = f"\n  ... and {len(errors) - 20} more" if len(errors) > 20 else ""
        super().__init__(f"{head}{len(errors)} problem(s) in the tracks:\n  " + "\n  ".join(lines) + more)


ISSUE_COLUMNS = ("level", "check", "rule", "flock", "id", "column", "rows", "detail")


def issues_table(issues, line_offset: int | None = None) -> pd.DataFrame:
    """The issues as a table (``ISSUE_COLUMNS``; empty text where an issue names no flock, id or column),
    errors first."""
    import pandas as pd
    rows = [{"level": i.level, "check": i.check, "rule": i.rule, "flock": i.flock or "", "id": i.id or "",
             "column": i.column or "", "rows": rows_text(i.rows, line_offset, limit=20).split(" ", 1)[-1] if i.rows else "",
             "detail": i.detail} for i in issues]
    frame = pd.DataFrame(rows, columns=list(ISSUE_COLUMNS))
    order = frame["level"].map({level: k for k, level in enumerate(LEVELS)})
    return frame.iloc[np.argsort(order.to_numpy(), kind="stable")].reset_index(drop=True)


def _steps(raw) -> tuple[np.ndarray, np.ndarray]:
    """(index of each step's later sample, its time difference) for consecutive samples of an individual."""
    same = np.flatnonzero(np.diff(raw.ind) == 0) + 1
    return same, raw.t[same] - raw.t[same - 1]


def infer_interval(raw) -> float:
    """The sampling interval of a flock's time stamps, exact to their precision
    (:func:`~observables.clock.sampling_clock`)."""
    from .clock import sampling_clock
    try:
        return sampling_clock(raw.t, raw.ind).interval
    except ValueError as err:
        raise ValueError(f"flock {raw.name!r}: {err}") from None


def _duplicates(raw) -> list[Issue]:
    later, dt = _steps(raw)
    same = later[dt == 0]
    if not same.size:
        return []
    ids = sorted({str(raw.ids[raw.ind[k]]) for k in same})
    rows = sorted(set(raw.source_rows(same)) | set(raw.source_rows(same - 1)))
    return [Issue("error", "duplicate", f"{same.size} samples repeat an individual's time "
                  f"(individuals {', '.join(ids[:10])}{' ...' if len(ids) > 10 else ''}); remove or merge them",
                  flock=raw.name, rows=tuple(rows))]


@dataclass(frozen=True)
class BurstRule:
    """When a fast sample is the group's burst rather than a glitch (see the module docstring)."""

    share: float = BURST_SHARE
    frames: float = BURST_FRAMES
    jump: float = BURST_JUMP


def _recent_speeds(raw, later: np.ndarray, speed: np.ndarray, fallback: float) -> np.ndarray:
    """Each step's individual's median speed over its previous RECENT_STEPS steps (``fallback``, the
    flock's median step speed, standing in for the steps before its first)."""
    from numpy.lib.stride_tricks import sliding_window_view
    out = np.empty(len(later))
    ind = raw.ind[later]
    starts = np.flatnonzero(np.r_[True, np.diff(ind) != 0])
    for lo, hi in zip(starts, np.r_[starts[1:], len(ind)]):
        padded = np.concatenate([np.full(RECENT_STEPS, fallback), speed[lo:hi - 1]])
        out[lo:hi] = np.median(sliding_window_view(padded, RECENT_STEPS), axis=1)
    return out


class _Group:
    """Who moves how at each time: the steps in time order, and which are jumps (faster than ``rule.jump``
    times the individual's own recent speed)."""

    def __init__(self, raw, later, speed, median, interval, rule: BurstRule):
        order = np.argsort(raw.t[later], kind="stable")
        self.t = raw.t[later][order]
        self.ind = raw.ind[later][order]
        recent = _recent_speeds(raw, later, speed, median)
        self.jump = (speed > rule.jump * np.maximum(recent, 1e-300))[order]
        self.window = rule.frames * interval
        self.rule = rule

    def share(self, i: int, t: float) -> tuple[float, int]:
        """(share of the other individuals with a step within the window of ``t`` that jump there, their count)."""
        lo = np.searchsorted(self.t, t - self.window * (1 + 1e-9), side="left")
        hi = np.searchsorted(self.t, t + self.window * (1 + 1e-9), side="right")
        ind, jump = self.ind[lo:hi], self.jump[lo:hi]
        others = ind != i
        present = np.unique(ind[others])
        if present.size == 0:
            return 0.0, 0
        return np.unique(ind[others & jump]).size / present.size, int(present.size)

    def burst(self, i: int, t: float) -> bool:
        share, count = self.share(i, t)
        return count > 0 and share >= self.rule.share


def _too_fast(raw, limit: float, group=None) -> tuple[np.ndarray, np.ndarray]:
    """(glitches, bursts): samples reached from the individual's last good sample faster than ``limit``
    (greedy, in time order); those the group moves with are bursts, kept as motion. ``group``: a function
    returning the flock's :class:`_Group` (built only when some sample is too fast)."""
    flagged = np.zeros(len(raw.t), dtype=bool)
    bursts = np.zeros(len(raw.t), dtype=bool)
    later, dt = _steps(raw)
    speed = np.linalg.norm(raw.pos[later] - raw.pos[later - 1], axis=1) / dt
    suspects = np.unique(raw.ind[later[speed > limit]])
    bounds = raw.bounds()
    for i in suspects:
        good = bounds[i]
        for k in range(bounds[i] + 1, bounds[i + 1]):
            if np.linalg.norm(raw.pos[k] - raw.pos[good]) / (raw.t[k] - raw.t[good]) > limit:
                if group is not None and group().burst(i, raw.t[k]):
                    bursts[k] = True
                    good = k
                else:
                    flagged[k] = True
            else:
                good = k
    return flagged, bursts


def _ids_text(raw, samples) -> str:
    ids = sorted({str(raw.ids[raw.ind[k]]) for k in samples})
    return f"{', '.join(ids[:10])}{' ...' if len(ids) > 10 else ''}"


def _speeds(raw, max_speed: float | None, policy: str, unit: str, interval: float | None = None,
            rule: BurstRule | None = None):
    later, dt = _steps(raw)
    if later.size == 0:
        return raw, []
    speed = np.linalg.norm(raw.pos[later] - raw.pos[later - 1], axis=1) / dt
    median = float(np.median(speed))
    limit = max_speed if max_speed is not None else SPEED_FACTOR * median
    if not limit > 0:
        return raw, [Issue("note", "speed", "the median step speed is 0: no speed check", flock=raw.name)]
    rule = BurstRule() if rule is None else rule
    built = []

    def group() -> _Group:
        if not built:
            built.append(_Group(raw, later, speed, median, interval or float(np.median(dt)), rule))
        return built[0]

    flagged, bursts = _too_fast(raw, limit, group)
    how = "max_speed" if max_speed is not None else f"{SPEED_FACTOR:g} x the median step speed"
    issues = []
    if bursts.any():
        samples = np.flatnonzero(bursts)
        issues.append(Issue("note", "speed", f"burst: {samples.size} samples of individuals {_ids_text(raw, samples)} reached "
                            f"faster than {limit:.4g} {unit}/s ({how}) at t = {raw.t[samples].min():.6g} to "
                            f"{raw.t[samples].max():.6g} s, together with the group (at least {rule.share:.0%} of the "
                            f"others present within {rule.frames:g} sampling intervals moved faster than "
                            f"{rule.jump:g} x their own recent speed): a burst of the group, kept as motion",
                            flock=raw.name, rows=tuple(sorted(raw.source_rows(samples))), rule="burst"))
    if not flagged.any():
        return raw, issues
    samples = np.flatnonzero(flagged)
    text = (f"glitch: {samples.size} samples reached faster than {limit:.4g} {unit}/s ({how}) from the individual's previous "
            f"good sample while the group did not move with them (individuals {_ids_text(raw, samples)})")
    rows = tuple(sorted(raw.source_rows(samples)))
    if policy == "error":
        return raw, issues + [Issue("error", "speed", text + "; fix them, or pass bad_speeds = keep / drop",
                                    flock=raw.name, rows=rows, rule="glitch")]
    if policy == "keep":
        return raw, issues + [Issue("warning", "speed", text + "; kept (bad_speeds = keep)", flock=raw.name,
                                    rows=rows, rule="glitch")]
    keep = ~flagged
    cleaned = dataclasses.replace(raw, t=raw.t[keep], ind=raw.ind[keep], pos=raw.pos[keep],
                                  vel=None if raw.vel is None else raw.vel[keep],
                                  rows=None if raw.rows is None else raw.rows[keep])
    return cleaned, issues + [Issue("warning", "speed", text + "; left out (bad_speeds = drop)", flock=raw.name,
                                    rows=rows, rule="glitch")]


def difference_velocities(raw) -> np.ndarray:
    """(S, 3) each sample's velocity from positions: (p_next - p_prev) / (t_next - t_prev) over the
    individual's neighbouring samples (the sample itself at its first and last one); nan for a lone sample."""
    count = len(raw.t)
    index = np.arange(count)
    same = np.diff(raw.ind) == 0
    lo = np.where(np.r_[False, same], index - 1, index)
    hi = np.where(np.r_[same, False], index + 1, index)
    dt = raw.t[hi] - raw.t[lo]
    out = np.full((count, 3), np.nan)
    ok = dt > 0
    out[ok] = (raw.pos[hi[ok]] - raw.pos[lo[ok]]) / dt[ok, None]
    return out


def _velocity_agreement(raw, unit: str) -> list[Issue]:
    """A warning per individual whose recorded velocities disagree with its position differences."""
    if raw.vel is None or len(raw.t) == 0:
        return []
    diff = difference_velocities(raw)
    speed = np.linalg.norm(diff, axis=1)
    if not np.isfinite(speed).any():
        return []
    typical = float(np.nanmedian(speed))
    error = np.linalg.norm(raw.vel - diff, axis=1)
    with np.errstate(invalid="ignore"):
        bad = error > VELOCITY_TOLERANCE * np.maximum(speed, typical)
    issues = []
    for i in np.unique(raw.ind[bad]):
        samples = np.flatnonzero(bad & (raw.ind == i))
        k = samples[0]
        times = ", ".join(f"{t:.6g}" for t in raw.t[samples[:8]]) + (" ..." if len(samples) > 8 else "")
        issues.append(Issue("warning", "velocity", f"{len(samples)} sample(s) at t = {times} s: the recorded "
                            f"velocity vector differs from the position-difference one by more than "
                            f"{VELOCITY_TOLERANCE:g} x the speed (first: |recorded - from positions| = {error[k]:.4g} "
                            f"{unit}/s, {error[k] / max(speed[k], typical):.2f} x the speed {max(speed[k], typical):.4g}; "
                            f"recorded speed {np.linalg.norm(raw.vel[k]):.4g}, from positions {speed[k]:.4g}, the "
                            f"flock's median {typical:.4g}): zero padding, other units, a turn the positions do not "
                            "show, or another individual's velocities? Used as recorded; a velocity interval "
                            "differences positions instead", flock=raw.name, id=str(raw.ids[i]),
                            rows=raw.source_rows(samples)))
    return issues


def _gaps(raw, interval: float, max_gap: float) -> list[Issue]:
    later, dt = _steps(raw)
    gap = dt > GAP_FACTOR * interval
    issues = []
    for level, kind, selected in (("note", "bridged by interpolation", gap & (dt <= max_gap * (1 + 1e-9))),
                                  ("warning", "left missing", gap & (dt > max_gap * (1 + 1e-9)))):
        if not selected.any():
            continue
        worst = np.flatnonzero(selected)[np.argmax(dt[selected])]
        k = later[worst]
        count = int(np.unique(raw.ind[later[selected]]).size)
        issues.append(Issue(level, "gap", f"{int(selected.sum())} gap(s) of {count} individual(s) {kind} (max_gap "
                            f"{max_gap:g} s); the longest: {dt[worst]:.4g} s, from t = {raw.t[k - 1]:.6g} s to "
                            f"{raw.t[k]:.6g} s (its rows)", flock=raw.name, id=str(raw.ids[raw.ind[k]]),
                            rows=raw.source_rows([k - 1, k])))
    return issues


def check_flock(raw, interval: float, max_gap: float, max_speed: float | None = None, bad_speeds: str = "error",
                unit: str = "length units", burst: BurstRule | None = None):
    """(the flock to use, its issues): duplicates, impossible speeds (glitches and bursts, ``burst`` the
    rule), recorded velocities and gaps (see the module docstring); ``unit`` names the length unit in
    messages."""
    issues = _duplicates(raw)
    if issues:
        return raw, issues
    raw, speed_issues = _speeds(raw, max_speed, bad_speeds, unit, interval, burst)
    return raw, speed_issues + _velocity_agreement(raw, unit) + _gaps(raw, interval, max_gap)


def beyond_wall(tank, pos: np.ndarray, dims: int) -> np.ndarray:
    """(S,) how far each position (S, 3) lies beyond the walls of ``tank`` (a
    :class:`simcore.arena.Arena`; 0 or less: inside); ``dims`` 2: in the x-y plane only."""
    offset = np.asarray(pos, dtype=np.float64) - np.asarray(tank.centre, dtype=np.float64)
    if tank.kind == "cylinder":
        out = np.hypot(offset[:, 0], offset[:, 1]) - tank.radius
        if dims == 3 and tank.height is not None:
            out = np.maximum(out, np.abs(offset[:, 2]) - tank.height / 2.0)
        return out
    half = np.asarray(tank.size, dtype=np.float64)[:dims] / 2.0
    return (np.abs(offset[:, :dims]) - half).max(axis=1)


def check_tank(raw, tank, unit: str = "length units") -> list[Issue]:
    """The samples of ``raw`` outside the declared ``tank`` (see the module docstring): an error beyond the
    tolerance, a warning within it; [] when every sample is inside (or there is no tank)."""
    if tank is None or not len(raw.t):
        return []
    out = beyond_wall(tank, raw.pos, raw.dims)
    margin = TANK_TOLERANCE * tank.inner_extent(raw.dims)
    shape = (f"the declared {'circle' if raw.dims == 2 else 'cylinder'} of radius {tank.radius:.4g} {unit} about "
             if tank.kind == "cylinder" else
             f"the declared {'rectangle' if raw.dims == 2 else 'box'} of sides "
             f"{' x '.join(f'{s:.4g}' for s in tank.size[:raw.dims])} {unit} about ")
    shape += "(" + ", ".join(f"{c:.4g}" for c in tank.centre[:raw.dims]) + ")"
    issues = []
    for level, selected, said in (
            ("error", out > margin, f"more than {margin:.4g} {unit} ({TANK_TOLERANCE:.0%} of its inner extent) beyond "
                                    "its wall: check the arena's centre and size (in the file's length unit) and the "
                                    "tracks' units"),
            ("warning", (out > 0) & (out <= margin), f"within {margin:.4g} {unit} of its wall (the tolerance): "
                                                    "used as they are")):
        if not selected.any():
            continue
        worst = np.flatnonzero(selected)[np.argmax(out[selected])]
        count = int(np.unique(raw.ind[selected]).size)
        issues.append(Issue(level, "outside the tank", f"{int(selected.sum())} sample(s) of {count} individual(s) "
                            f"outside {shape}, {said}; the farthest {out[worst]:.4g} {unit} outside, at t = "
                            f"{raw.t[worst]:.6g} s", flock=raw.name, id=str(raw.ids[raw.ind[worst]]),
                            rows=raw.source_rows(np.flatnonzero(selected))))
    return issues
