"""Figures a scientist can read at the size they are shown (analysis.reports.layout): every figure the
report draws (main effects, heatmaps, time series, 3-D traces, effect sizes) and a simulate --plot
trace, checked from matplotlib's own layout after drawing: no text shown under the minimum height, no
two texts overlapping, no legend over plotted data; and the checks themselves catch each fault."""
from __future__ import annotations

import numpy as np
import pytest

from flocksweep.analysis.reports import layout, plotting
from paths import ROOT


@pytest.fixture
def captured(monkeypatch):
    """Every figure saved: (file name, the problems found in it as saved)."""
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
