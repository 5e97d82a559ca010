"""Named slots: the flat arrays the compiled kernel reads, each declared once.

Packed parameters. The kernel takes ``fp`` (float64[len(F)]) and ``ip`` (int64[len(I)]). Every slot is
declared ONCE, in ``FLOAT_SLOTS`` or ``INT_SLOTS`` below, as ``NAME: its value from (model, dt)``; the
IntEnums ``F`` and ``I`` are generated from those declarations and :func:`pack` fills every slot from
them, so adding a parameter is a one-line change that cannot get out of step. Kernels read
``fp[F.MAX_SPEED]``; numba folds an IntEnum member to a compile-time constant index.

Per-boid buffers. The kernel's ``steer`` buffer (N, STEER_WIDTH) holds what perceiving leaves for the
move, and its meaning depends on the dynamics: columns ``OS.*`` (opensteer: the raw steering force) or
``HB.*`` (hartman_benes: the separation, cohesion and alignment steers). Each is one declaration.

Enumerations (``PERCEPTION_*``, ``BOUNDARY_*``, ...) are the positions of the choices in the tuples of
:mod:`simcore.params`; a dynamics' number (``I.DYNAMICS``, the run loop's literal) is the registry's
(:mod:`simcore.registry`). The ``[steering]`` weights and ``[gains]`` live in the shared slots because
plug-ins' hooks read them there (docs/plugins.md). Angles become cosines/sines here, once, with exact values at multiples of 90
degrees so that geometric boundary cases (a field of exactly 180 degrees sees exactly sideways) hold bit
for bit.
"""
from __future__ import annotations

import math
from enum import IntEnum

import numpy as np

from .params import (BOUNDARIES, FRONT_GATES, PERCEPTION_KINDS, SEARCHES, SEPARATION_WEIGHTS, UPDATE_ORDERS,
                     ModelParams)
from .arena import ARENA_KINDS
from .registry import describe


def cos_deg(angle_deg: float) -> float:
    """cos of an angle in degrees, exact (0, +-1) at multiples of 90 degrees."""
    quarter, rest = divmod(float(angle_deg), 90.0)
    if rest == 0.0:
        return (1.0, 0.0, -1.0, 0.0)[int(quarter) % 4]
    return math.cos(math.radians(angle_deg))


def sin_deg(angle_deg: float) -> float:
    """sin of an angle in degrees, exact (0, +-1) at multiples of 90 degrees."""
    quarter, rest = divmod(float(angle_deg), 90.0)
    if rest == 0.0:
        return (0.0, 1.0, 0.0, -1.0)[int(quarter) % 4]
    return math.sin(math.radians(angle_deg))


def speed_kick(model: ModelParams, dt: float) -> float:
    """The sd of one step's speed kick (:mod:`simcore.noise`, step 3): the exact Ornstein-Uhlenbeck step
    with cruise, sigma sqrt(dt) without."""
    sigma = model.noise.speed_sd
    if sigma == 0.0:
        return 0.0
    if not model.cruise.enabled:
        return sigma * math.sqrt(dt)
    tau = model.cruise.tau
    return sigma * math.sqrt(-0.5 * tau * math.expm1(-2.0 * dt / tau))


def planar_turn_sd(model: ModelParams, dt: float) -> float:
    """The sd (radians) of one step's turn in the plane (:mod:`simcore.noise`, 2-D): 1 / sqrt(kappa per
    step); 0 in 3-D or without angular noise."""
    kappa = model.noise.kappa_per_step(dt)
    if model.world.dimensions == 3 or kappa == 0.0:
        return 0.0
    return 1.0 / math.sqrt(kappa)


# float parameters: slot name -> its value from the validated model and the step dt
FLOAT_SLOTS = {
    "SEP_W": lambda m, dt: m.steering.separation_weight,
    "ALI_W": lambda m, dt: m.steering.alignment_weight,
    "COH_W": lambda m, dt: m.steering.cohesion_weight,
    "MAX_SPEED": lambda m, dt: m.vehicle.max_speed,
    "MAX_FORCE": lambda m, dt: m.vehicle.max_force,
    "MASS": lambda m, dt: m.vehicle.mass,
    "DT": lambda m, dt: dt,
    "SPHERE_RADIUS": lambda m, dt: m.sphere_radius,
    "NEAR_R": lambda m, dt: m.perception.near_radius,
    "SEP_R": lambda m, dt: m.perception.separation_radius,
    "SEP_COS": lambda m, dt: m.perception.separation_cos,
    "ALI_R": lambda m, dt: m.perception.alignment_radius,
    "ALI_COS": lambda m, dt: m.perception.alignment_cos,
    "COH_R": lambda m, dt: m.perception.cohesion_radius,
    "COH_COS": lambda m, dt: m.perception.cohesion_cos,
    "COS_EYE": lambda m, dt: cos_deg(m.perception.eye_deg),
    "SIN_EYE": lambda m, dt: sin_deg(m.perception.eye_deg),
    "COS_GAZE": lambda m, dt: cos_deg(m.perception.direction_deg),
    "SIN_GAZE": lambda m, dt: sin_deg(m.perception.direction_deg),
    "COS_HALF_FIELD": lambda m, dt: cos_deg(m.perception.field_deg / 2.0),
    "RANGE": lambda m, dt: m.perception.range,
    "HEAD_R": lambda m, dt: m.perception.head_radius,
    "BODY_R": lambda m, dt: m.perception.body_radius,
    "TOPO_RADIUS": lambda m, dt: math.inf if m.perception.max_distance is None else m.perception.max_distance,
    "COS_HALF_BLIND": lambda m, dt: cos_deg(m.perception.blind_deg / 2.0),
    "WORLD_RADIUS": lambda m, dt: m.world.sphere_radius,
    "BOX": lambda m, dt: m.world.box_size,
    "GAIN_S": lambda m, dt: m.gains.separation,
    "GAIN_K": lambda m, dt: m.gains.cohesion,
    "GAIN_M": lambda m, dt: m.gains.alignment,
    "SEP_FALLOFF": lambda m, dt: m.gains.separation_falloff_exponent,
    "LEAD_X": lambda m, dt: m.leadership.x,
    "LEAD_SIGMA": lambda m, dt: m.leadership.sigma,
    "LEAD_DURATION": lambda m, dt: m.leadership.duration,
    "LEAD_GAIN": lambda m, dt: m.leadership.gain,
    "LEAD_BOOST": lambda m, dt: m.leadership.boost,
    "LEAD_REFRACTORY": lambda m, dt: m.leadership.refractory,
    "SLOW_SPEED": lambda m, dt: m.slow_speed,
    "PERCEPTION_RANGE": lambda m, dt: m.perception_range,
    "NOISE_KAPPA": lambda m, dt: m.noise.kappa_per_step(dt) if m.world.dimensions == 3 else 0.0,
    "PLANAR_TURN_SD": lambda m, dt: planar_turn_sd(m, dt),
    "SPEED_KICK": lambda m, dt: speed_kick(m, dt),
    "CRUISE_SPEED": lambda m, dt: m.cruise.speed if m.cruise.enabled else 0.0,
    "CRUISE_DECAY": lambda m, dt: math.exp(-dt / m.cruise.tau) if m.cruise.enabled else 1.0,
    "ARENA_CX": lambda m, dt: m.arena.centre[0],
    "ARENA_CY": lambda m, dt: m.arena.centre[1],
    "ARENA_CZ": lambda m, dt: m.arena.centre[2],
    "ARENA_RADIUS": lambda m, dt: m.arena.radius,
    "ARENA_HALF_X": lambda m, dt: m.arena.size[0] / 2.0,
    "ARENA_HALF_Y": lambda m, dt: m.arena.size[1] / 2.0,
    "ARENA_HALF_Z": lambda m, dt: arena_half_z(m.arena),
    "WALL_WEIGHT": lambda m, dt: m.arena.wall_weight,
    "WALL_RANGE": lambda m, dt: m.arena.wall_range,
}

# integer parameters (choices as their position in the params tuples, flags as 0/1)
INT_SLOTS = {
    "PERCEPTION": lambda m, dt: PERCEPTION_KINDS.index(m.perception.kind),
    "SEARCH": lambda m, dt: SEARCHES.index(m.perception.search),
    "OCCLUSION": lambda m, dt: int(m.perception.occlusion),
    "SEE_ALL": lambda m, dt: int(m.perception.field_deg >= 360.0),
    "NEIGHBOURS": lambda m, dt: m.perception.neighbours,
    "BLIND": lambda m, dt: int(m.perception.blind_deg > 0.0),
    "BOUNDARY": lambda m, dt: BOUNDARIES.index(m.world.boundary),
    "ORDER": lambda m, dt: UPDATE_ORDERS.index(m.world.update_order),
    "PATTERNS": lambda m, dt: int(m.patterns.enabled),
    "SEP_WEIGHT": lambda m, dt: SEPARATION_WEIGHTS.index(m.patterns.separation_weight),
    "NBITS": lambda m, dt: m.patterns.n_bits,
    "DYNAMICS": lambda m, dt: dynamics_number(m.dynamics),
    "LEADERSHIP": lambda m, dt: int(m.leadership.enabled),
    "FRONT_GATE": lambda m, dt: FRONT_GATES.index(m.leadership.front_gate),
    "DRIVE": lambda m, dt: int(m.noise.enabled or m.cruise.enabled),
    "DIMENSIONS": lambda m, dt: m.world.dimensions,
    "ARENA": lambda m, dt: ARENA_KINDS.index(m.arena.kind),
    "REFLECT": lambda m, dt: int(m.arena.reflect),
    "CONSTANT_SPEED": lambda m, dt: int(describe(m.dynamics).heading),
}

F = IntEnum("F", list(FLOAT_SLOTS), start=0)
I = IntEnum("I", list(INT_SLOTS), start=0)  # noqa: E741 (the int twin of F)

# columns of the per-boid steer buffer, per dynamics
OS = IntEnum("OS", "FX FY FZ", start=0)
HB = IntEnum("HB", "SX SY SZ KX KY KZ MX MY MZ", start=0)
STEER_WIDTH = max(len(OS), len(HB))

# enumerations, in the order of the params tuples
PERCEPTION_SPHERE, PERCEPTION_OPENSTEER, PERCEPTION_BINOCULAR, PERCEPTION_TOPOLOGICAL = range(4)
SEARCH_AUTO, SEARCH_GRID, SEARCH_ALL_PAIRS = range(3)
BOUNDARY_OPEN, BOUNDARY_SPHERE_WRAP, BOUNDARY_PERIODIC = range(3)
ORDER_SYNCHRONOUS, ORDER_SEQUENTIAL = range(2)
SEPW_SIMILARITY, SEPW_DISSIMILARITY, SEPW_UNIFORM = range(3)
GATE_POSITIVE, GATE_WEIGHTED, GATE_NONE = range(3)
ARENA_NONE, ARENA_CYLINDER, ARENA_BOX = range(3)

assert PERCEPTION_KINDS == ("sphere", "opensteer", "binocular", "topological")
assert SEARCHES == ("auto", "grid", "all_pairs")
assert BOUNDARIES == ("open", "sphere_wrap", "periodic_box")
assert UPDATE_ORDERS == ("synchronous", "sequential")
assert SEPARATION_WEIGHTS == ("similarity", "dissimilarity", "uniform")
assert FRONT_GATES == ("positive", "weighted", "none")
assert ARENA_KINDS == ("none", "cylinder", "box")


def arena_half_z(arena) -> float:
    """Half the arena's extent along z: a box's half side, a cylinder's half height (infinite without one)."""
    if arena.kind == "cylinder":
        return math.inf if arena.height is None else arena.height / 2.0
    return arena.size[2] / 2.0


def dynamics_number(dynamics: str) -> int:
    """The run loop's literal for a dynamics: a built-in's position in the registry, or a plug-in's number
    (loaded and registered here when this process has not yet, :mod:`simcore.registry`)."""
    return describe(dynamics).number


def pack(model: ModelParams, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """(fp, ip) arrays for the kernel from validated parameters and the step ``dt``."""
    fp = np.array([value(model, dt) for value in FLOAT_SLOTS.values()], dtype=np.float64)
    ip = np.array([value(model, dt) for value in INT_SLOTS.values()], dtype=np.int64)
    return fp, ip
