"""A plug-in dynamics whose steer numba cannot compile (an attribute the neighbour buffers do not have, on
line 15): the containment tests and the malformed-input battery expect one message naming this file and
that line, before anything is written or any run loop compiles."""
from dataclasses import dataclass

from flocksweep.simcore.plugin import PluginParams


@dataclass(frozen=True)
class Params(PluginParams):
    pass


def steer(i, step, m, nbrs, state, fp, ip, p, key):
    return (nbrs.nonexistent[0], 0.0, 0.0)
