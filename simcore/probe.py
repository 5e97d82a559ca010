"""Python-side views into single kernel pieces, for tests, notebooks and debugging.

``perceived(model, state, i)`` runs the compiled perception of boid i on a state (with the model's
``perception.search``) and returns its neighbours as plain arrays: ``idx`` int64 (m,) ascending,
``mask`` int64 (m,) rule bits (1 separation, 2 alignment, 4 cohesion), ``label`` int64 (m,) eye label
(1 left, 2 right, 3 both, 0 for non-binocular kinds), ``offset`` float64 (m, 3), and ``grid`` (whether
the grid was used). ``steering(model, state, i)`` is the raw steering force (3,) of boid i.
"""
from __future__ import annotations

import numpy as np

from .grid import new_grid
from .kernel import prepare_search
from .layout import I, pack
from .neighbours import new_neighbours
from .params import ModelParams
from .perception import perceive
from .rules import opensteer_force
from .state import State


def _perceive(model: ModelParams, state: State, i: int, dt: float):
    fp, ip = pack(model, dt)
    nbrs, grid = new_neighbours(state.n), new_grid(state.n)
    use_grid = prepare_search(grid, state.pos, fp, ip)
    m = perceive(int(ip[I.PERCEPTION]), i, state.pos, state.fwd, state.side, fp, ip, nbrs, grid, use_grid)
    return fp, ip, nbrs, m, bool(use_grid)


def perceived(model: ModelParams, state: State, i: int, dt: float = 1.0 / 60.0) -> dict:
    _, _, nbrs, m, use_grid = _perceive(model, state, i, dt)
    return {"idx": nbrs.idx[:m].copy(), "mask": nbrs.mask[:m].copy(), "label": nbrs.label[:m].copy(),
            "offset": nbrs.off[:m].copy(), "grid": use_grid}


def steering(model: ModelParams, state: State, i: int, dt: float = 1.0 / 60.0) -> np.ndarray:
    fp, ip, nbrs, m, _ = _perceive(model, state, i, dt)
    return np.array(opensteer_force(i, m, state.fwd, state.pattern, fp, ip, nbrs.idx, nbrs.off, nbrs.mask))
