"""The viewer page's data: one JSON object, format ``flocksweep-viewer/1``, built by :func:`page_data`.

Top-level keys (F frames, N boids; lengths in world units, times in seconds; y is up)::

    format       "flocksweep-viewer/1"
    title        str
    n, frames    N, F
    times        [F] floats, evenly spaced
    pos          stream (F, N, 3) u16: positions
    heading      stream (F, N, 3) i8: unit headings v/|v| (zero for a stopped boid)
    speed        stream (F, N) u8: |v|
    group        stream (F, N) u8 or u16: group rank at that frame (0 = largest group)
    leader       stream (F, N) bits, or null: leaders (change of leadership)
    pattern      [N] ints, or null
    metrics      {"polarization" | "n_groups" | "nn_distance" | "cohesion": [F] floats (null = nan)}
    params       {dotted preset key: value}; info {label: value} (seed, run id, source, ...)
    world        {"boundary": "open" | "sphere_wrap" | "periodic_box", "sphere_radius" | "box_size": float,
                  "dimensions": 2 for a run in the plane z = 0 (absent in 3-D)}; a flat run (this, or every z
                  of ``bounds`` 0, e.g. a 2-D track) is seen from above, +z, with the grid in its plane
    wrap_jump    float or null: a frame-to-frame step longer than this is a wrap (no trail, no interpolation)
    bounds       {"min": [3], "max": [3]} of every boid and agent over the run
    palettes     {"turbo" | "viridis": 64 hex colours, "tab10": 10}; pattern_colours {str(value): hex}
    defaults     {"color_by", "trail_s", "boid_scale", "follow", "start_time"}
    encoding     {"stride": frames of the source per frame here, "position_quantum": [3] (max error 1/2 of it)}
    scene        [scene objects]; agents [agents]   (both may be empty)

A *stream* is a quantised array: ``{"dtype", "shape", "delta", "offset", "scale", "data"}``. ``data`` is
base64 of zlib (RFC 1950) bytes. After inflating: ``u8``/``i8`` one byte per value; ``u16`` two byte
planes (all low bytes, then all high bytes); ``bits`` one bit per value, most significant bit first
(``numpy.packbits``). With ``delta`` true each frame is stored as its difference from the previous frame,
modulo 2^8 or 2^16 (undo: running sum along the first axis with the same wrap-around). The value is
``offset + scale * q`` (``offset``/``scale`` per last-axis component when lists; ``i8`` read as signed).

Scene objects (static; ``color`` "#rrggbb", ``opacity`` in (0, 1], ``label`` and ``wireframe`` optional)::

    {"type": "sphere",   "center": [x, y, z], "radius": r}
    {"type": "plane",    "point": [x, y, z], "normal": [x, y, z], "size": side of the drawn square}
    {"type": "box",      "center": [x, y, z], "size": [sx, sy, sz], "rotation": [qx, qy, qz, qw] (optional)}
    {"type": "cylinder", "a": [x, y, z], "b": [x, y, z], "radius": r, "caps": "flat" | "round"}

Agents (moving, drawn as larger cones with their own colour and legend entry): given to
:func:`page_data` as ``{"kind": "prey" | "predator" | any name, "label": str, "color": hex, "size": cone
scale relative to a boid, "pos": (F_source, M, 3) array on the track's frames, "vel": optional,
"appears_s": optional, the time it first appears (drawn ghosted, semi-transparent, before it)}``,
encoded as ``{"kind", "label", "color", "size", "m", "pos": stream, "heading": stream, "appears": s or
null}``.
"""
from __future__ import annotations

import base64
import math
import re
import zlib

import numpy as np

from .palette import AGENT_COLOURS, COLOR_MODES, TABLE_1_HEX  # noqa: F401 - part of this module's face
from .track import Track

FORMAT = "flocksweep-viewer/1"
SCENE_TYPES = ("sphere", "plane", "box", "cylinder")
HEX = re.compile(r"^#[0-9a-fA-F]{6}$")


# ---------------------------------------------------------------------------------------------- streams


def _b64(raw: bytes) -> str:
    return base64.b64encode(zlib.compress(raw, 6)).decode("ascii")


def _delta(q: np.ndarray) -> np.ndarray:
    """Differences along the first axis, wrapping in q's unsigned dtype (first frame kept)."""
    out = q.copy()
    out[1:] = q[1:] - q[:-1]
    return out


def stream(q: np.ndarray, dtype: str, offset=0.0, scale=1.0, delta: bool = True) -> dict:
    """A stream of already quantised values ``q`` (uint8/uint16 or, for i8, int8 bit patterns)."""
    shape = list(q.shape)
    if dtype == "bits":
        raw = np.packbits(np.asarray(q, dtype=bool).reshape(-1)).tobytes()
        return {"dtype": "bits", "shape": shape, "delta": False, "data": _b64(raw)}
    unsigned = {"u8": np.uint8, "i8": np.uint8, "u16": np.uint16}[dtype]
    q = np.ascontiguousarray(q).view(unsigned) if dtype == "i8" else np.ascontiguousarray(q, dtype=unsigned)
    if delta and q.shape[0] > 1:
        q = _delta(q)
    flat = q.reshape(-1)
    if dtype == "u16":  # byte planes: all low bytes, then all high bytes
        raw = (flat & 0xFF).astype(np.uint8).tobytes() + (flat >> 8).astype(np.uint8).tobytes()
    else:
        raw = flat.tobytes()
    as_list = lambda v: [float(x) for x in np.atleast_1d(v)] if np.ndim(v) else float(v)  # noqa: E731
    return {"dtype": dtype, "shape": shape, "delta": bool(delta), "offset": as_list(offset),
            "scale": as_list(scale), "data": _b64(raw)}


def decode_stream(s: dict) -> np.ndarray:
    """The inverse of :func:`stream`, as the page does it (used by the tests and by size estimates)."""
    raw = zlib.decompress(base64.b64decode(s["data"]))
    count = int(np.prod(s["shape"]))
    if s["dtype"] == "bits":
        return np.unpackbits(np.frombuffer(raw, np.uint8))[:count].astype(bool).reshape(s["shape"])
    if s["dtype"] == "u16":
        planes = np.frombuffer(raw, np.uint8)
        q = (planes[:count].astype(np.uint16) | (planes[count:].astype(np.uint16) << 8)).reshape(s["shape"])
    else:
        q = np.frombuffer(raw, np.uint8).reshape(s["shape"]).copy()
    if s["delta"]:
        q = np.cumsum(q, axis=0, dtype=q.dtype)
    if s["dtype"] == "i8":
        q = q.view(np.int8)
    return np.asarray(s["offset"]) + np.asarray(s["scale"]) * q.astype(np.float64)


def position_stream(pos: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> dict:
    """Positions (F, M, 3) quantised to 16 bits per axis over the box [lo, hi]."""
    scale = np.where(hi > lo, (hi - lo) / 65535.0, 1.0)
    q = np.rint((pos - lo) / scale).clip(0, 65535).astype(np.uint16)
    return stream(q, "u16", lo, scale)


def heading_stream(vel: np.ndarray) -> dict:
    speed = np.linalg.norm(vel, axis=-1, keepdims=True)
    unit = np.divide(vel, speed, out=np.zeros_like(vel), where=speed > 0)
    return stream(np.rint(unit * 127).astype(np.int8), "i8", 0.0, 1 / 127)


def speed_stream(speed: np.ndarray) -> dict:
    top = float(speed.max()) if speed.size and speed.max() > 0 else 1.0
    return stream(np.rint(speed / top * 255).astype(np.uint8), "u8", 0.0, top / 255)


def label_stream(labels: np.ndarray) -> dict:
    top = int(labels.max()) if labels.size else 0
    return stream(labels.astype(np.uint8 if top < 256 else np.uint16), "u8" if top < 256 else "u16")


# ------------------------------------------------------------------------------------------ validation


def _vector(obj: dict, key: str, where: str, nonzero: bool = False) -> list[float]:
    value = obj.get(key)
    ok = isinstance(value, (list, tuple, np.ndarray)) and len(value) == 3
    vec = [float(v) for v in value] if ok else []
    if not ok or not all(math.isfinite(v) for v in vec) or (nonzero and not any(vec)):
        raise ValueError(f"{where}.{key}: got {value!r}; expected 3 finite numbers"
                         + (", not all 0" if nonzero else ""))
    return vec


def _positive(obj: dict, key: str, where: str, default=None) -> float:
    value = obj.get(key, default)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not (math.isfinite(value) and value > 0):
        raise ValueError(f"{where}.{key}: got {value!r}; expected a finite number > 0")
    return float(value)


def _style(obj: dict, where: str, default_colour: str) -> dict:
    colour = obj.get("color", default_colour)
    if not isinstance(colour, str) or not HEX.match(colour):
        raise ValueError(f"{where}.color: got {colour!r}; expected a hex colour like '#888888'")
    opacity = obj.get("opacity", 0.35)
    if isinstance(opacity, bool) or not isinstance(opacity, (int, float)) or not 0 < opacity <= 1:
        raise ValueError(f"{where}.opacity: got {opacity!r}; expected a number in (0, 1]")
    return {"color": colour, "opacity": float(opacity), "label": str(obj.get("label", "")),
            "wireframe": bool(obj.get("wireframe", False))}


def check_scene(objects) -> list[dict]:
    """Validated scene objects (see the module docstring); ValueError naming the bad item and key."""
    out = []
    for k, obj in enumerate(objects or ()):
        where = f"scene[{k}]"
        kind = obj.get("type") if isinstance(obj, dict) else None
        if kind not in SCENE_TYPES:
            raise ValueError(f"{where}.type: got {kind!r}; allowed: {', '.join(SCENE_TYPES)}")
        item = {"type": kind, **_style(obj, where, "#8c8c8c")}
        if kind == "sphere":
            item.update(center=_vector(obj, "center", where), radius=_positive(obj, "radius", where))
        elif kind == "plane":
            item.update(point=_vector(obj, "point", where), normal=_vector(obj, "normal", where, nonzero=True),
                        size=_positive(obj, "size", where, 100.0))
        elif kind == "box":
            item.update(center=_vector(obj, "center", where), size=[_positive({"s": s}, "s", f"{where}.size")
                                                                    for s in _vector(obj, "size", where)])
            rotation = obj.get("rotation", [0.0, 0.0, 0.0, 1.0])
            quat = np.asarray(rotation, dtype=float) if np.shape(rotation) == (4,) else np.zeros(0)
            if quat.size != 4 or not np.isfinite(quat).all() or np.linalg.norm(quat) == 0:
                raise ValueError(f"{where}.rotation: got {rotation!r}; expected a quaternion [qx, qy, qz, qw]")
            item["rotation"] = [float(v) for v in quat / np.linalg.norm(quat)]
        else:
            a, b = _vector(obj, "a", where), _vector(obj, "b", where)
            if a == b:
                raise ValueError(f"{where}: a and b are the same point; a cylinder needs two distinct ends")
            caps = obj.get("caps", "flat")
            if caps not in ("flat", "round"):
                raise ValueError(f"{where}.caps: got {caps!r}; allowed: 'flat', 'round'")
            item.update(a=a, b=b, radius=_positive(obj, "radius", where), caps=caps)
        out.append(item)
    return out


def check_agents(agents, frames: int) -> list[dict]:
    """Validated agents with float (F, M, 3) ``pos`` and ``vel`` on the track's ``frames``."""
    out = []
    for k, agent in enumerate(agents or ()):
        where = f"agents[{k}]"
        if not isinstance(agent, dict) or "pos" not in agent:
            raise ValueError(f"{where}: expected a dict with 'pos' (F, M, 3) and optional kind, label, color, size")
        pos = np.asarray(agent["pos"], dtype=np.float64)
        if pos.ndim == 2:
            pos = pos[:, None, :]
        if pos.ndim != 3 or pos.shape[0] != frames or pos.shape[2] != 3 or not np.isfinite(pos).all():
            raise ValueError(f"{where}.pos: expected finite (F={frames}, M, 3) positions, got shape {pos.shape}")
        vel = agent.get("vel")
        vel = np.gradient(pos, axis=0) if vel is None and frames > 1 else (
            np.zeros_like(pos) if vel is None else np.asarray(vel, dtype=np.float64).reshape(pos.shape))
        kind = str(agent.get("kind", "agent"))
        style = _style(agent, where, AGENT_COLOURS.get(kind, "#9467bd"))
        size = _positive(agent, "size", where, 2.0 if kind == "predator" else 1.2)
        appears = agent.get("appears_s")
        if appears is not None and not (isinstance(appears, (int, float)) and math.isfinite(appears)):
            raise ValueError(f"{where}.appears_s: got {appears!r}; expected a time in seconds (or None)")
        out.append({"kind": kind, "label": style["label"] or kind, "color": style["color"], "size": size,
                    "pos": pos, "vel": vel, "appears": None if appears is None else float(appears)})
    return out


# -------------------------------------------------------------------------------------------- page data


def palettes() -> dict:
    import matplotlib
    from matplotlib.colors import to_hex

    grid = np.linspace(0, 1, 64)
    return {"turbo": [to_hex(c) for c in matplotlib.colormaps["turbo"](grid)],
            "viridis": [to_hex(c) for c in matplotlib.colormaps["viridis"](grid)],
            "tab10": [to_hex(c) for c in matplotlib.colormaps["tab10"](np.arange(10))]}


def pattern_colours(pattern) -> dict:
    if pattern is None:
        return {}
    tab10 = palettes()["tab10"]
    return {str(int(v)): TABLE_1_HEX.get(int(v), tab10[k % 10]) for k, v in enumerate(np.unique(pattern))}


def default_color_by(track: Track) -> str:
    if track.pattern is not None and len(np.unique(track.pattern)) > 1:
        return "pattern"
    if track.leader is not None and track.leader.any():
        return "leader"
    return "boid"


def _plain(value):
    if isinstance(value, (np.generic,)):
        return value.item()
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def _series(values: np.ndarray) -> list:
    return [None if not math.isfinite(v) else round(float(v), 5) for v in values]


def core_streams(track: Track, agents: list[dict]) -> tuple[dict, dict]:
    """(streams of positions, headings and speeds; bounds) of every frame of ``track`` and ``agents``."""
    stacks = [track.pos.reshape(-1, 3)] + [a["pos"].reshape(-1, 3) for a in agents]
    lo = np.min([s.min(axis=0) for s in stacks], axis=0)
    hi = np.max([s.max(axis=0) for s in stacks], axis=0)
    streams = {"pos": position_stream(track.pos, lo, hi), "heading": heading_stream(track.vel),
               "speed": speed_stream(np.linalg.norm(track.vel, axis=-1))}
    return streams, {"lo": lo, "hi": hi}


def page_data(track: Track, observables: dict, stride: int = 1, color_by: str = "auto", trail_s: float = 2.0,
              boid_scale: float = 1.0, follow: bool | None = None, start_time: float | None = None) -> dict:
    """The page's JSON object for ``track`` (already thinned to every ``stride``-th source frame) and
    its :func:`~analysis.viewer.observables.frame_observables`. ``start_time``: the simulated second the
    page opens at (None: the first frame; a URL fragment ``#t=SECONDS`` overrides it)."""
    if start_time is not None and not (math.isfinite(start_time) and start_time >= 0):
        raise ValueError(f"start_time: got {start_time!r}; expected a number of seconds >= 0")
    if color_by == "auto":
        color_by = default_color_by(track)
    if color_by not in COLOR_MODES:
        raise ValueError(f"color_by: got {color_by!r}; allowed: auto, {', '.join(COLOR_MODES)}")
    scene = check_scene(track.scene)
    agents = check_agents(track.agents, track.frames)
    streams, box = core_streams(track, agents)
    lo, hi = box["lo"], box["hi"]
    wrapped = track.world.get("boundary") in ("sphere_wrap", "periodic_box")
    info = {**{k: _plain(v) for k, v in track.info.items()}, "boids": track.n,
            "group radius": f"{observables['group_radius']:g}" + (" (assumed: the source does not say)"
                                                                 if observables["assumed"] else "")}
    return {
        "format": FORMAT, "title": track.title, "n": track.n, "frames": track.frames,
        "times": [round(float(t), 9) for t in track.times], **streams,
        "group": label_stream(observables["labels"]),
        "leader": stream(track.leader, "bits") if track.leader is not None and track.leader.any() else None,
        "pattern": None if track.pattern is None else [int(v) for v in track.pattern],
        "metrics": {name: _series(values) for name, values in observables["metrics"].items()},
        "params": {k: _plain(v) for k, v in track.params.items()}, "info": info,
        "world": track.world, "wrap_jump": track.wrap_jump,
        "bounds": {"min": lo.tolist(), "max": hi.tolist()},
        "palettes": palettes(), "pattern_colours": pattern_colours(track.pattern),
        "defaults": {"color_by": color_by, "trail_s": float(trail_s), "boid_scale": float(boid_scale),
                     "follow": (not wrapped) if follow is None else bool(follow),
                     "start_time": None if start_time is None else float(start_time)},
        "encoding": {"stride": int(stride), "position_quantum": streams["pos"]["scale"]},
        "scene": scene,
        "agents": [{"kind": a["kind"], "label": a["label"], "color": a["color"], "size": a["size"],
                    "m": int(a["pos"].shape[1]), "pos": position_stream(a["pos"], lo, hi),
                    "heading": heading_stream(a["vel"]), "appears": a["appears"]} for a in agents],
    }
