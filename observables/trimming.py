"""Which samples of a flock are measured: a logger's zero padding dropped, and a trim (``--trim START:END``).

* **Padding**: the sample times at the end (and at the start) of a flock at which every individual sampled
  then has a recorded velocity of exactly zero in every component are a logger's or an exporter's padding
  (arrays filled to a common length). :func:`drop_padding` drops them with one warning listing their
  times and rows; ``keep_padding = true`` (``--keep-padding``) keeps them (a warning says they look like
  padding). Only tracks with recorded velocities are judged, and a flock whose every recorded velocity is
  zero is not padding (it is kept, with a note).
* **Trim** ``START:END``, like a Python slice of each flock's samples: each end is empty (the flock's own
  end), a whole number of samples (counted on the flock's sampling clock from its first sample, negative
  from its last: ``--trim 10:-10``) or seconds with an ``s`` (from the flock's first sample time, negative
  from its last: ``--trim 2s:-0.5s``). :func:`trim_flock` keeps the samples from START (included) to END
  (excluded) with a note; a trim that leaves nothing is an error naming the flock.

``parse_trim(text) -> Trim`` checks the text (a ValueError saying what is allowed).
"""
from __future__ import annotations

import dataclasses
import math
import re
from dataclasses import dataclass

import numpy as np

from .validation import Issue

TRIM_END = re.compile(r"^\s*([+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?)\s*(s?)\s*$")


@dataclass(frozen=True)
class TrimEnd:
    value: float
    seconds: bool          # False: samples (a whole number)


@dataclass(frozen=True)
class Trim:
    start: TrimEnd | None
    end: TrimEnd | None
    text: str


def _end(text: str, whole: str) -> TrimEnd | None:
    if not text.strip():
        return None
    found = TRIM_END.match(text)
    if not found:
        raise ValueError(f"got {whole!r}; expected START:END, each empty, a whole number of samples or seconds "
                         "with an s (e.g. 10:-10, 2s:, :-0.5s)")
    value, unit = float(found.group(1)), found.group(2) == "s"
    if not math.isfinite(value) or (not unit and value != int(value)):
        raise ValueError(f"got {whole!r}; samples are whole numbers (seconds take an s: {found.group(1)}s)")
    return TrimEnd(value, unit)


def parse_trim(text: str) -> Trim:
    """The :class:`Trim` of ``START:END`` (module docstring); ValueError when it is not one."""
    if not isinstance(text, str) or text.count(":") != 1:
        raise ValueError(f"got {text!r}; expected START:END, each empty, a whole number of samples or seconds with "
                         "an s (e.g. 10:-10, 2s:, :-0.5s)")
    start, end = text.split(":")
    return Trim(_end(start, text), _end(end, text), text.strip())


def _subset(raw, keep: np.ndarray):
    return dataclasses.replace(raw, t=raw.t[keep], ind=raw.ind[keep], pos=raw.pos[keep],
                               vel=None if raw.vel is None else raw.vel[keep],
                               rows=None if raw.rows is None else raw.rows[keep])


def _times_text(times) -> str:
    times = list(times)
    shown = ", ".join(f"{t:.6g}" for t in times[:6])
    return shown + (f" (+{len(times) - 6} more)" if len(times) > 6 else "")


def drop_padding(raw, keep: bool = False) -> tuple:
    """(the flock without its padding, issues) (module docstring)."""
    if raw.vel is None or len(raw.t) == 0:
        return raw, []
    zero = (raw.vel == 0).all(axis=1)
    if not zero.any():
        return raw, []
    times, inverse = np.unique(raw.t, return_inverse=True)
    all_zero = np.ones(len(times), dtype=bool)
    np.logical_and.at(all_zero, inverse, zero)
    if all_zero.all():
        return raw, [Issue("note", "padding", "every recorded velocity is exactly zero: not taken for padding",
                           flock=raw.name)]
    first, last = int(np.argmin(all_zero)), len(times) - int(np.argmin(all_zero[::-1]))
    padded = np.r_[np.arange(first), np.arange(last, len(times))]
    if padded.size == 0:
        return raw, []
    selected = np.isin(inverse, padded)
    rows = tuple(sorted(raw.source_rows(np.flatnonzero(selected))))
    where = (f"{first} leading and {len(times) - last} trailing sample time(s)" if first else
             f"{len(times) - last} trailing sample time(s)") if len(times) - last else f"{first} leading sample time(s)"
    text = (f"{where} (t = {_times_text(times[padded])} s) at which every individual's recorded velocity is exactly "
            "zero: a logger's padding")
    if keep:
        return raw, [Issue("warning", "padding", text + "; kept (keep_padding)", flock=raw.name, rows=rows)]
    return _subset(raw, ~selected), [Issue("warning", "padding", text + "; left out (keep them with --keep-padding "
                                                                         "or keep_padding = true)",
                                           flock=raw.name, rows=rows)]


def trim_flock(raw, trim: Trim | None, clock) -> tuple:
    """(the flock's samples inside ``trim``, issues); ``clock`` its sampling clock (samples are counted on
    it). A trim that leaves nothing is an error issue."""
    if trim is None or len(raw.t) == 0:
        return raw, []
    t0, t1 = float(raw.t.min()), float(raw.t.max())
    k = clock.index(raw.t)
    k0, k1 = int(k.min()), int(k.max())
    keep = np.ones(len(raw.t), dtype=bool)
    if trim.start is not None:
        if trim.start.seconds:
            lower = (t0 + trim.start.value) if trim.start.value >= 0 else (t1 + trim.start.value)
            keep &= raw.t >= lower - clock.tolerance(raw.t)
        else:
            first = k0 + int(trim.start.value) if trim.start.value >= 0 else k1 + 1 + int(trim.start.value)
            keep &= k >= first
    if trim.end is not None:
        if trim.end.seconds:
            upper = (t0 + trim.end.value) if trim.end.value >= 0 else (t1 + trim.end.value)
            keep &= raw.t < upper - clock.tolerance(raw.t)
        else:
            last = k0 + int(trim.end.value) if trim.end.value >= 0 else k1 + 1 + int(trim.end.value)
            keep &= k < last
    if not keep.any():
        return raw, [Issue("error", "trim", f"trim {trim.text!r} leaves no sample of this flock (its samples span "
                           f"t = {t0:.6g} to {t1:.6g} s, {k1 - k0 + 1} sample times)", flock=raw.name)]
    cut = int((~keep).sum())
    if not cut:
        return raw, [Issue("note", "trim", f"trim {trim.text!r} leaves every sample", flock=raw.name)]
    kept_t = raw.t[keep]
    return _subset(raw, keep), [Issue("note", "trim", f"trim {trim.text!r}: {cut} sample(s) left out; kept t = "
                                      f"{kept_t.min():.6g} to {kept_t.max():.6g} s", flock=raw.name)]
