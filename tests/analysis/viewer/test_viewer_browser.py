"""The viewer page in a real headless Chromium (Debian's package, driven by Playwright): it opens from a
file:// URL with the network blocked and logs no error, draws a non-blank picture, advances when played,
changes when a control (colour by) is used, steps and seeks, and draws scene objects and extra agents.
Screenshots are kept in tests/artifacts/ (git-ignored)."""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from flocksweep.analysis.viewer import view
from flocksweep.analysis.viewer.track import from_arrays, recorded_agents
from browser import Browser
from viewer_data import milling_arrays, milling_track
from paths import TESTS

ARTIFACTS = TESTS / "artifacts"

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def browser():
    with Browser() as b:
        yield b


@pytest.fixture(scope="module")
def scene_page(tmp_path_factory):
    path = tmp_path_factory.mktemp("viewer") / "scene.html"
    view(milling_track(with_scene=True), path, color_by="boid", max_mb=None)
    return path


@pytest.fixture(scope="module")
def opened(browser, scene_page):
    page = browser.open(scene_page)
    yield page
    page.page.close()


def _differs(a: np.ndarray, b: np.ndarray) -> float:
    """Share of pixels that changed by more than a few levels."""
    return float((np.abs(a - b).max(axis=-1) > 8).mean())


@pytest.mark.slow
def test_page_loads_offline_without_errors(opened):
    assert opened.errors == []
    assert opened.blocked == []
    assert opened.state("frames") == 91
    assert opened.state("n") == 30


@pytest.mark.slow
def test_canvas_is_not_blank(opened):
    ARTIFACTS.mkdir(exist_ok=True)
    pixels = opened.screenshot(ARTIFACTS / "viewer_first_frame.png")
    assert pixels.shape[0] > 300 and pixels.shape[1] > 500
    assert pixels.reshape(-1, 3).std(axis=0).mean() > 10  # a flat background has ~0 variance
    distinct = len(np.unique(pixels.reshape(-1, 3) // 16, axis=0))
    assert distinct > 30


@pytest.mark.slow
def test_scene_objects_and_agents_are_drawn(opened):
    names = opened.state("sceneNames()")
    for name in ("scene:sphere", "scene:plane", "scene:box", "scene:cylinder", "agent:predator", "agent:prey"):
        assert name in names
    assert names.count("scene:cylinder") == 2
    pixels = opened.screenshot()
    r, g, b = pixels[..., 0], pixels[..., 1], pixels[..., 2]
    magenta = (r > 120) & (b > 120) & (g < 90)  # the opaque magenta sphere at the centre, shaded
    assert magenta.mean() > 0.002
    legend = opened.page.inner_text("#legend")
    assert "hawk (1)" in legend and "prey (2)" in legend


@pytest.mark.slow
def test_playing_advances_the_frames(opened):
    page = opened.page
    page.evaluate("window.flockViewer.seek(0)")
    page.wait_for_timeout(200)
    before = opened.screenshot(ARTIFACTS / "viewer_before_play.png")
    page.click("#play")
    page.wait_for_timeout(1200)
    page.click("#play")
    page.wait_for_timeout(200)
    after = opened.screenshot(ARTIFACTS / "viewer_after_play.png")
    assert opened.state("frame") > 5
    assert not opened.state("playing")
    assert _differs(before, after) > 0.002
    assert opened.errors == []


@pytest.mark.slow
def test_colour_by_changes_the_picture(opened):
    page = opened.page
    page.evaluate("window.flockViewer.seek(40)")
    page.select_option("#colorby", "boid")
    page.wait_for_timeout(200)
    by_boid = opened.screenshot(ARTIFACTS / "viewer_colour_boid.png")
    page.select_option("#colorby", "pattern")
    page.wait_for_timeout(200)
    by_pattern = opened.screenshot(ARTIFACTS / "viewer_colour_pattern.png")
    assert opened.state("colorBy") == "pattern"
    assert _differs(by_boid, by_pattern) > 0.001
    assert "pattern 11000101" in page.inner_text("#legend")
    page.select_option("#colorby", "leader")  # boid 0 leads at frame 40: legend says so
    assert "leader" in page.inner_text("#legend")


@pytest.mark.slow
def test_step_slider_and_panel_follow_the_frame(opened):
    page = opened.page
    page.evaluate("window.flockViewer.seek(10)")
    page.wait_for_timeout(100)
    page.click("#step")
    page.wait_for_timeout(100)
    assert opened.state("frame") == 11
    page.fill("#slider", "60")
    page.dispatch_event("#slider", "input")
    page.wait_for_timeout(100)
    assert opened.state("frame") == 60
    metrics = page.inner_text("#metrics")
    assert "2.00 s" in metrics and "polarization" in metrics and "leaders" in metrics
    assert "omega" in page.text_content("#params")  # inside the collapsed "Parameters" section


def test_a_boid_points_along_its_heading(opened):
    """The cone's +z axis (column 2 of its instance matrix) is the boid's unit heading."""
    page = opened.page
    page.evaluate("window.flockViewer.seek(30)")
    page.wait_for_timeout(100)
    matrix = np.array(opened.state("boidMatrix(3)")).reshape(4, 4).T  # three.js stores column-major
    data = page.evaluate("(() => { const d = window.flockViewer.data; return [d.times[30]]; })()")
    assert data[0] == pytest.approx(1.0)
    track = milling_track(with_scene=False)
    heading = track.vel[30, 3] / np.linalg.norm(track.vel[30, 3])
    axis = matrix[:3, 2] / np.linalg.norm(matrix[:3, 2])
    assert axis @ heading > 0.99
    np.testing.assert_allclose(matrix[:3, 3], track.pos[30, 3], atol=0.01)


@pytest.mark.slow
def test_a_single_frame_run_opens(browser, tmp_path):
    track = milling_track(with_scene=False, frames=1)
    path = view(track, tmp_path / "one.html").path
    page = browser.open(path)
    assert page.errors == [] and page.blocked == []
    assert page.state("frames") == 1
    page.page.close()


@pytest.mark.slow
def test_a_page_opens_at_its_start_time_or_at_the_time_and_colouring_its_url_says(browser, tmp_path):
    track = milling_track(with_scene=False)
    times = np.asarray(track.times)
    middle = float(times[len(times) // 2])
    path = view(track, tmp_path / "start.html", color_by="boid", max_mb=None, start_time=middle).path
    page = browser.open(path)
    assert page.errors == []
    assert abs(page.state("time") - middle) < 1e-6 and page.state("colorBy") == "boid"
    page.page.close()
    late = float(times[-3])
    page = browser.open(path, fragment=f"t={late}&color=group")
    assert abs(page.state("time") - late) < 1e-6 and page.state("colorBy") == "group"
    page.page.evaluate("window.flockViewer.seek(2)")            # a seek writes the fragment back
    assert page.page.evaluate("window.location.hash") == f"#t={float(times[2]):.2f}&color=group"
    page.page.close()


@pytest.mark.slow
def test_a_predator_that_appears_later_is_ghosted_where_it_appears_until_then(browser, tmp_path):
    arrays = milling_arrays()
    times = arrays["times"]
    predator = np.stack([18 * np.cos(-0.5 * times), np.full_like(times, 3.0), 18 * np.sin(-0.5 * times)], axis=-1)
    predator[:45] = np.nan                                      # absent for the first half, as Boids++ records it
    agents = recorded_agents(predator, None, times)
    assert agents[0]["appears_s"] == times[45] and "ghosted until" in agents[0]["label"]
    track = from_arrays(**arrays, title="late predator", group_radius=6.0, agents=agents)
    page = browser.open(view(track, tmp_path / "late.html", max_mb=None).path)
    assert page.errors == []
    assert page.state("agentOpacity(0)") < 0.5                  # visible from the start, ghosted
    at_start = np.array(page.state("agentMatrix(0)"))[12:15]    # drawn where it first appears
    assert np.allclose(at_start, predator[45], atol=0.1)
    page.page.evaluate("window.flockViewer.seek(44)")
    assert page.state("agentOpacity(0)") < 0.5
    page.page.evaluate("window.flockViewer.seek(45)")
    assert page.state("agentOpacity(0)") == 1                   # opaque once it has appeared
    assert "ghosted until" in page.page.inner_text("#legend")
    page.page.close()


@pytest.mark.slow
def test_the_url_fragment_names_the_run_as_well_as_the_time(browser, tmp_path):
    track = milling_track(with_scene=False)
    track = replace(track, info={"run id": "abc123def456", "seed": 1})
    times = np.asarray(track.times)
    path = view(track, tmp_path / "run.html", color_by="boid", max_mb=None).path
    page = browser.open(path, fragment=f"run=abc123&t={float(times[30])}&color=group")   # a prefix of the id
    assert page.errors == [] and abs(page.state("time") - times[30]) < 1e-6 and page.state("colorBy") == "group"
    assert not page.page.is_visible("#message")
    page.page.evaluate("window.flockViewer.seek(5)")
    assert page.page.evaluate("window.location.hash") == f"#run=abc123def456&t={float(times[5]):.2f}&color=group"
    page.page.close()
    page = browser.open(path, fragment=f"run=fff999&t={float(times[30])}&color=group")   # another run's address
    assert page.state("time") == times[0] and page.state("colorBy") == "boid"           # not applied here
    message = page.page.inner_text("#message")
    assert "run fff999" in message and "this page shows run abc123def456" in message and "--run fff999" in message
    page.page.close()


@pytest.mark.slow
def test_the_metrics_chart_keeps_its_legend_off_the_lines(opened):
    """The chart's legend has its own strip: right of the legend text, the strip is background only
    (the lines, cohesion near 1 at the top, start below it)."""
    drawn = opened.page.evaluate("""() => {
        const cv = document.getElementById("chart"), g = cv.getContext("2d");
        g.font = "22px system-ui, sans-serif";
        const legend = 12 + ["polarization", "cohesion", "NND (scaled)"]
            .map((t) => g.measureText(t).width + 16).reduce((a, b) => a + b, 0);
        const img = g.getImageData(0, 0, cv.width, 34).data;
        let foreign = 0;
        for (let y = 0; y < 30; y++) for (let x = Math.ceil(legend); x < cv.width; x++) {  // 2-px lines end at 33
            const i = 4 * (y * cv.width + x);
            const dx = Math.abs(img[i] - 0xfb) + Math.abs(img[i + 1] - 0xfc) + Math.abs(img[i + 2] - 0xfd);
            if (dx > 30) foreign++;
        }
        return {foreign, width: cv.width, legend};
    }""")
    assert drawn["legend"] < drawn["width"] - 20
    assert drawn["foreign"] == 0


@pytest.mark.slow
def test_a_page_of_several_runs_shows_the_run_its_fragment_names_and_switching_writes_it(browser, tmp_path):
    base = milling_track(with_scene=False)
    ids = ["aaaa11112222", "bbbb33334444", "cccc55556666"]
    runs = [replace(base, pos=base.pos * (1 + k), info={"run id": run, "seed": k}, title=f"run {run}")
            for k, run in enumerate(ids)]
    from flocksweep.analysis.viewer import view_runs

    path = view_runs(runs, ids, tmp_path / "runs.html", color_by="boid", max_mb=None).path
    times = np.asarray(base.times)
    t = float(times[40])
    page = browser.open(path, fragment=f"run=bbbb33&t={t}&color=group")     # a prefix of the second run
    assert page.errors == [] and page.blocked == []
    assert page.state("run") == ids[1] and abs(page.state("time") - t) < 1e-6 and page.state("colorBy") == "group"
    np.testing.assert_allclose(np.array(page.state("boidMatrix(3)"))[12:15], runs[1].pos[40, 3], atol=0.02)
    assert page.page.is_visible("#run") and page.page.input_value("#run") == ids[1]
    assert page.page.inner_text("#title") == f"run {ids[1]}" and not page.page.is_visible("#message")
    page.page.evaluate("window.flockViewer.seek(20)")                         # a seek keeps the run in the address
    assert page.page.evaluate("window.location.hash") == f"#run={ids[1]}&t={float(times[20]):.2f}&color=group"
    page.page.select_option("#run", ids[2])                                   # the menu switches the run
    page.page.wait_for_function(f"window.flockViewer && window.flockViewer.run === '{ids[2]}'", timeout=60_000)
    assert page.page.evaluate("window.location.hash") == f"#run={ids[2]}&t={float(times[20]):.2f}&color=group"
    assert abs(page.state("time") - times[20]) < 0.006 and page.state("colorBy") == "group"
    # the address keeps t to 0.01 s: boid 3 (radius ~36 here) is interpolated up to 0.005 s later than frame 20
    np.testing.assert_allclose(np.array(page.state("boidMatrix(3)"))[12:15], runs[2].pos[20, 3], atol=0.25)
    page.page.go_back()                                                        # Back: the run before
    page.page.wait_for_function(f"window.flockViewer && window.flockViewer.run === '{ids[1]}'", timeout=60_000)
    page.page.close()
    page = browser.open(path, fragment=f"run=fff999&t={t}")                   # a run this page does not hold
    assert page.state("run") == ids[0] and page.state("time") == times[0]
    message = page.page.inner_text("#message")
    assert "run fff999" in message and f"holds runs {', '.join(ids)}" in message
    page.page.close()


@pytest.mark.slow
@pytest.mark.parametrize("world", [{"boundary": "open", "dimensions": 2}, {"boundary": "open"}],
                         ids=["2-D run", "flat track"])
def test_a_flat_run_is_seen_from_above_with_its_grid_in_its_plane(browser, tmp_path, world):
    """A run in the plane z = 0 (a 2-D model's, or a measured track whose every z is 0) opens looking down
    -z at the plane, its grid lying in it, and the picture is not blank; a 3-D run keeps its oblique view."""
    arrays = milling_arrays()
    pos, vel = arrays["pos"][..., [0, 2, 1]].copy(), arrays["vel"][..., [0, 2, 1]].copy()   # mill about +z
    pos[..., 2] = vel[..., 2] = 0.0
    flat = from_arrays(**{**arrays, "pos": pos, "vel": vel}, title="a mill in the plane", world=world)
    page = browser.open(view(flat, tmp_path / "flat.html").path)
    assert page.errors == [] and page.blocked == []
    direction = page.page.evaluate("window.flockViewer.cameraDirection()")
    assert np.allclose(direction, [0.0, 0.0, -1.0], atol=1e-9)
    assert np.allclose(np.abs(page.page.evaluate("window.flockViewer.gridNormal()")), [0.0, 0.0, 1.0], atol=1e-9)
    ARTIFACTS.mkdir(exist_ok=True)
    shot = page.screenshot(ARTIFACTS / f"viewer_flat_{len(world)}.png")
    assert shot.reshape(-1, 3).std(axis=0).mean() > 10   # boids and grid drawn on the background
    page.page.close()
    spatial = browser.open(view(from_arrays(**arrays, title="3-D"), tmp_path / "spatial.html").path)
    assert spatial.page.evaluate("window.flockViewer.cameraDirection()")[2] > -0.99
    spatial.page.close()


@pytest.mark.slow
def test_measured_tracks_open_from_the_command_line_seen_from_above_with_a_menu_of_flocks(browser, tmp_path):
    """flocksweep view of a measure folder: the page of its flocks opens offline without errors, looks
    down at the plane of the 2-D tracks, and its menu switches between the flocks."""
    import pandas as pd

    from flocksweep.cli import main
    rows = [(flock, i, s * 0.1, (6 + 4 * k) * np.cos(0.05 * s + i), (6 + 4 * k) * np.sin(0.05 * s + i))
            for k, flock in enumerate(("F1", "F2")) for i in range(8) for s in range(40)]
    pd.DataFrame(rows, columns=["flock", "id", "t", "x", "y"]).to_csv(tmp_path / "mill.csv", index=False)
    folder = tmp_path / "measured"
    assert main(["measure", str(tmp_path / "mill.csv"), "--group-radius", "4", "--out", str(folder),
                 "--no-figures", "--no-progress"]) == 0
    assert main(["view", str(folder), "--no-progress"]) == 0
    page = browser.open(folder / "viewer" / "flocks.html")
    assert page.errors == [] and page.blocked == []
    assert page.state("run") == "F1" and page.state("n") == 8 and page.state("frames") == 39
    assert np.allclose(page.page.evaluate("window.flockViewer.cameraDirection()"), [0.0, 0.0, -1.0], atol=1e-9)
    ARTIFACTS.mkdir(exist_ok=True)
    assert page.screenshot(ARTIFACTS / "viewer_measured_flocks.png").reshape(-1, 3).std(axis=0).mean() > 10
    page.page.select_option("#run", "F2")
    page.page.wait_for_function("window.flockViewer && window.flockViewer.run === 'F2'", timeout=60_000)
    np.testing.assert_allclose(np.array(page.state("boidMatrix(0)"))[12:14], [10.0, 0.0], atol=0.05)
    assert page.errors == []
    page.page.close()


@pytest.mark.slow
def test_the_tank_tracks_declare_is_drawn_around_them(browser, tmp_path):
    """flocksweep view of pixel tracks that declare a round tank: the page opens offline without errors and
    draws the tank as a scene cylinder for each flock of the menu."""
    from flocksweep.cli import main
    from tank_tracks import write_tank_tracks

    path = write_tank_tracks(tmp_path)
    assert main(["view", str(path), "--out", str(tmp_path / "tank.html"), "--group-radius", "5", "--no-progress"]) == 0
    page = browser.open(tmp_path / "tank.html")
    assert page.errors == [] and page.blocked == []
    assert page.state("sceneNames()").count("scene:cylinder") == 1
    page.page.select_option("#run", "B")
    page.page.wait_for_function("window.flockViewer && window.flockViewer.run === 'B'", timeout=60_000)
    assert page.state("sceneNames()").count("scene:cylinder") == 1 and page.errors == []
    ARTIFACTS.mkdir(exist_ok=True)
    assert page.screenshot(ARTIFACTS / "viewer_tank_tracks.png").reshape(-1, 3).std(axis=0).mean() > 10
    page.page.close()
