"""Measured tracks in the viewer from the command line (flocksweep view TRACKS / MEASURE_FOLDER): any file
measure reads, with its reading options; a measure folder read again as it was measured, its flocks in a
menu; and 2-D tracks and 2-D runs drawn from above in posters and animations (the page's view). The page
itself in Chromium: test_viewer_browser.py."""
from __future__ import annotations

import json
import re

import numpy as np
import pandas as pd
import pytest

from flocksweep.analysis.viewer.animation import _Drawing, is_flat, poster
from flocksweep.analysis.viewer.track import from_arrays
from flocksweep.cli import main
from viewer_data import milling_arrays


def mill_csv(path, flocks=("A", "B"), n: int = 6, samples: int = 30):
    rows = []
    for k, flock in enumerate(flocks):
        for i in range(n):
            for s in range(samples):
                angle = 0.5 * s * 0.1 + i
                rows.append((flock, i, s * 0.1, (5 + k) * np.cos(angle), (5 + k) * np.sin(angle)))
    pd.DataFrame(rows, columns=["flock", "id", "t", "x", "y"]).to_csv(path, index=False)
    return path


def blocks(html: str) -> list:
    return re.findall(r'<script type="application/json" id="flock-data[-0-9]*" data-run="([^"]+)"', html)


def test_a_track_file_opens_as_a_page_with_a_menu_of_its_flocks(tmp_path, capsys):
    path = mill_csv(tmp_path / "mill.csv")
    out = tmp_path / "mill.html"
    assert main(["view", str(path), "--out", str(out), "--group-radius", "3", "--no-progress"]) == 0
    assert "2 flocks, a menu switches between them" in capsys.readouterr().out
    html = out.read_text()
    assert blocks(html) == ["A", "B"]
    data = json.loads(re.search(r'id="flock-data" data-run="A"[^>]*>(.*?)</script>', html, re.S).group(1))
    assert data["world"]["dimensions"] == 2                       # 2-D tracks: seen from above
    assert main(["view", str(path), "--flock", "B", "--out", str(tmp_path / "b.html"), "--no-progress"]) == 0
    assert blocks((tmp_path / "b.html").read_text()) == []        # one flock: a page of one run
    assert main(["view", str(path), "--flock", "C", "--no-progress"]) == 2
    assert "--flock: got 'C'; mill.csv holds the flocks A, B" in capsys.readouterr().err
    assert main(["view", str(path), "--animate", str(tmp_path / "a.gif"), "--no-progress"]) == 2
    assert "--animate: animates one flock; mill.csv holds 2 (A, B): name one with --flock" in capsys.readouterr().err


def test_any_format_measure_reads_opens_with_its_options(tmp_path, capsys):
    traj = np.transpose(np.stack([np.stack([np.arange(20) * 2.0, np.full(20, 30.0 * i)], -1) for i in range(4)]),
                        (1, 0, 2))                                # frames x fish x 2, pixels
    np.save(tmp_path / "bare.npy", traj)
    out = tmp_path / "fish.html"
    assert main(["view", str(tmp_path / "bare.npy"), "--tracks-fps", "25", "--body-length-px", "30", "--out", str(out),
                 "--no-progress"]) == 0
    assert "4 boids, 19 frames" in capsys.readouterr().out
    assert main(["view", str(tmp_path / "bare.npy"), "--no-progress"]) == 2
    assert "fps: the times are frame numbers" in capsys.readouterr().err


def test_a_measure_folder_is_read_again_as_it_was_measured(tmp_path, capsys):
    path = mill_csv(tmp_path / "mill.csv")
    folder = tmp_path / "measured"
    assert main(["measure", str(path), "--group-radius", "3", "--trim", "2:", "--out", str(folder), "--no-figures",
                 "--no-progress"]) == 0
    capsys.readouterr()
    assert main(["view", str(folder), "--no-progress"]) == 0
    page = folder / "viewer" / "flocks.html"
    assert str(page) in capsys.readouterr().out and blocks(page.read_text()) == ["A", "B"]
    runs = pd.read_parquet(folder / "runs.parquet")
    data = json.loads(re.search(r'data-run="A"[^>]*>(.*?)</script>', page.read_text(), re.S).group(1))
    assert len(data["times"]) == runs.loc[0, "records"] == 27       # the trim of measure kept: 28 samples, 27 records
    assert main(["view", str(folder), "--interval", "0.2", "--no-progress"]) == 2
    assert "--interval: only applies when SOURCE is a track file or folder (got a measured source: a measure folder " \
           "reads its tracks as it measured them)" in capsys.readouterr().err
    assert main(["view", str(folder), "--flock", "A", "--animate", str(tmp_path / "a.gif"), "--no-page", "--fps", "5",
                 "--no-progress"]) == 0
    from PIL import Image
    assert Image.open(tmp_path / "a.gif").n_frames == 14           # 2.6 s of records at 5 frames per second


def _flat_arrays():
    arrays = milling_arrays(n=8, frames=20)
    pos, vel = arrays["pos"][..., [0, 2, 1]].copy(), arrays["vel"][..., [0, 2, 1]].copy()
    pos[..., 2] = vel[..., 2] = 0.0
    return {**arrays, "pos": pos, "vel": vel}


@pytest.mark.parametrize("world", [{"boundary": "open", "dimensions": 2}, {"boundary": "open"}],
                         ids=["2-D run", "flat track"])
def test_posters_of_2d_tracks_and_2d_runs_are_drawn_from_above(tmp_path, world):
    track = from_arrays(**_flat_arrays(), title="a mill in the plane", world=world)
    assert is_flat(track)
    drawing = _Drawing(track, "boid", np.array([5]), 1.0, (320, 240), 100, None, False, 1.0)
    try:
        drawing.draw(0, 5)
        assert drawing.ax.name == "rectilinear" and drawing.ax.get_ylabel() == "y" and drawing.ax.get_xlabel() == "x"
        heads = drawing.quiver.get_offsets()
        assert np.allclose(heads, track.pos[5][:, :2])              # each arrow starts at its boid, in (x, y)
    finally:
        drawing.close()
    path = poster(track, tmp_path / "flat.png", size=(320, 240))
    from PIL import Image
    pixels = np.asarray(Image.open(path).convert("RGB"), dtype=np.int16)
    assert pixels.reshape(-1, 3).std(axis=0).mean() > 10
    spatial = from_arrays(**milling_arrays(n=8, frames=20))
    assert not is_flat(spatial)
    drawing = _Drawing(spatial, "boid", np.array([0]), 1.0, (320, 240), 100, None, False, 1.0)
    assert drawing.ax.name == "3d"
    drawing.close()


def test_a_2d_models_world_is_drawn_from_above():
    from flocksweep.analysis.viewer.track import world_of
    from flocksweep.simcore import load_preset
    from paths import ROOT
    world = world_of(load_preset(ROOT / "configs/models/vicsek.toml").model)
    assert world["dimensions"] == 2
    arrays = _flat_arrays()
    arrays["pos"][..., 2] = 1e-9          # even a run not exactly in z = 0: the model's world says 2-D
    track = from_arrays(**arrays, world=world)
    drawing = _Drawing(track, "boid", np.array([0]), 1.0, (320, 240), 100, None, False, 1.0)
    assert is_flat(track) and drawing.ax.name == "rectilinear"
    drawing.close()


def _page_data(html: str, run: str | None = None) -> dict:
    tag = f'id="flock-data[-0-9]*" data-run="{run}"' if run else 'id="flock-data"'
    return json.loads(re.search(tag + r'[^>]*>(.*?)</script>', html, re.S).group(1))


def test_the_tank_the_tracks_declare_is_drawn_on_their_page_and_in_their_animation(tmp_path, capsys):
    from tank_tracks import write_tank_tracks

    path = write_tank_tracks(tmp_path)                     # pixels, a round tank of radius 10 BL about (16, 12)
    out = tmp_path / "tank.html"
    assert main(["view", str(path), "--out", str(out), "--group-radius", "5", "--no-progress"]) == 0
    for run in ("A", "B"):
        (tank,) = _page_data(out.read_text(), run)["scene"]
        assert tank["type"] == "cylinder" and tank["wireframe"] and tank["label"] == "arena"
        assert tank["radius"] == pytest.approx(10.0) and tank["a"][:2] == pytest.approx([16.0, 12.0])
    folder = tmp_path / "measured"                         # a measure folder keeps the tank it was read with
    assert main(["measure", str(path), "--group-radius", "5", "--out", str(folder), "--no-figures",
                 "--no-progress"]) == 0
    assert json.loads((folder / "measure.json").read_text())["reading"]["arena"]["radius"] == 200.0
    assert main(["view", str(folder), "--flock", "A", "--no-progress"]) == 0
    (tank,) = _page_data((folder / "viewer" / "A.html").read_text())["scene"]
    assert tank["radius"] == pytest.approx(10.0)
    capsys.readouterr()
    from flocksweep.analysis.viewer.command import _track_pages
    from argparse import Namespace
    args = Namespace(source=str(path), reading={}, interval=None, max_gap=None, velocity_interval=None,
                     group_radius=5.0, flock="A", animate=None)
    (track,), _, _ = _track_pages(args, "tracks", None)
    drawing = _Drawing(track, "boid", np.array([5]), 1.0, (320, 240), 100, None, False, 1.0)
    try:
        drawing.draw(0, 5)
        (walls,) = [c for c in drawing.ax.collections if c.get_gid() == "tank"]
        ring = walls.get_segments()[0]
        assert np.hypot(ring[:, 0] - 16.0, ring[:, 1] - 12.0) == pytest.approx(np.full(len(ring), 10.0))
        low, high = drawing.ax.get_xlim()                   # the view holds the whole tank
        assert low <= 6.0 and high >= 26.0
    finally:
        drawing.close()


def test_a_simulated_runs_page_and_animation_draw_its_models_tank(tmp_path):
    from flocksweep.analysis.viewer.animation import tank_outline
    from flocksweep.analysis.viewer.track import arena_scene
    from flocksweep.simcore.arena import Arena

    preset = tmp_path / "tank.toml"
    preset.write_text('name = "walled"\ndynamics = "vicsek"\n[perception]\nkind = "sphere"\n[vicsek]\nradius = 3.0\n'
                      'speed = 1.5\nnoise = 0.5\n[world]\ndimensions = 2\nboundary = "open"\n[init]\nn = 6\n'
                      'radius = 3.0\nspeed = 1.5\n[arena]\nkind = "box"\nsize = [12.0, 8.0, 1.0]\n'
                      '[run]\ndt = 0.1\nduration = 2.0\n')
    out = tmp_path / "run.html"
    assert main(["view", str(preset), "--out", str(out), "--no-progress"]) == 0
    (tank,) = _page_data(out.read_text())["scene"]
    assert tank["type"] == "box" and tank["size"][:2] == [12.0, 8.0] and tank["label"] == "arena"
    (rectangle,) = tank_outline(tank, flat=True)
    assert rectangle[:, :2].min(axis=0) == pytest.approx([-6.0, -4.0]) and rectangle[:, :2].max(axis=0) == pytest.approx([6.0, 4.0])
    box = tank_outline(arena_scene(Arena(kind="box", size=(2.0, 4.0, 6.0)), 3), flat=False)
    assert len(box) == 12 and all(np.count_nonzero(e[1] - e[0]) == 1 for e in box)   # 12 edges along the axes
    cylinder = tank_outline(arena_scene(Arena(kind="cylinder", radius=2.0, height=4.0), 3), flat=False)
    assert len(cylinder) == 6 and cylinder[0][:, 2] == pytest.approx(-2.0) and cylinder[1][:, 2] == pytest.approx(2.0)
