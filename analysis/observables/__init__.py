"""analysis.observables: what a flock does, measured from a run's recorded observations.

Per-record metrics and their compiled kernels (``metrics``, ``groups``, ``kernels``), the leadership
metrics (``leadership``) and the one step from a run to its summary row (``summary``). This layer sits
directly on ``simcore`` and below ``sweeps``: it imports nothing else of ours (docs/architecture.md).
"""
