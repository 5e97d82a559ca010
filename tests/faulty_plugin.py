"""A plug-in dynamics (docs/plugins.md) with a fault chosen by its parameter ``fault``, for the containment
tests and the fault battery (tests/faults.py): 0 none (a boid steers towards its neighbours), 1 boid 2's
force is NaN in step 3, 2 an out-of-bounds write in steer from boid 1 on (SIGSEGV), 3 a loop that never
ends. One module, so one run loop compiles for every fault (the fault is a run-time value)."""
from dataclasses import dataclass

from flocksweep.simcore.plugin import PluginParams, parameter, slots

NONE, NAN_FORCE, OUT_OF_BOUNDS, ENDLESS = 0, 1, 2, 3


@dataclass(frozen=True)
class Params(PluginParams):
    fault: int = parameter(0, low=0, high=3, doc="0 none, 1 NaN force, 2 out-of-bounds write, 3 endless loop")


P = slots(Params)


def steer(i, step, m, nbrs, state, fp, ip, p, key):
    fault = int(p[P.fault])
    if fault == NAN_FORCE and step == 3 and i == 2:
        return (float("nan"), 0.0, 0.0)
    if fault == OUT_OF_BOUNDS:
        pos = state[0]
        pos[(i + 1) * 100_000_000, 0] = 1.0   # far beyond the array: SIGSEGV
    if fault == ENDLESS:
        x = 0.0
        while x >= 0.0:
            x += 1.0
            if x > 1e300:
                x = 0.0
        return (x, 0.0, 0.0)
    fx = fy = fz = 0.0
    for a in range(m):
        fx, fy, fz = fx + nbrs.off[a, 0], fy + nbrs.off[a, 1], fz + nbrs.off[a, 2]
    return (fx, fy, fz)
