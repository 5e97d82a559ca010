"""The viewer page: one self-contained HTML file (every script inlined, nothing fetched) from a Track.

``build_page(track, max_mb=5.0, stride=None, ...) -> ViewerPage`` thins the track to a frame stride
that keeps the page under ``max_mb`` megabytes (``stride`` fixes it instead; ``max_mb=None`` keeps
every frame), computes the per-frame observables of the kept frames, encodes them
(:mod:`analysis.viewer.encode`) and renders ``templates/viewer.html.j2`` with jinja2.

Inlining: three.js (``vendor/three``, see its README) and the page's own scripts (``static/*.js``)
sit in ``<script type="text/plain">`` blocks; a small classic script turns each into a ``blob:`` URL,
installs an import map naming them (``three``, ``three-core``, the OrbitControls add-on, the page's
``flock/streams.js`` and ``flock/panel.js``) and starts the page's module (``static/viewer.js``). So the
page opens from a ``file://`` URL with no server and no network. Inlined
text must not contain ``</script`` or ``<!--`` (checked); the JSON data has every ``<`` escaped as ``\\u003c``.

:class:`ViewerPage` holds the HTML; ``save(path)`` writes it atomically and ``_repr_html_`` shows it
inline in Jupyter (an ``iframe`` with ``srcdoc``).
"""
from __future__ import annotations

import html as html_lib
import json
import math
from dataclasses import dataclass, replace
from functools import lru_cache
from importlib import resources
from pathlib import Path

import numpy as np

from flocksweep.sweeps.files import write_text

from .encode import (check_agents, heading_stream, label_stream, page_data, position_stream,
                     speed_stream, stream)
from .observables import frame_observables, group_labels
from .track import Track

MB = 1_000_000
METRIC_BYTES_PER_FRAME = 90   # times and four metrics as JSON text
WINDOW = 20                   # consecutive frames per sample of a size estimate


@lru_cache(maxsize=None)
def _asset(relative: str) -> str:
    return resources.files(__package__).joinpath(relative).read_text(encoding="utf-8")


def _inline(text: str, name: str) -> str:
    if "</script" in text.lower() or "<!--" in text:
        raise ValueError(f"{name}: cannot be inlined in a <script> block (contains '</script' or '<!--')")
    return text


def scripts() -> dict[str, str]:
    """The inlined sources: three's core and module builds (the module's import of the core renamed to
    the import-map name ``three-core``), the OrbitControls add-on and the page's own modules."""
    module = _asset("vendor/three/three.module.min.js")
    if '"./three.core.min.js"' not in module:
        raise RuntimeError("vendor/three/three.module.min.js no longer imports ./three.core.min.js; "
                           "see vendor/three/README.md")
    return {"three_core": _inline(_asset("vendor/three/three.core.min.js"), "three.core.min.js"),
            "three": _inline(module.replace('"./three.core.min.js"', '"three-core"'), "three.module.min.js"),
            "orbit": _inline(_asset("vendor/three/OrbitControls.js"), "OrbitControls.js"),
            "streams": _inline(_asset("static/streams.js"), "streams.js"),
            "panel": _inline(_asset("static/panel.js"), "panel.js"),
            "app": _inline(_asset("static/viewer.js"), "viewer.js")}


def _json_for_script(data: dict) -> str:
    return json.dumps(data, separators=(",", ":"), allow_nan=False).replace("<", "\\u003c")


def render_html(data: dict, others: tuple = (), runs: tuple = ()) -> str:
    """The page of ``data``; with ``others`` (the data of more runs) and ``runs`` (one ``(run id, label)``
    per run, ``data``'s first) a page of several runs: each run's data in its own block, marked with
    its run id, and a run menu (viewer.js shows the run the URL fragment names)."""
    import jinja2

    env = jinja2.Environment(autoescape=True, undefined=jinja2.StrictUndefined)
    template = env.from_string(_asset("templates/viewer.html.j2"))
    blocks = [{"run": run, "label": label, "data": jinja2_safe(_json_for_script(d))}
              for (run, label), d in zip(runs, (data, *others))]
    return template.render(title=data["title"], scripts={k: jinja2_safe(v) for k, v in scripts().items()},
                           data=jinja2_safe(_json_for_script(data)), runs=blocks[1:], first=blocks[:1])


def jinja2_safe(text: str):
    from markupsafe import Markup

    return Markup(text)


@lru_cache(maxsize=1)
def overhead_bytes() -> int:
    """Bytes of a page without frames: the template and the inlined scripts."""
    return sum(len(s.encode()) for s in scripts().values()) + len(_asset("templates/viewer.html.j2").encode()) + 40_000


def _windows(frames: int, length: int = WINDOW, count: int = 3) -> list[slice]:
    """``count`` runs of ``length`` consecutive frames spread over ``frames`` (one run of all when few)."""
    if frames <= length * count:
        return [slice(0, frames)]
    starts = np.linspace(0, frames - length, count).astype(int)
    return [slice(int(a), int(a) + length) for a in starts]


def _stream_bytes(part: Track, agents: list[dict], window: slice, lo, hi) -> int:
    streams = [position_stream(part.pos, lo, hi), heading_stream(part.vel),
               speed_stream(np.linalg.norm(part.vel, axis=-1)), label_stream(group_labels(part))]
    if part.leader is not None:
        streams.append(stream(part.leader, "bits"))
    for agent in agents:
        streams += [position_stream(agent["pos"][window], lo, hi), heading_stream(agent["vel"][window])]
    return sum(len(s["data"]) for s in streams)


def estimate_bytes(track: Track, stride: int) -> int:
    """Page size at ``stride``: every stream (positions, headings, speeds, groups, leaders, agents) encoded
    for real on a few windows of consecutive kept frames. A window's first frame is stored whole and the
    others as differences, so the page's first frame is costed as a window's first frame and every other
    as a window's later frames (their cost: the window's bytes less its first frame's alone). Plus the
    metrics' JSON and the fixed scripts."""
    thin = track.every(stride)
    agents = check_agents(thin.agents, thin.frames)
    points = np.concatenate([thin.pos.reshape(-1, 3)] + [a["pos"].reshape(-1, 3) for a in agents])
    lo, hi = points.min(axis=0), points.max(axis=0)
    first = later = counted = 0
    for window in _windows(thin.frames):
        part = replace(thin, times=thin.times[window], pos=thin.pos[window], vel=thin.vel[window],
                       leader=None if thin.leader is None else thin.leader[window], visible=None, binocular=None,
                       agents=())
        head = slice(window.start, window.start + 1)
        alone = _stream_bytes(part.every(part.frames), agents, head, lo, hi)  # the window's first frame
        first = first or alone
        later += _stream_bytes(part, agents, window, lo, hi) - alone
        counted += part.frames - 1
    frames_bytes = first + (later / counted * (thin.frames - 1) if counted else 0)
    return int(overhead_bytes() + frames_bytes + thin.frames * METRIC_BYTES_PER_FRAME)


def choose_stride(track: Track, max_bytes: float) -> int:
    """The smallest frame stride whose page fits ``max_bytes`` (the last frame may be dropped)."""
    size = estimate_bytes(track, 1)
    if size <= max_bytes:
        return 1
    room = max_bytes - overhead_bytes()
    if room <= 0:
        raise ValueError(f"max_mb: {max_bytes / MB:g} MB is less than the page's scripts alone "
                         f"({overhead_bytes() / MB:.2f} MB)")
    stride = max(2, math.ceil((size - overhead_bytes()) / room))
    while stride < track.frames and estimate_bytes(track, stride) > max_bytes:
        stride = stride + max(1, stride // 4)
    return min(stride, max(track.frames - 1, 1))


@dataclass
class ViewerPage:
    """A rendered viewer page (see the module docstring)."""

    html: str
    title: str
    n: int
    frames: int
    stride: int
    frame_interval: float
    path: Path | None = None
    runs: int = 1

    @property
    def size_bytes(self) -> int:
        return len(self.html.encode())

    def save(self, path) -> Path:

        self.path = Path(path)
        write_text(self.path, self.html)
        return self.path

    def _repr_html_(self) -> str:
        return (f"<iframe title='{html_lib.escape(self.title)}' srcdoc=\"{html_lib.escape(self.html, quote=True)}\" "
                "style='width:100%;height:620px;border:1px solid #ddd' allowfullscreen></iframe>")

    def __repr__(self) -> str:
        where = f" at {self.path}" if self.path else ""
        several = f"{self.runs} runs, the first: " if self.runs > 1 else ""
        return (f"<ViewerPage {self.title!r}: {several}{self.n} boids, {self.frames} frames every {self.frame_interval:g} s, "
                f"{self.size_bytes / MB:.2f} MB{where}>")


def build_page(track: Track, max_mb: float | None = 5.0, stride: int | None = None, color_by: str = "auto",
               trail_s: float = 2.0, boid_scale: float = 1.0, follow: bool | None = None,
               start_time: float | None = None) -> ViewerPage:
    if stride is not None and (isinstance(stride, bool) or int(stride) != stride or stride < 1):
        raise ValueError(f"stride: got {stride!r}; expected an integer >= 1")
    if max_mb is not None and not (max_mb > 0 and math.isfinite(max_mb)):
        raise ValueError(f"max_mb: got {max_mb!r}; expected a number > 0 (or None for no limit)")
    fixed = stride is not None or max_mb is None
    if stride is None:
        stride = 1 if max_mb is None else choose_stride(track, max_mb * MB)
    while True:
        thin = track.every(int(stride))
        data = page_data(thin, frame_observables(thin), int(stride), color_by, trail_s, boid_scale, follow,
                         start_time)
        page = ViewerPage(render_html(data), track.title, track.n, thin.frames, int(stride), thin.frame_interval)
        if fixed or page.size_bytes <= max_mb * MB or thin.frames <= 2:
            return page
        stride = int(stride) + max(1, int(stride) // 4)  # the allowances were too small: thin more


def build_runs_page(tracks, run_ids, max_mb: float | None = 5.0, stride: int | None = None, color_by: str = "auto",
                    trail_s: float = 2.0, start_time: float | None = None) -> ViewerPage:
    """One page of several runs (``tracks``, named by ``run_ids``), with a run menu; the URL fragment
    ``#run=ID`` (a unique prefix of 6 or more characters) picks the run shown. The size cap holds for the
    whole page: the scripts are inlined once and each run gets an equal share of the rest (its own
    stride, chosen as for one run)."""
    tracks, run_ids = list(tracks), [str(r) for r in run_ids]
    if len(tracks) < 2 or len(tracks) != len(run_ids) or len(set(run_ids)) != len(run_ids):
        raise ValueError(f"run_ids: got {run_ids}; expected one distinct id for each of the {len(tracks)} runs "
                         "(two or more)")
    if max_mb is not None and not (max_mb > 0 and math.isfinite(max_mb)):
        raise ValueError(f"max_mb: got {max_mb!r}; expected a number > 0 (or None for no limit)")
    fixed = stride is not None or max_mb is None
    if stride is not None:
        strides = [int(stride)] * len(tracks)
    elif max_mb is None:
        strides = [1] * len(tracks)
    else:
        share = overhead_bytes() + (max_mb * MB - overhead_bytes()) / len(tracks)
        strides = [choose_stride(track, share) for track in tracks]
    labels = _run_labels(tracks, run_ids)
    while True:
        thin = [track.every(k) for track, k in zip(tracks, strides)]
        data = [page_data(t, frame_observables(t), k, color_by, trail_s, 1.0, None, start_time)
                for t, k in zip(thin, strides)]
        html = render_html(data[0], tuple(data[1:]), tuple(zip(run_ids, labels)))
        page = ViewerPage(html, data[0]["title"], tracks[0].n, thin[0].frames, strides[0], thin[0].frame_interval,
                          runs=len(tracks))
        if fixed or page.size_bytes <= max_mb * MB or all(t.frames <= 2 for t in thin):
            return page
        strides = [k + max(1, k // 4) for k in strides]   # the allowances were too small: thin more


def _run_labels(tracks, run_ids) -> list[str]:
    """Each run's menu entry: its id and the parameters (of those every run has) whose values differ between
    the runs (a measured flock has none: its entry is its id)."""
    keys = sorted(set.intersection(*(set(t.params) for t in tracks)))
    differing = [k for k in keys if len({repr(t.params.get(k)) for t in tracks}) > 1]
    labels = []
    for track, run in zip(tracks, run_ids):
        said = [f"{k}={track.params.get(k)}" for k in differing[:4]]
        if "replicate" in track.info:
            said.append(f"replicate {track.info['replicate']}")
        labels.append(f"{run}: {', '.join(said)}" if said else run)
    return labels
