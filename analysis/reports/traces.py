"""3-D trace plots: every boid's path over a run (after Hartman & Benes, Figure 7).

``plot_traces(pos, path, pattern=None, color_by="auto", wrap_jump=None, title="", obstacles=(),
predator=None, prey=None)`` draws the positions ``pos`` float64 (R, N, 3) as one polyline per boid and
saves a PNG (or SVG, by extension); ``draw_traces(ax, pos, ...)`` with the same arguments draws the same
into an existing 3-D axes (e.g. one thumbnail of a grid) and returns the axes. ``obstacles`` (a model's
``world.obstacles``) are drawn as translucent solids (:mod:`analysis.reports.obstacle_artists`), on
equal axis scales;
``predator`` and ``prey`` positions (R, 3) as thick paths of their own colour (predator red, prey green)
ending in a large marker, with legend entries (their line artists carry the ``gid`` "predator" /
"prey"). ``wrap_distance(model)`` is the
jump that marks a boundary wrap in a model's world (None in an open world).
Colours: one per boid (``"boid"``), or one per pattern value (``"pattern"``; Holland's Table 1 body
colours for its four patterns); ``"auto"`` picks pattern when more than one pattern is present. Jumps
longer than ``wrap_jump`` (boundary wraps) break the line instead of drawing across the world.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from flocksweep.analysis.viewer.palette import AGENT_COLOURS

from .obstacle_artists import draw_obstacles
from .plotting import pyplot, save

AGENT_STYLES = {"predator": (AGENT_COLOURS["predator"], "X"), "prey": (AGENT_COLOURS["prey"], "*")}
TABLE_1_COLOURS = {0b00000000: "gold", 0b00111010: "green", 0b11000101: "blue", 0b11111111: "red"}


def _segments(track: np.ndarray, wrap_jump: float | None):
    """Pieces of one boid's (R, 3) track split where a step is longer than ``wrap_jump``."""
    if wrap_jump is None or len(track) < 2:
        return [track]
    jumps = np.nonzero(np.linalg.norm(np.diff(track, axis=0), axis=1) > wrap_jump)[0]
    return np.split(track, jumps + 1)


def wrap_distance(model) -> float | None:
    """Steps longer than this are boundary wraps: the sphere radius or half the box; None when open."""
    world = model.world
    if world.boundary == "sphere_wrap":
        return world.sphere_radius
    if world.boundary == "periodic_box":
        return world.box_size / 2
    return None


def boid_colours(n: int, pattern: np.ndarray | None, color_by: str):
    import matplotlib

    values = np.unique(pattern) if pattern is not None else np.array([0])
    if color_by == "auto":
        color_by = "pattern" if len(values) > 1 else "boid"
    if color_by == "pattern":
        cmap = matplotlib.colormaps["tab10"]
        lookup = {v: TABLE_1_COLOURS.get(int(v), cmap(k % 10)) for k, v in enumerate(values)}
        return [lookup[v] for v in pattern], lookup
    cmap = matplotlib.colormaps["turbo"]
    return [cmap(k / max(n - 1, 1)) for k in range(n)], None


def _draw_agent(ax, name: str, track: np.ndarray, wrap_jump: float | None) -> None:
    """An agent's path (R, 3) as a thick line of its colour, its last position as a large marker."""
    colour, marker = AGENT_STYLES[name]
    track = np.asarray(track, dtype=np.float64)
    for k, piece in enumerate(_segments(track, wrap_jump)):
        line, = ax.plot(piece[:, 0], piece[:, 2], piece[:, 1], color=colour, linewidth=2.0,
                        label=name if k == 0 else None)
        line.set_gid(name)
    ax.scatter(track[-1:, 0], track[-1:, 2], track[-1:, 1], color=colour, marker=marker, s=90,
               edgecolors="black", linewidths=0.5, depthshade=False)


def draw_traces(ax, pos: np.ndarray, pattern: np.ndarray | None = None, color_by: str = "auto",
                wrap_jump: float | None = None, title: str = "", obstacles=(), predator=None, prey=None):
    """Draw the traces of ``pos`` (R, N, 3) into the existing 3-D axes ``ax``; returns ``ax``.

    The world's y axis (up) is drawn as the plot's vertical axis. Used by ``plot_traces`` (one figure)
    and by ``figures.thumbnails_figure`` (a grid of thumbnails). ``obstacles``, ``predator`` and
    ``prey`` as in the module docstring."""
    n = pos.shape[1]
    colours, legend = boid_colours(n, pattern, color_by)
    agents = {name: track for name, track in (("predator", predator), ("prey", prey)) if track is not None}
    if obstacles:
        around = np.concatenate([pos.reshape(-1, 3)] + [np.asarray(t).reshape(-1, 3) for t in agents.values()])
        draw_obstacles(ax, obstacles, around)
    for i in range(n):
        for piece in _segments(pos[:, i], wrap_jump):
            ax.plot(piece[:, 0], piece[:, 2], piece[:, 1], color=colours[i], linewidth=0.7, alpha=0.85)
    ax.scatter(pos[-1, :, 0], pos[-1, :, 2], pos[-1, :, 1], c=colours, s=6, depthshade=False)
    for name, track in agents.items():
        _draw_agent(ax, name, track, wrap_jump)
    if legend:
        for value, colour in legend.items():
            ax.plot([], [], color=colour, label=f"pattern {int(value):0b}")
    if legend or agents:
        ax.legend(loc="upper left", fontsize=7)
    ax.set_aspect("equal")   # one scale on all three axes: paths and solids keep their shapes
    ax.set_xlabel("x")
    ax.set_ylabel("z")
    ax.set_zlabel("y (up)")
    ax.set_title(title, fontsize=9)
    return ax


def plot_traces(pos: np.ndarray, path, pattern: np.ndarray | None = None, color_by: str = "auto",
                wrap_jump: float | None = None, title: str = "", obstacles=(), predator=None, prey=None) -> Path:
    fig = pyplot().figure(figsize=(7, 6), dpi=110)
    ax = fig.add_subplot(projection="3d")
    draw_traces(ax, pos, pattern, color_by, wrap_jump, title, obstacles, predator, prey)
    return save(fig, path)
