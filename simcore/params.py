"""Validated, frozen simulation parameters (docs/model.md: configuration keys and the models).

A model preset is a TOML file whose top-level keys are the fields of :class:`ModelParams` plus two tables,
``[init]`` (:class:`InitParams`) and ``[run]`` (:class:`RunSettings`). :func:`load_preset` reads one,
applies ``key=value`` overrides and returns a frozen :class:`Preset`; :meth:`Preset.replace` gives a
copy with dotted keys changed, validated the same way. Every check raises
:class:`~simcore.schema.ConfigError` naming the dotted key, the bad value and what is allowed; the
compiled kernel trusts what passes.

Preset keys have one alias, ``n`` for ``init.n`` (:data:`KEY_ALIASES`, :func:`canonical_key`); the
``[run]`` tables of sweep and calibration files set four preset keys by short names
(:data:`RUN_SHORTHANDS`).

Angles are in degrees, lengths in world units (body lengths: body radius 0.5), times in seconds; a file
may state its lengths in metres with a ``[units]`` table (:mod:`simcore.units`), converted when it is read.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, make_dataclass
from typing import Any

from . import registry
from .arena import Arena
from .obstacle_spec import Obstacle, canonical_obstacles
from .pattern_params import HOLLAND_TABLE_1, SEPARATION_WEIGHTS, PatternEntry, Patterns  # noqa: F401
from .units import Units, to_body_lengths
from .schema import (ConfigError, apply_overrides, build, check_choice as _choice, check_non_negative as _non_negative,
                     check_positive as _positive, check_within as _within, read_toml as _read_toml, replace_fields,
                     to_dict, unknown_key)

PERCEPTION_KINDS = ("sphere", "opensteer", "binocular", "topological")
SEARCHES = ("auto", "grid", "all_pairs")
DYNAMICS = registry.builtin_names()   # the built-in dynamics (simcore.registry: what each one can do)
FRONT_GATES = ("positive", "weighted", "none")
BOUNDARIES = ("open", "sphere_wrap", "periodic_box")
UPDATE_ORDERS = ("synchronous", "sequential")
INIT_REGIONS = ("ball", "cube")

KEY_ALIASES = {"n": "init.n"}  # the one alias table of preset keys
RUN_SHORTHANDS = {"n": "init.n", "duration": "run.duration", "dt": "run.dt",
                  "record_interval": "run.record_interval"}  # [run] keys of sweep and calibration files


def canonical_key(key: str) -> str:
    """The dotted preset key an alias stands for (``n`` -> ``init.n``); other keys unchanged."""
    return KEY_ALIASES.get(key, key)


# Keys of [perception] that only mean something for one kind; setting them for another kind is an error.
PERCEPTION_KIND_KEYS = {
    "sphere": ("radius",),
    "opensteer": ("near_radius", "separation_radius", "separation_cos", "alignment_radius",
                  "alignment_cos", "cohesion_radius", "cohesion_cos"),
    "binocular": ("direction_deg", "eye_position_deg", "field_deg", "range", "head_radius",
                  "occlusion", "body_radius"),
    "topological": ("neighbours", "max_distance", "blind_deg"),
}


@dataclass(frozen=True)
class Perception:
    """Who boid i sees (docs/model.md, perception)."""

    kind: str = "opensteer"
    # sphere
    radius: float = 9.0
    # opensteer: per rule a radius and the cosine of the forward cone; always seen within near_radius
    near_radius: float = 1.5
    separation_radius: float = 5.0
    separation_cos: float = -0.707
    alignment_radius: float = 7.5
    alignment_cos: float = 0.7
    cohesion_radius: float = 9.0
    cohesion_cos: float = -0.15
    # binocular (Holland & Semwal)
    direction_deg: float = 60.0
    eye_position_deg: float | None = None  # None: equal to direction_deg (see ``eye_deg``)
    field_deg: float = 120.0
    range: float = 20.0
    head_radius: float = 0.5
    occlusion: bool = True
    body_radius: float = 0.5
    # topological (Ballerini et al. 2008): the k nearest, optionally within max_distance, none in the blind cone
    neighbours: int = 7
    max_distance: float | None = None  # None: no distance limit
    blind_deg: float = 0.0             # full angle of the blind cone behind the boid; 0: none
    # how neighbours are found; every choice gives bit-identical results, so it is not part of a run's identity
    search: str = "auto"

    def __post_init__(self):
        _choice("perception.kind", self.kind, PERCEPTION_KINDS)
        _choice("perception.search", self.search, SEARCHES)
        if self.neighbours < 1:
            raise ConfigError("perception.neighbours", f"got {self.neighbours!r}; must be an integer >= 1")
        if self.max_distance is not None:
            _positive("perception.max_distance", self.max_distance)
        if not (math.isfinite(self.blind_deg) and 0.0 <= self.blind_deg < 360.0):
            raise ConfigError("perception.blind_deg", f"got {self.blind_deg!r}; allowed range [0, 360)")
        _positive("perception.radius", self.radius)
        _non_negative("perception.near_radius", self.near_radius)
        for rule in ("separation", "alignment", "cohesion"):
            _positive(f"perception.{rule}_radius", getattr(self, f"{rule}_radius"))
            _within(f"perception.{rule}_cos", getattr(self, f"{rule}_cos"), -1.0, 1.0)
        _within("perception.direction_deg", self.direction_deg, 0.0, 90.0)
        if self.eye_position_deg is not None:
            _within("perception.eye_position_deg", self.eye_position_deg, 0.0, 90.0)
        _within("perception.field_deg", self.field_deg, 0.0, 360.0, lo_open=True)
        _positive("perception.range", self.range)
        _non_negative("perception.head_radius", self.head_radius)
        _positive("perception.body_radius", self.body_radius)

    @property
    def eye_deg(self) -> float:
        """Eye position angle in use: ``eye_position_deg``, or ``direction_deg`` when unset."""
        return self.direction_deg if self.eye_position_deg is None else self.eye_position_deg

    def resolved(self) -> dict:
        """The keys that matter for this kind, with defaults resolved (canonical form; ``search`` is left
        out because every search gives the same results)."""
        keys = ("kind",) + PERCEPTION_KIND_KEYS[self.kind]
        out = {key: getattr(self, key) for key in keys}
        if self.kind == "binocular":
            out["eye_position_deg"] = self.eye_deg
        return out


@dataclass(frozen=True)
class Vehicle:
    """OpenSteer SimpleVehicle physics constants."""

    max_speed: float = 9.0
    max_force: float = 27.0
    mass: float = 1.0

    def __post_init__(self):
        for name in ("max_speed", "max_force", "mass"):
            _positive(f"vehicle.{name}", getattr(self, name))


@dataclass(frozen=True)
class World:
    """Boundary and update order (docs/model.md, the world)."""

    boundary: str = "open"
    sphere_radius: float = 50.0
    box_size: float = 100.0
    update_order: str = "synchronous"
    obstacles: tuple[Obstacle, ...] = ()
    dimensions: int = 3  # 2: motion in the plane z = 0 (a dynamics whose descriptor says PLANAR)

    def __post_init__(self):
        _choice("world.boundary", self.boundary, BOUNDARIES)
        _choice("world.dimensions", self.dimensions, (2, 3))
        _positive("world.sphere_radius", self.sphere_radius)
        _positive("world.box_size", self.box_size)
        _choice("world.update_order", self.update_order, UPDATE_ORDERS)


@dataclass(frozen=True)
class Leadership:
    """Hartman-Benes change of leadership (docs/model.md, change of leadership); ``x = 0`` disables it exactly.
    Available on every dynamics: the escape acts through a velocity boost and a raised speed cap."""

    x: float = 0.0
    front_gate: str = "positive"
    sigma: float = 1.0 / 6.0
    duration: float = 3.0
    gain: float = 0.2
    boost: float = 1.0
    refractory: float = 0.0
    slow_speed: float | None = None  # None: 0.05 max_speed

    def __post_init__(self):
        _non_negative("leadership.x", self.x)
        _choice("leadership.front_gate", self.front_gate, FRONT_GATES)
        _positive("leadership.sigma", self.sigma)
        _positive("leadership.duration", self.duration)
        _non_negative("leadership.gain", self.gain)
        _non_negative("leadership.boost", self.boost)
        _non_negative("leadership.refractory", self.refractory)
        if self.slow_speed is not None:
            _non_negative("leadership.slow_speed", self.slow_speed)

    @property
    def enabled(self) -> bool:
        return self.x > 0.0


@dataclass(frozen=True)
class Noise:
    """Intrinsic noise on every boid's new velocity (docs/model.md section 3.5, :mod:`simcore.noise`): a von
    Mises-Fisher turn of the heading each step, of concentration ``kappa`` per step or of angular sd
    ``angular_sd_deg`` per sqrt(second) (kappa = 1 / (sd^2 dt), sd in radians), and a normal speed kick of
    sd ``speed_sd`` per sqrt(second). Off (all unset / 0) by default."""

    kappa: float | None = None
    angular_sd_deg: float | None = None
    speed_sd: float = 0.0

    def __post_init__(self):
        if self.kappa is not None:
            _positive("noise.kappa", self.kappa)
        if self.angular_sd_deg is not None:
            _positive("noise.angular_sd_deg", self.angular_sd_deg)
            if self.kappa is not None:
                raise ConfigError("noise.angular_sd_deg", "give either noise.kappa or noise.angular_sd_deg, not both")
        _non_negative("noise.speed_sd", self.speed_sd)

    @property
    def enabled(self) -> bool:
        return self.kappa is not None or self.angular_sd_deg is not None or self.speed_sd > 0.0

    def kappa_per_step(self, dt: float) -> float:
        """The concentration of one step's turn; 0 without angular noise."""
        if self.kappa is not None:
            return self.kappa
        if self.angular_sd_deg is not None:
            return 1.0 / (math.radians(self.angular_sd_deg) ** 2 * dt)
        return 0.0


@dataclass(frozen=True)
class Cruise:
    """A preferred speed (docs/model.md section 3.5): the speed relaxes to ``speed`` with time constant
    ``tau`` seconds (a force along the heading). Off (``speed`` unset) by default."""

    speed: float | None = None
    tau: float = 1.0

    def __post_init__(self):
        if self.speed is not None:
            _positive("cruise.speed", self.speed)
        _positive("cruise.tau", self.tau)

    @property
    def enabled(self) -> bool:
        return self.speed is not None


class _Model:
    """The methods of :class:`ModelParams` (its fields come from the registry, below)."""

    def __post_init__(self):
        if not isinstance(self.dynamics, str):
            raise ConfigError("dynamics", f"expected a string, got {self.dynamics!r}")
        dynamics = registry.describe(self.dynamics)
        if dynamics.builtin:
            _check_builtin(self)
        else:
            _check_plugin(self)
        _check_capabilities(self, dynamics)
        if self.arena.enabled:
            _check_arena(self)
        if self.leadership.enabled and not math.isfinite(self.perception_range):
            raise ConfigError("perception.max_distance", "the change of leadership measures eccentricity against "
                                                         "the perception range: set perception.max_distance")

    @property
    def slow_speed(self) -> float:
        lead = self.leadership
        return 0.05 * self.vehicle.max_speed if lead.slow_speed is None else lead.slow_speed

    @property
    def sphere_radius(self) -> float:
        """The radius of the perception sphere: ``perception.radius``, or what the dynamics derives it from
        (its descriptor's ``sphere_radius``: couzin2002's zone of attraction, vicsek's alignment radius)."""
        derived = registry.describe(self.dynamics).sphere_radius
        return self.perception.radius if derived is None else derived(self)

    @property
    def perception_range(self) -> float:
        """e: the distance the flock is judged over (sphere radius, binocular range, opensteer cohesion radius,
        topological max_distance; infinite for a topological perception without one)."""
        per = self.perception
        if per.kind == "topological":
            return math.inf if per.max_distance is None else per.max_distance
        return {"sphere": self.sphere_radius, "binocular": per.range, "opensteer": per.cohesion_radius}[per.kind]


# the tables every model has; then each built-in dynamics' own table (simcore.registry), then a plug-in's
SHARED_FIELDS = (
    ("name", str, DYNAMICS[0]), ("dynamics", str, DYNAMICS[0]), ("description", str, ""),
    ("perception", Perception, field(default_factory=Perception)),
    ("vehicle", Vehicle, field(default_factory=Vehicle)), ("world", World, field(default_factory=World)),
    ("patterns", Patterns, field(default_factory=Patterns)),
    ("leadership", Leadership, field(default_factory=Leadership)),
    ("noise", Noise, field(default_factory=Noise)), ("cruise", Cruise, field(default_factory=Cruise)),
    ("arena", Arena, field(default_factory=Arena)),
)
PLUGIN_FIELDS = (
    ("plugin", Any, None),                  # a plug-in dynamics' parameters (simcore.plugin): its Params
    ("plugin_sha256", str | None, None),    # the plug-in module's SHA-256 (filled in; checked when given)
)
MODEL_TABLES = tuple(registry.builtin_tables())   # the built-ins' own tables, in registry order
ModelParams = make_dataclass(
    "ModelParams",
    [*SHARED_FIELDS, *((name, cls, field(default_factory=cls)) for name, cls in registry.builtin_tables().items()),
     *PLUGIN_FIELDS],
    bases=(_Model,), frozen=True,
    namespace={"__doc__": "Everything that defines the model (not the run): perception, rules, physics, world; "
                          "one table per built-in dynamics (simcore.registry) and a plug-in's ``plugin``.",
               "__module__": __name__})


def _check_builtin(model) -> None:
    """A built-in dynamics has no [plugin] table."""
    if model.plugin not in (None, {}):
        raise ConfigError("plugin", f"applies only to a plug-in dynamics, not {model.dynamics!r} (docs/plugins.md)")
    if model.plugin_sha256 is not None:
        raise ConfigError("plugin_sha256", f"applies only to a plug-in dynamics, not {model.dynamics!r}")
    object.__setattr__(model, "plugin", None)


def _check_plugin(model) -> None:
    """A plug-in dynamics (simcore.plugin): its [plugin] table built and its source hash recorded."""
    from .plugin import validate

    values, sha = validate(model, DYNAMICS)
    object.__setattr__(model, "plugin", values)
    object.__setattr__(model, "plugin_sha256", sha)


def _check_capabilities(model, dynamics: registry.Dynamics) -> None:
    """What the model asks of its dynamics, against what the dynamics can do (its descriptor's flags,
    then its own ``check``); ConfigError naming the key."""
    name = model.dynamics
    if model.world.dimensions == 2:
        _check_planar(model, dynamics)
    if model.leadership.enabled and not dynamics.leadership:
        raise ConfigError("leadership.x", f"got {model.leadership.x!r}; dynamics {name!r} has no change of "
                                          "leadership: set leadership.x = 0")
    if model.patterns.enabled and not dynamics.patterns:
        raise ConfigError("patterns.enabled", f"dynamics {name!r} has no pattern mode: set patterns.enabled = false")
    if not dynamics.shared_noise and model.noise.enabled:
        raise ConfigError("noise", f"dynamics {name!r} has its own noise and a constant speed ([{dynamics.table}]): "
                                   "leave [noise] out")
    if not dynamics.shared_noise and model.cruise.enabled:
        raise ConfigError("cruise.speed", f"got {model.cruise.speed!r}; dynamics {name!r} flies at a constant "
                                          f"speed ([{dynamics.table}]): leave [cruise] out")
    dynamics.check(model)
    if model.world.obstacles and not dynamics.obstacles:
        readers = tuple(d.name for d in registry.builtins() if d.obstacles)
        raise ConfigError("world.obstacles", f"dynamics {name!r} does not avoid obstacles; obstacles "
                                             f"are read by dynamics {readers}")
    if dynamics.perception is not None and model.perception.kind != dynamics.perception:
        raise ConfigError("perception.kind", f"got {model.perception.kind!r}; dynamics {name!r} uses the "
                                             f"perception {dynamics.perception}: set perception.kind = "
                                             f"'{dynamics.perception}'")


def _check_arena(model) -> None:
    """A tank (``[arena]``, docs/model.md section 16) needs an open world, and in 2-D lies in the plane."""
    if model.world.boundary != "open":
        raise ConfigError("world.boundary", f"got {model.world.boundary!r}; an arena (arena.kind = "
                                            f"{model.arena.kind!r}) needs an open world: set world.boundary = 'open'")
    if model.world.dimensions == 2 and model.arena.centre[2] != 0.0:
        raise ConfigError("arena.centre", f"got {list(model.arena.centre)!r}; with world.dimensions = 2 the arena "
                                          "lies in the plane: its z must be 0")


def _check_planar(model, dynamics: registry.Dynamics) -> None:
    """A 2-D model (``world.dimensions = 2``): a dynamics that moves in the plane, and nothing that lives
    out of the plane z = 0 (ConfigError naming the key; docs/model.md section 15)."""
    if not dynamics.planar:
        planar = tuple(d.name for d in registry.builtins() if d.planar)
        raise ConfigError("world.dimensions", f"got 2; dynamics {model.dynamics!r} runs in 3-D only: 2-D "
                                              f"motion is available for dynamics {planar}")
    if model.world.obstacles:
        raise ConfigError("world.obstacles", f"{len(model.world.obstacles)} obstacle(s) with world.dimensions = 2: "
                                             "obstacles are 3-D solids and a 2-D run has none; leave them out "
                                             "or set world.dimensions = 3")


@dataclass(frozen=True)
class InitParams:
    """Initial conditions (docs/model.md section 0.5): N boids uniform in a ball, headings uniform on the
    sphere, all at ``speed``; the ball radius grows as (N/100)^(1/3) when ``scale_with_n``. Or the state
    in ``from_file`` (:mod:`simcore.initfile`): then ``n`` must be the file's boid count (a preset may
    leave it out) and ``from_file_sha256`` is the file's digest (filled in; checked when given).
    ``region = "cube"`` draws the positions uniform in the cube [-radius, radius)^3 instead of the ball
    (a periodic box of side 2 radius filled evenly); in 2-D (``world.dimensions = 2``) the ball is a disc
    and the cube a square in the plane z = 0, headings uniform on the circle."""

    n: int = 100
    radius: float = 20.0
    speed: float = 2.7
    scale_with_n: bool = False
    region: str = "ball"
    from_file: str | None = None
    from_file_sha256: str | None = None

    def __post_init__(self):
        if self.n < 1:
            raise ConfigError("init.n", f"got {self.n!r}; must be an integer >= 1")
        _positive("init.radius", self.radius)
        _choice("init.region", self.region, INIT_REGIONS)
        _non_negative("init.speed", self.speed)
        if self.from_file is None:
            if self.from_file_sha256 is not None:
                raise ConfigError("init.from_file_sha256", "applies only with init.from_file")
            return
        from .initfile import boid_count, file_digest

        count, digest = boid_count(self.from_file), file_digest(self.from_file)
        if self.n != count:
            raise ConfigError("init.n", f"got {self.n!r}, but init.from_file {self.from_file!r} holds {count} boids: "
                                        f"set init.n = {count} or leave it out")
        if self.from_file_sha256 is None:
            object.__setattr__(self, "from_file_sha256", digest)
        elif self.from_file_sha256 != digest:
            raise ConfigError("init.from_file", f"{self.from_file!r} changed since this spec was made (its SHA-256 is "
                                                f"{digest}, the spec says {self.from_file_sha256})")

    @property
    def ball_radius(self) -> float:
        return self.region_radius(3)

    def region_radius(self, dimensions: int) -> float:
        """The radius (half side of the cube) of the start region: ``radius``, times (N/100)^(1/dimensions)
        with ``scale_with_n`` (the same density for every N)."""
        return self.radius * (self.n / 100.0) ** (1.0 / dimensions) if self.scale_with_n else self.radius


def init_dict(init: InitParams) -> dict:
    """Canonical resolved dict of the initial conditions: the file keys only when a file is used, and then
    without the keys of the random draw it replaces (so adding the option changed no existing run id)."""
    out = to_dict(init)
    if init.from_file is None:
        del out["from_file"], out["from_file_sha256"]
        if init.region == "ball":
            del out["region"]
    else:
        for key in ("radius", "speed", "scale_with_n", "region"):
            del out[key]
    return out


MAX_STEPS = 10 ** 10   # steps of one run (a day of simulated time at dt = 1/60 is 5 x 10^6)


@dataclass(frozen=True)
class RunSettings:
    """Duration, fixed step and record interval of one run (seconds)."""

    duration: float = 30.0
    dt: float = 1.0 / 60.0
    record_interval: float = 1.0

    def __post_init__(self):
        _positive("run.dt", self.dt)
        _positive("run.duration", self.duration)
        _positive("run.record_interval", self.record_interval)
        whole = self.duration / self.dt
        if not whole <= MAX_STEPS:   # also inf (1e308 / 0.01): counted before any step is
            raise ConfigError("run.duration", f"got {self.duration!r} with run.dt = {self.dt!r}: {whole:.3g} steps; a "
                                              f"run takes at most {MAX_STEPS:,} steps")
        if round(whole) < 1:
            raise ConfigError("run.duration", f"got {self.duration!r}; shorter than one step of run.dt = {self.dt!r}")
        if abs(whole - round(whole)) > 1e-6 * max(1.0, whole):
            raise ConfigError("run.duration", f"got {self.duration!r}; must be a whole number of steps of "
                                              f"run.dt = {self.dt!r} (e.g. {round(whole) * self.dt!r})")
        steps = self.record_interval / self.dt
        if not steps <= MAX_STEPS:
            raise ConfigError("run.record_interval", f"got {self.record_interval!r} with run.dt = {self.dt!r}: every "
                                                     f"{steps:.3g} steps; at most {MAX_STEPS:,}")
        if abs(steps - round(steps)) > 1e-6 * max(1.0, steps) or round(steps) < 1:
            raise ConfigError("run.record_interval",
                              f"got {self.record_interval!r}; must be a whole multiple of run.dt = {self.dt!r}")

    @property
    def n_steps(self) -> int:
        return int(round(self.duration / self.dt))

    @property
    def record_every(self) -> int:
        return int(round(self.record_interval / self.dt))


@dataclass(frozen=True)
class Preset:
    """A model preset file, resolved: the model, its initial conditions and run settings."""

    model: ModelParams
    init: InitParams
    run: RunSettings
    units: Units = field(default_factory=Units)  # what the file was written in (section 12); not part of identity

    def __post_init__(self):
        _check_start_region(self.model, self.init)

    def full_dict(self) -> dict:
        """Every key with its resolved value (nothing left out), for reading swept values back."""
        out = {**to_dict(self.model), "init": to_dict(self.init), "run": to_dict(self.run)}
        out["perception"]["eye_position_deg"] = self.model.perception.eye_deg
        return out

    def to_dict(self) -> dict:
        """Canonical resolved form: every key that matters, defaults filled in, keys of other
        perception kinds left out. ``preset_from_dict(p.to_dict()) == p`` up to that resolution."""
        return {**model_dict(self.model), "init": init_dict(self.init), "run": to_dict(self.run)}

    def replace(self, changes: dict | None = None, /, **values) -> "Preset":
        """A copy with dotted keys set: ``p.replace({"perception.field_deg": 90, "n": 50})`` or
        ``p.replace(**{"run.duration": 10.0})``. A value may be a whole table (``{"perception": {...}}``,
        which replaces the table as a preset file would). The result is exactly what the preset file
        with those values gives, and is validated the same way: ConfigError naming the key. Keys of
        the same table change together (``run.dt`` with ``run.duration`` is one change)."""
        sections: dict[str, list] = {"model": [], "init": [], "run": []}
        for key, value in {**(changes or {}), **values}.items():
            parts = tuple(canonical_key(key).split("."))
            if not all(parts):
                raise ConfigError(key, "a preset key must be dotted names like perception.field_deg")
            section = parts[0] if parts[0] in ("init", "run") else "model"
            if section == "model" and parts[0] not in _MODEL_KEYS:
                raise unknown_key(parts[0], _MODEL_KEYS + ("init", "run"))
            sections[section].append((parts[1:] if section != "model" else parts, value))
        whole = {section: [v for p, v in items if not p] for section, items in sections.items()}
        init, run = self.init, self.run
        if whole["init"] or whole["run"]:
            init = build(InitParams, whole["init"][-1], "init") if whole["init"] else init
            run = build(RunSettings, whole["run"][-1], "run") if whole["run"] else run
        model = replace_fields(self.model, _new_dynamics(sections["model"]), "")
        _check_kind_keys(model.perception.kind, _perception_keys(sections["model"]))
        return Preset(model=model, init=replace_fields(init, [c for c in sections["init"] if c[0]], "init"),
                      run=replace_fields(run, [c for c in sections["run"] if c[0]], "run"), units=self.units)


def _check_start_region(model, init) -> None:
    """With an arena, the drawn start region (a ball or cube about the origin) lies inside it."""
    arena = model.arena
    if not arena.enabled or init.from_file is not None:
        return
    dimensions = model.world.dimensions
    reach = init.region_radius(dimensions) * (math.sqrt(dimensions) if init.region == "cube" else 1.0)
    offset = math.sqrt(sum(c * c for c in arena.centre[:dimensions]))
    if offset + reach > arena.inner_extent(dimensions):
        raise ConfigError("init.radius", f"the start region (reach {reach:g} from the origin) does not fit in the "
                                         f"arena (its largest inner {'disc' if dimensions == 2 else 'ball'} about "
                                         f"{list(arena.centre[:dimensions])} has radius "
                                         f"{arena.inner_extent(dimensions):g}): make init.radius smaller or the "
                                         "arena larger")


def _new_dynamics(changes) -> list:
    """Model changes, plus: a change of dynamics drops the plug-in table and hash of the old one (unless the
    changes set them), so the new dynamics' are built and recorded afresh."""
    touched = {parts[0] for parts, value in changes}
    if "dynamics" not in touched:
        return changes
    return changes + [((name,), None) for name in ("plugin", "plugin_sha256") if name not in touched]


def _perception_keys(changes) -> list[str]:
    """The perception keys a list of model changes sets (leaves, or the keys of a whole table)."""
    keys = []
    for parts, value in changes:
        if parts[0] != "perception":
            continue
        if len(parts) > 1:
            keys.append(parts[1])
        elif isinstance(value, dict):
            keys += list(value)
    return keys


def model_dict(model: ModelParams) -> dict:
    """Canonical resolved dict of a model (see :meth:`Preset.to_dict`): tables that cannot affect the
    run are left out (the tables of the other dynamics, the shared tables its dynamics does not use, a
    feature that is off: leadership while x = 0), so adding a feature never changes the identity of runs
    that do not use it. What a dynamics keeps is its descriptor's (:meth:`simcore.registry.Dynamics.keeps`)."""
    dynamics = registry.describe(model.dynamics)
    out = to_dict(model)
    # a dynamics that derives its sphere from its own table records only the kind
    out["perception"] = {"kind": model.perception.kind} if dynamics.sphere_radius else model.perception.resolved()
    if model.world.dimensions == 3:
        del out["world"]["dimensions"]
    features = {"leadership": model.leadership.enabled, "noise": model.noise.enabled, "cruise": model.cruise.enabled}
    for table in ("vehicle", "patterns", *features, *MODEL_TABLES):
        if not dynamics.keeps(table, features.get(table, True)):
            del out[table]
        elif table == dynamics.table and dynamics.canonical is not None:
            out[table] = dynamics.canonical(getattr(model, table))
    if dynamics.builtin and "plugin" not in dynamics.uses:   # added later: absent, so run ids stay valid
        del out["plugin"], out["plugin_sha256"]
    if model.world.obstacles:
        out["world"]["obstacles"] = canonical_obstacles(model.world.obstacles)
    else:
        del out["world"]["obstacles"]
    if model.arena.enabled:   # added later: absent while off, so run ids without an arena stay valid
        out["arena"] = model.arena.canonical()
    else:
        del out["arena"]
    return out


_MODEL_KEYS = tuple(f.name for f in fields(ModelParams))


def _check_kind_keys(kind, keys) -> None:
    """Perception ``keys`` that belong to another perception kind than ``kind`` are an error."""
    if not isinstance(kind, str):
        raise ConfigError("perception.kind", f"expected a string, got {kind!r}")
    _choice("perception.kind", kind, PERCEPTION_KINDS)
    for other_kind, kind_keys in PERCEPTION_KIND_KEYS.items():
        if other_kind == kind:
            continue
        for key in keys:
            if key in kind_keys and key not in PERCEPTION_KIND_KEYS.get(kind, ()):
                raise ConfigError(f"perception.{key}",
                                  f"applies only to perception.kind = '{other_kind}', not '{kind}'")


def preset_from_dict(data: dict) -> Preset:
    """Validated :class:`Preset` from a parsed preset dict (see module docstring)."""
    data = dict(data)
    units_table = data.pop("units", {})
    if not isinstance(units_table, dict):
        raise ConfigError("units", f"expected a table, got {units_table!r}")
    units = build(Units, units_table, "units")
    data = to_body_lengths(data, units)
    init = data.pop("init", {})
    run = data.pop("run", {})
    for key in data:
        if key not in _MODEL_KEYS:
            raise unknown_key(key, _MODEL_KEYS + ("init", "run", "units"))
    if isinstance(data.get("perception"), dict):
        _check_kind_keys(data["perception"].get("kind", Perception.kind), data["perception"])
    for name, table in (("init", init), ("run", run)):
        if not isinstance(table, dict):
            raise ConfigError(name, f"expected a table, got {table!r}")
    if isinstance(init.get("from_file"), str) and "n" not in init:
        from .initfile import boid_count

        init = {**init, "n": boid_count(init["from_file"])}
    return Preset(model=build(ModelParams, data), init=build(InitParams, init, "init"),
                  run=build(RunSettings, run, "run"), units=units)


def read_toml(path) -> dict:
    """A model preset file as a dict (ConfigError naming the file when it is missing or not TOML)."""
    return _read_toml(path, "model file")


def load_preset(path, overrides=()) -> Preset:
    """Read a preset TOML, apply ``key=value`` overrides, validate."""
    return preset_from_dict(apply_overrides(read_toml(path), overrides))
