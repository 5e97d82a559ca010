"""matplotlib plumbing of every figure we draw (reports, traces, calibration).

``pyplot()`` selects the Agg backend and returns ``matplotlib.pyplot`` (importing this module does not
import matplotlib). ``save(fig, path, tight=True)`` lays the figure out (tight layout unless it has a
layout engine or ``tight`` is False), writes it atomically (:func:`sweeps.files.atomic_path`; the
format follows the extension: ``.png`` at up to 150 dpi with the longest side at most 3600 pixels,
``.svg`` vector, anything else matplotlib knows), closes it and returns the ``Path``.
"""
from __future__ import annotations

import warnings
from pathlib import Path

from sweeps.files import atomic_path

PNG_DPI = 150
MAX_PIXELS = 3600          # longest side of a PNG; large figures get a lower dpi


def pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save(fig, path, tight: bool = True) -> Path:
    """Lay out, save by extension (atomically), close; see the module docstring."""
    plt = pyplot()
    path = Path(path)
    try:
        constrained = fig.get_layout_engine() is not None
        if tight and not constrained:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", UserWarning)   # 3-D axes: "not compatible with tight_layout"
                fig.tight_layout()
        width, height = fig.get_size_inches()
        dpi = min(PNG_DPI, MAX_PIXELS / max(width, height))
        with atomic_path(path) as tmp:
            # constrained layout already fits the canvas; a tight bbox would cost a second full draw
            fig.savefig(tmp, dpi=dpi, bbox_inches=None if constrained else "tight", pad_inches=0.05)
    finally:
        plt.close(fig)
    return path
