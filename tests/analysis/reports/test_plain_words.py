"""The report's answer in plain words (analysis.reports.plain_words), on planted effects with a fixed seed:
a steady modest trend (significant as a trend, not by Kruskal-Wallis: the disagreement note), a
categorical difference, no effect, an effect that rises and falls again, and labels with units."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from flocksweep.analysis.reports import stats
from flocksweep.analysis.reports.labels import metric_label, parameter_label
from flocksweep.analysis.reports.plain_words import disagreement_note, plain_findings

FIELDS = [30.0, 60.0, 90.0, 120.0, 150.0, 180.0]


@pytest.fixture(scope="module")
def findings():
    rng = np.random.default_rng(45)
    rows = []
    for field in FIELDS:
        for mode in ("normal", "pattern"):
            for direction in (0.0, 45.0, 90.0):
                for _ in range(10):
                    k = FIELDS.index(field)
                    rows.append({"perception.field_deg": field, "mode": mode, "perception.direction_deg": direction,
                                 # a steady, modest rise with the field: +0.1 over the range, sd 0.15
                                 "cohesion_mean": 0.5 + 0.02 * k + rng.normal(0, 0.15),
                                 # pattern mode clearly lower; the field and direction do nothing
                                 "polarization_mean": (0.8 if mode == "normal" else 0.6) + rng.normal(0, 0.05),
                                 # up then down again with the direction: no trend, the levels differ
                                 "speed_mean_mean": 2.0 + (0.5 if direction == 45.0 else 0.0) + rng.normal(0, 0.1)})
    runs = pd.DataFrame(rows)
    factors = ["perception.field_deg", "mode", "perception.direction_deg"]
    metrics = ["cohesion_mean", "polarization_mean", "speed_mean_mean"]
    report = stats.factor_report(runs, factors, metrics, seed=1, n_resamples=200)
    table = plain_findings(runs, report["tests"], report["main_effects"], factors, metrics)
    return table.set_index(["metric", "factor"])


def test_a_steady_modest_trend_is_said_with_its_size_units_and_both_tests(findings):
    row = findings.loc[("cohesion_mean", "perception.field_deg")]
    assert row["finding"] == "raises" and row["kind"] == "trend"
    assert row["trend_p_holm"] < 0.05 <= row["kw_p_holm"] and row["disagree"]       # fixed seed 45
    assert row["sentence"].startswith("field of vision phi raises cohesion (share in the largest group): +0.")
    assert "from 30 to 180 deg (trend: Spearman rho" in row["sentence"] and "Kruskal-Wallis p (Holm)" in row["sentence"]
    assert row["change"] == pytest.approx(0.1, abs=0.05)


def test_a_categorical_difference_no_effect_and_an_effect_that_turns_back(findings):
    mode = findings.loc[("polarization_mean", "mode")]
    assert mode["finding"] == "differs" and mode["high_level"] == "normal" and mode["low_level"] == "pattern"
    assert mode["sentence"].startswith("alignment (polarization, 0-1) depends on mode: highest at normal")
    none = findings.loc[("polarization_mean", "perception.field_deg")]
    assert none["finding"] == "no clear effect" and not none["disagree"]
    bump = findings.loc[("speed_mean_mean", "perception.direction_deg")]
    assert bump["finding"] == "changes" and bump["disagree"]
    assert "but not steadily one way" in bump["sentence"] and "units/s" in bump["sentence"]


def test_the_note_explains_a_disagreement_and_names_each_case(findings):
    note = disagreement_note(findings.reset_index())
    assert note.startswith("Two tests, two questions.")
    assert "field of vision phi on cohesion (share in the largest group)" in note
    assert "direction of vision delta on mean speed" in note
    assert disagreement_note(findings.reset_index().assign(disagree=False)) == ""


def test_labels_carry_words_and_units():
    assert parameter_label("perception.field_deg") == "field of vision phi (deg)"
    assert parameter_label("init.n") == "flock size N (boids)"
    assert parameter_label("vehicle.some_angle_deg") == "some angle (deg)"
    assert metric_label("speed_mean_mean") == "mean speed (units/s)"
    assert metric_label("nn_distance_final") == "nearest-neighbour distance at the end of the run (units)"
    assert metric_label("trigger_rate") == "leadership triggers (per boid per min)"
    assert metric_label("my_own_metric") == "my_own_metric"
