"""Seeing flocks: an interactive 3-D viewer page and animation export for any run.

Public API (importing this package loads nothing heavy)::

    from flocksweep.analysis.viewer import view, animate
    page = view(obs, "flock.html", preset=preset)      # Observations, Track, trajectory .npz or arrays
    page                                                # in Jupyter: the page inline
    anim = animate(obs, "flock.gif", preset=preset, rotate=True)

* :func:`view` writes one self-contained HTML page (``analysis/viewer/page.py``; three.js inlined,
  nothing fetched) and returns a :class:`~analysis.viewer.page.ViewerPage`.
* :func:`view_runs` writes one page of several runs with a run menu (the URL fragment ``#run=ID`` picks
  the run shown).
* :func:`animate` writes a GIF (Pillow) or MP4 (the ffmpeg of the ``imageio-ffmpeg`` wheel) with
  matplotlib (``analysis/viewer/animation.py``) and returns an :class:`~analysis.viewer.animation.Animation`.
* ``analysis.viewer.resimulate`` re-simulates a sweep's run from its stored spec and seed and checks it
  against the stored summary bit for bit; ``analysis.viewer.command`` is ``flocksweep view``;
  ``analysis.viewer.hooks`` writes the page of a stored run or of a preset for other commands (the
  report's showcase runs, a calibration's posterior median).

The page's data format (for adding obstacles, prey and predators) is documented in
``analysis/viewer/encode.py``; the choice of three.js in ``docs/viewer.md``.
"""
from __future__ import annotations


def view(source, path=None, *, preset=None, title: str | None = None, color_by: str = "auto",
         trail_s: float = 2.0, boid_scale: float = 1.0, follow: bool | None = None, max_mb: float | None = 5.0,
         stride: int | None = None, scene=(), agents=(), info: dict | None = None, start_time: float | None = None):
    """Write (when ``path`` is given) and return the viewer page of ``source``.

    ``source``: simulator ``Observations`` (with ``preset`` for its parameters, group radius and world),
    a :class:`~analysis.viewer.track.Track`, a path to a trajectory ``.npz`` or a dict of arrays
    (``times``, ``pos``, optional ``vel``, ``pattern``, ``leader``). ``color_by``: ``auto`` (pattern in
    pattern mode, leader state with change of leadership, else boid), ``boid``, ``pattern``, ``leader``,
    ``group`` or ``speed`` (switchable in the page). ``max_mb`` caps the page size by thinning frames
    (``stride`` fixes the thinning instead). ``scene``/``agents``: obstacles and extra agents
    (format in ``analysis/viewer/encode.py``). ``start_time``: the simulated second the page opens at
    (a URL fragment ``#t=SECONDS&color=MODE`` overrides it when the page is opened)."""
    from dataclasses import replace

    from .page import build_page
    from .track import as_track

    track = as_track(source, preset)
    extra = {}
    if title:
        extra["title"] = title
    if scene:
        extra["scene"] = tuple(track.scene) + tuple(scene)
    if agents:
        extra["agents"] = tuple(track.agents) + tuple(agents)
    if info:
        extra["info"] = {**track.info, **info}
    track = replace(track, **extra) if extra else track
    page = build_page(track, max_mb=max_mb, stride=stride, color_by=color_by, trail_s=trail_s,
                      boid_scale=boid_scale, follow=follow, start_time=start_time)
    if path is not None:
        page.save(path)
    return page


def view_runs(sources, run_ids, path=None, *, preset=None, color_by: str = "auto", trail_s: float = 2.0,
              max_mb: float | None = 5.0, stride: int | None = None, start_time: float | None = None):
    """Write (when ``path`` is given) and return one page of several runs with a run menu: ``sources``
    (each as for :func:`view`, with ``preset`` for all of them), named by ``run_ids`` (distinct). The URL
    fragment ``#run=ID&t=SECONDS`` opens that run at that time; switching runs in the menu writes the
    fragment. ``max_mb`` caps the whole page (each run gets an equal share after the scripts)."""
    from .page import build_runs_page
    from .track import as_track

    page = build_runs_page([as_track(s, preset) for s in sources], run_ids, max_mb=max_mb, stride=stride,
                           color_by=color_by, trail_s=trail_s, start_time=start_time)
    if path is not None:
        page.save(path)
    return page


def animate(source, path, *, preset=None, color_by: str = "auto", fps: float = 20.0, speed: float = 1.0,
            rotate: bool = False, trail_s: float = 1.0, size=(640, 480), dpi: int = 100,
            title: str | None = None, progress: bool = False):
    """Write a GIF or MP4 (by the extension of ``path``) of ``source`` (as for :func:`view`) and return
    an :class:`~analysis.viewer.animation.Animation`; see ``analysis/viewer/animation.py``."""
    from .animation import write_animation
    from .track import as_track

    track = as_track(source, preset)
    return write_animation(track, path, color_by=color_by, fps=fps, speed=speed, rotate=rotate,
                           trail_s=trail_s, size=size, dpi=dpi, title=title, progress=progress)


__all__ = ["animate", "view", "view_runs"]
