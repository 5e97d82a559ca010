"""Vicsek et al. (1995)'s heading rule as a plug-in with the full hook set (docs/plugins.md, "The full hook
set"). Each step a particle takes the mean heading of every particle within the perception sphere (itself
included) plus uniform angular noise, and moves at a constant speed. Its runs are those of the built-in
``vicsek`` dynamics bit for bit (tests/simcore/test_registry.py): a heading model written outside the
package, through the interface every built-in uses.

Preset: ``dynamics = "examples.vicsek_heading"``, ``perception.kind = "sphere"`` with ``radius`` = r, and
``[plugin]`` speed and noise (``examples/vicsek_heading.toml``).
"""
import math
from dataclasses import dataclass

from flocksweep.simcore.dynamics import apply_boundary
from flocksweep.simcore.headings import heading_scratch, rotate_planar, set_heading, tilt, unit_heading
from flocksweep.simcore.layout import F, I
from flocksweep.simcore.plugin import PluginParams, parameter, slots
from flocksweep.simcore.rng import uniform01

# what it can do (simcore.registry): a constant-speed heading model of the sphere, in 2-D or 3-D, with
# its own noise and speed
PLANAR = True
HEADING = True
PERCEPTION = "sphere"
PATTERNS = False
SHARED_NOISE = False
THREADS = True            # sense writes only row i of its buffer: a synchronous run may split over threads
STREAMS = {"noise": 9}    # the built-in vicsek's stream, so that the two draw the same numbers
NOISE = STREAMS["noise"]


@dataclass(frozen=True)
class Params(PluginParams):
    speed: float = parameter(0.03, unit="units/s", low=0.0, low_open=True, doc="v0, the constant speed")
    noise: float = parameter(2.0, unit="rad", low=0.0, high=2.0 * math.pi, doc="eta, the noise amplitude")


P = slots(Params)
scratch = heading_scratch   # per boid: its new heading, (N, 3)


def sense(dynamics, i, step, m, nbrs, state, params, key, scratch):
    """Boid i's new heading: the mean of its own and its m neighbours' headings, turned by the noise."""
    fwd = state[2]
    fp, ip, dyn = params
    planar = ip[I.DIMENSIONS] == 2
    mx, my, mz = fwd[i, 0], fwd[i, 1], fwd[i, 2]
    for a in range(m):
        j = nbrs.idx[a]
        mx, my, mz = mx + fwd[j, 0], my + fwd[j, 1], mz + fwd[j, 2]
    if planar:
        mz = 0.0
    norm = math.sqrt(mx * mx + my * my + mz * mz)
    if norm == 0.0:   # the headings cancel exactly: keep its own
        mx, my, mz = fwd[i, 0], fwd[i, 1], fwd[i, 2]
    else:
        mx, my, mz = mx / norm, my / norm, mz / norm
    eta = dyn[0][P.noise]
    heading = scratch[0]
    if eta == 0.0:
        heading[i, 0], heading[i, 1], heading[i, 2] = mx, my, mz
    elif planar:
        hx, hy = rotate_planar(mx, my, eta * (uniform01(key, NOISE, step, i) - 0.5))
        heading[i, 0], heading[i, 1], heading[i, 2] = unit_heading(hx, hy, 0.0, planar)
    else:   # uniform on the cap of solid angle 2 eta about the mean
        polar = math.acos(max(-1.0, 1.0 - uniform01(key, NOISE, step, 2 * i) * eta / math.pi))
        azimuth = 2.0 * math.pi * uniform01(key, NOISE, step, 2 * i + 1)
        hx, hy, hz = tilt(mx, my, mz, polar, math.cos(azimuth), math.sin(azimuth))
        heading[i, 0], heading[i, 1], heading[i, 2] = unit_heading(hx, hy, hz, planar)
    return False   # no change of leadership


def move(dynamics, i, state, params, scratch):
    """Move along the old heading at v0, then take the new heading (with its frame) and the boundary."""
    pos, vel, fwd, up, side, acc = state[0], state[1], state[2], state[3], state[4], state[5]
    fp, ip, dyn = params
    heading = scratch[0]
    speed, dt = dyn[0][P.speed], fp[F.DT]
    pos[i, 0] += speed * fwd[i, 0] * dt
    pos[i, 1] += speed * fwd[i, 1] * dt
    pos[i, 2] += speed * fwd[i, 2] * dt
    set_heading(i, heading[i, 0], heading[i, 1], heading[i, 2], speed, ip[I.DIMENSIONS] == 2, vel, fwd, up, side,
                acc, fp)
    apply_boundary(i, pos, fp, ip)
