"""Determinism and reproducibility (docs/model.md section 7) and the initial pattern draw (section 3).

Same spec => bit-identical trajectories: twice in a row, batched or alone, and in a fresh Python process.
Different seeds give different runs. Pattern counts follow the largest-remainder rule.
"""
from __future__ import annotations

import hashlib
import json
import subprocess
import sys
import time
from pathlib import Path

import numba
import numpy as np
import pytest

import flocksweep.simcore as simcore
from conftest import make_model
from flocksweep.simcore import InitParams, initial_state, simulate, simulate_batch
from flocksweep.simcore.params import HOLLAND_TABLE_1, PatternEntry, Patterns
from flocksweep.simcore.rng import run_streams
from flocksweep.simcore.simulate import _each_on_threads
from flocksweep.simcore.state import pattern_counts
from paths import TESTS

DT = 1 / 60
INIT = InitParams(n=25, radius=6.0)
STATE_FIELDS = ("pos", "vel", "fwd", "up", "side", "acc", "pattern")
KINDS = ("sphere", "opensteer", "binocular")


def arrays(obs) -> dict:
    """Every array of an Observations, the final state's fields included."""
    out = {name: getattr(obs, name) for name in ("times", "pos", "vel", "visible", "binocular", "pattern")}
    out.update({f"final.{name}": getattr(obs.final, name) for name in STATE_FIELDS})
    return out


def assert_bit_identical(a, b):
    xa, xb = arrays(a), arrays(b)
    for name in xa:
        assert xa[name].dtype == xb[name].dtype, name
        assert np.array_equal(xa[name], xb[name]), f"{name} differs"


def digest(obs) -> str:
    h = hashlib.sha256()
    for name, value in sorted(arrays(obs).items()):
        h.update(name.encode())
        h.update(np.ascontiguousarray(value).tobytes())
    return h.hexdigest()


@pytest.mark.parametrize("kind", KINDS)
def test_same_seed_is_bit_identical(kind):
    model = make_model(kind, patterns="similarity")
    first = simulate(model, INIT, seed=21, duration=1.0, dt=DT, record_every=3)
    second = simulate(model, INIT, seed=21, duration=1.0, dt=DT, record_every=3)
    assert_bit_identical(first, second)
    assert first.visible.sum() > 0


@pytest.mark.parametrize("kind", KINDS)
def test_different_seeds_differ(kind):
    model = make_model(kind)
    a = simulate(model, INIT, seed=21, duration=0.5, dt=DT)
    b = simulate(model, INIT, seed=22, duration=0.5, dt=DT)
    assert not np.array_equal(a.pos[0], b.pos[0])
    assert not np.array_equal(a.final.pos, b.final.pos)


@pytest.mark.parametrize("order", ("synchronous", "sequential"))
@pytest.mark.parametrize("kind", ("opensteer", "binocular"))
def test_batch_equals_separate_runs(kind, order):
    model = make_model(kind, order=order)
    seeds = [3, 7, 11]
    batch = simulate_batch(model, INIT, seeds, duration=1.0, dt=DT, record_every=2)
    assert len(batch) == len(seeds)
    for seed, batched in zip(seeds, batch):
        assert_bit_identical(batched, simulate(model, INIT, seed, duration=1.0, dt=DT, record_every=2))
    assert not np.array_equal(batch[0].final.pos, batch[1].final.pos)


def test_batch_result_does_not_depend_on_batch_composition():
    model = make_model("opensteer")
    alone = simulate_batch(model, INIT, [7], duration=0.5, dt=DT)[0]
    among_others = simulate_batch(model, INIT, [1, 2, 7, 4], duration=0.5, dt=DT)[2]
    assert_bit_identical(alone, among_others)


def test_batch_does_not_depend_on_the_thread_count():
    model = make_model("binocular", order="sequential")
    seeds = [5, 6, 7]
    previous = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one_thread = simulate_batch(model, INIT, seeds, duration=0.5, dt=DT)
        numba.set_num_threads(min(2, numba.config.NUMBA_NUM_THREADS))
        threaded = simulate_batch(model, INIT, seeds, duration=0.5, dt=DT)
    finally:
        numba.set_num_threads(previous)
    for a, b in zip(one_thread, threaded):
        assert_bit_identical(a, b)


def test_a_batch_runs_the_one_run_loop_on_threads_without_the_gil():
    assert simcore.kernel.run_model.targetoptions.get("nogil") is True
    assert not hasattr(simcore.kernel, "run_batch")  # no second loop to compile


def test_every_task_of_a_batch_ends_before_its_first_error_is_raised():
    ran = []

    def task(b):
        time.sleep(0.01 * (3 - b))
        ran.append(b)
        if b == 0:
            raise RuntimeError("run 0 failed")

    with pytest.raises(RuntimeError, match="run 0 failed"):
        _each_on_threads(task, 4, 2)
    assert sorted(ran) == [0, 1, 2, 3]


def fixed_run():
    """The run compared across processes: binocular with overlapping eyes, pattern mode."""
    model = make_model("binocular", direction_deg=30.0, patterns="uniform")
    return simulate(model, INIT, seed=42, duration=1.0, dt=DT, record_every=5)


# Runs fixed_run() in a fresh interpreter and prints the digest of its observations.
CHILD_SCRIPT = """
import json, sys
sys.path[:0] = [{package_root!r}, {tests_dir!r}, {here_dir!r}]  # the same simcore and helpers as this process
from test_determinism import digest, fixed_run
print(json.dumps(digest(fixed_run())))
"""


@pytest.mark.slow
def test_bit_identical_across_processes(tmp_path):
    tests_dir = str(TESTS)
    package_root = str(Path(simcore.__file__).resolve().parents[1])
    script = tmp_path / "child.py"
    script.write_text(CHILD_SCRIPT.format(package_root=package_root, tests_dir=tests_dir,
                                         here_dir=str(Path(__file__).resolve().parent)))
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=300,
                          cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    child = json.loads(done.stdout.strip().splitlines()[-1])
    here = fixed_run()
    assert here.binocular.sum() > 0
    assert child == digest(here)


def test_initial_state_is_reproducible():
    patterns = Patterns(enabled=True)
    a = initial_state(INIT, patterns, run_streams(5)[0])
    b = initial_state(INIT, patterns, run_streams(5)[0])
    c = initial_state(INIT, patterns, run_streams(6)[0])
    for name in STATE_FIELDS:
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert not np.array_equal(a.pos, c.pos)
    assert not np.array_equal(a.pattern, c.pattern)


@pytest.mark.parametrize("n, expected", [
    (10, [4, 4, 1, 1]),   # 3.5 3.5 1.5 1.5: floors 3 3 1 1, two left over, ties go to the earlier entries
    (7, [3, 2, 1, 1]),    # 2.45 2.45 1.05 1.05: floors 2 2 1 1, one left over -> first entry
    (20, [7, 7, 3, 3]),   # exact
    (1, [1, 0, 0, 0]),    # 0.35 0.35 0.15 0.15: one left over -> first entry
    (3, [1, 1, 1, 0]),    # 1.05 1.05 0.45 0.45: floors 1 1 0 0, one left over -> third (largest remainder)
])
def test_pattern_counts_follow_largest_remainder(n, expected):
    assert pattern_counts(Patterns(enabled=True), n).tolist() == expected


def test_largest_remainder_beats_entry_order():
    # 0.1 and 0.9 of 4 boids: 0.4 and 3.6 -> floors 0 and 3; the spare boid goes to the larger remainder
    patterns = Patterns(enabled=True, set=(PatternEntry("0", 0.1), PatternEntry("1", 0.9)))
    assert pattern_counts(patterns, 4).tolist() == [0, 4]


@pytest.mark.parametrize("n, expected", [(10, [4, 4, 1, 1]), (7, [3, 2, 1, 1])])
def test_initial_state_realises_pattern_counts(n, expected):
    values = [p.value for p in HOLLAND_TABLE_1]
    for seed in (1, 2):
        state = initial_state(InitParams(n=n), Patterns(enabled=True), run_streams(seed)[0])
        assert state.pattern.dtype == np.uint32
        assert [int(np.sum(state.pattern == v)) for v in values] == expected
    obs = simulate(make_model("opensteer", patterns="similarity"), InitParams(n=n), seed=3, duration=0.1, dt=DT)
    assert [int(np.sum(obs.pattern == v)) for v in values] == expected


def test_patterns_disabled_gives_zero_patterns():
    state = initial_state(InitParams(n=10), Patterns(enabled=False), run_streams(1)[0])
    assert state.pattern.dtype == np.uint32 and not state.pattern.any()
