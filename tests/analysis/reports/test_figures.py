"""Report figures (analysis.reports.figures) and the trace plot refactor (analysis.reports.traces), on synthetic data.

Each figure function must write a non-empty PNG (or SVG, by extension), close its figure and return
the path; the inputs mimic a sweep's tables: categorical and numeric (numpy-typed) factors, NaN and
missing cells, cells with few runs, thumbnails with and without patterns.
"""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from flocksweep.analysis.reports import figures
from flocksweep.analysis.reports.traces import draw_traces, plot_traces
from paths import ROOT

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
FACTORS = {
    "mode": ["normal", "pattern"],
    "init.n": [np.int64(100), np.int64(20), np.int64(50)],          # unsorted, numpy ints
    "perception.direction_deg": [0.0, 20.0, 40.0, 60.0, 80.0, 90.0],
    "perception.field_deg": [30.0, 60.0, 90.0, 120.0, 150.0, 180.0],
    "perception.range": [10.0, 20.0, 40.0],
}
TABLE_1 = np.array([0b00000000, 0b00111010, 0b11000101, 0b11111111])


def assert_png(path: Path, min_kb: float = 5) -> None:
    assert path.exists(), path
    data = path.read_bytes()
    assert data[:8] == PNG_SIGNATURE
    assert len(data) > min_kb * 1024, f"{path} is only {len(data)} bytes"


def assert_svg(path: Path) -> None:
    assert path.exists(), path
    text = path.read_text()
    assert "<svg" in text[:2000]
    assert len(text) > 5 * 1024


# every test here must close its figures: tests/conftest.py's closes_what_it_opens checks it


@pytest.fixture
def effects() -> pd.DataFrame:
    rng = np.random.default_rng(1)
    rows = []
    for factor, levels in FACTORS.items():
        for level in levels:
            n = 108
            mean = rng.uniform(0.2, 0.9)
            half = rng.uniform(0.01, 0.08)
            rows.append(dict(factor=factor, level=level, n=n, mean=mean, ci_low=mean - half, ci_high=mean + half))
    frame = pd.DataFrame(rows)
    frame.loc[frame["factor"] == "perception.range", ["ci_low", "ci_high"]] = np.nan  # CI unavailable
    return frame


@pytest.fixture
def cells() -> pd.DataFrame:
    """One row per design cell (2 x 3 x 6 x 6 x 3) with the cell mean; some NaN, some missing."""
    index = pd.MultiIndex.from_product(list(FACTORS.values()), names=list(FACTORS))
    frame = index.to_frame(index=False)
    rng = np.random.default_rng(2)
    frame["mean"] = (frame["perception.range"] / 40 + frame["perception.field_deg"] / 360
                     + rng.normal(0, 0.05, len(frame)))
    frame.loc[rng.choice(len(frame), 12, replace=False), "mean"] = np.nan
    return frame.drop(index=rng.choice(len(frame), 5, replace=False))


@pytest.fixture
def timeseries() -> tuple[pd.DataFrame, dict[str, list[str]]]:
    rng = np.random.default_rng(3)
    frames = []
    cells = {"range 10, N=20": [f"a{k}" for k in range(4)],
             "range 40, N=20": ["b0", "b1"],                       # < 3 runs: min-max band
             "range 40, N=100": ["c0"]}
    for label, run_ids in cells.items():
        for run_id in run_ids:
            t = np.arange(0.0, 31.0)
            decay = rng.uniform(0.05, 0.2)
            frame = pd.DataFrame({"run_id": run_id, "t": t,
                                  "cohesion": np.exp(-decay * t) + rng.normal(0, 0.02, len(t)),
                                  "polarization": 0.3 + rng.normal(0, 0.05, len(t)),
                                  "elongation": rng.uniform(1, 3, len(t))})
            frame.loc[frame["t"] < 3, "elongation"] = np.nan
            frames.append(frame)
    return pd.concat(frames, ignore_index=True), cells


def tracks(rng, r=40, n=12) -> np.ndarray:
    return np.cumsum(rng.normal(size=(r, n, 3)), axis=0) + rng.uniform(-10, 10, size=(1, n, 3))


# -- main effects ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("suffix", ["png", pytest.param("svg", marks=pytest.mark.slow)])
def test_main_effects_figure(effects, tmp_path, suffix):
    target = tmp_path / "sub" / f"effects.{suffix}"
    out = figures.main_effects_figure(effects, "cohesion_mean", target)
    assert out == target
    assert_png(out) if suffix == "png" else assert_svg(out)


def test_main_effects_single_factor_and_errors(effects, tmp_path):
    only_mode = effects[effects["factor"] == "mode"]
    assert_png(figures.main_effects_figure(only_mode, "cohesion_mean", tmp_path / "mode.png"), min_kb=3)
    with pytest.raises(ValueError):
        figures.main_effects_figure(effects.drop(columns="ci_low"), "cohesion_mean", tmp_path / "x.png")


# -- heatmaps -------------------------------------------------------------------------------------------

@pytest.mark.slow
def test_heatmap_figure_panels_and_rows(cells, tmp_path):
    # the full report layout: 3 panels x 6 grid rows of 6 x 6 annotated heatmaps
    out = figures.heatmap_figure(cells, "cohesion_mean", "perception.field_deg", "perception.direction_deg",
                                 tmp_path / "heat.png", panel="perception.range", rows=["mode", "init.n"])
    assert_png(out, min_kb=50)


@pytest.mark.slow   # over half a second of CPU: out of the quick loop (CI runs it)
def test_heatmap_figure_svg_single_row_factor(cells, tmp_path):
    out = figures.heatmap_figure(cells, "cohesion_mean", "perception.field_deg", "init.n", tmp_path / "heat.svg",
                                 panel="perception.range", rows="mode")
    assert_svg(out)


def test_heatmap_figure_single_panel_marginalises(cells, tmp_path):
    # no panel/rows: the other factors are averaged over; categorical x
    out = figures.heatmap_figure(cells, "cohesion_mean", "mode", "init.n", tmp_path / "one.png")
    assert_png(out)


def test_heatmap_figure_large_grid_and_all_nan_panel(tmp_path):
    # 12 x 10 grid: no annotations; one panel entirely NaN (grey)
    x, y = np.arange(12) * 15.0, np.arange(10) * 0.1
    frame = pd.MultiIndex.from_product([x, y, ["a", "b"]], names=["fx", "fy", "g"]).to_frame(index=False)
    frame["mean"] = np.where(frame["g"] == "b", np.nan, frame["fx"] * frame["fy"])
    out = figures.heatmap_figure(frame, "m", "fx", "fy", tmp_path / "big.png", panel="g")
    assert_png(out)


def test_heatmap_figure_rejects_bad_keys(cells, tmp_path):
    with pytest.raises(ValueError):
        figures.heatmap_figure(cells, "m", "mode", "mode", tmp_path / "x.png")
    with pytest.raises(ValueError):
        figures.heatmap_figure(cells, "m", "mode", "init.n", tmp_path / "x.png", panel="nope")


# -- time series ----------------------------------------------------------------------------------------

@pytest.mark.parametrize("suffix", ["png", pytest.param("svg", marks=pytest.mark.slow)])
def test_timeseries_figure(timeseries, tmp_path, suffix):
    ts, cells = timeseries
    out = figures.timeseries_figure(ts, cells, ["cohesion", "polarization", "elongation"],
                                    tmp_path / f"ts.{suffix}")
    assert_png(out, min_kb=20) if suffix == "png" else assert_svg(out)


@pytest.mark.slow   # over half a second of CPU: out of the quick loop (CI runs it)
def test_timeseries_figure_empty_cell_and_many_panels(timeseries, tmp_path):
    ts, cells = timeseries
    cells = dict(cells, missing=["zzz"])
    with pytest.warns(UserWarning, match="missing"):
        out = figures.timeseries_figure(ts, cells, ["cohesion", "polarization", "elongation", "cohesion"],
                                        tmp_path / "ts4.png", ncols=2)
    assert_png(out)
    with pytest.raises(ValueError), pytest.warns(UserWarning):
        figures.timeseries_figure(ts, {"x": ["zzz"]}, ["cohesion"], tmp_path / "none.png")
    with pytest.raises(ValueError):
        figures.timeseries_figure(ts, cells, ["no_such_metric"], tmp_path / "bad.png")


# -- thumbnails -----------------------------------------------------------------------------------------

@pytest.mark.slow
@pytest.mark.parametrize("suffix", ["png", pytest.param("svg", marks=pytest.mark.slow)])
def test_thumbnails_figure_with_and_without_patterns(tmp_path, suffix):
    rng = np.random.default_rng(4)
    items = [("no pattern", tracks(rng), None),
             ("patterns", tracks(rng), rng.choice(TABLE_1, 12)),
             ("one pattern", tracks(rng), np.zeros(12, dtype=np.uint32)),
             ("wrapped", np.mod(tracks(rng), 20.0), rng.choice(TABLE_1[:2], 12))]
    out = figures.thumbnails_figure(items, tmp_path / f"thumbs.{suffix}", ncols=3, wrap_jump=10.0)
    assert_png(out, min_kb=30) if suffix == "png" else assert_svg(out)


def test_thumbnails_figure_single_item_and_errors(tmp_path):
    rng = np.random.default_rng(5)
    out = figures.thumbnails_figure([("only", tracks(rng), None)], tmp_path / "one.png", ncols=4,
                                    color_by="pattern")
    assert_png(out)
    with pytest.raises(ValueError):
        figures.thumbnails_figure([], tmp_path / "none.png")
    with pytest.raises(ValueError):
        figures.thumbnails_figure([("flat", np.zeros((5, 3)), None)], tmp_path / "flat.png")
    with pytest.raises(ValueError):
        figures.thumbnails_figure([("bad pattern", tracks(rng), np.zeros(3))], tmp_path / "bad.png")


# -- effect sizes ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("suffix", ["png", pytest.param("svg", marks=pytest.mark.slow)])
def test_effect_sizes_figure(tmp_path, suffix):
    rng = np.random.default_rng(6)
    metrics = ["cohesion_mean", "polarization_mean", "stray_fraction_mean", "n_groups_mean", "elongation_mean"]
    tests = pd.DataFrame([dict(metric=m, factor=f, epsilon2=rng.uniform(0, 0.8), p_holm=rng.uniform(0, 0.1))
                          for m in metrics for f in FACTORS])
    tests.loc[3, "epsilon2"] = np.nan
    tests.loc[4, "p_holm"] = np.nan
    out = figures.effect_sizes_figure(tests, tmp_path / f"eps.{suffix}")
    assert_png(out, min_kb=20) if suffix == "png" else assert_svg(out)


def test_effect_sizes_figure_without_p_values(tmp_path):
    tests = pd.DataFrame({"metric": ["a", "a", "b"], "factor": ["f", "g", "f"], "epsilon2": [0.1, 0.0, 0.3]})
    assert_png(figures.effect_sizes_figure(tests, tmp_path / "eps.png"))


# -- traces refactor, import hygiene --------------------------------------------------------------------

def test_plot_traces_still_works(tmp_path):
    rng = np.random.default_rng(7)
    assert_png(plot_traces(tracks(rng), tmp_path / "traces.png", title="plain"), min_kb=20)
    out = plot_traces(tracks(rng), tmp_path / "traces.svg", rng.choice(TABLE_1, 12), "auto", 15.0, "patterns")
    assert_svg(out)


def test_draw_traces_into_existing_axes():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rng = np.random.default_rng(8)
    fig = plt.figure()
    try:
        ax = fig.add_subplot(projection="3d")
        assert draw_traces(ax, tracks(rng, n=5), rng.choice(TABLE_1, 5), title="t") is ax
        assert ax.get_title() == "t"
        assert len(ax.lines) >= 5
        assert ax.get_legend() is not None
    finally:
        plt.close(fig)


def test_importing_figures_has_no_side_effects():
    code = ("import sys, analysis.reports.figures, analysis.reports.traces; "
            "print('matplotlib' in sys.modules)")
    result = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True)
    assert result.stdout.strip() == "False"
