"""What the viewer and the animation show: one run as a :class:`Track`, from whatever the user has.

A :class:`Track` holds a run's recorded frames and what is known about it:

* ``times`` float64 (F,) seconds, evenly spaced; ``pos``, ``vel`` float64 (F, N, 3);
* ``pattern`` (N,) uint or None; ``leader`` bool (F, N) or None (change of leadership);
  ``visible``, ``binocular`` int (F, N) or None (perception counts, for the metrics);
* ``title``; ``params`` {dotted key: value} (the resolved preset, shown in the page's panel);
  ``info`` {label: value} (seed, run id, source, ...);
* ``group_radius`` (links boids into groups; None: unknown), ``box`` (periodic box side for the
  metrics, None otherwise), ``world`` {"boundary": ..., "sphere_radius" | "box_size": ...} (drawn);
* ``scene`` and ``agents``: obstacles and extra agents (prey, predators), in the format of
  :mod:`analysis.viewer.encode` (validated there).

Constructors: :func:`from_observations` (a simulator ``Observations``, optionally with its preset),
:func:`from_npz` (a trajectory file, :mod:`sweeps.trajectory`: ``trajectory.npz`` of ``flocksweep
simulate --out`` with its ``params.json``, or a sweep's ``trajectories/<run_id>.npz`` with its results
store for the parameters), :func:`from_arrays` (plain arrays), :func:`from_observed` (an observed flock: measured tracks, gaps
interpolated) and :func:`as_track` (any of these). :meth:`Track.every` keeps every k-th frame, :meth:`Track.since` the frames from a time on.

Scene objects of a model are read by :func:`scene_of` (its ``world.obstacles`` and its ``[arena]``); extra agents of a run
by :func:`agents_of` (prey and predators, when the observations record them) or, from a saved
trajectory's ``predator`` / ``prey`` arrays, by :func:`recorded_agents`.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from flocksweep.observables.summary import default_group_radius, world_box
from flocksweep.simcore import Observations, preset_from_dict
from flocksweep.simcore.schema import ConfigError
from flocksweep.sweeps.design import rebuild
from flocksweep.sweeps.store import ResultsStore
from flocksweep.sweeps.trajectory import read_trajectory

DEFAULT_GROUP_RADIUS = 20.0  # used, and said so in the page, when nothing tells the run's radius


@dataclass(frozen=True)
class Track:
    times: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    pattern: np.ndarray | None = None
    leader: np.ndarray | None = None
    visible: np.ndarray | None = None
    binocular: np.ndarray | None = None
    title: str = "flock"
    params: dict = field(default_factory=dict)
    info: dict = field(default_factory=dict)
    group_radius: float | None = None
    box: float | None = None
    world: dict = field(default_factory=lambda: {"boundary": "open"})
    scene: tuple = ()
    agents: tuple = ()

    def __post_init__(self):
        pos, vel, times = np.asarray(self.pos), np.asarray(self.vel), np.asarray(self.times)
        if pos.ndim != 3 or pos.shape[2] != 3 or pos.shape[0] < 1 or pos.shape[1] < 1:
            raise ValueError(f"pos: expected shape (F, N, 3) with F, N >= 1, got {pos.shape}")
        if vel.shape != pos.shape:
            raise ValueError(f"vel: expected the shape of pos {pos.shape}, got {vel.shape}")
        if times.shape != pos.shape[:1]:
            raise ValueError(f"times: expected shape ({pos.shape[0]},), got {times.shape}")
        if not (np.isfinite(pos).all() and np.isfinite(vel).all() and np.isfinite(times).all()):
            raise ValueError("pos, vel and times must be finite (a run that went non-finite cannot be shown)")
        if len(times) > 1 and not (np.diff(times) > 0).all():
            raise ValueError("times must increase")
        f, n = pos.shape[:2]
        for name, shape in (("pattern", (n,)), ("leader", (f, n)), ("visible", (f, n)), ("binocular", (f, n))):
            value = getattr(self, name)
            if value is not None and np.shape(value) != shape:
                raise ValueError(f"{name}: expected shape {shape}, got {np.shape(value)}")

    @property
    def n(self) -> int:
        return self.pos.shape[1]

    @property
    def frames(self) -> int:
        return self.pos.shape[0]

    @property
    def frame_interval(self) -> float:
        """Seconds between frames (0 for a single frame)."""
        return float(self.times[1] - self.times[0]) if self.frames > 1 else 0.0

    @property
    def wrap_jump(self) -> float | None:
        """A step longer than this is a boundary wrap, not motion (None: the world never wraps)."""
        if self.world.get("boundary") == "sphere_wrap":
            return float(self.world["sphere_radius"])
        if self.world.get("boundary") == "periodic_box":
            return float(self.world["box_size"]) / 2
        return None

    def every(self, k: int) -> "Track":
        """Every ``k``-th frame (the first always kept); agents' tracks likewise."""
        if k == 1:
            return self
        return self._frames(slice(None, None, k))


    def since(self, start: float, shift: float = 0.0) -> "Track":
        """The frames at or after ``start`` seconds (at least the last), their times minus ``shift``;
        agents' tracks likewise."""
        first = min(int(np.searchsorted(self.times, start - 1e-9 * max(1.0, abs(start)))), self.frames - 1)
        return self._frames(slice(first, None), shift)

    def _frames(self, pick: slice, shift: float = 0.0) -> "Track":
        cut = {name: None if getattr(self, name) is None else getattr(self, name)[pick]
               for name in ("leader", "visible", "binocular")}
        agents = tuple({**a, **{key: np.asarray(a[key])[pick] for key in ("pos", "vel") if key in a},
                        **({"appears_s": a["appears_s"] - shift} if a.get("appears_s") is not None else {})}
                       for a in self.agents)
        times = self.times[pick] - shift if shift else self.times[pick]
        return replace(self, times=times, pos=self.pos[pick], vel=self.vel[pick], agents=agents, **cut)


def flat_params(preset_dict: dict, prefix: str = "") -> dict:
    """A nested preset dict as {dotted key: value}, in the preset's order."""
    out = {}
    for key, value in preset_dict.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            out.update(flat_params(value, name + "."))
        else:
            out[name] = value
    return out


def world_of(model) -> dict:
    world = model.world
    out = {"boundary": world.boundary}
    if world.boundary == "sphere_wrap":
        out["sphere_radius"] = float(world.sphere_radius)
    elif world.boundary == "periodic_box":
        out["box_size"] = float(world.box_size)
    if world.dimensions == 2:
        out["dimensions"] = 2   # drawn flat, seen from above (+z)
    return out


def obstacle_scene(obstacle, around=None) -> dict:
    """One :class:`simcore.obstacle_spec.Obstacle` as a scene object of :mod:`analysis.viewer.encode`.

    A plane is drawn as a square patch centred on the foot of the middle of ``around`` (positions
    (..., 3), e.g. the run's) on the plane, 2.2 times as wide as their farthest in-plane offset from it
    (at least 100 units without positions); a cylinder as the segment between its cap centres."""
    label = {"label": obstacle.kind}
    if obstacle.kind == "sphere":
        return {"type": "sphere", "center": list(obstacle.centre), "radius": obstacle.radius, **label}
    if obstacle.kind == "box":
        return {"type": "box", "center": list(obstacle.centre), "size": [2.0 * h for h in obstacle.half_extents],
                **label}
    if obstacle.kind == "cylinder":
        centre, axis = np.asarray(obstacle.centre), np.asarray(obstacle.axis)
        half = obstacle.length / 2.0
        return {"type": "cylinder", "a": list(centre - half * axis), "b": list(centre + half * axis),
                "radius": obstacle.radius, "caps": "flat", **label}
    normal, point = np.asarray(obstacle.normal), np.asarray(obstacle.centre, dtype=np.float64)
    size = 100.0
    if around is not None and np.size(around):
        points = np.asarray(around, dtype=np.float64).reshape(-1, 3)
        middle = points.mean(axis=0)
        point = middle - np.dot(middle - point, normal) * normal
        offsets = points - point
        in_plane = offsets - np.outer(offsets @ normal, normal)
        size = 2.2 * max(float(np.linalg.norm(in_plane, axis=1).max()), 5.0)
    return {"type": "plane", "point": list(point), "normal": list(normal), "size": size, **label}


def arena_scene(arena, dimensions: int = 3, around=None) -> dict:
    """A tank (:class:`simcore.arena.Arena`, a preset's ``[arena]`` or a track file's) as a wireframe scene
    object: a box, or a cylinder along z. In 2-D (and for a cylinder with no height) its extent along z
    is a thin slab, or the z range of ``around`` (positions (..., 3)) widened by a tenth."""
    centre = np.asarray(arena.centre, dtype=np.float64)
    low, high = centre[2] - 0.05, centre[2] + 0.05
    if dimensions == 3 and around is not None and np.size(around):
        z = np.asarray(around, dtype=np.float64).reshape(-1, 3)[:, 2]
        z = z[np.isfinite(z)]
        if z.size:
            pad = 0.1 * max(float(z.max() - z.min()), 1.0)
            low, high = float(z.min()) - pad, float(z.max()) + pad
    common = {"label": "arena", "wireframe": True}
    if arena.kind == "box":
        size = list(arena.size) if dimensions == 3 else [arena.size[0], arena.size[1], high - low]
        return {"type": "box", "center": list(centre) if dimensions == 3 else [centre[0], centre[1], 0.0],
                "size": size, **common}
    if dimensions == 3 and arena.height is not None:
        low, high = centre[2] - arena.height / 2.0, centre[2] + arena.height / 2.0
    return {"type": "cylinder", "a": [centre[0], centre[1], low], "b": [centre[0], centre[1], high],
            "radius": arena.radius, "caps": "flat", **common}


def scene_of(model, around=None) -> tuple:
    """Scene objects of a model: its ``world.obstacles`` (:func:`obstacle_scene`; ``around`` the run's
    positions, for the size of plane patches) and its tank when it has one (:func:`arena_scene`)."""
    scene = tuple(obstacle_scene(obstacle, around) for obstacle in model.world.obstacles)
    arena = getattr(model, "arena", None)
    if arena is not None and arena.enabled:
        scene += (arena_scene(arena, getattr(model.world, "dimensions", 3), around),)
    return scene


def recorded_agents(predator=None, prey=None, times=None) -> tuple:
    """Viewer agents (:mod:`analysis.viewer.encode` dicts) of recorded (F, 3) predator and prey positions.
    Frames before an agent appears (NaN) show it where it first appears, ghosted (semi-transparent) until
    ``appears_s``, the time (of ``times``, the records' times) it is first present; an agent never present
    is left out."""
    out = []
    for kind, pos in (("predator", predator), ("prey", prey)):
        if pos is None:
            continue
        pos = np.asarray(pos, dtype=np.float64)
        present = np.flatnonzero(np.isfinite(pos).all(axis=1))
        if len(present) == 0:
            continue
        pos = pos.copy()
        pos[:present[0]] = pos[present[0]]
        agent = {"kind": kind, "label": kind, "pos": pos[:, None, :]}
        if present[0] > 0:
            when = f"t = {float(times[present[0]]):g} s" if times is not None else f"frame {present[0]}"
            agent["label"] = f"{kind} (ghosted until {when})"
            agent["appears_s"] = None if times is None else float(times[present[0]])
        out.append(agent)
    return tuple(out)


def agents_of(obs) -> tuple:
    """Extra agents (prey, predators) recorded by the simulator (``obs.predator``, ``obs.prey``), as
    :mod:`analysis.viewer.encode` dicts with their (F, 1, 3) tracks; () when the observations record none."""
    return recorded_agents(getattr(obs, "predator", None), getattr(obs, "prey", None), obs.times)


def metric_settings(model) -> tuple[float, float | None]:
    """(group radius, periodic box side or None) of a model, as the sweeps use them."""
    return float(default_group_radius(model)), world_box(model)


def _preset_meta(preset, around=None) -> dict:
    model = preset.model
    radius, box = metric_settings(model)
    return {"params": flat_params(preset.to_dict()), "group_radius": radius, "box": box,
            "world": world_of(model), "scene": scene_of(model, around)}


def from_observations(obs, preset=None, title: str | None = None, info: dict | None = None,
                      scene=(), agents=(), group_radius: float | None = None) -> Track:
    """A Track of simulator observations; with ``preset`` the panel shows its parameters and the metrics
    use its group radius and world."""
    meta = _preset_meta(preset, obs.pos) if preset is not None else {}
    if group_radius is not None:
        meta["group_radius"] = float(group_radius)
    leader = obs.leader if obs.leader is not None and obs.leader.any() else None
    name = title or (f"{preset.model.name}: N = {obs.n}" if preset is not None else f"flock of {obs.n}")
    return Track(times=obs.times, pos=obs.pos, vel=obs.vel, pattern=obs.pattern, leader=leader,
                 visible=obs.visible, binocular=obs.binocular, title=name, info=dict(info or {}),
                 **{**meta, "scene": tuple(meta.get("scene", ())) + tuple(scene)},
                 agents=agents_of(obs) + tuple(agents))


def from_arrays(times, pos, vel=None, pattern=None, leader=None, **meta) -> Track:
    """A Track of plain arrays; without ``vel`` the velocities are finite differences of ``pos``."""
    times = np.asarray(times, dtype=np.float64)
    pos = np.asarray(pos, dtype=np.float64)
    if vel is None:
        vel = np.gradient(pos, times, axis=0) if len(times) > 1 else np.zeros_like(pos)
    return Track(times=times, pos=pos, vel=np.asarray(vel, dtype=np.float64),
                 pattern=None if pattern is None else np.asarray(pattern),
                 leader=None if leader is None else np.asarray(leader, dtype=bool), **meta)


def from_observed(flock, title: str | None = None, info: dict | None = None,
                  group_radius: float | None = None, tank=None) -> Track:
    """A Track of an observed flock (:class:`observables.observed.ObservedFlock`: measured tracks, or a run
    seen through an observation model). The viewer draws a fixed flock, so every individual present at some
    record is drawn at every record: where it was not present, its position and velocity are interpolated
    linearly in time between its known records (held before its first and after its last); ``info`` says
    how many individuals are drawn and what share of their positions was filled in; 2-D tracks are marked
    as a run in the plane (drawn from above); ``tank`` (a :class:`simcore.arena.Arena`, the tank the tracks
    declare, in their analysis unit) is drawn as the scene's wireframe (:func:`arena_scene`). ValueError when
    nobody is ever present."""
    seen = flock.present.any(axis=0)
    if not seen.any():
        raise ValueError(f"flock {flock.name!r}: no individual is present at any record")
    present = flock.present[:, seen]
    pos, vel = _filled(flock.times, flock.pos[:, seen], present), _filled(flock.times, flock.vel[:, seen], present)
    filled = int((~present).sum())
    shown = f"{int(seen.sum())} of {flock.n}" + ("" if seen.all() else " (the others are never present)")
    said = {"individuals shown": shown,
            "filled in": f"{filled} of {present.size} positions ({filled / present.size:.1%}), interpolated "
                         "between detections"}
    world = {"boundary": "open", **({"dimensions": 2} if getattr(flock, "dims", 3) == 2 else {})}
    return Track(times=flock.times, pos=pos, vel=vel,
                 pattern=None if flock.pattern is None else np.asarray(flock.pattern)[seen],
                 title=title or f"flock {flock.name}", info={**(info or {}), **said},
                 group_radius=None if group_radius is None else float(group_radius), world=world,
                 scene=() if tank is None else (arena_scene(tank, getattr(flock, "dims", 3), pos),))


def _filled(times: np.ndarray, values: np.ndarray, present: np.ndarray) -> np.ndarray:
    """(R, N, 3) ``values`` with each individual's records where it is not ``present`` interpolated in time
    from those where it is (held at the ends: ``numpy.interp``)."""
    out = np.array(values, dtype=np.float64)
    for i in np.flatnonzero(~present.all(axis=0)):
        known = present[:, i]
        for c in range(out.shape[2]):
            out[:, i, c] = np.interp(times, times[known], values[known, i, c])
    return out


def _sweep_meta(path: Path, run_id: str, around=None) -> dict:
    """Parameters of a sweep trajectory ``<results>/trajectories/<run_id>.npz`` from its results store."""
    store = ResultsStore(path.parent.parent)
    record = store.model()
    design = store.design()
    if not record or design is None or run_id not in set(design["run_id"]):
        return {}
    row = design[design["run_id"] == run_id].iloc[0].to_dict()
    preset, metrics = rebuild(record, row)
    meta = _preset_meta(preset, around)
    meta["group_radius"] = float(metrics.group_radius)
    meta["info"] = {"run id": run_id, "replicate": int(row["replicate"]), "seed": int(row["seed"])}
    meta["title"] = f"{path.parent.parent.name}: run {run_id}"
    return meta


def _saved_params(path: Path):
    """(the parameters, their preset) of a trajectory's ``params.json``; an error naming the file when it
    cannot be read or holds no valid preset."""
    try:
        saved = json.loads(path.read_text())
        if not isinstance(saved, dict) or not isinstance(saved.get("preset"), dict):
            raise ValueError("expected a JSON object with a 'preset' object, as flocksweep simulate writes")
        return saved, preset_from_dict(saved["preset"])
    except ConfigError as err:
        raise ConfigError(str(path), f"its preset: {err}") from None
    except (OSError, ValueError) as err:
        raise ValueError(f"{path}: cannot be read as a trajectory's parameters ({err})") from None


def from_npz(path) -> Track:
    """A Track of a saved trajectory (:func:`sweeps.trajectory.read_trajectory`; see the module docstring)."""
    path = Path(path)
    arrays = read_trajectory(path)
    meta: dict = {"title": path.stem, "info": {"source": str(path)}}
    params_path = path.with_name("params.json")
    if params_path.is_file():
        saved, preset = _saved_params(params_path)
        meta.update(_preset_meta(preset, arrays["pos"]))
        meta["title"] = f"{saved['preset'].get('name', path.stem)}: seed {saved.get('seed')}"
        meta["info"] = {"source": str(path), "seed": saved.get("seed")}
    elif path.parent.name == "trajectories":
        meta.update(_sweep_meta(path, path.stem, arrays["pos"]))
        meta["info"] = {**meta.get("info", {}), "source": str(path)}
    if arrays["seed"] is not None and "seed" not in meta["info"]:
        seed = arrays["seed"]
        meta["info"]["seed"] = int(seed) if seed.ndim == 0 else [int(s) for s in seed]
    leader = arrays["leader"]
    return Track(times=arrays["times"].astype(np.float64), pos=arrays["pos"].astype(np.float64),
                 vel=arrays["vel"].astype(np.float64), pattern=arrays["pattern"],
                 leader=leader if leader is not None and leader.any() else None, visible=arrays["visible"],
                 binocular=arrays["binocular"], agents=recorded_agents(arrays["predator"], arrays["prey"],
                                                                         arrays["times"]),
                 **meta)


def as_track(source, preset=None, **options) -> Track:
    """A Track of a Track, an ``Observations``, a path to a ``.npz`` or a mapping of arrays."""
    if isinstance(source, Track):
        return replace(source, **options) if options else source
    if isinstance(source, Observations):
        return from_observations(source, preset, **options)
    if preset is not None:
        raise ValueError("preset: only used with simulator Observations (a Track or a saved trajectory "
                         "carries its own parameters)")
    if isinstance(source, (str, Path)):
        track = from_npz(source)
        return replace(track, **options) if options else track
    if isinstance(source, dict) or hasattr(source, "files"):
        arrays = {key: source[key] for key in (source.files if hasattr(source, "files") else source)}
        return from_arrays(**{k: v for k, v in arrays.items()
                              if k in ("times", "pos", "vel", "pattern", "leader")}, **options)
    raise TypeError(f"cannot view a {type(source).__name__}: pass Observations, a Track, a trajectory .npz "
                    "path or a dict with times, pos (and vel)")
