"""analysis.reports.drawing: figures drawn in forked children are the files drawn inline, byte for byte; a
failing figure stops the report with the child's traceback; an error elsewhere stops the children."""
from __future__ import annotations

import sys

import numpy as np
import pytest

from flocksweep.analysis.reports import drawing, plotting
from flocksweep.analysis.reports.drawing import FigureFailed, Figures

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="figures fork on Linux only")


def line_figure(seed: int):
    def draw(target):
        plt = plotting.pyplot()
        fig, ax = plt.subplots(figsize=(3, 2))
        ax.plot(np.random.default_rng(seed).normal(size=50), label=f"seed {seed}")
        ax.legend(loc="upper left")
        plotting.save(fig, target)
    return draw


def test_figures_drawn_in_children_are_the_files_drawn_inline(tmp_path, monkeypatch):
    monkeypatch.setattr(drawing, "forking_is_safe", lambda: True)    # (JAX may be loaded by other tests)
    (tmp_path / "forked").mkdir()
    (tmp_path / "inline").mkdir()
    with Figures(workers=2) as figures:
        for seed in range(3):
            figures.submit(line_figure(seed), tmp_path / "forked" / f"f{seed}.png")
        assert len(figures.running) == 2                     # at most two at a time, the rest waited for
        figures.wait()
    with Figures(workers=1) as figures:
        for seed in range(3):
            figures.submit(line_figure(seed), tmp_path / "inline" / f"f{seed}.png")
    for seed in range(3):
        forked, inline = (tmp_path / where / f"f{seed}.png" for where in ("forked", "inline"))
        assert forked.read_bytes() == inline.read_bytes()
    assert len({(tmp_path / "forked" / f"f{seed}.png").read_bytes() for seed in range(3)}) == 3


def test_a_failing_figure_raises_with_the_childs_traceback(tmp_path, monkeypatch):
    monkeypatch.setattr(drawing, "forking_is_safe", lambda: True)

    def broken(target):
        raise ValueError("no cells to draw")
    with Figures(workers=2) as figures:
        figures.submit(broken, tmp_path / "x.png")
        with pytest.raises(FigureFailed, match=r"(?s)could not be drawn.*ValueError: no cells to draw"):
            figures.wait()


def test_an_error_elsewhere_stops_the_children(tmp_path, monkeypatch):
    monkeypatch.setattr(drawing, "forking_is_safe", lambda: True)
    import time

    def slow(target):
        time.sleep(600)
    with pytest.raises(KeyError):
        with Figures(workers=2) as figures:
            figures.submit(slow, tmp_path / "x.png")
            (process, _), = figures.running
            raise KeyError("elsewhere")
    assert not process.is_alive() and figures.running == []


def test_with_jax_loaded_or_one_worker_figures_are_drawn_inline(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "jax", sys.modules.get("jax", object()))
    assert not drawing.forking_is_safe()
    with Figures(workers=2) as figures:
        figures.submit(line_figure(1), tmp_path / "a.png")
        assert figures.running == [] and (tmp_path / "a.png").is_file()
