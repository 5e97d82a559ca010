"""The viewer page's data and HTML: streams decode to what was encoded (within the stated quantum),
scene objects and agents are validated with clear messages, the page inlines everything (no external
URL in any src or href), the frame stride keeps a page under its size cap, and the Jupyter display."""
from __future__ import annotations

import json
import re
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest

from flocksweep.analysis.viewer import view
from flocksweep.analysis.viewer.encode import (check_agents, check_scene, decode_stream, heading_stream, label_stream,
                                    position_stream, speed_stream, stream)
from flocksweep.analysis.viewer.observables import frame_observables
from flocksweep.analysis.viewer.palette import AGENT_COLOURS
from flocksweep.analysis.viewer.page import build_page, choose_stride, estimate_bytes
from flocksweep.analysis.viewer.track import Track, as_track, from_arrays, from_npz
from viewer_data import milling_arrays, milling_track
from paths import ROOT



def page_json(html: str) -> dict:
    match = re.search(r'<script type="application/json" id="flock-data">(.*?)</script>', html, re.S)
    return json.loads(match.group(1))


class Attributes(HTMLParser):
    def __init__(self):
        super().__init__()
        self.urls, self.scripts = [], []

    def handle_starttag(self, tag, attrs):
        for name, value in attrs:
            if name in ("src", "href", "action", "srcset", "poster", "data"):
                self.urls.append((tag, name, value))
        if tag in ("script", "link", "iframe", "img"):
            self.scripts.append((tag, dict(attrs)))


def test_position_stream_round_trips_within_half_a_quantum():
    rng = np.random.default_rng(0)
    pos = np.cumsum(rng.normal(0, 0.2, (50, 7, 3)), axis=0) + np.array([100.0, -40.0, 3.0])
    lo, hi = pos.reshape(-1, 3).min(axis=0), pos.reshape(-1, 3).max(axis=0)
    s = position_stream(pos, lo, hi)
    back = decode_stream(s)
    quantum = np.asarray(s["scale"])
    assert back.shape == pos.shape
    assert np.all(np.abs(back - pos) <= quantum / 2 + 1e-9)
    assert s["delta"] and s["dtype"] == "u16"


def test_delta_coding_wraps_around():
    q = np.array([[65535, 0], [0, 65535], [1, 1], [65535, 2]], dtype=np.uint16)
    np.testing.assert_array_equal(decode_stream(stream(q, "u16")), q)
    h = np.array([[127, -127, 0], [-127, 127, 5]], dtype=np.int8)
    np.testing.assert_array_equal(decode_stream(stream(h, "i8")), h)


def test_heading_speed_labels_and_bits_round_trip():
    rng = np.random.default_rng(1)
    vel = rng.normal(0, 3, (20, 9, 3))
    vel[4, 2] = 0.0  # a stopped boid has no heading
    moving = np.linalg.norm(vel, axis=-1) > 0
    unit = vel / np.where(moving, np.linalg.norm(vel, axis=-1), 1.0)[..., None]
    back = decode_stream(heading_stream(vel))
    assert np.abs(back[moving] - unit[moving]).max() <= 0.5 / 127 + 1e-12
    assert np.all(back[4, 2] == 0)
    speed = np.linalg.norm(vel, axis=-1)
    assert np.abs(decode_stream(speed_stream(speed)) - speed).max() <= speed.max() / 255 / 2 + 1e-12
    labels = rng.integers(0, 300, (20, 9))
    np.testing.assert_array_equal(decode_stream(label_stream(labels)), labels)
    assert label_stream(labels % 200)["dtype"] == "u8" and label_stream(labels)["dtype"] == "u16"
    bits = rng.random((20, 9)) < 0.3
    np.testing.assert_array_equal(decode_stream(stream(bits, "bits")), bits)


def test_scene_objects_are_validated_with_the_key_named():
    good = check_scene([{"type": "sphere", "center": [0, 1, 2], "radius": 3},
                        {"type": "box", "center": [0, 0, 0], "size": [1, 2, 3], "rotation": [0, 0, 0, 2]},
                        {"type": "cylinder", "a": [0, 0, 0], "b": [0, 1, 0], "radius": 1, "caps": "round"},
                        {"type": "plane", "point": [0, 0, 0], "normal": [0, 2, 0]}])
    assert [o["type"] for o in good] == ["sphere", "box", "cylinder", "plane"]
    assert good[1]["rotation"] == [0, 0, 0, 1.0]  # normalised
    assert good[3]["size"] == 100.0 and good[0]["opacity"] == 0.35
    bad = [({"type": "cone"}, "scene[0].type"),
           ({"type": "sphere", "center": [0, 0], "radius": 1}, "scene[0].center"),
           ({"type": "sphere", "center": [0, 0, 0], "radius": -1}, "scene[0].radius"),
           ({"type": "plane", "point": [0, 0, 0], "normal": [0, 0, 0]}, "scene[0].normal"),
           ({"type": "cylinder", "a": [1, 1, 1], "b": [1, 1, 1], "radius": 1}, "two distinct ends"),
           ({"type": "cylinder", "a": [0, 0, 0], "b": [1, 1, 1], "radius": 1, "caps": "domed"}, "scene[0].caps"),
           ({"type": "sphere", "center": [0, 0, 0], "radius": 1, "color": "red"}, "scene[0].color"),
           ({"type": "box", "center": [0, 0, 0], "size": [1, 0, 1]}, "scene[0].size")]
    for obj, message in bad:
        with pytest.raises(ValueError, match=re.escape(message)):
            check_scene([obj])


def test_agents_need_a_track_on_the_flock_frames():
    arrays = milling_arrays(frames=11)
    out = check_agents([{"kind": "predator", "pos": arrays["pos"][:, 0]}], 11)
    assert out[0]["pos"].shape == (11, 1, 3) and out[0]["color"] == AGENT_COLOURS["predator"] and out[0]["size"] == 2.0
    with pytest.raises(ValueError, match=r"agents\[0\]\.pos"):
        check_agents([{"kind": "prey", "pos": arrays["pos"][:5]}], 11)
    with pytest.raises(ValueError, match=r"agents\[0\]"):
        check_agents([np.zeros((11, 3))], 11)


def test_track_rejects_bad_arrays():
    arrays = milling_arrays(frames=5, n=4)
    with pytest.raises(ValueError, match="vel"):
        from_arrays(arrays["times"], arrays["pos"], arrays["vel"][:, :3])
    with pytest.raises(ValueError, match="times must increase"):
        from_arrays(arrays["times"][::-1].copy(), arrays["pos"])
    bad = arrays["pos"].copy()
    bad[2, 1, 0] = np.nan
    with pytest.raises(ValueError, match="finite"):
        from_arrays(arrays["times"], bad)
    with pytest.raises(TypeError, match="cannot view a int"):
        as_track(3)


def test_page_is_self_contained_and_carries_the_data():
    page = view(milling_track(), color_by="group")
    html = page.html
    parsed = Attributes()
    parsed.feed(html)
    assert parsed.urls == []  # no src, href, ... at all: every script is inline
    assert all(tag == "script" and "src" not in attrs for tag, attrs in parsed.scripts)
    assert not re.search(r"""(src|href)\s*=\s*["']?\s*(https?:)?//""", html)
    assert "<link" not in html and "@import" not in html
    data = page_json(html)
    assert data["format"] == "flocksweep-viewer/1"
    assert data["n"] == 30 and data["frames"] == 91 and data["defaults"]["color_by"] == "group"
    assert len(data["scene"]) == 5 and [a["kind"] for a in data["agents"]] == ["predator", "prey"]
    track = milling_track()
    np.testing.assert_allclose(decode_stream(data["pos"]), track.pos, atol=max(data["encoding"]["position_quantum"]))
    np.testing.assert_array_equal(decode_stream(data["leader"]), track.leader)
    assert data["pattern_colours"] == {"58": "#008000", "197": "#0000ff"}  # Holland's Table 1 colours


def test_metrics_in_the_page_are_the_sweep_metrics():
    """The panel's numbers follow the definitions of observables.metrics (to rounding), on a flock that
    splits into several groups."""
    from flocksweep.observables.metrics import frame_metrics

    rng = np.random.default_rng(4)
    pos = np.cumsum(rng.normal(0, 0.4, (40, 25, 3)), axis=0) + rng.normal(0, 6, (1, 25, 3))
    track = from_arrays(np.arange(40) * 0.1, pos, group_radius=3.0)
    series = frame_metrics(track.pos, track.vel, None, None, None, 3.0)
    observed = frame_observables(track)
    assert series["n_groups"].max() >= 3
    for name in ("polarization", "n_groups", "nn_distance", "cohesion"):
        np.testing.assert_allclose(observed["metrics"][name], series[name], rtol=1e-12, atol=1e-12)
    data = page_json(view(track).html)
    np.testing.assert_allclose(data["metrics"]["cohesion"], series["cohesion"], atol=5e-6)  # JSON: 5 decimals
    assert (observed["labels"] == 0).sum(axis=1).tolist() == np.rint(series["cohesion"] * 25).astype(int).tolist()
    # a ring of 30 boids circling (omega 1): headings are spread round the circle, polarization is low
    assert max(page_json(view(milling_track(with_scene=False)).html)["metrics"]["polarization"]) < 0.35


def test_title_cannot_break_out_of_its_script_block():
    track = milling_track(with_scene=False, frames=3)
    html = view(as_track(track, title="</script><script>alert(1)</script>")).html
    assert "</script><script>alert" not in html
    block = re.search(r'id="flock-data">(.*?)</script>', html, re.S).group(1)
    assert "<" not in block
    assert page_json(html)["title"] == "</script><script>alert(1)</script>"


def test_stride_keeps_the_page_under_its_cap():
    track = milling_track(with_scene=False, n=200, frames=601, dt=1 / 60)
    full = build_page(track, max_mb=None)
    assert full.stride == 1
    cap = (full.size_bytes + 1_000_000) / 2 / 1e6  # about half the page's frames fit
    capped = build_page(track, max_mb=cap)
    assert capped.size_bytes <= cap * 1e6
    assert capped.stride >= 2
    assert capped.frames == len(range(0, 601, capped.stride))
    assert estimate_bytes(track, 1) > estimate_bytes(track, 4)
    assert choose_stride(track, 1e9) == 1
    with pytest.raises(ValueError, match="less than the page's scripts alone"):
        build_page(track, max_mb=0.1)
    assert build_page(track, stride=7, max_mb=0.9).stride == 7  # an explicit stride wins


def test_jupyter_display_and_repr(tmp_path):
    page = view(milling_track(with_scene=False, frames=5), tmp_path / "p.html")
    shown = page._repr_html_()
    assert shown.startswith("<iframe") and "srcdoc=" in shown and "&lt;!DOCTYPE html&gt;" in shown
    assert (tmp_path / "p.html").read_text() == page.html
    assert "5 frames" in repr(page) and str(tmp_path / "p.html") in repr(page)


def test_trajectory_npz_with_params_json_is_shown_with_its_preset(tmp_path):
    from flocksweep.simcore import load_preset
    from flocksweep.sweeps.single import run_single

    preset = load_preset(ROOT / "configs/models/holland.toml", ["init.n=8", "run.duration=0.5"])
    run_single(preset, 4, tmp_path / "run", record_every=1)
    track = from_npz(tmp_path / "run" / "trajectory.npz")
    assert track.n == 8 and track.frames == 31
    assert track.params["perception.field_deg"] == 120.0 and track.group_radius == 20.0
    assert track.info["seed"] == 4
    bare = tmp_path / "bare.npz"
    np.savez(bare, times=track.times, pos=track.pos, vel=track.vel)
    data = page_json(view(bare).html)
    assert "assumed" in data["info"]["group radius"]
    np.savez(tmp_path / "wrong.npz", t=track.times)
    with pytest.raises(ValueError, match="missing times, pos, vel"):
        from_npz(tmp_path / "wrong.npz")


def test_wrapped_world_breaks_trails_and_frames_the_world():
    arrays = milling_arrays(frames=4, n=3)
    track = Track(**{k: arrays[k] for k in ("times", "pos", "vel")},
                  world={"boundary": "periodic_box", "box_size": 40.0}, box=40.0, group_radius=5.0)
    data = page_json(view(track).html)
    assert data["wrap_jump"] == 20.0 and data["defaults"]["follow"] is False


def test_predator_and_prey_colours_lie_outside_every_boid_colouring():
    """Neither agent colour is near a colour a boid can take: the turbo (per boid) and viridis (speed)
    maps sampled finely, and Table 1's pattern colours (RGB distance > 60 of 441)."""
    import matplotlib

    from flocksweep.analysis.viewer.palette import TABLE_1_HEX

    def rgb(hex_colour):
        return np.array(matplotlib.colors.to_rgb(hex_colour)) * 255

    boid = [np.array(matplotlib.colormaps[name](x)[:3]) * 255 for name in ("turbo", "viridis")
            for x in np.linspace(0, 1, 256)] + [rgb(c) for c in TABLE_1_HEX.values()]
    for kind, colour in AGENT_COLOURS.items():
        nearest = min(np.linalg.norm(rgb(colour) - c) for c in boid)
        assert nearest > 60, (kind, colour, nearest)
