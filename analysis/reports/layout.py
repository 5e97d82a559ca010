"""Figures a scientist can read at the size they are shown: the checks and the fixes, from matplotlib's
own layout (bounding boxes of the drawn artists), applied by :func:`analysis.reports.plotting.save` to
every figure we write (reports, traces, calibration plots, measured tracks).

A PNG is shown at most :data:`SHOWN_PX` pixels wide (the report's text column; a wider image is scaled
down by the browser), so a text's shown height is ``fontsize (pt) x dpi / 72 x min(1, SHOWN_PX / width
in pixels)``.

* ``problems(fig, dpi) -> list[str]``: what is wrong, each named: a text shown smaller than
  :data:`MIN_TEXT_PX`; two visible texts that overlap (compared as the rotated rectangles they are, so
  labels rotated side by side are not taken for overlapping ones); a legend that covers plotted data
  (line vertices or scatter points of a 2-D axes inside its box) or, for a figure legend, the box of an
  axes; an annotation (a text placed in an axes) that covers plotted points; a tick label of a
  categorical axis (labels that are words, not numbers) that is not drawn; a numeric axis whose lowest
  or highest labelled tick lost its label (an unlabelled extreme). Empty: the figure is readable.
* ``raise_fonts(fig, dpi)``: every font up to the minimum; ``fix_overlaps(fig, dpi)`` (after a layout):
  numeric tick labels that overlap thinned (every second, third, ... kept, always with both ends), the
  words of a categorical axis turned upright rather than dropped, a legend that covers data moved
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
    """The figure laid out and drawn at ``dpi`` as it will be saved, without painting a pixel (every
    text, tick and layout engine placed, so their boxes can be measured): painting is a fifth of a draw
    and nothing here looks at pixels."""
    fig.set_dpi(dpi)
    fig.draw_without_rendering()
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


def _corners(text, renderer) -> np.ndarray:
    """The four corners (display coordinates) of a text's rectangle, rotated as it is drawn, shrunk by a
    pixel (texts that only touch do not overlap). The box matplotlib reports for a rotated text is the
    upright box around it, whose centre is the rectangle's centre; the rectangle's own width and height
    are those of the same text upright."""
    box = text.get_window_extent(renderer)
    angle = float(text.get_rotation()) % 180.0
    if min(angle % 90.0, 90.0 - angle % 90.0) < 0.5:   # upright or at a right angle: the box is the text
        return np.array([[box.x0 + 1, box.y0 + 1], [box.x1 - 1, box.y0 + 1], [box.x1 - 1, box.y1 - 1],
                         [box.x0 + 1, box.y1 - 1]])
    text.set_rotation(0)
    try:
        upright = text.get_window_extent(renderer)
    finally:
        text.set_rotation(angle)
    half = np.array([upright.width / 2 - 1, upright.height / 2 - 1]).clip(0)
    theta = np.radians(angle)
    rotation = np.array([[np.cos(theta), -np.sin(theta)], [np.sin(theta), np.cos(theta)]])
    unit = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], dtype=float)
    return (unit * half) @ rotation.T + np.array([(box.x0 + box.x1) / 2, (box.y0 + box.y1) / 2])


def _polygons_overlap(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether two convex polygons (corners in order) overlap (separating axis test)."""
    for poly in (a, b):
        for k in range(len(poly)):
            edge = poly[(k + 1) % len(poly)] - poly[k]
            normal = np.array([-edge[1], edge[0]])
            pa, pb = a @ normal, b @ normal
            if pa.max() <= pb.min() or pb.max() <= pa.min():
                return False
    return True


class _Shapes:
    """Each text's box and rotated corners, measured once (a text's layout is costly to measure)."""

    def __init__(self, renderer):
        self.renderer, self.boxes, self.corners = renderer, {}, {}

    def box(self, text):
        if id(text) not in self.boxes:
            self.boxes[id(text)] = _shrunk(text.get_window_extent(self.renderer))
        return self.boxes[id(text)]

    def corner(self, text):
        if id(text) not in self.corners:
            self.corners[id(text)] = _corners(text, self.renderer)
        return self.corners[id(text)]


def _collide(a, b, renderer, shapes: _Shapes | None = None) -> bool:
    shapes = shapes or _Shapes(renderer)
    if not shapes.box(a).overlaps(shapes.box(b)):
        return False
    return _polygons_overlap(shapes.corner(a), shapes.corner(b))


def _is_number_text(text: str) -> bool:
    try:
        float(text.replace("\N{MINUS SIGN}", "-").replace("−", "-").replace(",", ""))
    except ValueError:
        return False
    return True


def _categorical(axis) -> bool:
    """An axis whose tick labels are words (a factor's levels, metric or factor names), not numbers."""
    words = [label.get_text().strip() for _, label in _labelled_ticks(axis)]
    return bool(words) and not all(_is_number_text(w) for w in words)


def _labelled_ticks(axis) -> list:
    """(position, label) of the major ticks inside the view whose label has text."""
    low, high = sorted(axis.get_view_interval())
    span = (high - low) * 1e-9
    out = []
    for tick in axis.get_major_ticks():
        if low - span <= tick.get_loc() <= high + span and tick.get_visible():
            label = tick.label1 if tick.label1.get_text().strip() else tick.label2
            if label.get_text().strip():
                out.append((tick.get_loc(), label))
    return sorted(out, key=lambda item: item[0])


def _axis_problems(ax) -> list[str]:
    """Categorical tick labels not drawn; numeric axes whose extreme labelled tick is not drawn."""
    found = []
    if getattr(ax, "name", "") == "3d" or not ax.get_visible():
        return found
    name = ax.get_title() or ax.get_xlabel() or ax.get_ylabel() or "untitled"
    for which, axis in (("x", ax.xaxis), ("y", ax.yaxis)):
        ticks = _labelled_ticks(axis)
        if not ticks:
            continue
        hidden = [label.get_text() for _, label in ticks if not label.get_visible()]
        if len(hidden) == len(ticks):   # switched off (an inner panel of shared axes): nothing dropped
            continue
        if _categorical(axis):
            if hidden:
                found.append(f"the {which} axis of {name!r} drops the tick label(s) {hidden} of a categorical axis")
        elif any(label.get_visible() for _, label in ticks):
            for end, (_, label) in (("lowest", ticks[0]), ("highest", ticks[-1])):
                if not label.get_visible():
                    found.append(f"the {which} axis of {name!r} leaves its {end} tick ({label.get_text()}) "
                                 "unlabelled")
    return found


def _annotations(ax) -> list:
    """Texts placed inside a 2-D axes (notes, value labels), not its title or tick labels."""
    if getattr(ax, "name", "") == "3d" or not ax.get_visible():
        return []
    return [t for t in ax.texts if t.get_visible() and t.get_text().strip()]


def _covered_by_text(text, points: np.ndarray, renderer) -> int:
    """How many of an axes' plotted ``points`` lie under ``text`` (its box, or its background patch)."""
    patch = text.get_bbox_patch()
    box = patch.get_window_extent(renderer) if patch is not None else text.get_window_extent(renderer)
    box = _shrunk(box)
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
    shapes = _Shapes(renderer)
    for a, b in itertools.combinations(texts, 2):
        if _collide(a, b, renderer, shapes):
            found.append(f"texts {a.get_text()!r} and {b.get_text()!r} overlap")
    for ax in fig.axes:
        found += _axis_problems(ax)
        annotations = _annotations(ax)
        points = _data_points(ax) if annotations else None
        for text in annotations:
            covered = _covered_by_text(text, points, renderer)
            if covered:
                found.append(f"the annotation {text.get_text()[:40]!r} covers {covered} plotted points")
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
    for ax in fig.axes:   # tick labels are made again at each draw, from the axis's label size
        axes = [ax.xaxis, ax.yaxis] + ([ax.zaxis] if hasattr(ax, "zaxis") else [])
        for axis in axes:
            for which, ticks in (("major", axis.get_major_ticks()), ("minor", axis.get_minor_ticks())):
                if ticks and ticks[0].label1.get_fontsize() < smallest:
                    axis.set_tick_params(which=which, labelsize=smallest)
    for text in _texts(fig):
        if text.get_fontsize() < smallest:
            text.set_fontsize(smallest)
    for legend in _legends(fig):
        title = legend.get_title()
        if title.get_text() and title.get_fontsize() < smallest:
            title.set_fontsize(smallest)


def _thin(labels, renderer) -> None:
    """Hide every other, every third, ... tick label until the shown ones do not overlap, keeping the
    first and the last (an extreme is never left unlabelled; the label next to it gives way)."""
    labels = [t for t in labels if t.get_visible() and t.get_text().strip()]
    if len(labels) < 3:
        return
    shapes = _Shapes(renderer)
    for keep in range(1, len(labels)):
        shown = labels[::keep]
        if shown[-1] is not labels[-1]:
            last_meets = _collide(shown[-1], labels[-1], renderer, shapes)
            shown = shown[:-1] + [labels[-1]] if last_meets else shown + [labels[-1]]
        if not any(_collide(a, b, renderer, shapes) for a, b in zip(shown, shown[1:])):
            kept = {id(t) for t in shown}
            for text in labels:
                text.set_visible(id(text) in kept)
            return


def _upright(labels, renderer) -> None:
    """Turn the words of a categorical axis upright (90 degrees) when they overlap: never drop one."""
    labels = [t for t in labels if t.get_visible() and t.get_text().strip()]
    if any(_collide(a, b, renderer) for a, b in zip(labels, labels[1:])):
        for text in labels:
            text.set_rotation(90)
            text.set_rotation_mode("default")
            text.set_horizontalalignment("center")


def fix_overlaps(fig, dpi: float) -> None:
    """Thin overlapping numeric tick labels, turn overlapping words upright, and move legends that cover
    data outside their axes."""
    from matplotlib.ticker import MaxNLocator

    renderer = _renderer(fig, dpi)
    for ax in fig.axes:
        if not ax.get_visible():
            continue
        if getattr(ax, "name", "") == "3d":   # three tick rows meet at the corners: few ticks, none thinned
            for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
                axis.set_major_locator(MaxNLocator(3))
            continue
        for axis, labels in ((ax.xaxis, ax.get_xticklabels()), (ax.yaxis, ax.get_yticklabels())):
            if _categorical(axis):
                if axis is ax.xaxis:
                    _upright(labels, renderer)
            else:
                _thin(labels, renderer)
    for ax in fig.axes:
        legend = ax.get_legend()
        if legend is not None and legend.get_visible() and _covered(legend, ax, renderer):
            legend.set_loc("upper left")
            legend.set_bbox_to_anchor((1.02, 1.0), transform=ax.transAxes)
