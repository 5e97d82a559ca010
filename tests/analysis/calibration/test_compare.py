"""Model comparison (analysis.calibration.compare, ``flocksweep compare``): the file validated with keys
named, the classifier's check (confusion matrix, confident share) computed right, and a small comparison
of metric against topological perception end to end: resumable, deterministic, the true model found."""
from __future__ import annotations

import json

import numpy as np
import pytest

from flocksweep.analysis.calibration.compare import CONFIDENT, load_comparison, model_choice
from flocksweep.cli import main
from paths import ROOT
from flocksweep.simcore.schema import ConfigError

MODELS = ROOT / "configs/models"
RUN = '[run]\nn = 10\nduration = 2.0\nrecord_interval = 0.5\nwarmup = 1.0\ngroup_radius = 20.0\n'
METRIC = f'''name = "m"
[model]
preset = "{MODELS / 'holland.toml'}"
{RUN}
[parameters.field]
key = "perception.field_deg"
prior = {{ dist = "uniform", low = 200, high = 300 }}
[targets]
stats = ["polarization"]
mean = [0.5]
sd = [0.1]
[method]
kind = "emcee"
n_sim = 8
'''
TOPOLOGICAL = METRIC.replace("holland.toml", "topological.toml").replace(
    '[parameters.field]\nkey = "perception.field_deg"\nprior = { dist = "uniform", low = 200, high = 300 }',
    '[parameters.k]\nkey = "perception.neighbours"\nprior = { dist = "uniform", low = 1, high = 9 }\n'
    '[parameters.blind]\nkey = "perception.blind_deg"\nprior = { dist = "uniform", low = 0, high = 90 }').replace(
    "[model]\n", '[model]\nset = { "init.scale_with_n" = false, "init.radius" = 20.0 }\n')
COMPARE = '''name = "cmp"
seed = 2
simulations = 60
heldout = 30
[models]
metric = "metric.toml"
topological = "topological.toml"
[targets]
stats = ["polarization", "binocular_share", "speed_cv"]
mean = [0.8, 0.2, 0.1]
sd = [0.02, 0.005, 0.02]
'''


def files(tmp_path, compare: str = COMPARE, metric: str = METRIC):
    (tmp_path / "metric.toml").write_text(metric)
    (tmp_path / "topological.toml").write_text(TOPOLOGICAL)
    path = tmp_path / "compare.toml"
    path.write_text(compare)
    return path


def test_each_model_is_its_calibration_file_with_the_comparisons_targets_and_seed(tmp_path):
    comparison = load_comparison(files(tmp_path))
    assert comparison.names == ["metric", "topological"]
    metric, topological = (config for _, config in comparison.models)
    assert metric.names == ("field",) and topological.names == ("k", "blind")
    assert metric.targets.columns == topological.targets.columns == ("polarization_mean", "binocular_share_mean",
                                                                     "speed_cv_mean")
    assert metric.seed == topological.seed == 2 and comparison.simulations == 60


@pytest.mark.parametrize("compare, metric, key, words", [
    (COMPARE.replace('topological = "topological.toml"\n', ""), METRIC, "models", "at least two"),
    (COMPARE.replace('"metric.toml"', '"nowhere.toml"'), METRIC, "models.metric", "not found"),
    (COMPARE, METRIC.replace("low = 200", "low = -60"), "models.metric.parameters.field.prior", "metric.toml"),
    (COMPARE.replace("simulations = 60", "simulations = 5"), METRIC, "simulations", ">= 20"),
    (COMPARE.replace('"speed_cv"]', '"speed_cvv"]'), METRIC, "models.metric.targets.stats", "speed_cv"),
])
def test_bad_comparisons_are_refused_naming_the_key(tmp_path, compare, metric, key, words):
    with pytest.raises(ConfigError) as err:
        load_comparison(files(tmp_path, compare, metric))
    assert err.value.key == key and words in str(err.value), str(err.value)


def test_the_shipped_comparison_is_valid():
    comparison = load_comparison(ROOT / "configs/compare/perception.toml")
    assert comparison.names == ["metric", "topological"] and (comparison.simulations, comparison.heldout) == (1000, 200)
    assert dict(comparison.models)["topological"].names == ("neighbours", "blind")
    assert comparison.unobservable == ["visible_mean", "binocular_share", "visible_sd"]   # what a simulator perceives
    tracked = load_comparison(ROOT / "configs/compare/perception_tracks.toml")
    assert tracked.tracker_statistics and tracked.unobservable == [] and len(tracked.targets.stats) >= 30
    assert all(config.preset.run.duration == 30.0 for _, config in tracked.models)


class Fixed:
    """A classifier whose probabilities are given: held-out rows first, then the observed rows."""

    def __init__(self, held, observed):
        self.answers = [np.asarray(held), np.asarray(observed)]

    def predict_proba(self, x):
        answer = self.answers.pop(0)
        assert len(answer) == len(x)
        return answer


def test_the_check_counts_the_confusion_matrix_and_the_confident_true_answers():
    held = [[0.95, 0.05], [0.6, 0.4], [0.3, 0.7], [0.02, 0.98], [0.01, 0.99], [0.92, 0.08]]
    labels = [0, 0, 0, 1, 1, 1]
    choice = model_choice(Fixed(held, [[0.97, 0.03]]), np.zeros((6, 2)), labels, np.zeros(2), ["a", "b"])
    assert choice["confusion"].tolist() == [[2, 1], [1, 2]]
    assert choice["accuracy"] == pytest.approx(4 / 6)
    assert choice["confident"].tolist() == pytest.approx([1 / 3, 2 / 3])   # above CONFIDENT = 0.9 only
    assert CONFIDENT == 0.9 and choice["probabilities"].tolist() == [[0.97, 0.03]]
    assert choice["messages"][0].startswith("the targets are best explained by a (posterior model probability 0.970")


@pytest.mark.slow
def test_a_small_comparison_finds_the_true_model_and_reruns_without_simulating(tmp_path, capsys):
    # binocular_share tells binocular vision with overlapping eyes (fields 200-300 deg) from a topological
    # neighbourhood (0 there), measured to +-0.005: with 60 training and
    # 30 held-out simulations per model the true model gets probability > 0.9 on at least 90 % of each
    # model's held-out sets (tolerance: the target, on a problem where it must hold)
    path = files(tmp_path)
    out = tmp_path / "out"
    assert main(["compare", str(path), "--out", str(out), "--no-progress", "--workers", "2"]) == 0
    first = json.loads((out / "compare.json").read_text())
    assert first["simulations"]["total_computed"] == 180
    assert min(first["confident_share"].values()) >= 0.9 and first["accuracy"] >= 0.95
    assert np.sum(first["confusion"]) == 60
    assert (out / "confusion.csv").is_file() and "Confusion matrix" in (out / "report.md").read_text()
    # targets with binocular_share 0.2 are a binocular flock's
    said = capsys.readouterr().out
    assert first["probabilities"][0][0] > 0.9 and "metric" in said.splitlines()[0]
    assert f"next:\n  open {out / 'report.md'}" in said                     # the command names what comes next
    assert main(["compare", str(path), "--out", str(out), "--no-progress"]) == 0
    again = json.loads((out / "compare.json").read_text())
    assert again["simulations"]["total_computed"] == 0                      # the runs are found, not rerun
    assert again["probabilities"] == first["probabilities"] and again["confusion"] == first["confusion"]


def test_the_comparisons_run_keys_reach_every_model_and_unobservable_statistics_are_named(tmp_path):
    longer = COMPARE.replace("[targets]", "[run]\nduration = 3.0\nk_nearest = 3\n[targets]")
    comparison = load_comparison(files(tmp_path, longer))
    for _, config in comparison.models:
        assert config.preset.run.duration == 3.0 and config.metrics.k_nearest == 3
        assert config.preset.init.n == 10                                  # the model file's own [run] keys stay
    assert comparison.unobservable == ["binocular_share"] and not comparison.tracker_statistics
    with pytest.raises(ConfigError) as err:                                # the comparison's own key is named
        load_comparison(files(tmp_path, COMPARE.replace("[targets]", "[run]\nduration = -1.0\n[targets]")))
    assert err.value.key.startswith("run.duration"), err.value.key


def test_a_comparison_of_tracked_flocks_refuses_what_no_tracker_measures(tmp_path):
    tracked = COMPARE.replace('heldout = 30', 'heldout = 30\ntracker_statistics = true')
    with pytest.raises(ConfigError, match=r"targets.stats: 'binocular_share' is not measured by a tracker"):
        load_comparison(files(tmp_path, tracked))
    observable = tracked.replace('"binocular_share"', '"nn_ahead_fraction"')
    comparison = load_comparison(files(tmp_path, observable))
    assert comparison.tracker_statistics and comparison.unobservable == []
    assert comparison.targets.columns[1] == "nn_ahead_fraction_mean"


@pytest.mark.parametrize("case", __import__("malformed").COMPARISONS, ids=lambda c: c.name)
def test_a_huge_simulations_value_is_refused_before_anything_runs(case, tmp_path):
    """issue 42: compare with simulations = 10**12 allocated its design until memory ran out; now it is
    counted from the file before any model is read: the key, the value and what is allowed, exit 2."""
    from malformed import attempt
    refusal = attempt(case, tmp_path)
    assert refusal.crash == "" and refusal.code == 2, refusal.crash or refusal.stderr
    assert case.expect in refusal.stderr and refusal.written == set(), refusal.stderr
