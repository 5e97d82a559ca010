"""A ready calibration file from a tracks file and a model preset (``flocksweep init``): the start
of a fit to a measured flock, every line commented, for a researcher to edit the priors and run.

Contract
--------
``start_calibration(tracks, preset_path, out, reading=None, stats=STATS, method="npe", name=None) -> Starter``
reads the tracks (:func:`observables.tracks.load_tracks`; ``reading``: the ``[targets.tracks]`` keys, e.g.
columns, units, body_length, fps, as ``flocksweep measure`` takes them; the file's sidecar JSON otherwise),
which must be in body lengths (tracks in metres need ``body_length``), measures them
(:func:`observables.measured.measure_tracks`) and writes ``out``:

* ``[model]``: the preset (its path relative to ``out``; its lengths and the tracks' both in body lengths),
  an open world (tracks are differenced over time: a periodic or wrapping world is replaced); its initial
  conditions are kept and stated beside the measured flock's size and speed (a comment says how to change
  them: the first seconds of a run depend on them);
* ``[run]``: ``n`` the median number of individuals, ``warmup`` (:data:`WARMUP_S`) plus the tracks'
  median duration (at most :data:`WINDOW_S`), a ``dt`` that divides the sampling interval, the group radius
  (:data:`GROUP_RADIUS_NN` x the measured nearest-neighbour distance);
* ``[observation]``: the tracks' sampling interval (median over flocks), velocities as recorded when the
  file has them (else differenced over the fewest whole intervals spanning :data:`VELOCITY_S`, 0.4 s: position
  noise differenced over a short interval becomes heading noise), the detection probability estimated from the
  tracks' gaps, position noise 0 (the tracker's error, to be filled in), a 2-D projection for 2-D tracks
  (``xz``, the simulator's horizontal plane; ``xy`` for a planar model);
* ``[parameters.*]``: the model's speed, interaction range and noise (and its separation weight where it
  has one) with priors sized from the measured speed and spacing (:data:`CANDIDATES`);
* a tank the tracks declare (their ``arena``): the model's ``[model] set`` puts it in that tank (kind, radius or
  size, height, centred on the origin where the flock starts, in the preset file's units; the start region made
  to fit it), unless the preset's own tank has that geometry; 2-D tracks are then seen along the tank's axis
  (``projection = "xy"``), as the calibration requires (:func:`analysis.calibration.tracks_targets.shared_tank`);
* ``[targets]``: ``from_tracks`` (relative to ``out``), ``stats``, the reading keys;
* ``[method]``: ``method`` (default npe: 1,500 training + 200 held-out simulations, an ensemble of 3).

The file is validated (read as a calibration) before it is written; an existing ``out`` is a ConfigError
(``--force`` replaces it). :class:`Starter`: ``path``, ``text``, ``measured`` (the scales it used),
``parameters`` (name -> key).
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from flocksweep.simcore.schema import ConfigError, get_dotted

STATS = ("polarization", "nn_distance", "speed_mean", "speed_cv")
WARMUP_S = 5.0
WINDOW_S = 60.0
GROUP_RADIUS_NN = 4.0
VELOCITY_S = 0.4

# per dynamics: (kind, key) candidates; kind sizes the prior from the measured scales
CANDIDATES = {
    "opensteer": (("speed_cap", "vehicle.max_speed"), ("range", "perception.range"), ("range", "perception.radius"),
                  ("range", "perception.cohesion_radius"), ("weight", "steering.separation_weight")),
    "vicsek": (("speed", "vicsek.speed"), ("range", "vicsek.radius"), ("angle", "vicsek.noise")),
    "couzin2002": (("speed", "couzin.speed"), ("range", "couzin.orientation_width"),
                   ("small", "couzin.repulsion_radius"), ("angle_sd", "couzin.noise_sd")),
    "reynolds87": (("speed_cap", "reynolds.max_speed"), ("range", "perception.radius"),
                   ("weight", "reynolds.separation_weight")),
    "hartman_benes": (("speed_cap", "vehicle.max_speed"), ("range", "perception.radius"),
                      ("weight", "gains.separation")),
    "boidspp": (("speed_cap", "vehicle.max_speed"), ("range", "perception.radius")),
}
PLUGIN_HINTS = (("speed", "speed"), ("range", "radius"), ("range", "range"), ("angle_sd", "noise"))


@dataclass
class Starter:
    path: Path
    text: str
    measured: dict = field(default_factory=dict)
    parameters: dict = field(default_factory=dict)


def _sig(value: float, digits: int = 3) -> float:
    return float(f"{value:.{digits}g}")


def _relative(target: Path, start: Path) -> str:
    try:
        return os.path.relpath(Path(target).resolve(), Path(start).resolve())
    except ValueError:   # another drive
        return str(Path(target).resolve())


def _prior(kind: str, key: str, scales: dict, current: float) -> tuple[str, str]:
    """(prior table, comment) of a free parameter of ``kind`` (module docstring)."""
    s, d = scales["speed"], scales["nn_distance"]
    if kind == "speed":
        low, high, why = 0.5 * s, 2.0 * s, f"around the measured speed {s:.3g} BL/s"
    elif kind == "speed_cap":
        low, high, why = 1.0 * s, 4.0 * s, f"a speed limit above the measured speed {s:.3g} BL/s"
    elif kind == "range":
        low, high, why = 1.0 * d, 10.0 * d, f"1-10 x the measured nearest-neighbour distance {d:.3g} BL"
    elif kind == "small":
        low, high, why = 0.2 * d, 2.0 * d, f"0.2-2 x the measured nearest-neighbour distance {d:.3g} BL"
    elif kind == "angle":
        low, high, why = 0.01, 3.0, "radians, from nearly none to strong heading noise"
    elif kind == "angle_sd":
        low, high, why = 0.0, 0.5, "radians (sd), from none to strong heading noise"
    else:   # a weight: a factor of 4 either way of the preset's
        low, high, why = current / 4.0, current * 4.0, f"a factor of 4 either way of the preset's {current:g}"
        return (f'{{ dist = "loguniform", low = {_sig(low)}, high = {_sig(high)} }}', why)
    return f'{{ dist = "uniform", low = {_sig(low)}, high = {_sig(high)} }}', why


def _free_parameters(preset, scales: dict) -> list[tuple[str, str, str, str]]:
    """(name, key, prior, comment) of the parameters to fit (module docstring)."""
    from flocksweep.analysis.reports.labels import parameter_label

    full = preset.full_dict()
    dynamics = preset.model.dynamics
    candidates = CANDIDATES.get(dynamics)
    if candidates is None:      # a plug-in: its own parameters, by name
        plugin = full.get("plugin", {})
        candidates = tuple((kind, f"plugin.{name}") for name in plugin for kind, hint in PLUGIN_HINTS
                           if hint in name and isinstance(plugin[name], (int, float)))
    out, kinds = [], set()
    for kind, key in candidates:
        try:
            current = get_dotted(full, key)
        except (KeyError, TypeError, ConfigError):
            continue
        if not isinstance(current, (int, float)) or isinstance(current, bool) or kind in kinds:
            continue
        if kind == "range" and "range" in kinds:
            continue
        kinds.add(kind)
        prior, why = _prior(kind, key, scales, float(current))
        name = key.split(".")[-1].replace("_deg", "")
        out.append((name, key, prior, f"{parameter_label(key)}: {why}"))
    if not out:
        raise ConfigError("--model", f"found no parameter of the {dynamics!r} dynamics to fit; write the "
                                     "[parameters.<name>] tables yourself")
    return out


def _scales(table, interval: float, velocity) -> dict:
    """The measured scales of the tracks (median over flocks)."""
    from flocksweep.observables.measured import measure_tracks, track_settings
    from flocksweep.observables.validation import TrackError

    try:
        measurement = measure_tracks(table, track_settings(1e9), interval, None, velocity)
    except TrackError as err:
        raise ConfigError("TRACKS", str(err)) from None
    runs = measurement.runs[measurement.runs["status"] == "ok"]
    if not len(runs):
        raise ConfigError("TRACKS", "no flock of the file could be measured")
    median = (lambda column: float(np.nanmedian(runs[column].to_numpy(dtype=float))))
    return {"speed": median("speed_mean_mean"), "nn_distance": median("nn_distance_mean"),
            "gyration_radius": median("gyration_radius_mean"), "individuals": median("individuals"),
            "duration": median("duration"), "flocks": int(len(runs)),
            "detection": _detection(table, interval), "polarization": median("polarization_mean")}


def _detection(table, interval: float) -> float:
    """The share of samples present between each individual's first and last sample (every flock)."""
    from flocksweep.observables.tracks import raw_flocks

    present, expected = 0, 0
    for flock in raw_flocks(table)[0]:
        bounds = flock.bounds()
        for i in range(len(flock.ids)):
            t = flock.t[bounds[i]:bounds[i + 1]]
            if len(t):
                present += len(np.unique(np.round(t / interval)))
                expected += int(round((t.max() - t.min()) / interval)) + 1
    return present / expected if expected else 1.0


def _velocity_interval(interval: float) -> float:
    """The smallest whole number of sampling intervals spanning at least :data:`VELOCITY_S` seconds."""
    return _sig(interval * max(1, math.ceil(VELOCITY_S / interval - 1e-9)), 9)


def _dt(interval: float, dt: float) -> tuple[float, bool]:
    """A step that divides the sampling interval: the preset's, or the interval over a whole number of steps."""
    steps = interval / dt
    if abs(steps - round(steps)) <= 1e-9 * max(1.0, steps) and round(steps) >= 1:
        return dt, False
    return interval / max(1, math.ceil(steps)), True


def _toml_value(value) -> str:
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{k} = {_toml_value(v)}" for k, v in value.items()) + " }"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, bool):
        return "true" if value else "false"
    return repr(value)


def _tank_settings(tank, preset, table, n: int, model_set: dict, name: str) -> list[str]:
    """Put the model in the tank the tracks declare: its ``[model] set`` entries added to ``model_set`` (in the
    preset file's units), and the comment lines that say so; [] without a tank."""
    from .tracks_targets import same_tank, describe_tank

    if tank is None:
        return []
    said = f"{describe_tank(tank, table.dims)} body lengths"
    arena = preset.model.arena
    if arena.enabled and same_tank(arena, tank, table.dims):
        return [f"The tracks' tank ({said}, declared by {name}) is the preset's own: the simulated flock lives in it."]
    scale = preset.units.body_length_m if preset.units.length == "m" else 1.0
    why = (f"the tank {name} declares ({said}), centred where the flock starts"
           + (f"; it replaces the preset's {describe_tank(arena, table.dims)}" if arena.enabled else ""))
    model_set["arena.kind"] = (tank.kind, why)
    if tank.kind == "cylinder":
        model_set["arena.radius"] = (_sig(tank.radius * scale, 9), "the tank's radius")
        if tank.height is not None:
            model_set["arena.height"] = (_sig(tank.height * scale, 9), "the tank's height")
    else:
        model_set["arena.size"] = ([_sig(v * scale, 9) for v in tank.size], "the tank's sides")
    if arena.enabled and any(arena.centre):
        model_set["arena.centre"] = ([0.0, 0.0, 0.0], "the tank about the origin, where the flock starts")
    dims = int(preset.model.world.dimensions)
    init = preset.init
    inner = tank.inner_extent(dims)
    cube = math.sqrt(dims) if init.region == "cube" else 1.0
    reach = (init.radius * (n / 100.0) ** (1.0 / dims) if init.scale_with_n else init.radius) * cube
    if init.from_file is None and reach > inner:
        model_set["init.radius"] = (_sig(0.5 * inner / cube * scale, 3), f"the preset's start region (reach {reach:.3g} "
                                    f"BL) does not fit in the tank: half the tank's inner radius {inner:.3g} BL")
        if init.scale_with_n:
            model_set["init.scale_with_n"] = (False, "the start region as stated, inside the tank")
    return ["The flock lives in the tank the tracks declare: the walls' strength and range (arena.wall_weight, "
            f"arena.wall_range: {arena.wall_weight:g} and {arena.wall_range:g}) may be set here or fitted "
            "as parameters."]


def start_calibration(tracks, preset_path, out, reading: dict | None = None, stats=STATS, method: str = "npe",
                      name: str | None = None, force: bool = False) -> Starter:
    """Write a ready calibration file (module docstring)."""
    from flocksweep.observables.resample import RECORDED
    from flocksweep.observables.tracks import load_tracks, raw_flocks, track_source
    from flocksweep.observables.validation import TrackError, infer_interval
    from flocksweep.simcore import load_preset

    from flocksweep.simcore.schema import read_config
    from flocksweep.sweeps.files import atomic_path

    from .config import calibration_from_dict
    from .tracks_targets import TracksTable

    tracks, preset_path, out = Path(tracks), Path(preset_path), Path(out)
    if out.exists() and not force:
        raise ConfigError("--out", f"{out} exists; choose another file or pass --force to replace it")
    if not tracks.exists():
        raise ConfigError("TRACKS", f"file not found: {tracks}")
    reading = dict(reading or {})
    try:
        source = track_source(tracks, reading, "targets.tracks", cls=TracksTable)
        table = load_tracks(tracks, source)
    except TrackError as err:
        raise ConfigError("TRACKS", str(err)) from None
    if table.unit_label != "BL":
        raise ConfigError("--body-length", f"{tracks.name} is in metres: give the body length in metres "
                                           "(--body-length 0.3), so that lengths are in body lengths, the model's "
                                           "units")
    preset = load_preset(preset_path)
    flocks, _ = raw_flocks(table)
    interval = _sig(float(np.median([infer_interval(f) for f in flocks])), 6)
    velocity = RECORDED if table.has_velocity else None
    scales = _scales(table, interval, velocity)
    planar = int(preset.model.world.dimensions) == 2
    tank = table.source.tank()
    projection = "none" if table.dims == 3 else ("xy" if planar or tank is not None else "xz")
    dt, changed_dt = _dt(interval, preset.run.dt)
    window = min(scales["duration"], WINDOW_S)
    n = max(2, int(round(scales["individuals"])))
    detection = max(0.5, min(1.0, round(scales["detection"], 2)))
    radius = _sig(GROUP_RADIUS_NN * scales["nn_distance"], 2)
    free = _free_parameters(preset, scales)
    folder = out.parent
    name = name or f"{tracks.name.split('.')[0]}_{preset.model.name}".replace("-", "_")
    full = preset.full_dict()
    model_set = {}
    if preset.run.dt * preset.run.record_every > 0.5 * window:
        model_set["run.record_interval"] = (_sig(interval, 6), f"the preset records every "
                                            f"{preset.run.dt * preset.run.record_every:g} s, too few records for "
                                            "the window (the observation's samples are the records that count)")
    if preset.model.world.boundary != "open":
        model_set["world.boundary"] = ("open", f"the preset's world is {preset.model.world.boundary!r}; tracks "
                                               "are differenced over time, which needs an open world")
    tank_said = _tank_settings(tank, preset, table, n, model_set, tracks.name)
    lines = [f"# A calibration of {preset.model.name} to the flock(s) in {tracks.name}, written by flocksweep init.",
             "# Measured from the tracks (median over flocks): "
             f"{scales['flocks']} flock(s), {scales['individuals']:.0f} individuals, {scales['duration']:.3g} s, "
             f"sampled every {interval:g} s; speed {scales['speed']:.3g} BL/s, nearest-neighbour distance "
             f"{scales['nn_distance']:.3g} BL, flock radius {scales['gyration_radius']:.3g} BL, polarization "
             f"{scales['polarization']:.3g}.",
             "# Edit the priors (and the free parameters) to what you know, then run:",
             f"#     flocksweep calibrate {out.name}",
             "# and read the verdict at the end (credible, or not credible and why).",
             f'name = "{name}"',
             "seed = 1",
             "",
             "[model]",
             f'preset = "{_relative(preset_path, folder)}"    # the model (relative to this file)']
    if model_set:
        lines.append("set = { " + ", ".join(f'"{k}" = {_toml_value(v)}' for k, (v, _) in model_set.items()) + " }")
        lines += [f"#   {k}: {why}" for k, (_, why) in model_set.items()]
    lines += [f"# {line}" for line in tank_said]
    start = full.get("init", {})
    lines += [f"# The simulated flock starts as the preset says: a ball of radius {start.get('radius', '?')} BL at "
              f"{start.get('speed', '?')} BL/s (the tracked flock's radius is {scales['gyration_radius']:.3g} BL, its "
              f"speed {scales['speed']:.3g} BL/s). A run's first seconds depend on it: if your flock started otherwise, "
              'set "init.radius" and "init.speed" here, or lengthen run.warmup.']
    lines += ["",
              "[run]",
              f"n = {n}                 # individuals: the median number tracked",
              f"warmup = {WARMUP_S:g}            # seconds for the simulated flock to form before its records are compared",
              f"duration = {_sig(WARMUP_S + window, 6):g}        # the warm-up plus the tracks' duration"
              + (f" (at most {WINDOW_S:g} s of it)" if scales["duration"] > WINDOW_S else ""),
              f"dt = {dt!r}" + ("     # a step that divides the sampling interval (the preset's does not)" if changed_dt
                               else "     # the preset's step"),
              f"group_radius = {radius:g}     # body lengths: {GROUP_RADIUS_NN:g} x the measured nearest-neighbour "
              "distance; individuals closer than this are one group",
              "",
              "[observation]      # how the tracks were measured; every simulated run is measured the same way",
              f"interval = {interval!r}    # seconds between samples (the tracks' median sampling interval)",
              ('velocity_interval = "recorded"    # the tracker\'s own velocities' if velocity == RECORDED else
               f"velocity_interval = {_velocity_interval(interval)!r}    # velocities: positions differenced over "
               f"{_velocity_interval(interval) / interval:.0f} interval(s), at least {VELOCITY_S:g} s: a shorter one "
               "turns position noise into heading noise (docs/measured.md, pitfalls)"),
              f"detection_probability = {detection:g}    # the share of samples present within each track (its gaps)",
              "position_sd = 0.0     # the tracker's position error (BL): put yours here",
              f'projection = "{projection}"' + (("    # the tracks are 2-D: the simulated flock is seen along the "
                                                 "tank's axis (z)" if tank is not None else
                                                 "    # the tracks are 2-D: the simulated flock is seen from above")
                                                if projection != "none" else "    # the tracks are 3-D"),
              ""]
    for pname, key, prior, why in free:
        lines += [f"[parameters.{pname}]    # {why}", f'key = "{key}"', f"prior = {prior}", ""]
    reading_lines = [f"{k} = {_toml_value(v)}" for k, v in reading.items() if v is not None]
    lines += ["[targets]",
              'summary = "mean"      # each flock (and each run) summarised by its window mean',
              "stats = [" + ", ".join(f'"{s}"' for s in stats) + "]",
              f'from_tracks = "{_relative(tracks, folder)}"    # each flock of the file is one sample of the statistics',
              ""]
    if reading_lines:
        lines += ["[targets.tracks]    # how the file is read", *reading_lines, ""]
    lines += ["[method]", f'kind = "{method}"']
    if method == "npe":
        lines += ["simulations = 1500    # training simulations (prior draws; stored runs are found, not rerun)",
                  "heldout = 200         # more, never trained on: the coverage check the verdict needs",
                  "ensemble = 3          # three flows: less over-confident than one"]
    elif method == "emcee":
        lines += ["n_sim = 16", "steps = 2000", "until_converged = true", "moves = \"de\"", "reevaluate_every = 25"]
    text = "\n".join(lines) + "\n"
    folder.mkdir(parents=True, exist_ok=True)
    tmp = folder / f".{out.name}.check"
    tmp.write_text(text)
    try:
        calibration_from_dict(read_config(tmp, "calibration file"), folder)
    except ConfigError as err:
        raise ConfigError(err.key, f"the calibration written for these tracks and this model does not validate "
                                   f"({err.detail}); this is a gap in flocksweep init: please report it") from None
    finally:
        tmp.unlink(missing_ok=True)
    with atomic_path(out) as written:
        Path(written).write_text(text)
    return Starter(out, text, scales, {pname: key for pname, key, _, _ in free})
