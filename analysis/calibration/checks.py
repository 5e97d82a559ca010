"""Argument checks of the calibration functions (their arguments are programs' values, not config
files: a bad one is a ValueError naming the argument)."""
from __future__ import annotations

import numbers

import numpy as np


def integer(value, name: str, minimum: int) -> int:
    """``value`` as an int when it is an integer (not a bool) >= ``minimum``; ValueError otherwise."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral) or value < minimum:
        raise ValueError(f"{name}: got {value!r}; must be an integer >= {minimum}")
    return int(value)
