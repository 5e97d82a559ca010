"""GIF/MP4 frames a reader can read (analysis.viewer.animation): drawn frames checked from matplotlib's
layout like the report figures (analysis.reports.layout: text at least 9 px, no overlapping texts, the
caption on its own strip), and the view box keeps every boid of the largest group inside the axes in
every frame."""
from __future__ import annotations

import numpy as np

from flocksweep.analysis.reports import layout
from flocksweep.analysis.viewer.animation import _Drawing, source_frames
from viewer_data import milling_track


def test_every_frame_is_readable_and_keeps_the_flock_in_view():
    track = milling_track(with_scene=True)
    shown = source_frames(track, 10.0, 1.0)
    drawing = _Drawing(track, "group", shown, 1.0, (640, 480), 100, None, False, 10.0)
    try:
        for k, f in list(enumerate(shown))[:: max(1, len(shown) // 6)]:
            drawing.draw(k, int(f))
            assert layout.problems(drawing.fig, 100) == [], (k, layout.problems(drawing.fig, 100))
            largest = drawing.obs["labels"][int(f)] == 0
            world = track.pos[int(f)][largest][:, [0, 2, 1]]
            limits = np.array([drawing.ax.get_xlim(), drawing.ax.get_ylim(), drawing.ax.get_zlim()])
            assert ((world >= limits[:, 0]) & (world <= limits[:, 1])).all(), k
    finally:
        drawing.close()
