"""The ``opensteer`` dynamics' descriptor (:mod:`simcore.registry`): its ``[steering]`` table and
capabilities; its hooks are :mod:`simcore.opensteer` (docs/model.md sections 3.1-3.4).

``[steering]``: the weights of the combined OpenSteer steering force (each a non-negative force per
unit of the rule's direction, so a length per second squared). The vehicle physics' ``[vehicle]`` and the
pattern mode's ``[patterns]`` are shared tables it keeps in its canonical form; it has the change of
leadership, the pattern mode, 2-D motion, and ``[noise]``/``[cruise]``.
"""
from __future__ import annotations

from dataclasses import dataclass

from .plugin import PluginParams, parameter

TABLE = "steering"
HOOKS = ".opensteer"
PLANAR = True
LEADERSHIP = True
USES = ("vehicle", "patterns")


@dataclass(frozen=True)
class Steering(PluginParams):
    """Weights of the combined OpenSteer steering force (docs/model.md, steering)."""

    TABLE = "steering"
    separation_weight: float = parameter(12.0, unit="units/s^2", low=0.0, length=1, doc="separation rule weight")
    alignment_weight: float = parameter(8.0, unit="units/s^2", low=0.0, length=1, doc="alignment rule weight")
    cohesion_weight: float = parameter(8.0, unit="units/s^2", low=0.0, length=1, doc="cohesion rule weight")


Params = Steering
