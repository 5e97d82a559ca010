"""Calibration simulator: theta -> (n_sim, k) summary table (analysis/calibration/simulator.py).

Small runs (12 boids, 3 s) with fixed seeds; equality checks are bit for bit."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from flocksweep.analysis.calibration.simulator import ALL_COLUMNS, SummarySimulator
from flocksweep.observables.leadership import leadership_metrics
from flocksweep.observables.metrics import frame_metrics, summarize
from flocksweep.observables.summary import default_group_radius, world_box
from flocksweep.simcore.params import read_toml
from flocksweep.simcore.schema import ConfigError, set_dotted
from flocksweep.simcore.simulate import simulate
from flocksweep.sweeps.seeds import common_seeds, seeds_for
from paths import ROOT

MODELS = ROOT / "configs" / "models"
COLUMNS = ("cohesion_mean", "polarization_final", "nn_distance_mean")
KEYS = ("perception.field_deg", "perception.direction_deg")
THETA = [120.0, 60.0]
WARMUP = 1.0


def small(name: str, n: int = 12, duration: float = 3.0, record_interval: float = 0.5) -> dict:
    data = read_toml(MODELS / f"{name}.toml")
    set_dotted(data, "init.n", n)
    set_dotted(data, "run.duration", duration)
    set_dotted(data, "run.record_interval", record_interval)
    return data


@pytest.fixture(scope="module")
def holland():
    return small("holland")


@pytest.fixture(scope="module")
def sim(holland):
    return SummarySimulator(holland, KEYS, COLUMNS, n_sim=5, warmup=WARMUP)


def reference_row(preset, seed, columns, warmup, group_radius=None) -> np.ndarray:
    """One seed alone: simulate + frame_metrics + summarize (+ leadership_metrics)."""
    model, run = preset.model, preset.run
    obs = simulate(model, preset.init, seed, run.duration, run.dt, run.record_every)
    radius = default_group_radius(model) if group_radius is None else group_radius
    box = world_box(model)
    values = summarize(frame_metrics(obs.pos, obs.vel, obs.visible, obs.binocular, obs.pattern, radius, box),
                       obs.times, warmup)
    values.update(leadership_metrics(obs, radius, model.leadership.duration, box))
    return np.array([values[c] for c in columns])


# ---------------------------------------------------------------- shape, determinism, equivalence

def test_shape_and_finite(sim):
    rows = sim.simulate(THETA, common_seeds(1, 5))
    assert rows.shape == (5, len(COLUMNS)) and rows.dtype == np.float64
    assert np.isfinite(rows).all()
    assert np.all((rows[:, 0] >= 0) & (rows[:, 0] <= 1))           # cohesion is a share
    assert np.all((rows[:, 1] >= 0) & (rows[:, 1] <= 1))           # polarization is in [0, 1]


def test_same_seeds_bit_identical_and_different_seeds_differ(sim):
    seeds = common_seeds(11, 5)
    a = sim.simulate(THETA, seeds)
    b = sim.simulate(THETA, seeds)
    assert np.array_equal(a, b)
    c = sim.simulate(THETA, common_seeds(12, 5))
    assert not np.array_equal(a, c)
    assert len({tuple(r) for r in a}) == 5                          # replicates differ from each other


def test_seed_sequences_are_not_advanced(sim):
    seeds = [np.random.SeedSequence(s) for s in range(5)]
    a = sim.simulate(THETA, seeds)
    b = sim.simulate(THETA, seeds)
    assert np.array_equal(a, b)
    assert np.array_equal(a, sim.simulate(THETA, list(range(5))))  # SeedSequence(s) is what seed s means


def test_batch_equals_each_seed_alone(holland):
    columns = ("cohesion_mean", "polarization_final", "nn_distance_mean", "speed_mean_mean", "visible_mean_final")
    sim = SummarySimulator(holland, KEYS, columns, n_sim=4, warmup=WARMUP)
    seeds = common_seeds(5, 4)
    rows = sim.simulate(THETA, seeds)
    preset = sim.preset(THETA)
    for i, seed in enumerate(seeds):
        assert np.array_equal(rows[i], reference_row(preset, seed, columns, WARMUP))


def test_call_draws_fresh_seeds_from_the_generator(sim):
    rows = sim(THETA, np.random.default_rng(3))
    assert np.array_equal(rows, sim.simulate(THETA, seeds_for(np.random.default_rng(3), 5)))
    rng = np.random.default_rng(3)
    assert not np.array_equal(sim(THETA, rng), sim(THETA, rng))     # the generator advances


def test_seed_helpers():
    a = seeds_for(np.random.default_rng(0), 1000)
    assert len(a) == 1000 and all(isinstance(s, int) and 0 <= s < 2 ** 63 for s in a)
    assert len(set(a)) == 1000
    assert a == seeds_for(np.random.default_rng(0), 1000)
    c = common_seeds(42, 8)
    assert c == common_seeds(42, 8) and c != common_seeds(43, 8)
    assert all(isinstance(s, int) and 0 <= s < 2 ** 63 for s in c)
    words = np.random.SeedSequence(42).generate_state(8, np.uint64)
    assert c == [int(w) >> 1 for w in words]
    assert max(common_seeds(0, 64)) >= 2 ** 61                      # the high bits are used


# ---------------------------------------------------------------- theta

def test_perception_range_changes_the_result_in_the_expected_direction(holland):
    seeds = common_seeds(7, 6)
    sim = SummarySimulator(holland, ("perception.range",), ("cohesion_mean", "polarization_mean"), 6, WARMUP)
    near, far = sim.simulate([4.0], seeds), sim.simulate([40.0], seeds)
    # default group radius = the range at theta: at 4 the flock is mostly strays, at 40 one group
    assert far[:, 0].mean() > near[:, 0].mean() + 0.5
    assert np.all(far[:, 0] > near[:, 0])
    # radius-independent check: seeing further aligns the flock (12 boids, 3 s)
    fixed = SummarySimulator(holland, ("perception.range",), ("polarization_mean",), 6, WARMUP, group_radius=10.0)
    assert fixed.simulate([40.0], seeds).mean() > fixed.simulate([4.0], seeds).mean() + 0.2


def test_integer_keys_are_rounded(holland):
    sim = SummarySimulator(holland, ("init.n", "perception.range"), COLUMNS, n_sim=4, warmup=WARMUP)
    assert sim.integer_keys == (True, False)
    assert sim.preset([11.6, 20.0]).init.n == 12
    assert sim.preset([12.4, 20.0]).init.n == 12
    assert sim.preset([9.2, 20.0]).init.n == 9
    seeds = common_seeds(2, 4)
    assert np.array_equal(sim.simulate([11.6, 20.0], seeds), sim.simulate([12.0, 20.0], seeds))
    assert not np.array_equal(sim.simulate([9.0, 20.0], seeds), sim.simulate([12.0, 20.0], seeds))


def test_invalid_theta_raises_config_error_naming_the_key(sim, holland):
    with pytest.raises(ConfigError, match="perception.field_deg") as err:
        sim.simulate([400.0, 60.0], common_seeds(1, 5))
    assert err.value.key == "perception.field_deg"
    with pytest.raises(ConfigError, match="perception.direction_deg"):
        sim.simulate([120.0, float("nan")], common_seeds(1, 5))
    with pytest.raises(ConfigError, match="init.n"):
        SummarySimulator(holland, ("init.n",), COLUMNS, 2, WARMUP).simulate([0.2], [1, 2])
    assert holland["perception"]["field_deg"] == 120.0               # the base dict is never modified


def test_bad_configuration_is_rejected(holland, sim):
    with pytest.raises(ConfigError, match="perception.feild_deg"):
        SummarySimulator(holland, ("perception.feild_deg",), COLUMNS, 2, WARMUP)
    with pytest.raises(ConfigError, match="perception.occlusion"):
        SummarySimulator(holland, ("perception.occlusion",), COLUMNS, 2, WARMUP)
    with pytest.raises(ValueError, match="cohesion_mean"):
        SummarySimulator(holland, KEYS, ("cohesion_maen",), 2, WARMUP)
    with pytest.raises(ValueError, match="n_sim"):
        SummarySimulator(holland, KEYS, COLUMNS, 0, WARMUP)
    with pytest.raises(ValueError, match="seeds"):
        sim.simulate(THETA, [1, 2, 3])
    with pytest.raises(ValueError, match="theta"):
        sim.simulate([120.0], common_seeds(1, 5))
    assert "trigger_rate" in ALL_COLUMNS and "time_to_fragmentation" in ALL_COLUMNS


def test_non_finite_summaries_give_a_nan_row(holland):
    """time_to_fragmentation is nan for a run that never fragments: that whole row is NaN."""
    columns = ("cohesion_mean", "time_to_fragmentation")
    sim = SummarySimulator(holland, ("perception.range",), columns, n_sim=6, warmup=WARMUP)
    seeds = common_seeds(7, 6)
    rows = sim.simulate([10.0], seeds)                                # range 10: some runs fragment, some not
    preset = sim.preset([10.0])
    finite = np.isfinite(rows).all(axis=1)
    assert np.all(finite | np.isnan(rows).all(axis=1))               # all finite or all NaN
    assert finite.any() and not finite.all()                         # both cases occur with these seeds
    for i, seed in enumerate(seeds):
        ref = reference_row(preset, seed, columns, WARMUP)
        assert finite[i] == np.isfinite(ref).all()
        if finite[i]:
            assert np.array_equal(rows[i], ref)
    never = SummarySimulator(holland, ("perception.range",), columns, n_sim=6, warmup=WARMUP)
    assert np.isnan(never.simulate([40.0], seeds)).all()              # range 40: one cohesive flock


# ---------------------------------------------------------------- leadership

@pytest.mark.slow
def test_leadership_columns():
    data = small("hartman_benes", record_interval=1.0)
    columns = ("trigger_rate", "leader_time_fraction", "cohesion_mean")
    sim = SummarySimulator(data, ("leadership.x",), columns, n_sim=5, warmup=WARMUP)
    seeds = common_seeds(3, 5)
    off, on = sim.simulate([0.0], seeds), sim.simulate([1.0], seeds)
    assert np.isfinite(off).all() and np.isfinite(on).all()
    assert np.all(off[:, 0] == 0.0) and np.all(off[:, 1] == 0.0)
    assert np.all(on[:, 0] > 0.0)
    preset = sim.preset([1.0])
    for i, seed in enumerate(seeds[:2]):
        assert np.array_equal(on[i], reference_row(preset, seed, columns, WARMUP))
