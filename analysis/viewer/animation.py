"""Animation export: a run as a GIF (Pillow) or MP4 (the ffmpeg bundled in the imageio-ffmpeg wheel).

``write_animation(track, path, color_by="auto", fps=20, speed=1, rotate=False, trail_s=1, size=(640, 480),
dpi=100, title=None, progress=False) -> Animation`` draws the run with matplotlib's 3-D axes (the world's
y axis up), or, for a run in the plane z = 0 (a 2-D model's, measured 2-D tracks: :func:`is_flat`), from
above on plain axes (x right, y up, equal scales; ``rotate`` does nothing there), as the viewer page
does: boids as arrows along their heading, extra agents (prey, predators) as large markers of their colour with a legend, trails of the last ``trail_s`` seconds (agents' thicker), a time stamp
with the frame's polarization and number of groups, and optionally a camera turning slowly about the
vertical (``rotate``: 6 degrees per second of video).

Frames: frame k shows simulated time t0 + k * speed / fps, k = 0 .. floor((t_end - t0) * fps / speed),
each drawn from the nearest recorded frame of the track, so the file has exactly
``frame_count(track, fps, speed)`` frames of ``size`` pixels, 16 to ``MAX_SIDE`` (3840) a side (MP4 sizes
must be even; another size is a ValueError). Colours (``boid``, ``pattern``, ``leader``, ``group``, ``speed``) follow the viewer page.
The view follows the flock (the centroid of its largest group, at a fixed scale) in an open world and
shows the whole world when it wraps. A tank (the scene's ``arena`` wireframe: a model's ``[arena]``, or the
tank measured tracks declare) is drawn as its outline, a circle or rectangle from above, the edges of its
cylinder or box in 3-D, and the view then holds the whole tank. The file is written atomically. Without ``imageio-ffmpeg`` an MP4
raises :class:`AnimationUnavailable` naming the install command.

:class:`Animation` (path, format, frames, fps, width, height) displays inline in Jupyter.
``poster(track, path, frame=-1)`` draws one frame the same way as a PNG (the report's linked thumbnails).
"""
from __future__ import annotations

import base64
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from flocksweep.sweeps.files import atomic_path

from .encode import COLOR_MODES, TABLE_1_HEX, check_agents, default_color_by
from .observables import frame_observables
from .track import Track

FORMATS = {".gif": "gif", ".mp4": "mp4"}
ROTATE_DEG_PER_S = 6.0
MAX_SIDE = 3840   # pixels a side at most (4K UHD): a frame is drawn in memory, and matplotlib stops at 2^16


class AnimationUnavailable(RuntimeError):
    pass


@dataclass
class Animation:
    path: Path
    format: str
    frames: int
    fps: float
    width: int
    height: int

    def _repr_html_(self) -> str:
        data = base64.b64encode(Path(self.path).read_bytes()).decode()
        if self.format == "gif":
            return f"<img src='data:image/gif;base64,{data}' width='{self.width}' height='{self.height}'>"
        return (f"<video controls loop autoplay muted width='{self.width}' height='{self.height}' "
                f"src='data:video/mp4;base64,{data}'></video>")

    def __repr__(self) -> str:
        return (f"<Animation {self.path}: {self.format}, {self.frames} frames at {self.fps:g} fps, "
                f"{self.width}x{self.height}>")


def frame_count(track: Track, fps: float, speed: float) -> int:
    span = float(track.times[-1] - track.times[0])
    return int(math.floor(span * fps / speed + 1e-9)) + 1


def source_frames(track: Track, fps: float, speed: float) -> np.ndarray:
    """Index of the recorded frame shown by each video frame (nearest in time)."""
    times = track.times[0] + np.arange(frame_count(track, fps, speed)) * (speed / fps)
    if track.frames == 1:
        return np.zeros(len(times), dtype=int)
    return np.clip(np.rint((times - track.times[0]) / track.frame_interval), 0, track.frames - 1).astype(int)


def check_options(path: Path, fps, speed, size, dpi, color_by) -> str:
    """The format (gif or mp4) of ``path``, after checking every option (ValueError naming it)."""
    kind = FORMATS.get(path.suffix.lower())
    if kind is None:
        raise ValueError(f"{path}: animation format from the extension: .gif or .mp4, got {path.suffix!r}")
    for name, value in (("fps", fps), ("speed", speed), ("dpi", dpi)):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not (math.isfinite(value) and value > 0):
            raise ValueError(f"{name}: got {value!r}; expected a number > 0")
    if len(size) != 2 or any(int(s) != s or not 16 <= s <= MAX_SIDE for s in size):
        raise ValueError(f"size: got {size!r}; expected (width, height) in whole pixels from 16 to {MAX_SIDE}")
    if kind == "mp4" and any(int(s) % 2 for s in size):
        raise ValueError(f"size: got {size!r}; an MP4 (H.264) needs an even width and height")
    if color_by != "auto" and color_by not in COLOR_MODES:
        raise ValueError(f"color_by: got {color_by!r}; allowed: auto, {', '.join(COLOR_MODES)}")
    return kind


def ffmpeg_exe() -> str:
    """The ffmpeg binary of the imageio-ffmpeg wheel, or AnimationUnavailable saying how to get it."""
    try:
        import imageio_ffmpeg
    except ImportError:
        raise AnimationUnavailable("MP4 export needs the ffmpeg of the imageio-ffmpeg wheel: "
                                   "pip install imageio-ffmpeg (or pip install 'flocksweep[video]'); "
                                   "GIF export works without it (--animate out.gif)") from None
    return imageio_ffmpeg.get_ffmpeg_exe()


def _colours(track: Track, mode: str, obs: dict, frames: np.ndarray) -> np.ndarray:
    """RGBA (K, N, 4) colour of every boid at every shown frame."""
    import matplotlib
    from matplotlib.colors import to_rgba

    k, n = len(frames), track.n
    if mode == "boid":
        return np.broadcast_to(matplotlib.colormaps["turbo"](np.linspace(0, 1, n)), (k, n, 4))
    if mode == "pattern":
        pattern = track.pattern if track.pattern is not None else np.zeros(n)
        values = np.unique(pattern)
        tab10 = matplotlib.colormaps["tab10"]
        lookup = {v: to_rgba(TABLE_1_HEX.get(int(v), tab10(j % 10))) for j, v in enumerate(values)}
        return np.broadcast_to(np.array([lookup[v] for v in pattern]), (k, n, 4))
    if mode == "leader":
        lead = track.leader[frames] if track.leader is not None else np.zeros((k, n), bool)
        return np.where(lead[..., None], to_rgba("#e0301e"), to_rgba("#7f93a8"))
    if mode == "speed":
        speed = obs["speed"][frames]
        return matplotlib.colormaps["viridis"](speed / max(float(obs["speed"].max()), 1e-12))
    labels = obs["labels"][frames]
    sizes = np.stack([np.bincount(row, minlength=n)[row] for row in labels])
    colours = matplotlib.colormaps["tab10"](np.minimum(labels, 9))
    colours[labels >= 10] = to_rgba("#8a8f96")
    colours[sizes == 1] = to_rgba("#c4cad1")
    return colours


def is_flat(track: Track) -> bool:
    """A run in the plane z = 0 (a 2-D model's, or tracks whose every z is 0): drawn from above, as the
    viewer page shows it."""
    return track.world.get("dimensions") == 2 or not (np.any(track.pos[..., 2]) or np.any(track.vel[..., 2]))


def tank_of(track: Track) -> dict | None:
    """The track's tank: its scene's ``arena`` wireframe (a box or a cylinder, :func:`.track.arena_scene`)."""
    return next((o for o in track.scene if o.get("label") == "arena" and o.get("type") in ("box", "cylinder")), None)


def tank_outline(tank: dict, flat: bool, points: int = 96) -> list[np.ndarray]:
    """The tank's edges as polylines (K, 3) in world coordinates: from above, its circle or rectangle in the
    plane; in 3-D, a cylinder's two rims and four side lines, a box's twelve edges."""
    if tank["type"] == "cylinder":
        a, b = np.asarray(tank["a"], dtype=float), np.asarray(tank["b"], dtype=float)
        angle = np.linspace(0.0, 2.0 * np.pi, points + 1)
        ring = np.stack([tank["radius"] * np.cos(angle), tank["radius"] * np.sin(angle), np.zeros_like(angle)], -1)
        if flat:
            return [ring + [a[0], a[1], 0.0]]
        sides = [np.array([a, b]) + [tank["radius"] * np.cos(t), tank["radius"] * np.sin(t), 0.0]
                 for t in np.arange(4) * np.pi / 2]
        return [ring + a, ring + b] + sides
    centre, half = np.asarray(tank["center"], dtype=float), np.asarray(tank["size"], dtype=float) / 2.0
    if flat:
        corners = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1], [-1, -1]], dtype=float) * half[:2] + centre[:2]
        return [np.column_stack([corners, np.zeros(5)])]
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)
    corners = centre + signs * half
    return [corners[[i, j]] for i in range(8) for j in range(i + 1, 8) if np.abs(signs[i] - signs[j]).sum() == 2]


def _view_box(track: Track, labels: np.ndarray) -> tuple[np.ndarray, float]:
    """Per shown frame the centre of the view, and one half-width for all frames."""
    tank = tank_of(track)
    if tank is not None and track.wrap_jump is None:     # the whole tank, and the flock in it
        edges = np.concatenate(tank_outline(tank, is_flat(track)))
        low, high = edges.min(axis=0), edges.max(axis=0)
        if is_flat(track):
            low[2] = high[2] = 0.0
        centre = (low + high) / 2.0
        spread = np.nanmax(np.abs(track.pos - centre)) if np.isfinite(track.pos).any() else 0.0
        return np.tile(centre, (track.frames, 1)), max(float((high - low).max()) / 2.0, float(spread)) * 1.05
    if track.wrap_jump is not None:
        half = track.world.get("sphere_radius", track.world.get("box_size", 0) / 2)
        return np.zeros((track.frames, 3)), float(half) * 1.05
    largest = labels == 0
    centre = (track.pos * largest[..., None]).sum(axis=1) / largest.sum(axis=1)[:, None]
    spread = np.linalg.norm(track.pos - centre[:, None], axis=-1)[largest]
    return centre, max(float(spread.max()) * 1.1, 5.0)   # every boid of the largest group in view, always


def _trail_segments(pos: np.ndarray, frame: int, length: int, jump: float | None) -> tuple[np.ndarray, np.ndarray]:
    """(S, 2, 3) segments of every boid's last ``length`` recorded steps up to ``frame``, and the boid
    of each segment; steps longer than ``jump`` (boundary wraps) are left out."""
    start = max(0, frame - length)
    n = pos.shape[1]
    if frame - start < 1:
        return np.zeros((0, 2, 3)), np.zeros(0, dtype=int)
    segments = np.stack([pos[start:frame], pos[start + 1:frame + 1]], axis=2).reshape(-1, 2, 3)
    boid = np.tile(np.arange(n), frame - start)
    if jump is not None:
        keep = np.linalg.norm(segments[:, 1] - segments[:, 0], axis=1) <= jump
        segments, boid = segments[keep], boid[keep]
    return segments, boid


class _Drawing:
    """One matplotlib 3-D figure of a track; ``draw(k, f)`` shows recorded frame ``f`` as video frame ``k``."""

    def __init__(self, track: Track, color_by: str, shown: np.ndarray, trail_s: float, size, dpi: int,
                 title: str | None, rotate: bool, fps: float):
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        from matplotlib.collections import LineCollection
        from mpl_toolkits.mplot3d.art3d import Line3DCollection

        self.track, self.rotate, self.fps, self.plt = track, rotate, fps, plt
        self.mode = default_color_by(track) if color_by == "auto" else color_by
        self.obs = frame_observables(track)
        self.colours = _colours(track, self.mode, self.obs, shown)
        self.centre, self.half = _view_box(track, self.obs["labels"])
        self.trail = int(round(trail_s / track.frame_interval)) if track.frames > 1 else 0
        self.arrow = max(self.half / 12, 1.5)
        self.fig = plt.figure(figsize=(int(size[0]) / dpi, int(size[1]) / dpi), dpi=dpi)
        self.flat = is_flat(track)
        # the caption gets its own strip below the axes (it never sits on tick labels); text >= 9 px
        if self.flat:   # a run in the plane z = 0, seen from above as the page shows it: x right, y up
            self.ax = self.fig.add_axes((0.1, 0.13, 0.86, 0.77))
            self.ax.set_aspect("equal", adjustable="box")
            labels = ((self.ax.set_xlabel, "x"), (self.ax.set_ylabel, "y"))
            axes = (self.ax.xaxis, self.ax.yaxis)
            collection = LineCollection
        else:
            self.ax = self.fig.add_axes((0, 0.08, 1, 0.84), projection="3d")
            labels = ((self.ax.set_xlabel, "x"), (self.ax.set_ylabel, "z"), (self.ax.set_zlabel, "y (up)"))
            axes = (self.ax.xaxis, self.ax.yaxis, self.ax.zaxis)
            collection = Line3DCollection
        self.fig.suptitle(title or track.title, fontsize=max(9, 7.5 * 100 / dpi), y=0.985)
        self.stamp = self.fig.text(0.02, 0.015, "", fontsize=max(8, 7 * 100 / dpi), family="monospace")
        for axis_label, text in labels:
            axis_label(text, fontsize=max(8, 7 * 100 / dpi))
        self.ax.tick_params(labelsize=max(7, 6.5 * 100 / dpi))
        for axis in axes:
            axis.set_major_locator(matplotlib.ticker.MaxNLocator(3))
        self.trails = collection([], linewidths=0.6, alpha=0.45)
        self._add(self.trails)
        tank = tank_of(track)
        if tank is not None:   # drawn once: the walls do not move
            edges = tank_outline(tank, self.flat)
            walls = collection([e[:, :2] if self.flat else e[:, [0, 2, 1]] for e in edges], linewidths=1.2,
                               colors="0.35")
            walls.set_gid("tank")
            self._add(walls)
        self.quiver = None
        self.agents = check_agents(track.agents, track.frames)
        self.agent_trails, self.agent_marks = [], []
        for agent in self.agents:
            trail = collection([], linewidths=1.8, colors=agent["color"])
            trail.set_gid(f"agent-trail:{agent['kind']}")
            self._add(trail)
            self.agent_trails.append(trail)
            self.agent_marks.append(None)
        if self.agents:
            from matplotlib.lines import Line2D

            self.ax.legend(handles=[Line2D([], [], color=a["color"], marker="o", markeredgecolor="black",
                                           linewidth=1.8, label=a["label"]) for a in self.agents],
                           loc="upper right", fontsize=max(8, 7 * 100 / dpi))

    def _add(self, collection) -> None:
        if self.flat:
            self.ax.add_collection(collection, autolim=False)
        else:
            self.ax.add_collection3d(collection, autolim=False)

    def draw(self, k: int, f: int) -> None:
        if self.flat:
            self._draw_flat(k, f)
        else:
            self._draw_3d(k, f)
        metrics = self.obs["metrics"]
        self.stamp.set_text(f"t = {self.track.times[f]:6.2f} s   polarization {metrics['polarization'][f]:.2f}"
                            f"   groups {metrics['n_groups'][f]:.0f}   (colour: {self.mode})")

    def _draw_flat(self, k: int, f: int) -> None:
        """Frame ``f`` in the plane, from above: arrows along the headings, trails and agents in (x, y)."""
        track, ax = self.track, self.ax
        c, half = self.centre[f], self.half
        ax.set_xlim(c[0] - half, c[0] + half)
        ax.set_ylim(c[1] - half, c[1] + half)
        p, v = track.pos[f][:, :2], track.vel[f][:, :2]
        norm = np.linalg.norm(v, axis=1, keepdims=True)
        h = np.divide(v, norm, out=np.zeros_like(v), where=norm > 0) * self.arrow
        if self.quiver is not None:
            self.quiver.remove()
        colours = self.colours[k]
        self.quiver = ax.quiver(p[:, 0], p[:, 1], h[:, 0], h[:, 1], color=colours, angles="xy", scale_units="xy",
                                scale=1.0, width=0.004, headwidth=4, headlength=5, pivot="tail")
        segments, boid = _trail_segments(track.pos, f, self.trail, track.wrap_jump)
        self.trails.set_segments(segments[:, :, :2])
        self.trails.set_color(colours[boid])
        for a, (agent, trail) in enumerate(zip(self.agents, self.agent_trails)):
            trail.set_segments(_trail_segments(agent["pos"], f, self.trail, track.wrap_jump)[0][:, :, :2])
            if self.agent_marks[a] is not None:
                self.agent_marks[a].remove()
            q = agent["pos"][f][:, :2]
            self.agent_marks[a] = ax.scatter(q[:, 0], q[:, 1], s=60 * agent["size"], color=agent["color"],
                                             edgecolors="black", linewidths=0.5, zorder=3)
            self.agent_marks[a].set_gid(f"agent:{agent['kind']}")

    def _draw_3d(self, k: int, f: int) -> None:
        track, ax = self.track, self.ax
        swap = [0, 2, 1]  # world (x, y, z) -> plot (x, z, y): y up
        c, half = self.centre[f][swap], self.half
        ax.set_xlim(c[0] - half, c[0] + half)
        ax.set_ylim(c[1] - half, c[1] + half)
        ax.set_zlim(c[2] - half, c[2] + half)
        ax.set_box_aspect((1, 1, 1))
        ax.view_init(elev=18, azim=-60 + (ROTATE_DEG_PER_S * k / self.fps if self.rotate else 0.0))
        p, v = track.pos[f][:, swap], track.vel[f][:, swap]
        norm = np.linalg.norm(v, axis=1, keepdims=True)
        h = np.divide(v, norm, out=np.zeros_like(v), where=norm > 0)
        if self.quiver is not None:
            self.quiver.remove()
        # a 3-D quiver draws every shaft, then every left head line, then every right one
        colours = self.colours[k]
        self.quiver = ax.quiver(p[:, 0], p[:, 1], p[:, 2], h[:, 0], h[:, 1], h[:, 2], length=self.arrow,
                                colors=np.concatenate([colours] * 3), linewidths=1.4, arrow_length_ratio=0.4)
        segments, boid = _trail_segments(track.pos, f, self.trail, track.wrap_jump)
        self.trails.set_segments(segments[:, :, swap])
        self.trails.set_color(colours[boid])
        for a, (agent, trail) in enumerate(zip(self.agents, self.agent_trails)):
            trail.set_segments(_trail_segments(agent["pos"], f, self.trail, track.wrap_jump)[0][:, :, swap])
            if self.agent_marks[a] is not None:
                self.agent_marks[a].remove()
            q = agent["pos"][f][:, swap]
            self.agent_marks[a] = ax.scatter(q[:, 0], q[:, 1], q[:, 2], s=60 * agent["size"], color=agent["color"],
                                             edgecolors="black", linewidths=0.5, depthshade=False)
            self.agent_marks[a].set_gid(f"agent:{agent['kind']}")

    def close(self) -> None:
        self.plt.close(self.fig)


def write_animation(track: Track, path, color_by: str = "auto", fps: float = 20.0, speed: float = 1.0,
                    rotate: bool = False, trail_s: float = 1.0, size=(640, 480), dpi: int = 100,
                    title: str | None = None, progress: bool = False) -> Animation:
    import matplotlib
    from matplotlib import animation
    from tqdm import tqdm


    path = Path(path)
    kind = check_options(path, fps, speed, size, dpi, color_by)
    if kind == "mp4":
        matplotlib.rcParams["animation.ffmpeg_path"] = ffmpeg_exe()
    shown = source_frames(track, fps, speed)
    drawing = _Drawing(track, color_by, shown, trail_s, size, dpi, title, rotate, fps)
    writer = (animation.PillowWriter(fps=fps) if kind == "gif"
              else animation.FFMpegWriter(fps=fps, codec="libx264", extra_args=["-pix_fmt", "yuv420p"]))
    try:
        with atomic_path(path) as tmp:
            target = tmp.with_suffix(path.suffix)
            with writer.saving(drawing.fig, str(target), dpi):
                for k, f in enumerate(tqdm(shown, desc=path.name, unit="frame", disable=not progress)):
                    drawing.draw(k, int(f))
                    writer.grab_frame()
            target.replace(tmp)
    finally:
        drawing.close()
    return Animation(path, kind, len(shown), float(fps), int(size[0]), int(size[1]))


def poster(track: Track, path, color_by: str = "auto", frame: int = -1, trail_s: float = 3.0,
           size=(480, 400), dpi: int = 100, title: str | None = None) -> Path:
    """A still PNG of one recorded frame (default the last), drawn as the animation draws it."""

    path = Path(path)
    f = range(track.frames)[frame]
    drawing = _Drawing(track, color_by, np.array([f]), trail_s, size, dpi, title, False, 1.0)
    try:
        drawing.draw(0, f)
        with atomic_path(path) as tmp:
            drawing.fig.savefig(tmp, format="png")
    finally:
        drawing.close()
    return path
