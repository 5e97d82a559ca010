"""analysis.reports.drawing: figures drawn in forked children are the files drawn inline, byte for byte; a
failing figure stops the report with the child's traceback; an error elsewhere stops the children; with JAX
loaded (or one worker) figures are drawn inline. The forking checks run in a fresh interpreter
(tests/figure_children.py): this process may have loaded JAX."""
from __future__ import annotations

import os
import subprocess
import sys

import pytest

from flocksweep.analysis.reports import drawing
from flocksweep.analysis.reports.drawing import Figures
from paths import ROOT

linux = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="figures fork on Linux only")


def fresh(check: str, folder) -> None:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT / "tests"), os.environ.get("PYTHONPATH", "")])}
    done = subprocess.run([sys.executable, "-c", f"import figure_children as f; f.{check}({str(folder)!r})"],
                          env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    assert "RuntimeWarning" not in done.stderr, done.stderr


@linux
@pytest.mark.parametrize("check", ["same_files", "failure_raised", "children_stopped"])
def test_figures_in_forked_children(check, tmp_path):
    fresh(check, tmp_path)


def test_with_jax_loaded_or_one_worker_figures_are_drawn_inline(tmp_path, monkeypatch):
    from figure_children import line_figure

    monkeypatch.setitem(sys.modules, "jax", sys.modules.get("jax", object()))
    assert not drawing.forking_is_safe()
    with Figures(workers=2) as figures:
        figures.submit(line_figure(1), tmp_path / "a.png")
        assert figures.running == [] and (tmp_path / "a.png").is_file()
    monkeypatch.delitem(sys.modules, "jax")
    monkeypatch.setattr(drawing, "forking_is_safe", lambda: True)
    with Figures(workers=1) as figures:
        figures.submit(line_figure(2), tmp_path / "b.png")
        assert figures.running == [] and (tmp_path / "b.png").is_file()
