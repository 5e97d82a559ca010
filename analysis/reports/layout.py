"""Figures a scientist can read at the size they are shown: the checks and the fixes, from matplotlib's
own layout (bounding boxes of the drawn artists), applied by :func:`analysis.reports.plotting.save` to
every figure we write (reports, traces, calibration plots, measured tracks).

A PNG is shown at most :data:`SHOWN_PX` pixels wide (the report's text column; a wider image is scaled
down by the browser), so a text's shown height is ``fontsize (pt) x dpi / 72 x min(1, SHOWN_PX / width
in pixels)``.

* ``problems(fig, dpi) -> list[str]``: what is wrong, each named: a text shown smaller than
  :data:`MIN_TEXT_PX`; two visible texts that overlap (tick labels rotated into each other, a caption on
  tick labels); a legend that covers plotted data (line vertices or scatter points of a 2-D axes inside
  its box) or, for a figure legend, the box of an axes. Empty: the figure is readable.
* ``raise_fonts(fig, dpi)``: every font up to the minimum; ``fix_overlaps(fig, dpi)`` (after a layout):
  tick labels that overlap thinned (every second, third, ... kept), a legend that covers data moved
  outside its axes (to the right). ``save`` calls them around its layout; ``problems`` is what the tests
  assert on.
"""
from __future__ import annotations

import itertools

import numpy as np

SHOWN_PX = 1000      # width a figure is shown at in the report (its column), at most
MIN_TEXT_PX = 9.0    # the smallest text height (pixels, as shown) a reader is asked to read


def shown_scale(fig, dpi: float) -> float:
    return min(1.0, SHOWN_PX / (fig.get_figwidth() * dpi))


def min_points(fig, dpi: float) -> float:
    """The smallest font size (points) shown at least MIN_TEXT_PX tall."""
    return MIN_TEXT_PX * 72.0 / (dpi * shown_scale(fig, dpi))


def _undrawn_tick_labels(fig) -> set:
    """Tick labels an axis keeps but does not draw: ticks outside its view, or labels switched off."""
    out = set()
    for ax in fig.axes:
        axes = [ax.xaxis, ax.yaxis] + ([ax.zaxis] if hasattr(ax, "zaxis") else [])
        for axis in axes:
            low, high = sorted(axis.get_view_interval())
            span = (high - low) * 1e-9
            for tick in axis.get_major_ticks() + axis.get_minor_ticks():
                outside = not (low - span <= tick.get_loc() <= high + span)
                for label, on in ((tick.label1, tick.label1.get_visible()), (tick.label2, tick.label2.get_visible())):
                    if outside or not on or not tick.get_visible():
                        out.add(id(label))
    return out


def _texts(fig) -> list:
    from matplotlib.text import Text

    out = []
    undrawn = _undrawn_tick_labels(fig)
    for text in fig.findobj(Text):
        if id(text) in undrawn:
            continue
        if not text.get_visible() or not text.get_text().strip() or text.get_alpha() == 0:
            continue
        if any(not parent.get_visible() for parent in _parents(text)):
            continue
        out.append(text)
    return out


def _parents(artist):
    parent = getattr(artist, "axes", None)
    return [parent] if parent is not None else []


def _renderer(fig, dpi):
    fig.set_dpi(dpi)
    fig.canvas.draw()
    return fig.canvas.get_renderer()


def _inside_figure(box, fig_box) -> bool:
    return box.width > 0 and box.height > 0 and box.overlaps(fig_box)


def _shrunk(box, by: float = 1.0):
    from matplotlib.transforms import Bbox

    return Bbox.from_extents(box.x0 + by, box.y0 + by, box.x1 - by, box.y1 - by)


def _legends(fig) -> list:
    found = list(fig.legends)
    for ax in fig.axes:
        if ax.get_legend() is not None and ax.get_legend().get_visible():
            found.append(ax.get_legend())
    return found


def _data_points(ax) -> np.ndarray:
    """Display coordinates of the 2-D axes' plotted points (line vertices, scatter offsets)."""
    points = []
    for line in ax.get_lines():
        xy = np.asarray(line.get_xydata(), float)
        if line.get_visible() and len(xy):
            points.append(ax.transData.transform(xy))
    for collection in ax.collections:
        offsets = np.asarray(collection.get_offsets(), float)
        if collection.get_visible() and offsets.ndim == 2 and len(offsets) > 1:
            points.append(ax.transData.transform(offsets))
    points = [p[np.isfinite(p).all(axis=1)] for p in points]
    return np.vstack(points) if points else np.empty((0, 2))


def _covered(legend, ax, renderer) -> int:
    if getattr(ax, "name", "") == "3d":
        return 0
    box = legend.get_window_extent(renderer)
    points = _data_points(ax)
    return int(((points[:, 0] > box.x0) & (points[:, 0] < box.x1) &
                (points[:, 1] > box.y0) & (points[:, 1] < box.y1)).sum())


def problems(fig, dpi: float) -> list[str]:
    """What makes ``fig`` hard to read at its shown size (see the module docstring)."""
    renderer = _renderer(fig, dpi)
    fig_box = fig.bbox
    found = []
    scale = shown_scale(fig, dpi)
    texts = [t for t in _texts(fig) if _inside_figure(t.get_window_extent(renderer), fig_box)]
    for text in texts:
        shown = text.get_fontsize() * dpi / 72.0 * scale
        if shown < MIN_TEXT_PX - 1e-6:
            found.append(f"text {text.get_text()!r} is shown {shown:.1f} px tall (< {MIN_TEXT_PX:g})")
    boxes = [(t, _shrunk(t.get_window_extent(renderer))) for t in texts]
    for (a, box_a), (b, box_b) in itertools.combinations(boxes, 2):
        if box_a.overlaps(box_b):
            found.append(f"texts {a.get_text()!r} and {b.get_text()!r} overlap")
    for legend in _legends(fig):
        box = _shrunk(legend.get_window_extent(renderer))
        if legend in fig.legends:
            for ax in fig.axes:
                if ax.get_visible() and ax.has_data() and box.overlaps(_shrunk(ax.get_window_extent(renderer), 2)):
                    found.append(f"the figure legend covers the axes {ax.get_title()!r}")
        else:
            covered = _covered(legend, legend.axes, renderer)
            if covered:
                found.append(f"the legend of axes {legend.axes.get_title()!r} covers {covered} data points")
    return found


def raise_fonts(fig, dpi: float) -> None:
    smallest = min_points(fig, dpi)
    for text in _texts(fig):
        if text.get_fontsize() < smallest:
            text.set_fontsize(smallest)
    for legend in _legends(fig):
        title = legend.get_title()
        if title.get_text() and title.get_fontsize() < smallest:
            title.set_fontsize(smallest)


def _thin(labels, renderer) -> None:
    """Hide every other, every third, ... tick label until the shown ones do not overlap."""
    labels = [t for t in labels if t.get_visible() and t.get_text().strip()]
    for keep in range(1, len(labels) + 1):
        shown = labels[::keep]
        boxes = [_shrunk(t.get_window_extent(renderer)) for t in shown]
        if not any(a.overlaps(b) for a, b in zip(boxes, boxes[1:])):
            for k, text in enumerate(labels):
                text.set_visible(k % keep == 0)
            return


def fix_overlaps(fig, dpi: float) -> None:
    """Thin overlapping tick labels and move legends that cover data outside their axes."""
    from matplotlib.ticker import MaxNLocator

    renderer = _renderer(fig, dpi)
    for ax in fig.axes:
        if not ax.get_visible():
            continue
        if getattr(ax, "name", "") == "3d":   # three tick rows meet at the corners: few ticks, none thinned
            for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
                axis.set_major_locator(MaxNLocator(3))
            continue
        _thin(ax.get_xticklabels(), renderer)
        _thin(ax.get_yticklabels(), renderer)
    for ax in fig.axes:
        legend = ax.get_legend()
        if legend is not None and legend.get_visible() and _covered(legend, ax, renderer):
            legend.set_loc("upper left")
            legend.set_bbox_to_anchor((1.02, 1.0), transform=ax.transAxes)

