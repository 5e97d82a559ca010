"""Python-side views into single kernel pieces, for tests, notebooks and debugging.

``perceived(model, state, i)`` runs the compiled perception of boid i on a state and returns its
neighbours as plain arrays: ``idx`` int64 (m,) ascending, ``mask`` int64 (m,) rule bits
(1 separation, 2 alignment, 4 cohesion), ``label`` int64 (m,) eye label (1 left, 2 right, 3 both,
0 for non-binocular kinds). ``steering(model, state, i)`` is the raw steering force (3,) of boid i.
"""
from __future__ import annotations

import numpy as np

from .layout import pack
from .params import ModelParams
from .perception import perceive
from .rules import opensteer_force
from .state import State


def _buffers(n: int):
    return (np.empty(n, np.int64), np.empty((n, 3)), np.empty(n, np.int64), np.empty(n, np.int64),
            np.empty((n, 5)), np.empty((n + 2, 4), np.int64))


def perceived(model: ModelParams, state: State, i: int, dt: float = 1.0 / 60.0) -> dict:
    fp, ip = pack(model, dt)
    idx, off, mask, label, work_f, work_i = _buffers(state.n)
    m = perceive(i, state.pos, state.fwd, state.side, fp, ip, idx, off, mask, label, work_f, work_i)
    return {"idx": idx[:m].copy(), "mask": mask[:m].copy(), "label": label[:m].copy(), "offset": off[:m].copy()}


def steering(model: ModelParams, state: State, i: int, dt: float = 1.0 / 60.0) -> np.ndarray:
    fp, ip = pack(model, dt)
    idx, off, mask, label, work_f, work_i = _buffers(state.n)
    m = perceive(i, state.pos, state.fwd, state.side, fp, ip, idx, off, mask, label, work_f, work_i)
    return np.array(opensteer_force(i, m, state.fwd, state.pattern, fp, ip, idx, off, mask))
