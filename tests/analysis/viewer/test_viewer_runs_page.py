"""A viewer page of several runs (analysis.viewer.view_runs, flocksweep view RESULTS --run ID ID ...):
each run's data in its own block marked with its run id and menu label, the scripts inlined once, the
size cap held by the whole page; a page of one run is unchanged. The browser side (the fragment picks
the run, the menu switches and writes the fragment) is in test_viewer_browser.py."""
from __future__ import annotations

import json
import re
from dataclasses import replace

import pytest

from flocksweep.analysis.viewer import view, view_runs
from flocksweep.analysis.viewer.page import overhead_bytes
from viewer_data import milling_track

IDS = ["aaaa11112222", "bbbb33334444", "cccc55556666"]


def three_runs(**kwargs):
    base = milling_track(with_scene=False, **kwargs)
    return [replace(base, params={**base.params, "omega": omega}, info={"run id": run, "replicate": 0, "seed": k},
                    title=f"run {run}") for k, (run, omega) in enumerate(zip(IDS, (0.5, 1.0, 2.0)))]


def blocks(html):
    return re.findall(r'<script type="application/json" id="(flock-data[-0-9]*)" data-run="([^"]+)" '
                      r'data-label="([^"]+)">(.*?)</script>', html, re.S)


def test_each_run_has_its_own_block_with_its_id_and_a_label_saying_what_differs():
    page = view_runs(three_runs(), IDS, max_mb=None)
    found = blocks(page.html)
    assert [b[1] for b in found] == IDS and found[0][0] == "flock-data"
    assert [b[2] for b in found] == [f"{run}: omega={w}, replicate 0" for run, w in zip(IDS, (0.5, 1.0, 2.0))]
    assert [json.loads(b[3])["title"] for b in found] == [f"run {r}" for r in IDS]
    assert page.html.count('id="src-three-core"') == 1 and page.runs == 3
    assert 'id="run-row" hidden' in page.html


def test_a_page_of_one_run_is_as_before():
    html = view(three_runs()[0], max_mb=None).html
    assert 'data-run="' not in html and len(re.findall(r'id="flock-data">', html)) == 1


def test_the_size_cap_holds_for_the_whole_page():
    runs = three_runs(n=120, frames=401, dt=1 / 60)
    full = view_runs(runs, IDS, max_mb=None)
    cap = (full.size_bytes + overhead_bytes()) / 2 / 1e6   # the scripts and about half the frames of each run
    capped = view_runs(runs, IDS, max_mb=cap)
    assert capped.size_bytes <= cap * 1e6 < full.size_bytes
    strides = [json.loads(b[3])["encoding"]["stride"] for b in blocks(capped.html)]
    assert min(strides) >= 2


def test_run_ids_must_be_distinct_and_one_per_run():
    with pytest.raises(ValueError, match="one distinct id for each"):
        view_runs(three_runs(), [IDS[0], IDS[0], IDS[1]])
    with pytest.raises(ValueError, match="one distinct id for each"):
        view_runs(three_runs()[:1], IDS[:1])
