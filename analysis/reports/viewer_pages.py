"""The report's section of interactive 3-D pages: one per showcase run.

``viewer_blocks(results_dir, out_dir, cells) -> list`` is called by ``flocksweep report`` with the cells
whose traces it shows ((name, rows) pairs, rows of ``runs.parquet``). For each it takes replicate 0 and
writes its page and still with :func:`analysis.viewer.hooks.showcase_page` (re-simulated and checked bit
for bit), and returns the report's blocks: a heading, a sentence and a :class:`~analysis.reports.document.Gallery`
of the stills, each linked to its page (pages of an earlier build are removed by the report, which
removes only files it wrote). A run that does not reproduce gets no page; the report says so.
"""
from __future__ import annotations

from pathlib import Path

from flocksweep.analysis.viewer.hooks import showcase_page
from flocksweep.analysis.viewer.resimulate import NotReproduced

from .document import Gallery, Heading, Para


def viewer_blocks(results_dir, out_dir, cells) -> list:
    """The report's blocks for the showcase runs' pages (see the module docstring)."""
    items, refused = [], []
    for name, rows in cells:
        row = rows.sort_values("replicate").iloc[0].to_dict()
        try:
            page, still = showcase_page(results_dir, out_dir, name, row)
        except NotReproduced as err:
            refused.append(f"{name}: {err}")
            continue
        items.append((still, f"{name} (run {row['run_id']})", page.relative_to(Path(out_dir)).as_posix()))
    blocks = [Heading("Watch the showcase runs in 3-D")]
    if items:
        blocks.append(Para("Click a still to open the run's interactive viewer page (beside this report, in "
                           "`viewer/`; works offline): play, pause, scrub, orbit, colour by boid, pattern, leader, "
                           "group or speed, with the frame's metrics. Each run was re-simulated from its seed and "
                           "matches the table bit for bit."))
        blocks.append(Gallery(items))
    for message in refused:
        blocks.append(Para(f"No viewer page for {message}"))
    return blocks
