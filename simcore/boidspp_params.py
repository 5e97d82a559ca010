"""The ``boidspp`` dynamics' descriptor (:mod:`simcore.registry`): its ``[boidspp]`` table, capabilities
(obstacles, agents: a predator and a prey; 2-D motion; no change of leadership or pattern mode; one
thread per run) and random streams; its hooks are :mod:`simcore.boidspp`.

Sub-tables (docs/model.md section 6 and the keys table of section 9): ``alignment``, ``cohesion`` and
``separation`` (each a blend ``S`` in [0, 1]; separation also its radius and ``form``), ``random_force``
(``every`` steps, ``magnitude`` of the velocity kick), ``avoid`` (the golden-angle ray fan: ``rays``,
``lookahead``, ``weight``, ``body_radius``), ``prey`` and ``predator``. ``min_speed`` is the lower speed
clamp; the upper one is ``vehicle.max_speed``. Every check raises
:class:`~simcore.schema.ConfigError` naming the dotted key; the table only enters a run's identity when
``dynamics = "boidspp"`` (:func:`simcore.params.model_dict`). Its keys are not converted from metres
(they declare no power of length), so a preset in metres with this dynamics is refused.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from .schema import (ConfigError, check_at_least, check_choice, check_non_negative, check_positive, check_vector3,
                     check_within)

SEPARATION_FORMS = ("inverse_square", "velocity_over_distance")
SCOPES = ("neighbours", "flock")
PREDATOR_TARGETS = ("centre", "nearest")

TABLE = "boidspp"
HOOKS = ".boidspp"
PLANAR = True
OBSTACLES = True
AGENTS = True
PATTERNS = False
THREADS = False
USES = ("vehicle", "patterns")
STREAMS = {"random_force": 2, "targets": 3}   # the random kicks; the prey's targets and the predator's start


@dataclass(frozen=True)
class Blend:
    """One blended rule: v <- S target + (1 - S) v, over the perceived neighbours or the whole flock."""

    blend: float = 0.5
    scope: str = "neighbours"

    def __post_init__(self):
        check_within("blend", self.blend, 0.0, 1.0)
        check_choice("scope", self.scope, SCOPES)


@dataclass(frozen=True)
class Separation:
    """Separation: the blend S, the radius of the neighbours it pushes from, and the target's form."""

    blend: float = 0.5
    radius: float = 2.0
    form: str = "inverse_square"

    def __post_init__(self):
        check_within("blend", self.blend, 0.0, 1.0)
        check_positive("radius", self.radius)
        check_choice("form", self.form, SEPARATION_FORMS)


@dataclass(frozen=True)
class RandomForce:
    """Every ``every`` steps each boid's velocity gets a kick of ``magnitude`` (units/s) in a random
    direction; magnitude 0 switches it off."""

    every: int = 20
    magnitude: float = 0.0

    def __post_init__(self):
        check_at_least("every", self.every, 1)
        check_non_negative("magnitude", self.magnitude)


@dataclass(frozen=True)
class Avoid:
    """Obstacle avoidance by the golden-angle ray fan over the forward hemisphere."""

    rays: int = 64
    lookahead: float = 8.0
    weight: float = 60.0
    body_radius: float = 0.5

    def __post_init__(self):
        check_at_least("rays", self.rays, 1)
        check_non_negative("lookahead", self.lookahead)
        check_non_negative("weight", self.weight)
        check_positive("body_radius", self.body_radius)


@dataclass(frozen=True)
class Prey:
    """A prey agent flying at ``speed`` to random target points uniform in the ball of ``target_radius``
    about ``target_centre`` (a new one when within ``arrive_radius``); every boid adds a seek
    acceleration of ``weight`` toward it."""

    enabled: bool = False
    speed: float = 4.0
    weight: float = 5.0
    target_centre: tuple[float, ...] = (0.0, 0.0, 0.0)
    target_radius: float = 30.0
    arrive_radius: float = 1.0

    def __post_init__(self):
        check_positive("speed", self.speed)
        check_non_negative("weight", self.weight)
        object.__setattr__(self, "target_centre", check_vector3("target_centre", self.target_centre))
        check_positive("target_radius", self.target_radius)
        check_positive("arrive_radius", self.arrive_radius)


@dataclass(frozen=True)
class Predator:
    """A predator present from ``start_s`` to ``leave_s`` seconds: it appears ``start_distance`` from the
    flock centre in a random direction, seeks the centre (``target = "centre"``) or the nearest boid
    (``"nearest"``) at ``speed``, and after ``leave_s`` flies straight away from the centre. Boids within ``avoid_radius`` of a present predator
    flee (v <- S away + (1 - S) v with S = ``flee_blend``, away = max_speed times the unit vector from
    the predator) and skip the rules. A boid within ``capture_radius`` (None: off) is recorded as
    captured (record only)."""

    enabled: bool = False
    speed: float = 12.0
    target: str = "centre"
    avoid_radius: float = 10.0
    flee_blend: float = 0.5
    start_s: float = 0.0
    leave_s: float | None = None
    start_distance: float = 40.0
    capture_radius: float | None = None

    def __post_init__(self):
        check_positive("speed", self.speed)
        check_choice("target", self.target, PREDATOR_TARGETS)
        check_non_negative("avoid_radius", self.avoid_radius)
        check_within("flee_blend", self.flee_blend, 0.0, 1.0)
        check_non_negative("start_s", self.start_s)
        if not math.isfinite(self.start_s):
            raise ConfigError("start_s", f"got {self.start_s!r}; must be finite")
        if self.leave_s is not None and not (math.isfinite(self.leave_s) and self.leave_s > self.start_s):
            raise ConfigError("leave_s", f"got {self.leave_s!r}; must be finite and > predator.start_s = "
                                         f"{self.start_s!r} (leave it out: the predator stays)")
        check_non_negative("start_distance", self.start_distance)
        if self.capture_radius is not None:
            check_positive("capture_radius", self.capture_radius)


@dataclass(frozen=True)
class BoidsPP:
    """The ``[boidspp]`` table (see the module docstring)."""

    min_speed: float = 2.0
    alignment: Blend = field(default_factory=Blend)
    cohesion: Blend = field(default_factory=Blend)
    separation: Separation = field(default_factory=Separation)
    random_force: RandomForce = field(default_factory=RandomForce)
    avoid: Avoid = field(default_factory=Avoid)
    prey: Prey = field(default_factory=Prey)
    predator: Predator = field(default_factory=Predator)

    def __post_init__(self):
        check_non_negative("min_speed", self.min_speed)


def check(model) -> None:
    """Cross-table checks of a model with ``dynamics = "boidspp"`` (ConfigError naming the key)."""
    if model.boidspp.min_speed > model.vehicle.max_speed:
        raise ConfigError("boidspp.min_speed", f"got {model.boidspp.min_speed!r}; must be <= vehicle.max_speed "
                                               f"= {model.vehicle.max_speed!r}")
    if model.world.dimensions == 2 and model.boidspp.prey.enabled and model.boidspp.prey.target_centre[2] != 0.0:
        raise ConfigError("boidspp.prey.target_centre", f"got {list(model.boidspp.prey.target_centre)!r}; with "
                                                        "world.dimensions = 2 the prey's targets lie in the plane: "
                                                        "its z must be 0")


def boidspp_dict(table: BoidsPP, to_dict) -> dict:
    """Canonical form of the table: the predator's keys only when it is enabled, the prey's likewise,
    and the random-force interval only with a non-zero magnitude (they cannot affect the run otherwise)."""
    out = to_dict(table)
    if not table.predator.enabled:
        out["predator"] = {"enabled": False}
    if not table.prey.enabled:
        out["prey"] = {"enabled": False}
    if table.random_force.magnitude == 0.0:
        out["random_force"] = {"magnitude": 0.0}
    return out


Params = BoidsPP


def canonical(table: BoidsPP) -> dict:
    from .schema import to_dict

    return boidspp_dict(table, to_dict)


def agent_observations(model, agents, capture_step) -> dict:
    """The agents' part of a run's observations: the predator's and the prey's recorded rows (None when
    off) and the captures [(step, boid)] in step then boid order (None without a capture radius)."""
    import numpy as np

    table = model.boidspp
    captures = None
    if table.predator.enabled and table.predator.capture_radius is not None:
        boids = np.flatnonzero(capture_step >= 0)
        order = np.lexsort((boids, capture_step[boids]))
        captures = np.stack([capture_step[boids][order], boids[order]], axis=1).astype(np.int64)
    return {"predator": agents[:, 0].copy() if table.predator.enabled else None,
            "prey": agents[:, 1].copy() if table.prey.enabled else None, "captures": captures}
