"""The names a track file is described with, declared without numpy: the column roles, the length units,
the file formats and the velocity choice ``recorded``. Importing this module loads nothing but Python, so
``flocksweep measure --help`` lists them without loading the readers; :mod:`observables.tracks`,
:mod:`observables.track_formats` and :mod:`observables.resample` take them from here.
"""
from __future__ import annotations

ROLES = ("flock", "id", "t", "x", "y", "z", "vx", "vy", "vz", "pattern")
LENGTH_UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001, "km": 1000.0, "bl": None, "px": None}
LONG_FORMATS = ("csv", "parquet")
WIDE_FORMATS = ("mat", "npy", "idtracker", "trex", "trajr", "movebank")
ARRAY_FORMATS = ("mat", "npy")         # read by a declared layout (observables.track_arrays)
COLUMN_FORMATS = ("csv", "parquet", "trajr", "movebank")   # the ones a column map applies to
FORMATS = ("auto",) + LONG_FORMATS + WIDE_FORMATS
RECORDED = "recorded"   # velocity_interval: use the tracks' own velocity columns (observables.resample)
