"""The tiny Holland calibration of method npe that the npe tests run (10 boids, 2 s, one parameter; 60
training + 20 held-out simulations, a small flow of 20 epochs at most)."""
from __future__ import annotations

from paths import ROOT

CALIBRATION = f'''
name = "npe_tiny"
seed = 3
[model]
preset = "{ROOT / 'configs/models/holland.toml'}"
[run]
n = 10
duration = 2.0
record_interval = 0.5
warmup = 1.0
[parameters.field]
key = "perception.field_deg"
prior = {{ dist = "uniform", low = 60, high = 300 }}
[targets]
summary = "mean"
stats = ["visible_mean", "binocular_share"]
mean = [3.0, 0.2]
sd = [0.1, 0.02]
[method]
kind = "npe"
simulations = 60
heldout = 20
draws = 400
flow = {{ width = 16, layers = 2, max_epochs = 20, patience = 5 }}
'''


COLUMNS = ["visible_mean", "binocular_share"]
MEASUREMENT = {"interval": 0.5, "velocity_interval": 0.5, "max_gap": None, "dims": 3, "length_unit": "BL",
               "group_radius": 5.0, "fragmentation_cohesion": 0.5, "dcd_max_delay": 1.0, "warmup": 0.0}


def fake_estimator(where, width: int = 8, passed: bool = True, replicates: int | None = None):
    """An estimator folder as calibrate writes it, for the reading tests: an untrained flow of one parameter
    (field, 60 to 300) given the two statistics of CALIBRATION, its identity, a coverage verdict, and the
    manifest sealing them (no training: a flow's weights as built). ``replicates``: the identity of an estimator
    trained on that many flocks at a time."""
    import json
    from pathlib import Path

    import numpy as np

    from flocksweep.analysis.calibration.estimator_folder import seal
    from flocksweep.analysis.calibration.npe_flow import Estimator, FlowSettings, _build, require_jax

    jax, _ = require_jax()
    where = Path(where)
    settings = FlowSettings(width=width, layers=1, knots=4)
    flow = _build(settings, 1, 2, jax.random.key(0))
    Estimator(flow, settings, np.array([180.0]), np.array([60.0]), np.array([3.0, 0.2]), np.array([1.0, 0.1])).save(where)
    identity = {"parameters": [["field", "perception.field_deg"]], "bounds": [[60.0, 300.0]], "columns": COLUMNS,
                "transforms": {}, "measurement": MEASUREMENT, "seed": 3, "simulations": 60, "heldout": 20}
    if replicates is not None:
        identity["replicates"] = replicates
    (where / "identity.json").write_text(json.dumps(identity))
    (where / "coverage.json").write_text(json.dumps({"passed": passed, "heldout": 20, "excluded": 0,
                                                     "messages": ["coverage: fine" if passed else "coverage FAILED",
                                                                  "field: 50% intervals cover 10%"]}))
    seal(where, calibration="c.toml", out=str(where.parent))
    return where

# the tiny calibration of a learned summary from tracks (tests of analysis.calibration.learned_*): one
# parameter, 24 + 10 simulations, a flow of 4 epochs; learned_calibration(name) names it
LEARNED_CALIBRATION = f'''
name = "npe_learned"
seed = 4
[model]
preset = "{ROOT / 'configs/models/holland.toml'}"
set = {{ "init.radius" = 6.0 }}
[run]
n = 8
duration = 3.0
warmup = 1.0
group_radius = 20.0
[observation]
interval = 0.2
detection_probability = 0.9
position_sd = 0.05
[parameters.separation]
key = "steering.separation_weight"
prior = {{ dist = "uniform", low = 6, high = 18 }}
[targets]
stats = ["polarization"]
from_tracks = "tracks.parquet"
[targets.tracks]
warmup = 1.0
[method]
kind = "npe"
simulations = 24
heldout = 10
draws = 200
flow = {{ width = 8, layers = 1, max_epochs = 4, patience = 2 }}
[method.npe.summary]
kind = "learned"
series = ["polarization", "nn_distance"]
series_length = 4
width = 8
size = 3
'''


def learned_calibration(name: str) -> str:
    """:data:`LEARNED_CALIBRATION` named ``name``."""
    return LEARNED_CALIBRATION.replace('name = "npe_learned"', f'name = "{name}"', 1)
