"""A plug-in dynamics with OpenSteer's own rules (docs/plugins.md; tests, bench/bench_plugin.py): its runs are
those of the built-in ``opensteer`` dynamics bit for bit (without leadership), through the plug-in interface."""
from dataclasses import dataclass

from flocksweep.simcore.plugin import PluginParams
from flocksweep.simcore.rules import opensteer_force


@dataclass(frozen=True)
class Params(PluginParams):
    pass


def steer(i, step, m, nbrs, state, fp, ip, p, key):
    return opensteer_force(i, m, state[2], state[6], fp, ip, nbrs.idx, nbrs.off, nbrs.mask)
