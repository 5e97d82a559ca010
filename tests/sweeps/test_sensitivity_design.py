"""Sweep designs for sensitivity analysis (``[design]``, sweeps.sensitivity) and explicit ``[[points]]``.

* a Saltelli block is SALib's sample of the bounds (N (d + 2) rows, or N (2d + 2) with second order), in
  SALib's order, from the sweep seed; a Morris block r (d + 1) rows on a p-level grid;
* run identity and seeds are those of every design point (``run_seed(seed, point, replicate)``), so a
  point that is also a grid point has the grid point's run id; rows that coincide after rounding an
  integer key are one point;
* explicit points come after the product, keep every product run id, and are refused with the key when
  they miss a swept key, give an unknown one, repeat a design point or leave a labelled axis' values;
* bad ``[design]`` tables are refused before anything runs, naming the key.
"""
from __future__ import annotations

import numpy as np
import pytest

from flocksweep.simcore import ConfigError
from flocksweep.sweeps.config import sweep_from_dict
from flocksweep.sweeps.design import expand
from flocksweep.sweeps.identity import point_key
from flocksweep.sweeps.results import swept_columns
from flocksweep.sweeps.runner import design_table
from flocksweep.sweeps.seeds import run_seed
from paths import ROOT

HOLLAND = str(ROOT / "configs/models/holland.toml")
BOUNDS = {"perception.field_deg": [30, 180], "perception.direction_deg": [0, 90]}


def sweep(**tables):
    data = {"name": "sa", "seed": 9, "model": {"preset": HOLLAND}, "run": {"n": 6, "duration": 1.0, "warmup": 0.0}}
    data.update(tables)
    return sweep_from_dict(data, ROOT)


def test_saltelli_block_is_salibs_sample_in_order_with_the_usual_identity():
    config = sweep(design={"kind": "saltelli", "n": 8, "bounds": BOUNDS}, replicates=2)
    specs = expand(config)
    rows = config.design.sample(config.seed)
    assert rows.shape == (8 * 4, 2) and config.design.rows_count == 32
    points = [dict(s.columns) for s in specs if s.replicate == 0]
    assert [(p["perception.field_deg"], p["perception.direction_deg"]) for p in points] == [tuple(r) for r in rows]
    assert np.all((rows[:, 0] >= 30) & (rows[:, 0] <= 180) & (rows[:, 1] >= 0) & (rows[:, 1] <= 90))
    spec = specs[5]
    assert spec.seed == run_seed(9, point_key(dict(spec.columns)), spec.replicate)
    assert [s.index for s in specs] == list(range(64))
    again = expand(sweep(design={"kind": "saltelli", "n": 8, "bounds": BOUNDS}, replicates=2))
    assert [s.run_id for s in again] == [s.run_id for s in specs]          # deterministic in the seed
    other = sweep(design={"kind": "saltelli", "n": 8, "bounds": BOUNDS}, replicates=2, seed=10)
    assert not np.array_equal(other.design.sample(other.seed), rows)
    three = {**BOUNDS, "perception.range": [10, 30]}
    second = sweep(design={"kind": "saltelli", "n": 8, "bounds": three, "second_order": True})
    assert second.design.rows_count == len(expand(second)) == 8 * 8     # N (2d + 2), all distinct for d = 3


def test_a_design_point_that_is_also_a_grid_point_has_the_grid_points_run_id():
    config = sweep(design={"kind": "saltelli", "n": 4, "bounds": BOUNDS})
    first = dict(expand(config)[0].columns)
    grid = sweep(axes=[{"key": key, "values": [first[key]]} for key in BOUNDS])
    assert expand(grid)[0].run_id == expand(config)[0].run_id


def test_rows_that_coincide_after_rounding_are_one_point():
    config = sweep(design={"kind": "saltelli", "n": 16, "bounds": {"perception.field_deg": [30, 180],
                                                                    "init.n": [5, 7]}})
    rows = config.design.rows(config.seed, [False, True])
    specs = expand(config)
    assert len(rows) == 64 and len(specs) == len(set(rows)) < 64
    assert all(isinstance(dict(s.columns)["init.n"], int) for s in specs)


def test_morris_block_has_r_trajectories_of_d_plus_one_grid_points():
    config = sweep(design={"kind": "morris", "trajectories": 6, "levels": 4, "bounds": BOUNDS})
    rows = config.design.sample(config.seed)
    assert rows.shape == (6 * 3, 2)
    unit = (rows - [30, 0]) / [150, 90]
    assert np.allclose(unit * 3, np.round(unit * 3))                         # p = 4 levels: 0, 1/3, 2/3, 1
    steps = np.abs(np.diff(rows.reshape(6, 3, 2), axis=1)) > 0
    assert np.all(steps.sum(axis=2) == 1)                                    # one factor moves per step
    assert len(expand(config)) == len(set(map(tuple, rows)))


def test_design_block_factors_and_columns():
    config = sweep(design={"kind": "saltelli", "n": 4, "bounds": BOUNDS},
                   axes=[{"key": "perception.range", "values": [10, 20]}])
    assert config.factors == ("perception.range", *BOUNDS) and config.swept_keys[-2:] == list(BOUNDS)
    design = design_table(expand(config))
    assert len(design) == 2 * 16
    effective = {"axes": [{"key": "perception.range"}], "design": {"bounds": BOUNDS}}
    assert swept_columns(design, effective) == ["perception.range", *BOUNDS]


@pytest.mark.parametrize("table, key, words", [
    ({"kind": "saltelli", "n": 12, "bounds": BOUNDS}, "design.n", "power of 2"),
    ({"kind": "saltelli", "bounds": BOUNDS}, "design.n", "base sample size"),
    ({"kind": "saltelli", "n": 8, "trajectories": 4, "bounds": BOUNDS}, "design.trajectories", "morris"),
    ({"kind": "morris", "bounds": BOUNDS}, "design.trajectories", "trajectories"),
    ({"kind": "morris", "trajectories": 4, "levels": 5, "bounds": BOUNDS}, "design.levels", "even"),
    ({"kind": "morris", "trajectories": 4, "n": 8, "bounds": BOUNDS}, "design.n", "saltelli"),
    ({"kind": "sobol", "n": 8, "bounds": BOUNDS}, "design.kind", "saltelli"),
    ({"kind": "saltelli", "n": 8, "bounds": {"perception.field_deg": [90, 30]}}, "design.bounds.perception.field_deg",
     "low must be < high"),
    ({"kind": "saltelli", "n": 8, "bounds": {"perception.field_deg": [30, 400]}}, "perception.field_deg", "360"),
])
def test_bad_design_tables_name_the_key(table, key, words):
    with pytest.raises(ConfigError, match=words) as err:
        expand(sweep(design=table))
    assert key in str(err.value)


def test_sample_and_design_together_are_refused():
    with pytest.raises(ConfigError, match="not both"):
        sweep(design={"kind": "saltelli", "n": 8, "bounds": BOUNDS},
              sample={"method": "lhs", "n": 4, "bounds": {"perception.range": [5, 10]}})


GRID = [{"name": "mode", "key": "patterns.enabled", "values": [False, True], "labels": ["normal", "pattern"]},
        {"key": "perception.field_deg", "values": [60, 120]}]


def test_explicit_points_come_last_and_keep_every_product_run_id():
    plain = expand(sweep(axes=GRID, replicates=2))
    points = [{"patterns.enabled": False, "perception.field_deg": 95.5},
              {"patterns.enabled": True, "perception.field_deg": 33}]
    extended = expand(sweep(axes=GRID, replicates=2, points=points))
    assert [s.run_id for s in extended[:len(plain)]] == [s.run_id for s in plain]
    added = extended[len(plain):]
    assert [s.index for s in added] == [8, 9, 10, 11] and [s.point_index for s in added] == [4, 4, 5, 5]
    assert dict(added[0].columns) == {"mode": "normal", "patterns.enabled": False, "perception.field_deg": 95.5}
    assert added[2].seed == run_seed(9, point_key({"patterns.enabled": True, "perception.field_deg": 33.0}), 0)
    # the same point written as a grid level has the same run id
    grid = expand(sweep(axes=[GRID[0], {"key": "perception.field_deg", "values": [95.5]}], replicates=2))
    assert grid[0].run_id == added[0].run_id


@pytest.mark.parametrize("point, key, words", [
    ({"patterns.enabled": False}, "points[0]", "missing swept key"),
    ({"patterns.enabled": False, "perception.field_deg": 90, "perception.rnge": 3}, "points[0].perception.rnge",
     "not a swept key"),
    ({"patterns.enabled": False, "perception.field_deg": 60}, "points[0]", "same parameters"),
    ({"patterns.enabled": 3, "perception.field_deg": 90}, "points[0].patterns.enabled", "labelled"),
    ({"patterns.enabled": False, "perception.field_deg": 400}, "perception.field_deg", "360"),
])
def test_bad_points_are_refused_with_their_key(point, key, words):
    with pytest.raises(ConfigError, match=words) as err:
        expand(sweep(axes=GRID, points=[point]))
    assert key in str(err.value)
