"""Many flocks at once (analysis.calibration.npe_flow's samplers, posterior_command): a flock's draws are bit
for bit the same sampled alone (its row number given) or among many, in a table of any size; the leakage is
each flock's own; flows loaded again share one compiled sampler.

The estimators are untrained flows (tests/npe_tiny.py fake_estimator: one parameter, prior 60-300): their
draws depend on the observed statistics enough that some flocks leak 10-60 % of their draws outside the
prior (redrawn) and some leak all of them (no posterior: NaN)."""
from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

pytest.importorskip("flowjax", reason="the sbi extra (pip install -e '.[sbi]')")

from flocksweep.analysis.calibration import npe_flow  # noqa: E402
from flocksweep.analysis.calibration.npe_flow import (Ensemble, _one_structure, load_estimator,  # noqa: E402
                                                      rows_per_call, support_of)
from flocksweep.analysis.calibration.posterior_command import LEAKAGE_WARN, posteriors  # noqa: E402
from npe_tiny import COLUMNS, fake_estimator  # noqa: E402

# observed rows (visible_mean, binocular_share): leakage about 0.1, 0.64, 0.42, 0.2, 0.2, 0.34 at 50 draws
# (measured with the width-8 fake estimator); the last one lies far outside (leaks every draw: NaN)
ROWS = np.array([[3.0, 0.2], [10.0, 0.2], [0.0, 0.0], [3.5, 0.3], [5.0, 0.2], [3.0, 1.0], [30.0, 2.0]])
SUPPORT = support_of(bounds=[[60.0, 300.0]])


@pytest.fixture(scope="module")
def ensemble(tmp_path_factory):
    """Two members of the same architecture with different weights (the first from fake_estimator's flow,
    the second's weights moved), loaded from their folders as an ensemble is."""
    where = tmp_path_factory.mktemp("est")
    member = load_estimator(fake_estimator(where / "a"))
    import jax

    moved = jax.tree_util.tree_map(lambda leaf: leaf * 1.3 if hasattr(leaf, "dtype") and leaf.dtype.kind == "f" else leaf,
                                   member.flow)
    other = npe_flow.Estimator(moved, member.settings, member.theta_mean + 20, member.theta_sd, member.x_mean,
                               member.x_sd)
    return Ensemble(_one_structure((member, other)))


COUNT = 80            # 40 draws a member, as posterior's --draws 40 of one flow: one compiled sampler for all


@pytest.mark.slow
def test_a_flock_sampled_alone_gets_the_draws_it_gets_among_many(ensemble):
    count = COUNT     # 16 rows a compiled call: the 6 rows take one padded call, alone 1 each
    together = ensemble.sample_many(ROWS[:-1], count, 11, SUPPORT)
    leakage = ensemble.last_row_leakage.copy()
    assert ((together >= 60) & (together <= 300)).all() and (leakage > 0).all()
    for i in range(len(ROWS) - 1):
        alone = ensemble.sample_many(ROWS[i:i + 1], count, 11, SUPPORT, rows=[i])
        np.testing.assert_array_equal(alone[0], together[i])
        assert ensemble.last_row_leakage[0] == leakage[i]
    # without its row number a row is row 0: other draws (each flock its own stream)
    assert not np.array_equal(ensemble.sample_many(ROWS[3:4], count, 11, SUPPORT)[0], together[3])


@pytest.mark.slow
def test_a_table_of_any_size_gives_each_flock_the_same_draws(ensemble, monkeypatch):
    count = COUNT
    monkeypatch.setattr(npe_flow, "SAMPLE_BLOCK", 3 * count // 2)   # 3 rows a call (40 draws a member): 7 rows
    assert rows_per_call(count // 2) == 3                            # span 3 calls, 4 rows 2, 2 rows 1
    many = np.concatenate([ROWS[:-1]] * 2)                           # 12 flocks, each twice (rows differ)
    full = ensemble.sample_many(many, count, 5, SUPPORT)
    for size in (1, 2, 4, 7):
        np.testing.assert_array_equal(ensemble.sample_many(many[:size], count, 5, SUPPORT), full[:size])
    assert not np.array_equal(full[0], full[6])                      # the same flock at two rows: two streams


@pytest.mark.slow   # seconds of JAX/HDF5 work: out of the quick loop (CI runs it)
def test_leakage_is_each_flocks_own_and_pools_to_the_calls_share(ensemble):
    draws = ensemble.sample_many(ROWS, COUNT, 2, SUPPORT, short="nan")
    assert np.isnan(draws[-1]).all() and not np.isnan(draws[:-1]).any()     # the last row: no posterior
    per_flock = ensemble.last_row_leakage
    assert per_flock.shape == (len(ROWS),)
    assert per_flock[-1] == 1.0 and per_flock[:-1].max() < 1.0
    assert per_flock[:-1].max() - per_flock[:-1].min() > 0.2         # flocks leak differently
    assert ensemble.last_leakage == pytest.approx(per_flock.mean(), abs=1e-12)
    for member in ensemble.members:
        assert member.last_row_leakage.shape == (len(ROWS),)


def test_flows_loaded_again_reuse_the_compiled_sampler(tmp_path):
    first = load_estimator(fake_estimator(tmp_path / "a"))
    first.sample_many(ROWS[:2], COUNT // 2, 1)
    traces = npe_flow._sampler()._cached._cache_size()
    again = load_estimator(tmp_path / "a")
    again.sample_many(ROWS[2:5], COUNT // 2, 3)
    assert npe_flow._sampler()._cached._cache_size() == traces      # no new trace for another load, other rows


def test_posterior_gives_each_flock_its_leakage_and_names_the_leaky_ones(tmp_path):
    est = fake_estimator(tmp_path / "est")
    table = pd.DataFrame(np.concatenate([ROWS[:-1], [[2.0, 0.5], [1.0, 0.5]]]), columns=COLUMNS)   # + two that leak little
    table.insert(0, "flock", [f"flock{i}" for i in range(len(table))])
    out, notes = posteriors(est, table, draws=COUNT // 2, seed=4)
    assert list(out["flock"]) == list(table["flock"])
    leaky = out.loc[out["leakage"] > LEAKAGE_WARN, "flock"].tolist()
    assert 0 < len(leaky) < len(out) and out["leakage"].nunique() > 2
    note = next(n for n in notes if "outside the prior" in n)
    assert note.startswith(f"{len(leaky)} of {len(out)} flock(s) had more than 10%")
    assert all(name in note for name in leaky)
    assert not any(name in note for name in set(out["flock"]) - set(leaky))
    # the first rows of a table get the same posteriors as in the whole table
    part, _ = posteriors(est, table.iloc[:3], draws=COUNT // 2, seed=4)
    pd.testing.assert_frame_equal(part, out.iloc[:3].reset_index(drop=True))
    assert json.loads((est / "identity.json").read_text())["columns"] == COLUMNS


def test_an_estimator_of_several_flocks_gives_one_posterior_given_all_of_them(tmp_path):
    """Trained on the mean of 3 runs per simulation, it is conditioned on the mean of 3 flocks: a table of 3
    rows gives ONE posterior (named by all three, equal to that of their mean row given as one flock to an
    estimator of one); 2 rows, or each row alone, are refused (each would be read as a mean of 3)."""
    from flocksweep.simcore.schema import ConfigError

    three = fake_estimator(tmp_path / "three", replicates=3)
    one = fake_estimator(tmp_path / "one")
    table = pd.DataFrame({"flock": ["a", "b", "c"], "visible_mean": [3.0, 3.5, 5.0], "binocular_share": [0.2, 0.3, 0.2]})
    out, _ = posteriors(three, table, draws=40, seed=1)
    assert len(out) == 1 and out["flock"].iloc[0] == "a+b+c"
    mean_row = pd.DataFrame({"flock": ["m"], "visible_mean": [table["visible_mean"].mean()],
                             "binocular_share": [table["binocular_share"].mean()]})
    alone, _ = posteriors(one, mean_row, draws=40, seed=1)
    np.testing.assert_array_equal(out["field_median"].to_numpy(), alone["field_median"].to_numpy())
    with pytest.raises(ConfigError, match=r"2 flock\(s\) given.*trained on 3 flocks at a time.*exactly 3") as err:
        posteriors(three, table.iloc[:2], draws=40, seed=1)
    assert err.value.key == "--targets"


@pytest.mark.slow   # seconds of JAX work: out of the quick loop (CI runs it)
def test_with_a_margin_a_flock_keeps_its_first_draws_inside_and_gets_them_alone_or_among_many(ensemble):
    """posterior's margin: each row draws count + count / 4 at first and keeps its first count draws inside
    the prior (fewer redraw passes); still one posterior per row whatever the table, every draw inside."""
    member = ensemble.members[0]
    count, seed = 40, 3
    together = member.sample_many(ROWS[:-1], count, seed, SUPPORT, margin=4)
    assert together.shape == (len(ROWS) - 1, count, 1) and ((together >= 60) & (together <= 300)).all()
    leakage = member.last_row_leakage.copy()
    raw = member._raw(np.atleast_2d(member._condition(ROWS[:-1])), count + count // 4, seed, np.arange(len(ROWS) - 1))
    for i in range(len(ROWS) - 1):
        kept = raw[i][SUPPORT(raw[i])]
        assert leakage[i] == 1.0 - len(kept) / len(raw[i])
        if len(kept) >= count:                                    # no redraw: the first count inside, in order
            np.testing.assert_array_equal(together[i], kept[:count])
        alone = member.sample_many(ROWS[i:i + 1], count, seed, SUPPORT, rows=[i], margin=4)
        np.testing.assert_array_equal(alone[0], together[i])
    mixture = ensemble.sample_many(ROWS[:-1], COUNT, seed, SUPPORT, margin=4)
    assert ((mixture >= 60) & (mixture <= 300)).all()
