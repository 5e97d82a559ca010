"""Checks of analysis.reports.drawing run in a fresh interpreter (tests/analysis/reports/test_drawing.py): a test
process may have loaded JAX, whose threads a fork copies mid-work (drawing itself then draws inline), so
forking is checked where nothing but the report's own modules is loaded. ``python -c "import
figure_children as f; f.NAME(folder)"`` exits 0 when the check holds (an AssertionError otherwise)."""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

from flocksweep.analysis.reports import drawing, plotting
from flocksweep.analysis.reports.drawing import FigureFailed, Figures


def line_figure(seed: int):
    def draw(target):
        plt = plotting.pyplot()
        fig, ax = plt.subplots(figsize=(3, 2))
        ax.plot(np.random.default_rng(seed).normal(size=50), label=f"seed {seed}")
        ax.legend(loc="upper left")
        plotting.save(fig, target)
    return draw


def same_files(folder) -> None:
    """Figures drawn in children are the files drawn inline, at most two children at a time."""
    folder = Path(folder)
    assert "jax" not in sys.modules and drawing.forking_is_safe()
    (folder / "forked").mkdir()
    (folder / "inline").mkdir()
    with Figures(workers=2) as figures:
        for seed in range(3):
            figures.submit(line_figure(seed), folder / "forked" / f"f{seed}.png")
        assert len(figures.running) == 2                     # at most two at a time, the rest waited for
        figures.wait()
    with Figures(workers=1) as figures:
        for seed in range(3):
            figures.submit(line_figure(seed), folder / "inline" / f"f{seed}.png")
    for seed in range(3):
        forked, inline = (folder / where / f"f{seed}.png" for where in ("forked", "inline"))
        assert forked.read_bytes() == inline.read_bytes()
    assert len({(folder / "forked" / f"f{seed}.png").read_bytes() for seed in range(3)}) == 3


def failure_raised(folder) -> None:
    """A failing figure raises FigureFailed with the child's traceback."""
    def broken(target):
        raise ValueError("no cells to draw")
    with Figures(workers=2) as figures:
        figures.submit(broken, Path(folder) / "x.png")
        assert len(figures.running) == 1
        try:
            figures.wait()
        except FigureFailed as err:
            assert "could not be drawn" in str(err) and "ValueError: no cells to draw" in str(err)
        else:
            raise AssertionError("no FigureFailed")


def children_stopped(folder) -> None:
    """An error elsewhere stops the children still drawing."""
    def slow(target):
        time.sleep(600)
    try:
        with Figures(workers=2) as figures:
            figures.submit(slow, Path(folder) / "x.png")
            (process, _), = figures.running
            raise KeyError("elsewhere")
    except KeyError:
        pass
    assert not process.is_alive() and figures.running == []
