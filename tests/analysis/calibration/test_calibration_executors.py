"""Calibration executors: the same chain and the same optimum whatever runs the simulations (this
process, a local process pool, a Dask LocalCluster), and the executor's map keeps the order of its items."""
from __future__ import annotations

import numpy as np
import pytest

from flocksweep.analysis.calibration.bsl import run_bsl
from flocksweep.analysis.calibration.optimize import run_optimize
from flocksweep.analysis.calibration.priors import JointPrior, Uniform
from flocksweep.sweeps.executors import Executor

OBSERVED = np.array([1.3, -0.4])


def toy_simulate(theta, rng):
    """Summaries ~ N((theta, -theta/3), 0.5^2), 12 replicates, from the generator given."""
    mean = np.array([theta[0], -theta[0] / 3.0])
    return mean + 0.5 * rng.standard_normal((12, 2))


def toy_seeded(theta, seeds):
    rng = np.random.default_rng([int(s) for s in seeds])
    return toy_simulate(theta, rng)[:len(seeds)]


def _slow_square(x):
    import time
    time.sleep(0.01 * (5 - x))    # later items finish first
    return x * x


def prior():
    return JointPrior(["mu"], [Uniform(-5.0, 5.0)])


@pytest.mark.slow
def test_executor_keeps_order_and_validates():
    with Executor("local", workers=2) as ev:
        assert ev.map(_slow_square, range(5)) == [0, 1, 4, 9, 16]
        assert ev.map(lambda x: x + 1, [1, 2, 3]) == [2, 3, 4]    # closures are shipped by cloudpickle
        assert "2 processes" in ev.description
    with pytest.raises(ValueError, match="executor"):
        Executor("threads")
    with pytest.raises(ValueError, match="workers"):
        Executor("local", workers=0)
    with pytest.raises(ValueError, match="scheduler"):
        Executor("local", scheduler="tcp://x:1")


@pytest.mark.slow
@pytest.mark.parametrize("executor", ["local", "dask"])
def test_bsl_chain_identical_across_executors(executor):
    kwargs = dict(walkers=6, steps=12, seed=3, reevaluate_every=5)
    serial = run_bsl(toy_simulate, OBSERVED, prior(), **kwargs)
    with Executor(executor, workers=2) as ev:
        parallel = run_bsl(toy_simulate, OBSERVED, prior(), executor=ev, **kwargs)
    np.testing.assert_array_equal(serial.chain, parallel.chain)
    np.testing.assert_array_equal(serial.log_prob, parallel.log_prob)
    assert serial.acceptance_fraction.mean() > 0


@pytest.mark.slow
def test_optimize_identical_with_workers():
    kwargs = dict(seed=2, n_sim=12, maxiter=8, popsize=5, recheck=24)
    serial = run_optimize(toy_seeded, OBSERVED, prior(), **kwargs)
    with Executor("local", workers=2) as ev:
        parallel = run_optimize(toy_seeded, OBSERVED, prior(), executor=ev, **kwargs)
    np.testing.assert_array_equal(serial.theta, parallel.theta)
    np.testing.assert_array_equal(serial.recheck_summaries, parallel.recheck_summaries)
    assert abs(serial.theta[0] - 1.3) < 0.6
