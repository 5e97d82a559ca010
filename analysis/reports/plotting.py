"""matplotlib plumbing of every figure we draw (reports, traces, calibration).

``pyplot()`` selects the Agg backend and returns ``matplotlib.pyplot`` (importing this module does not
import matplotlib). ``save(fig, path, tight=True)`` lays the figure out (tight layout unless it has a
layout engine or ``tight`` is False), writes it atomically (:func:`sweeps.files.atomic_path`; the
format follows the extension: ``.png`` at up to 150 dpi with the longest side at most 3600 pixels,
``.svg`` vector, anything else matplotlib knows), closes it and returns the ``Path``; given a list of
paths it writes the one laid-out figure to each (a PNG and its SVG copy) and returns the first. Before writing it
makes the figure readable at the size it is shown (:mod:`analysis.reports.layout`: fonts raised to the
minimum, overlapping tick labels thinned, legends that cover data moved out).
"""
from __future__ import annotations

import warnings
from pathlib import Path

from flocksweep.sweeps.files import atomic_path

from .layout import fix_overlaps, raise_fonts

PNG_DPI = 150
MAX_PIXELS = 3600          # longest side of a PNG; large figures get a lower dpi


def pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save(fig, path, tight: bool = True) -> Path:
    """Lay out, save by extension (atomically), close; see the module docstring. ``path`` may be a list
    of paths: the figure, laid out and checked once, is written to each in turn (a PNG and its SVG copy
    without drawing the figure twice); the first is returned."""
    paths = [Path(p) for p in path] if isinstance(path, (list, tuple)) else [Path(path)]
    if not paths:
        raise ValueError("save: no path to write the figure to")
    dpi = PNG_DPI
    try:
        constrained = fig.get_layout_engine() is not None
        width, height = fig.get_size_inches()
        dpi = min(PNG_DPI, MAX_PIXELS / max(width, height))
        raise_fonts(fig, dpi)            # readable at the size it is shown (analysis.reports.layout)
        _layout(fig, tight and not constrained)
        fix_overlaps(fig, dpi)
        _layout(fig, tight and not constrained)
        for one in paths:
            with atomic_path(one) as tmp:   # a tight box: nothing cut off (3-D axis labels escape constrained layout)
                fig.savefig(tmp, dpi=dpi, bbox_inches="tight", pad_inches=0.05)
    finally:
        _finish(fig, dpi)
    return paths[0]


def _layout(fig, tight: bool) -> None:
    if tight:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)   # 3-D axes: "not compatible with tight_layout"
            fig.tight_layout()


def _finish(fig, dpi: float) -> None:
    """Close the saved figure (the layout tests look at it here first)."""
    pyplot().close(fig)
