"""observables: what a flock does, measured from a run's recorded observations.

Per-record metrics and their compiled kernels (``metrics``, ``groups``, ``kernels``), the leadership
metrics (``leadership``) and the one step from a run to its summary row (``summary``). Measured flocks:
track files (``tracks``) and their checks (``validation``), samples to records (``resample``), metrics
over the individuals present (``observed``), the observation model that measures simulated runs the
same way (``observation``) and tracks to tables (``measured``); docs/measured.md. This layer sits
directly on ``simcore`` and below ``sweeps``: it imports nothing else of ours (docs/architecture.md).
"""
from pathlib import Path as _Path

from flocksweep.simcore._cache import refresh as _refresh_cache

_refresh_cache(_Path(__file__).parent, __name__)   # numba's cache of this package's kernels kept in step
