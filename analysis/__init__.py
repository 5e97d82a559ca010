"""analysis: flock observables (below the sweep machinery), reports and calibration (above it).

See docs/architecture.md for the layers and what each may import.
"""
