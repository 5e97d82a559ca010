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
