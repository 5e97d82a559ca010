"""Packing of validated parameters into the flat arrays the compiled kernel reads.

The kernel takes two arrays, ``fp`` (float64[F_COUNT]) and ``ip`` (int64[I_COUNT]); the module-level
integer constants below name their slots (numba folds them as compile-time constants). Angles are
turned into cosines/sines here, once, with exact values at multiples of 90 degrees so that geometric
boundary cases (a field of exactly 180 degrees sees exactly sideways) hold bit for bit.
"""
from __future__ import annotations

import math

import numpy as np

from .params import (BOUNDARIES, DYNAMICS, FRONT_GATES, PERCEPTION_KINDS, SEPARATION_WEIGHTS, UPDATE_ORDERS,
                     ModelParams)

# float slots
(F_SEP_W, F_ALI_W, F_COH_W, F_MAX_SPEED, F_MAX_FORCE, F_MASS, F_DT,
 F_SPHERE_RADIUS, F_NEAR_R, F_SEP_R, F_SEP_COS, F_ALI_R, F_ALI_COS, F_COH_R, F_COH_COS,
 F_COS_EYE, F_SIN_EYE, F_COS_GAZE, F_SIN_GAZE, F_COS_HALF_FIELD, F_RANGE, F_HEAD_R, F_BODY_R,
 F_WORLD_RADIUS, F_BOX, F_GAIN_S, F_GAIN_K, F_GAIN_M, F_SEP_FALLOFF, F_LEAD_X, F_LEAD_SIGMA,
 F_LEAD_DURATION, F_LEAD_GAIN, F_LEAD_BOOST, F_LEAD_REFRACTORY, F_SLOW_SPEED, F_PERCEPTION_RANGE,
 F_COUNT) = range(38)

# int slots
(I_PERCEPTION, I_OCCLUSION, I_SEE_ALL, I_BOUNDARY, I_ORDER, I_PATTERNS, I_SEP_WEIGHT, I_NBITS,
 I_DYNAMICS, I_LEADERSHIP, I_FRONT_GATE, I_COUNT) = range(12)

# enumerations, in the order of the params tuples
PERCEPTION_SPHERE, PERCEPTION_OPENSTEER, PERCEPTION_BINOCULAR = range(3)
BOUNDARY_OPEN, BOUNDARY_SPHERE_WRAP, BOUNDARY_PERIODIC = range(3)
ORDER_SYNCHRONOUS, ORDER_SEQUENTIAL = range(2)
SEPW_SIMILARITY, SEPW_DISSIMILARITY, SEPW_UNIFORM = range(3)
DYNAMICS_OPENSTEER, DYNAMICS_HARTMAN_BENES = range(2)
GATE_POSITIVE, GATE_WEIGHTED, GATE_NONE = range(3)

assert PERCEPTION_KINDS == ("sphere", "opensteer", "binocular")
assert BOUNDARIES == ("open", "sphere_wrap", "periodic_box")
assert UPDATE_ORDERS == ("synchronous", "sequential")
assert SEPARATION_WEIGHTS == ("similarity", "dissimilarity", "uniform")
assert DYNAMICS == ("opensteer", "hartman_benes")
assert FRONT_GATES == ("positive", "weighted", "none")


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


def pack(model: ModelParams, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """(fp, ip) arrays for the kernel from validated parameters and the step ``dt``."""
    per, veh, world = model.perception, model.vehicle, model.world
    fp = np.zeros(F_COUNT, dtype=np.float64)
    ip = np.zeros(I_COUNT, dtype=np.int64)
    fp[F_SEP_W] = model.steering.separation_weight
    fp[F_ALI_W] = model.steering.alignment_weight
    fp[F_COH_W] = model.steering.cohesion_weight
    fp[F_MAX_SPEED] = veh.max_speed
    fp[F_MAX_FORCE] = veh.max_force
    fp[F_MASS] = veh.mass
    fp[F_DT] = dt
    fp[F_SPHERE_RADIUS] = per.radius
    fp[F_NEAR_R] = per.near_radius
    fp[F_SEP_R], fp[F_SEP_COS] = per.separation_radius, per.separation_cos
    fp[F_ALI_R], fp[F_ALI_COS] = per.alignment_radius, per.alignment_cos
    fp[F_COH_R], fp[F_COH_COS] = per.cohesion_radius, per.cohesion_cos
    fp[F_COS_EYE], fp[F_SIN_EYE] = cos_deg(per.eye_deg), sin_deg(per.eye_deg)
    fp[F_COS_GAZE], fp[F_SIN_GAZE] = cos_deg(per.direction_deg), sin_deg(per.direction_deg)
    fp[F_COS_HALF_FIELD] = cos_deg(per.field_deg / 2.0)
    fp[F_RANGE] = per.range
    fp[F_HEAD_R] = per.head_radius
    fp[F_BODY_R] = per.body_radius
    fp[F_WORLD_RADIUS] = world.sphere_radius
    fp[F_BOX] = world.box_size
    ip[I_PERCEPTION] = PERCEPTION_KINDS.index(per.kind)
    ip[I_OCCLUSION] = int(per.occlusion)
    ip[I_SEE_ALL] = int(per.field_deg >= 360.0)
    ip[I_BOUNDARY] = BOUNDARIES.index(world.boundary)
    ip[I_ORDER] = UPDATE_ORDERS.index(world.update_order)
    ip[I_PATTERNS] = int(model.patterns.enabled)
    ip[I_SEP_WEIGHT] = SEPARATION_WEIGHTS.index(model.patterns.separation_weight)
    ip[I_NBITS] = model.patterns.n_bits
    gains, lead = model.gains, model.leadership
    fp[F_GAIN_S], fp[F_GAIN_K], fp[F_GAIN_M] = gains.separation, gains.cohesion, gains.alignment
    fp[F_SEP_FALLOFF] = gains.separation_falloff_exponent
    fp[F_LEAD_X], fp[F_LEAD_SIGMA], fp[F_LEAD_DURATION] = lead.x, lead.sigma, lead.duration
    fp[F_LEAD_GAIN], fp[F_LEAD_BOOST], fp[F_LEAD_REFRACTORY] = lead.gain, lead.boost, lead.refractory
    fp[F_SLOW_SPEED] = model.slow_speed
    fp[F_PERCEPTION_RANGE] = model.perception_range
    ip[I_DYNAMICS] = DYNAMICS.index(model.dynamics)
    ip[I_LEADERSHIP] = int(lead.enabled)
    ip[I_FRONT_GATE] = FRONT_GATES.index(lead.front_gate)
    return fp, ip
