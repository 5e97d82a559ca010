"""The shipped sweeps of the Couzin et al. (2002) and Vicsek et al. (1995) findings
(configs/sweeps/couzin2002_zones.toml, its 2-D twin couzin2002_zones_2d.toml, couzin2002_hysteresis.toml,
vicsek_noise.toml) load and validate
without running, with the claims of their claims files; the hysteresis sweep's two start states are
found from the repository root, and a worker warms up on a run that starts from one (its boid count is
the file's: a 3-boid warm-up would be refused)."""
from __future__ import annotations

import pytest

from flocksweep.sweeps import worker
from flocksweep.sweeps.config import load_sweep
from flocksweep.sweeps.design import expand
from paths import ROOT

SWEEPS = ROOT / "configs" / "sweeps"

FINDINGS = {                 # sweep -> (claim ids, their family, runs in the design)
    "couzin2002_zones": (["polarization-rises", "states"], "couzin2002", 36),
    "couzin2002_zones_2d": (["states-2d", "torus-persists-2d"], "couzin2002_2d", 36),
    "couzin2002_hysteresis": (["memory", "branches-meet"], "couzin2002_hysteresis", 48),
    "vicsek_noise": (["order-disorder", "sharpens"], "vicsek", 72),
}


@pytest.mark.parametrize("name", sorted(FINDINGS))
def test_heading_model_sweeps_load_with_their_claims(name, monkeypatch):
    monkeypatch.chdir(ROOT)   # the hysteresis states are named relative to the repository root
    ids, family, runs = FINDINGS[name]
    config = load_sweep(SWEEPS / f"{name}.toml")
    assert [c.id for c in config.claims] == ids
    assert all(c.family == family and c.source is not None and c.statement for c in config.claims)
    assert len(expand(config)) == runs


@pytest.mark.slow   # the warm-up loads the run and metric kernels (seconds)
def test_hysteresis_starts_from_two_states_with_common_random_numbers(monkeypatch):
    monkeypatch.chdir(ROOT)
    specs = expand(load_sweep(SWEEPS / "couzin2002_hysteresis.toml"))
    starts = {spec.preset.init.from_file for spec in specs}
    assert starts == {"configs/states/couzin2002_torus.npz", "configs/states/couzin2002_parallel.npz"}
    seeds = {}
    for spec in specs:
        seeds.setdefault(spec.replicate, set()).add(spec.seed)
        assert spec.preset.init.n == 100 and spec.preset.init.from_file_sha256
    assert all(len(s) == 1 for s in seeds.values())
    worker.warm_up(specs[0])
