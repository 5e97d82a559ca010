"""simcore.jit: calling a compiled function with literal arguments through a remembered specialisation.

``specialise`` remembers each specialisation under the argument fingerprint numba's dispatcher uses; these
tests check that the fingerprint separates what numba types differently (dtype, layout, writability,
literal values) and that a remembered specialisation computes what a plain call does.
"""
from __future__ import annotations

import numba
import numpy as np

from flocksweep.simcore.jit import call_with_literals, specialise


@numba.njit(cache=True)
def scaled_sum(values, weights, power):
    numba.literally(power)
    total = 0.0
    for k in range(values.shape[0]):
        total += weights[0] * values[k] ** power
    return total


def test_the_same_argument_types_reuse_one_specialisation():
    values, weights = np.arange(4.0), (np.ones(1),)
    first = specialise(scaled_sum, (values, weights[0], 2), 1)
    assert specialise(scaled_sum, (np.zeros(9), np.full(1, 3.0), 2), 1) is first   # other values, same types
    assert call_with_literals(scaled_sum, (values, weights[0], 2), 1) == scaled_sum(values, weights[0], 2) == 14.0


def test_different_types_or_literals_get_their_own_specialisation():
    values, weight = np.arange(4.0), np.ones(1)
    base = specialise(scaled_sum, (values, weight, 2), 1)
    readonly = values.copy()
    readonly.flags.writeable = False
    others = [specialise(scaled_sum, (values, weight, 3), 1),                  # another literal
              specialise(scaled_sum, (values.astype(np.float32), weight, 2), 1),   # another dtype
              specialise(scaled_sum, (np.arange(8.0)[::2], weight, 2), 1),     # not contiguous
              specialise(scaled_sum, (readonly, weight, 2), 1)]                # read-only
    assert len({id(base), *map(id, others)}) == 5
    assert others[0](values, weight, 3) == 36.0
    assert others[2](np.arange(8.0)[::2], weight, 2) == 0.0 + 4.0 + 16.0 + 36.0
