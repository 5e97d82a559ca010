"""Packed parameters and agent rows of the Boids++ kernel (:mod:`simcore.boidspp`), each declared once.

``pack_boidspp(model, dt) -> (bp, bi, table, kinds, fan)``: ``bp`` float64[len(B)] and ``bi``
int64[len(BI)] hold the ``[boidspp]`` table (slots declared in ``B_SLOTS``/``BI_SLOTS`` as ``NAME: value
from (model, dt)``, as :mod:`simcore.layout` does for the shared slots); ``table``/``kinds`` are the
packed obstacles (:func:`simcore.obstacle_spec.pack_obstacles`) and ``fan`` the golden-angle ray fan
(:func:`simcore.obstacle_avoidance.golden_fan`).

The agents of a run live in one float64 (AGENT_ROWS, 3) array of the state (``State.agents``): rows
``PRED_POS``, ``PRED_VEL``, ``PREY_POS``, ``PREY_VEL``, ``PREY_TARGET`` and ``COUNTERS`` = (prey points
drawn so far, predator phase, 0). Phases: ``PHASE_WAITING`` (not yet appeared: position NaN),
``PHASE_HUNTING`` (seeks the flock centre), ``PHASE_LEAVING`` (flies away from it). A fresh state has
NaN positions and zero counters; the kernel places the agents when their time comes.
"""
from __future__ import annotations

import math
from enum import IntEnum

import numpy as np

from .boidspp_params import PREDATOR_TARGETS, SCOPES, SEPARATION_FORMS
from .obstacle_avoidance import golden_fan
from .obstacle_spec import pack_obstacles
from .params import ModelParams

NEVER = 2 ** 62  # a step that never comes


def _step_of(seconds: float | None, dt: float) -> int:
    """The first step at or after ``seconds`` (NEVER for None)."""
    if seconds is None:
        return NEVER
    return int(math.ceil(seconds / dt - 1e-9))


B_SLOTS = {
    "MIN_SPEED": lambda m, dt: m.boidspp.min_speed,
    "ALI_S": lambda m, dt: m.boidspp.alignment.blend,
    "COH_S": lambda m, dt: m.boidspp.cohesion.blend,
    "SEP_S": lambda m, dt: m.boidspp.separation.blend,
    "SEP_R": lambda m, dt: m.boidspp.separation.radius,
    "RF_MAG": lambda m, dt: m.boidspp.random_force.magnitude,
    "LOOKAHEAD": lambda m, dt: m.boidspp.avoid.lookahead,
    "AVOID_W": lambda m, dt: m.boidspp.avoid.weight,
    "AVOID_BODY": lambda m, dt: m.boidspp.avoid.body_radius,
    "PREY_SPEED": lambda m, dt: m.boidspp.prey.speed,
    "PREY_W": lambda m, dt: m.boidspp.prey.weight,
    "PREY_CX": lambda m, dt: m.boidspp.prey.target_centre[0],
    "PREY_CY": lambda m, dt: m.boidspp.prey.target_centre[1],
    "PREY_CZ": lambda m, dt: m.boidspp.prey.target_centre[2],
    "PREY_TARGET_R": lambda m, dt: m.boidspp.prey.target_radius,
    "PREY_ARRIVE": lambda m, dt: m.boidspp.prey.arrive_radius,
    "PRED_SPEED": lambda m, dt: m.boidspp.predator.speed,
    "PRED_AVOID_R": lambda m, dt: m.boidspp.predator.avoid_radius,
    "PRED_FLEE_S": lambda m, dt: m.boidspp.predator.flee_blend,
    "PRED_START_DIST": lambda m, dt: m.boidspp.predator.start_distance,
    "PRED_CAPTURE_R": lambda m, dt: (-1.0 if m.boidspp.predator.capture_radius is None
                                     else m.boidspp.predator.capture_radius),
}

BI_SLOTS = {
    "SEP_FORM": lambda m, dt: SEPARATION_FORMS.index(m.boidspp.separation.form),
    "ALI_SCOPE": lambda m, dt: SCOPES.index(m.boidspp.alignment.scope),
    "COH_SCOPE": lambda m, dt: SCOPES.index(m.boidspp.cohesion.scope),
    "RF_EVERY": lambda m, dt: m.boidspp.random_force.every,
    "PREY_ON": lambda m, dt: int(m.boidspp.prey.enabled),
    "PRED_ON": lambda m, dt: int(m.boidspp.predator.enabled),
    "PRED_TARGET": lambda m, dt: PREDATOR_TARGETS.index(m.boidspp.predator.target),
    "PRED_START": lambda m, dt: _step_of(m.boidspp.predator.start_s, dt),
    "PRED_LEAVE": lambda m, dt: _step_of(m.boidspp.predator.leave_s, dt),
}

B = IntEnum("B", list(B_SLOTS), start=0)
BI = IntEnum("BI", list(BI_SLOTS), start=0)
SEP_INVERSE_SQUARE, SEP_VELOCITY_OVER_DISTANCE = range(2)
SCOPE_NEIGHBOURS, SCOPE_FLOCK = range(2)
TARGET_CENTRE, TARGET_NEAREST = range(2)
assert PREDATOR_TARGETS == ("centre", "nearest")
assert SEPARATION_FORMS == ("inverse_square", "velocity_over_distance")
assert SCOPES == ("neighbours", "flock")

PRED_POS, PRED_VEL, PREY_POS, PREY_VEL, PREY_TARGET, COUNTERS, AGENT_ROWS = range(7)
PHASE_WAITING, PHASE_HUNTING, PHASE_LEAVING = 0.0, 1.0, 2.0


def new_agents() -> np.ndarray:
    """The agents of a fresh state: NaN positions and velocities, zero counters."""
    agents = np.full((AGENT_ROWS, 3), np.nan)
    agents[COUNTERS] = 0.0
    return agents


def pack_boidspp(model: ModelParams, dt: float):
    """(bp, bi, table, kinds, fan) for the Boids++ kernel (see the module docstring)."""
    bp = np.array([value(model, dt) for value in B_SLOTS.values()], dtype=np.float64)
    bi = np.array([value(model, dt) for value in BI_SLOTS.values()], dtype=np.int64)
    table, kinds = pack_obstacles(model.world.obstacles)
    return bp, bi, table, kinds, golden_fan(model.boidspp.avoid.rays)
