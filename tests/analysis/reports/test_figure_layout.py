"""Figures a scientist can read at the size they are shown (analysis.reports.layout): every figure the
report draws (main effects, heatmaps, time series, 3-D traces, effect sizes) and a simulate --plot
trace, checked from matplotlib's own layout after drawing: no text shown under the minimum height, no
two texts overlapping, no legend or annotation over plotted data, no word of a categorical axis dropped,
no numeric axis with an unlabelled extreme; each figure kind again with many factors and long names; and
the checks themselves catch each fault."""
from __future__ import annotations

import itertools

import numpy as np
import pandas as pd
import pytest

from flocksweep.analysis.reports import drawing, layout, plotting
from paths import ROOT


@pytest.fixture
def captured(monkeypatch):
    """Every figure saved: (file name, the problems found in it as saved); the report's figures drawn in
    this process (analysis.reports.drawing's children would see them instead)."""
    monkeypatch.setattr(drawing, "WORKERS", 1)
    seen = []
    real = plotting._finish

    def finish(fig, dpi):
        seen.append((fig, layout.problems(fig, dpi)))
        real(fig, dpi)
    monkeypatch.setattr(plotting, "_finish", finish)
    return seen


def crowded_figure():
    """Tiny rotated-free tick labels that run into each other and a legend over the line."""
    plt = plotting.pyplot()
    fig, ax = plt.subplots(figsize=(12, 3))
    ax.plot(np.arange(40), np.arange(40), label="a line")
    ax.set_xticks(np.arange(40))
    ax.set_xticklabels([f"level {k}" for k in range(40)], fontsize=5)
    ax.legend(loc="center")
    return fig


def test_the_checks_catch_small_text_overlapping_labels_and_a_legend_over_data():
    fig = crowded_figure()
    found = layout.problems(fig, 100)
    plotting.pyplot().close(fig)
    assert any("px tall" in p for p in found)
    assert any("overlap" in p for p in found)
    assert any("covers" in p and "data points" in p for p in found)


def test_save_mends_what_the_checks_find(tmp_path, captured):
    plotting.save(crowded_figure(), tmp_path / "fixed.png")
    assert captured[0][1] == []


def test_one_figure_saved_as_png_and_svg_equals_two_separate_saves(tmp_path, captured):
    """The report writes a figure's PNG and SVG from one laid-out figure: the files are those of the
    slow, obvious way (the figure drawn anew for each format), the PNG byte for byte, the SVG up to
    the date and random ids matplotlib writes, and the checks pass on it."""
    import re

    def svg(path):   # without the save's date and matplotlib's random ids (numbered in order instead)
        ids = {}
        text = re.sub(r"<dc:date>[^<]*</dc:date>", "", path.read_text())
        return re.sub(r"\b(p|image|m|c|t|h)[0-9a-f]{10}\b", lambda m: ids.setdefault(m.group(0), f"id{len(ids)}"), text)

    together, apart = tmp_path / "together", tmp_path / "apart"
    returned = plotting.save(crowded_figure(), [together / "f.png", together / "f.svg"])
    plotting.save(crowded_figure(), apart / "f.png")
    plotting.save(crowded_figure(), apart / "f.svg")
    assert returned == together / "f.png"
    assert (together / "f.png").read_bytes() == (apart / "f.png").read_bytes()
    assert svg(together / "f.svg") == svg(apart / "f.svg")
    assert [found for _, found in captured] == [[], [], []]


@pytest.mark.slow
def test_every_report_figure_and_a_trace_plot_are_readable(tmp_path, captured):
    from flocksweep.analysis.reports.report import build_report
    from flocksweep.analysis.reports.traces import plot_traces
    from flocksweep.simcore import load_preset, simulate_preset
    from flocksweep.sweeps.config import load_sweep
    from flocksweep.sweeps.runner import run_sweep

    smoke = ROOT / "configs/sweeps/smoke.toml"
    run_sweep(load_sweep(smoke), smoke.read_text(), tmp_path / "smoke", executor="serial", progress=False)
    build_report(tmp_path / "smoke", tmp_path / "report", formats=("md",))
    preset = load_preset(ROOT / "configs/models/holland_pattern.toml", ["init.n=20", "run.duration=2"])
    obs = simulate_preset(preset, 1, 6)
    plot_traces(obs.pos, tmp_path / "traces.png", obs.pattern, "auto", None, "holland_pattern: N = 20")
    assert len(captured) >= 8
    bad = {fig.get_suptitle() or str(i): found for i, (fig, found) in enumerate(captured) if found}
    assert bad == {}


# --- the checks' newer faults, and every figure kind crowded ---------------------------------------------

def _close(fig):
    plotting.pyplot().close(fig)


def test_the_checks_catch_a_dropped_category_a_covering_note_and_an_unlabelled_extreme():
    plt = plotting.pyplot()
    fig, (a, b, c) = plt.subplots(1, 3, figsize=(12, 3))
    a.plot(range(4), [1, 2, 3, 4])
    a.set_xticks(range(4), ["normal", "pattern", "leader", "follower"])
    a.get_xticklabels()[1].set_visible(False)                              # a word dropped
    b.scatter(np.linspace(0, 1, 30), np.linspace(0, 1, 30))
    b.text(0.5, 0.5, "power 0.00 at effect 0.015", transform=b.transAxes, ha="center",
           bbox={"facecolor": "white"})                                    # a note over the runs
    c.plot([0, 8], [0, 1])
    c.set_xticks([0, 2, 4, 8], ["0", "2", "4", "8"])
    c.get_xticklabels()[-1].set_visible(False)                             # the largest X unlabelled
    found = layout.problems(fig, 100)
    _close(fig)
    assert any("drops the tick label(s) ['pattern'] of a categorical axis" in p for p in found), found
    assert any("annotation 'power 0.00 at effect 0.015' covers" in p for p in found), found
    assert any("leaves its highest tick (8) unlabelled" in p for p in found), found


def test_labels_rotated_side_by_side_do_not_count_as_overlapping_and_are_never_thinned(tmp_path, captured):
    """Rotated labels' upright boxes overlap while the labels do not: the old check thinned a heatmap's
    factor names for that (two of five lost); now they are compared as drawn and all stay."""
    plt = plotting.pyplot()
    fig, ax = plt.subplots(figsize=(4.5, 3))
    ax.imshow(np.arange(15.0).reshape(3, 5))
    names = ["init.n", "perception.field_deg", "perception.direction_deg", "perception.range", "mode"]
    ax.set_xticks(range(5), names, rotation=35, ha="right", rotation_mode="anchor")
    texts = [t for t in ax.get_xticklabels()]
    renderer = layout._renderer(fig, 150)
    boxes = [t.get_window_extent(renderer) for t in texts]
    assert any(a.overlaps(b) for a, b in zip(boxes, boxes[1:]))          # upright boxes overlap ...
    assert not any(layout._collide(a, b, renderer) for a, b in zip(texts, texts[1:]))   # ... the labels do not
    plotting.save(fig, tmp_path / "rotated.png")
    shown, found = captured[0]
    assert found == [] and all(t.get_visible() for t in shown.axes[0].get_xticklabels())


LONG_FACTORS = {
    "perception.field_deg": [30.0, 60.0, 90.0, 120.0, 150.0, 180.0],
    "perception.direction_deg": [0.0, 20.0, 40.0, 60.0, 80.0, 90.0],
    "perception.range": [10.0, 20.0, 40.0],
    "init.n": [20, 50, 100],
    "mode": ["normal", "pattern"],
    "leadership.x": [0.0, 0.25, 0.5, 1.0, 2.0, 4.0, 8.0],
    "plugin.zone_of_orientation_width_in_body_lengths": [0.5, 1.0, 2.0, 4.0],
    "obstacles": ["none", "sparse spheres across the path", "dense spheres everywhere"],
}
LONG_METRICS = ["cohesion_mean", "polarization_mean", "stray_fraction_mean", "n_groups_mean", "elongation_mean",
                "speed_mean_mean", "nn_distance_mean", "some_plugin_metric_with_a_long_name_mean"]


def _effects(rng):
    rows = []
    for factor, levels in LONG_FACTORS.items():
        for level in levels:
            mean = rng.uniform(0.2, 0.9)
            rows.append(dict(factor=factor, level=level, n=40, mean=mean, ci_low=mean - 0.05, ci_high=mean + 0.05))
    return pd.DataFrame(rows)


@pytest.mark.slow
def test_every_figure_kind_stays_readable_with_many_factors_and_long_names(tmp_path, captured):
    from flocksweep.analysis.reports import figures
    from flocksweep.analysis.reports.hierarchy import hierarchy_figure
    from flocksweep.analysis.reports.labels import metric_unit, metric_words
    from flocksweep.observables.directional_correlation import DirectionalCorrelation

    rng = np.random.default_rng(3)
    effects = _effects(rng)
    figures.main_effects_figure(effects, "cohesion_mean", tmp_path / "main.png")
    leadership = effects[effects["factor"] == "leadership.x"]
    per_metric = pd.concat([leadership.assign(factor=m) for m in LONG_METRICS[:3]], ignore_index=True)
    figures.main_effects_figure(per_metric, "", tmp_path / "leadership.png", sharey=False, xlabel="leadership X",
                                panel_title=metric_words, panel_ylabel=lambda m: metric_unit(m) or "(no unit)")
    tests = pd.DataFrame([dict(metric=m, factor=f, epsilon2=rng.uniform(0, 0.4), p_holm=rng.uniform(0, 0.1))
                          for m in LONG_METRICS for f in LONG_FACTORS])
    figures.effect_sizes_figure(tests, tmp_path / "effects.png")
    cells = pd.DataFrame([dict(zip(("perception.field_deg", "perception.direction_deg", "obstacles"), combo),
                               mean=rng.uniform()) for combo in itertools.product(
        LONG_FACTORS["perception.field_deg"], LONG_FACTORS["perception.direction_deg"], LONG_FACTORS["obstacles"])])
    figures.heatmap_figure(cells, "cohesion_mean", "perception.field_deg", "perception.direction_deg",
                           tmp_path / "heat.png", panel="obstacles")
    times = np.arange(0, 30, 1.0)
    ts = pd.DataFrame([dict(run_id=f"r{k}", t=t, cohesion=rng.uniform(), polarization=rng.uniform(),
                            nn_distance=rng.uniform(1, 5)) for k in range(8) for t in times])
    mapping = {f"cell with a long name number {k}: obstacles = dense spheres everywhere": [f"r{k}"] for k in range(8)}
    figures.timeseries_figure(ts, mapping, ["cohesion", "nn_distance"], tmp_path / "ts.png")
    n = 20
    delay = rng.normal(0, 0.4, (n, n))
    delay = delay - delay.T
    corr = np.full((n, n), 0.8)
    np.fill_diagonal(corr, np.nan)
    dc = DirectionalCorrelation(delays=np.linspace(-2, 2, 9), corr=np.zeros((n, n, 9)), corr_max=corr,
                                delay=delay, edges=(delay > 0.2), score=np.nanmean(delay, axis=1),
                                rank=np.argsort(np.argsort(-np.nanmean(delay, axis=1))) + 1)
    hierarchy_figure(dc, [f"bird-{k:03d}-tag" for k in range(n)], tmp_path / "hier.png", title="flock 1")
    assert len(captured) == 6
    bad = {str(i): found for i, (fig, found) in enumerate(captured) if found}
    assert bad == {}
    for fig, _ in captured:   # every word of every categorical axis drawn, as saved
        for ax in fig.axes:
            for axis in (ax.xaxis, ax.yaxis):
                if layout._categorical(axis):
                    assert all(label.get_visible() for _, label in layout._labelled_ticks(axis)), ax.get_title()
