"""simcore.rng: run seeds become reproducible generators and keys; in-loop draws are pure functions of
(key, stream, step, index) with the right distributions (docs/model.md section 7).

Statistical tolerances are 5 standard errors from the central limit theorem for n = 100 000 draws:
uniform mean sd(U)/sqrt(n) = sqrt(1/12/n) = 0.00091, uniform variance sqrt((1/80 - 1/144)/n) = 0.00024,
normal mean 1/sqrt(n) = 0.0032, normal variance sqrt(2/n) = 0.0045, a correlation 1/sqrt(n) = 0.0032.
Keys are fixed, so every check is deterministic: it passes or fails the same way on every run.
"""
from __future__ import annotations

import math
import random

import numpy as np
import pytest
from scipy import stats

from flocksweep.simcore.boidspp_params import STREAMS
from flocksweep.simcore.rng import (STREAM_LEADERSHIP, normal, run_streams,
                         seed_sequence, uniform01)

STREAM_RANDOM_FORCE, STREAM_TARGETS = STREAMS["random_force"], STREAMS["targets"]

N = 100_000
Z = 5.0  # standard errors allowed
KEYS = [np.uint64(0), run_streams(2024)[1]]


def draws(fn, key, stream=STREAM_LEADERSHIP, step=7, n=N, along="index") -> np.ndarray:
    """n draws of ``fn`` with the counter named by ``along`` running 0..n-1 and the others fixed."""
    if along == "index":
        return np.array([fn(key, stream, step, i) for i in range(n)])
    if along == "step":
        return np.array([fn(key, stream, s, 3) for s in range(n)])
    return np.array([fn(key, s, step, 3) for s in range(n)])  # along the stream number


# --- purity -----------------------------------------------------------------------------------------

@pytest.mark.parametrize("fn", [uniform01, normal])
def test_same_counter_gives_the_same_value(fn):
    key = KEYS[1]
    assert fn(key, 2, 10, 5) == fn(key, 2, 10, 5)


@pytest.mark.parametrize("fn", [uniform01, normal])
def test_value_does_not_depend_on_evaluation_order(fn):
    key = KEYS[1]
    counters = [(stream, step, index) for stream in (1, 2, 3) for step in range(20) for index in range(20)]
    in_order = {c: fn(key, *c) for c in counters}
    shuffled = counters[:]
    random.Random(0).shuffle(shuffled)
    assert {c: fn(key, *c) for c in shuffled} == in_order
    assert {c: fn(key, *c) for c in reversed(counters)} == in_order


def test_python_int_and_uint64_keys_agree():
    key = KEYS[1]
    assert uniform01(int(key), 1, 2, 3) == uniform01(key, 1, 2, 3)
    assert normal(int(key), 1, 2, 3) == normal(key, 1, 2, 3)


def test_normal_is_box_muller_on_sub_counters_2i_and_2i_plus_1():
    # documented in simcore.rng: z = sqrt(-2 ln(1 - u1)) cos(2 pi u2), u1/u2 at indices 2i and 2i + 1
    key, i = KEYS[1], 11
    u1, u2 = uniform01(key, 3, 4, 2 * i), uniform01(key, 3, 4, 2 * i + 1)
    expected = math.sqrt(-2.0 * math.log(1.0 - u1)) * math.cos(2.0 * math.pi * u2)
    assert normal(key, 3, 4, i) == pytest.approx(expected, rel=1e-12, abs=1e-15)


@pytest.mark.parametrize("fn", [uniform01, normal])
def test_different_counters_give_different_values(fn):
    key = KEYS[1]
    grid = [fn(key, stream, step, index) for stream in (1, 2, 3) for step in range(30) for index in range(30)]
    assert len(set(grid)) == len(grid)
    base = fn(key, 1, 5, 5)
    assert len({base, fn(key, 2, 5, 5), fn(key, 1, 6, 5), fn(key, 1, 5, 6), fn(KEYS[0], 1, 5, 5)}) == 5


def test_counters_are_not_interchangeable():
    # (stream, step, index) is an ordered tuple: swapping two counters changes the draw
    key = KEYS[1]
    assert uniform01(key, 1, 2, 3) != uniform01(key, 1, 3, 2)
    assert uniform01(key, 1, 2, 3) != uniform01(key, 2, 1, 3)


# --- distributions ----------------------------------------------------------------------------------

@pytest.mark.parametrize("along", ["index", "step", "stream"])
@pytest.mark.parametrize("key", KEYS, ids=["key0", "key2024"])
def test_uniform01_is_uniform_on_the_half_open_unit_interval(key, along):
    u = draws(uniform01, key, along=along)
    assert u.min() >= 0.0 and u.max() < 1.0
    assert abs(u.mean() - 0.5) < Z * math.sqrt(1 / 12 / N)
    assert abs(u.var() - 1 / 12) < Z * math.sqrt((1 / 80 - 1 / 144) / N)
    assert stats.kstest(u, "uniform").pvalue > 0.001


@pytest.mark.parametrize("along", ["index", "step"])
@pytest.mark.parametrize("key", KEYS, ids=["key0", "key2024"])
def test_normal_is_standard_normal(key, along):
    z = draws(normal, key, along=along)
    assert np.isfinite(z).all()
    assert abs(z.mean()) < Z / math.sqrt(N)
    assert abs(z.var() - 1.0) < Z * math.sqrt(2 / N)
    assert stats.kstest(z, "norm").pvalue > 0.001


def test_uniform01_has_53_bit_resolution():
    # top 53 bits of the hash scaled by 2^-53: every value times 2^53 is an integer below 2^53
    u = draws(uniform01, KEYS[1], n=1000)
    scaled = u * 2.0**53
    assert np.array_equal(scaled, np.floor(scaled))
    assert (scaled < 2.0**53).all()


# --- independence -----------------------------------------------------------------------------------

def correlation(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.corrcoef(a, b)[0, 1])


@pytest.mark.parametrize("other", [
    dict(stream=STREAM_RANDOM_FORCE), dict(stream=STREAM_TARGETS), dict(step=8), dict(key=KEYS[0]),
], ids=["stream2", "stream3", "next_step", "other_key"])
def test_draws_with_one_counter_changed_are_uncorrelated(other):
    base = dict(key=KEYS[1], stream=STREAM_LEADERSHIP, step=7)
    a = draws(uniform01, **base)
    b = draws(uniform01, **{**base, **other})
    assert abs(correlation(a, b)) < Z / math.sqrt(N)


def test_neighbouring_indices_are_uncorrelated():
    u = draws(uniform01, KEYS[1], n=N + 1)
    assert abs(correlation(u[:-1], u[1:])) < Z / math.sqrt(N)


def test_normal_streams_are_uncorrelated():
    a = draws(normal, KEYS[1], stream=STREAM_LEADERSHIP)
    b = draws(normal, KEYS[1], stream=STREAM_RANDOM_FORCE)
    assert abs(correlation(a, b)) < Z / math.sqrt(N)


# --- run seeds --------------------------------------------------------------------------------------

def test_run_streams_is_reproducible():
    (gen_a, key_a), (gen_b, key_b) = run_streams(42), run_streams(42)
    assert key_a == key_b
    assert np.array_equal(gen_a.random(10), gen_b.random(10))


def test_run_streams_key_is_a_uint64():
    assert isinstance(run_streams(42)[1], np.uint64)


def test_different_seeds_give_different_generators_and_keys():
    seeds = list(range(50)) + [(1, 2), (2, 1), 2**64 + 1]
    streams = [run_streams(seed) for seed in seeds]
    keys = {int(key) for _, key in streams}
    first_draws = {gen.random() for gen, _ in streams}
    assert len(keys) == len(seeds)
    assert len(first_draws) == len(seeds)


def test_streams_are_the_documented_seed_sequence_children():
    # first child seeds Generator(PCG64) for initial conditions, second child gives the 64-bit loop key
    init_ss, loop_ss = np.random.SeedSequence(5).spawn(2)
    gen, key = run_streams(5)
    assert np.array_equal(gen.random(4), np.random.Generator(np.random.PCG64(init_ss)).random(4))
    assert key == loop_ss.generate_state(1, np.uint64)[0]


def test_seed_sequence_is_passed_through():
    ss = np.random.SeedSequence(9)
    assert seed_sequence(ss) is ss
    assert run_streams(ss)[1] == run_streams(9)[1]


@pytest.mark.parametrize("seed", [-1, np.int64(-3), True, False, np.bool_(True), (1, -1), [0, -2]],
                         ids=["minus1", "np_minus3", "True", "False", "np_True", "tuple_negative",
                              "list_negative"])
def test_bad_seeds_raise_value_error(seed):
    with pytest.raises(ValueError, match="seed"):
        run_streams(seed)


@pytest.mark.parametrize("seed", [1.5, "3"])
def test_non_integer_seeds_are_rejected(seed):
    with pytest.raises((ValueError, TypeError)):
        run_streams(seed)
