"""The ``hartman_benes`` dynamics' descriptor (:mod:`simcore.registry`): its ``[gains]`` table and
capabilities; its hooks are :mod:`simcore.hartman_benes` (docs/model.md, Hartman-Benes).

``[gains]``: the raw velocity update's gains per frame (= per step), v' = v + (S s + K k) / dt + M m with
s = sum_j (p_i - p_j) / |p_i - p_j|^falloff. The separation gain carries length to the power ``falloff``
(a preset in metres, :mod:`simcore.units`). It perceives with the sphere, keeps the shared ``[vehicle]``
and ``[patterns]`` tables, and has the change of leadership, the pattern mode, 2-D motion and
``[noise]``/``[cruise]``.
"""
from __future__ import annotations

from dataclasses import dataclass

from .plugin import PluginParams, parameter

TABLE = "gains"
HOOKS = ".hartman_benes"
PLANAR = True
LEADERSHIP = True
PERCEPTION = "sphere"
USES = ("vehicle", "patterns")


def separation_length_power(data: dict) -> float:
    """The power of length of the separation gain: the falloff exponent the preset's data gives."""
    value = data.get("gains", {}).get("separation_falloff_exponent", 2.0)
    return float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else 2.0


@dataclass(frozen=True)
class Gains(PluginParams):
    """Hartman-Benes raw velocity update (docs/model.md, Hartman-Benes), gains per frame (= per step):
    v' = v + (S s + K k) / dt + M m, with s = sum_j (p_i - p_j) / |p_i - p_j|^falloff."""

    TABLE = "gains"
    separation: float = parameter(0.005, low=0.0, high=1.0, length=separation_length_power,
                                  doc="S, the separation gain")
    cohesion: float = parameter(0.01, low=0.0, high=1.0, length=0, doc="K, the cohesion gain")
    alignment: float = parameter(0.1, low=0.0, high=1.0, length=0, doc="M, the alignment gain")
    separation_falloff_exponent: float = parameter(2.0, low=0.0, high=4.0, length=0,
                                                   doc="the power of distance separation falls off with")


Params = Gains
