"""analysis.summary_simulator: a calibration's exact simulator and observation noise for other tools.
The rows it gives in spawned worker processes (numba limited to one thread there) and in pyABC's worker
processes are bit for bit those the calibration's own evaluation (bsl.simulate_keyed on run.simulate_fn)
computes for the same theta and seed key; it pickles; its thread setting is restored after each call;
parameters by name or key."""
from __future__ import annotations

import json
import pickle
import subprocess
import sys
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context

import numba
import numpy as np
import pytest

from flocksweep.analysis import Calibration, summary_simulator
from flocksweep.analysis.calibration.bsl import simulate_keyed
from flocksweep.analysis.calibration.run import simulate_fn, summary_simulator as bare_simulator
from flocksweep.sweeps.seeds import Tag, generator
from paths import ROOT

CALIBRATION = ROOT / "configs/calibration/recover_holland.toml"
SMALL = ["run.n=8", "run.duration=2.0", "run.warmup=0.5"]   # the shipped problem on tiny runs
THETAS = [np.array([150.0, 45.0]), np.array([90.0, 10.0]), np.array([280.0, 80.0])]


def calibration_rows(config, theta, key, n_sim=None):
    """What the calibration computes for one evaluation: its simulate_fn on its simulator, as BSL maps it
    (n_sim = method.n_sim), or as the emulator's training runs and SBC's datasets (n_sim = 1)."""
    return simulate_keyed(simulate_fn(config, bare_simulator(config, n_sim)), (theta, key))


def worker_rows(task):
    sim, theta, key = task
    return numba.get_num_threads(), sim(theta, generator(*key))


@pytest.fixture(scope="module")
def config():
    return Calibration.from_toml(CALIBRATION, SMALL)


def test_rows_equal_the_calibrations_own_evaluation_and_noise_is_added(config):
    sim = summary_simulator(config, n_sim=config.method.n_sim)
    assert sim.names == ("field", "direction") and sim.columns == tuple(config.targets.columns)
    key = (config.seed, Tag.EVALUATION, 1, 3, 0)
    rows = sim(THETAS[0], generator(*key))
    assert rows.shape == (config.method.n_sim, len(sim.columns))
    np.testing.assert_array_equal(rows, calibration_rows(config, THETAS[0], key))
    bare = bare_simulator(config)(THETAS[0], generator(*key))     # the same runs without observation noise
    noise = rows - bare
    assert np.all(noise != 0) and np.all(np.abs(noise) < 6 * np.sqrt(np.diag(config.targets.cov)))


def test_it_pickles_restores_thread_counts_and_takes_parameters_by_name_or_key(config):
    sim = summary_simulator(config, threads=1)
    before = numba.get_num_threads()
    first = sim.summaries({"field": 150.0, "direction": 45.0}, seed=3)
    assert numba.get_num_threads() == before
    again = pickle.loads(pickle.dumps(sim))
    assert len(pickle.dumps(sim)) < 50_000
    assert again.summaries({"perception.field_deg": 150.0, "perception.direction_deg": 45.0}, seed=3) == first
    assert list(first) == list(sim.columns)
    assert first == dict(zip(sim.columns, calibration_rows(config, np.array([150.0, 45.0]), (3,), n_sim=1)[0]))
    with pytest.raises(KeyError, match="direction"):
        sim.summaries({"field": 150.0})
    with pytest.raises(ValueError, match="threads"):
        summary_simulator(config, threads=0)
    draws = sim.sample_prior(np.random.default_rng(0), 5)
    assert draws.shape == (5, 2) and all(np.isfinite(sim.log_prior(d)) for d in draws)
    assert sim.log_prior(np.array([400.0, 45.0])) == -np.inf


@pytest.mark.slow
def test_spawned_workers_give_the_calibrations_rows_bit_for_bit(config):
    sim = summary_simulator(config, n_sim=config.method.n_sim, threads=1)
    keys = [(config.seed, Tag.EVALUATION, 1, step, 0) for step in range(len(THETAS))]
    with ProcessPoolExecutor(2, mp_context=get_context("spawn")) as pool:
        results = list(pool.map(worker_rows, [(sim, theta, key) for theta, key in zip(THETAS, keys)]))
    for (threads, rows), theta, key in zip(results, THETAS, keys):
        assert threads == numba.get_num_threads()   # restored after the call, in the worker too
        np.testing.assert_array_equal(rows, calibration_rows(config, theta, key))


PYABC_SCRIPT = """
import json, sys, zlib
import pyabc
from flocksweep.analysis import Calibration, summary_simulator

class Model:
    '''pyABC model: the calibration's summaries with a seed derived from the parameters (reproducible).'''
    def __init__(self, sim):
        self.sim = sim
    def __call__(self, parameters):
        seed = zlib.crc32(json.dumps(sorted((k, float(v)) for k, v in parameters.items())).encode())
        return self.sim.summaries(parameters, seed=seed)

if __name__ == "__main__":
    config = Calibration.from_toml(sys.argv[1], sys.argv[3:])
    sim = summary_simulator(config, threads=1)
    observed = dict(zip(sim.columns, sim.observed[0]))
    prior = pyabc.Distribution(field=pyabc.RV("uniform", 60, 240), direction=pyabc.RV("uniform", 0, 90))
    sampler = pyabc.sampler.MulticoreEvalParallelSampler(n_procs=2)
    abc = pyabc.ABCSMC(Model(sim), prior, pyabc.PNormDistance(p=2), population_size=12, sampler=sampler)
    abc.new("sqlite:///" + sys.argv[2] + "/abc.db", observed)
    history = abc.run(max_nr_populations=2)
    out = [{"field": float(p.parameter["field"]), "direction": float(p.parameter["direction"]),
            "stats": {k: float(v) for k, v in p.sum_stat.items()}} for p in history.get_population().particles]
    json.dump({"particles": out, "workers": sampler.n_procs}, open(sys.argv[2] + "/particles.json", "w"))
"""


@pytest.mark.slow
def test_pyabc_in_worker_processes_gets_the_calibrations_statistics(config, tmp_path):
    import zlib

    script = tmp_path / "abc_run.py"
    script.write_text(PYABC_SCRIPT)
    done = subprocess.run([sys.executable, str(script), str(CALIBRATION), str(tmp_path), *SMALL],
                          capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr[-3000:]
    result = json.loads((tmp_path / "particles.json").read_text())
    assert result["workers"] == 2 and len(result["particles"]) == 12
    for particle in result["particles"]:
        parameters = {"direction": particle["direction"], "field": particle["field"]}
        seed = zlib.crc32(json.dumps(sorted(parameters.items())).encode())
        rows = calibration_rows(config, np.array([particle["field"], particle["direction"]]), (seed,), n_sim=1)
        assert particle["stats"] == dict(zip(config.targets.columns, rows[0].tolist()))
