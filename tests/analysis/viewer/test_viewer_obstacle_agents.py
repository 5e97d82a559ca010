"""A model's obstacles and a run's predator and prey in the viewer: scene objects from
``world.obstacles``, agents from ``Observations.predator`` / ``.prey`` and from a saved trajectory, and in
headless Chromium the page draws them, with trails for the agents too."""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from flocksweep.analysis.viewer import view
from flocksweep.analysis.viewer.encode import check_scene, page_data
from flocksweep.analysis.viewer.observables import frame_observables
from flocksweep.analysis.viewer.palette import AGENT_COLOURS
from flocksweep.analysis.viewer.track import (agents_of, arena_scene, from_npz, from_observations, obstacle_scene,
                                              scene_of)
from flocksweep.simcore.obstacle_spec import Obstacle
from flocksweep.simcore.simulate import Observations

OBSTACLES = (Obstacle(kind="sphere", centre=(0, 0, 0), radius=3.0),
             Obstacle(kind="plane", centre=(0, -10, 0), normal=(0, 1, 0)),
             Obstacle(kind="box", centre=(15, 0, 0), half_extents=(1, 2, 3)),
             Obstacle(kind="cylinder", centre=(-15, 0, 0), axis=(0, 0, 2), radius=1.5, length=6.0))
MODEL = SimpleNamespace(world=SimpleNamespace(obstacles=OBSTACLES))


def circling_run(n: int = 12, frames: int = 61, dt: float = 1 / 20) -> Observations:
    """Boids circling the y axis at radius 8 and a predator and prey circling at other radii."""
    times = np.arange(frames) * dt
    phase = np.linspace(0, 2 * np.pi, n, endpoint=False)
    angle = phase[None, :] + times[:, None]
    pos = np.stack([8 * np.cos(angle), np.zeros_like(angle), 8 * np.sin(angle)], axis=-1)
    vel = np.stack([-8 * np.sin(angle), np.zeros_like(angle), 8 * np.cos(angle)], axis=-1)
    predator = np.stack([14 * np.cos(-times), np.full_like(times, 2.0), 14 * np.sin(-times)], axis=-1)
    prey = np.stack([5 * np.cos(2 * times), np.full_like(times, -2.0), 5 * np.sin(2 * times)], axis=-1)
    blank = np.zeros((frames, n), np.int32)
    return Observations(times=times, pos=pos, vel=vel, visible=blank, binocular=blank, leader=blank.astype(bool),
                        triggers=np.zeros((0, 2), np.int64), pattern=np.zeros(n, np.uint32), final=None,
                        dt=dt, record_every=1, predator=predator, prey=prey)


def test_obstacles_become_scene_objects_of_the_same_solids():
    pos = circling_run().pos
    scene = check_scene(scene_of(MODEL, pos))
    assert [o["type"] for o in scene] == ["sphere", "plane", "box", "cylinder"]
    assert scene[0]["center"] == [0, 0, 0] and scene[0]["radius"] == 3.0
    assert scene[2]["size"] == [2.0, 4.0, 6.0]
    np.testing.assert_allclose(scene[3]["a"], [-15, 0, -3])          # the axis is normalised on load
    np.testing.assert_allclose(scene[3]["b"], [-15, 0, 3])
    plane = scene[1]
    np.testing.assert_allclose(plane["point"], [0, -10, 0], atol=1e-12)   # the flock's middle, dropped onto it
    assert plane["size"] == pytest.approx(2.2 * 8.0)                   # 2.2 x the farthest in-plane offset
    assert obstacle_scene(OBSTACLES[1])["size"] == 100.0              # no positions: a default patch


def test_a_tank_becomes_a_wireframe_of_its_walls():
    from flocksweep.simcore.arena import Arena

    pos = circling_run().pos
    box = Arena(kind="box", centre=(1.0, 2.0, 3.0), size=(30.0, 20.0, 10.0))
    cylinder = Arena(kind="cylinder", radius=12.0, height=6.0)
    model = SimpleNamespace(world=SimpleNamespace(obstacles=(), dimensions=3), arena=box)
    (drawn,) = check_scene(scene_of(model, pos))
    assert drawn["type"] == "box" and drawn["wireframe"] and drawn["size"] == [30.0, 20.0, 10.0]
    drawn = arena_scene(cylinder, 3, pos)
    assert drawn["radius"] == 12.0 and drawn["a"][2] == -3.0 and drawn["b"][2] == 3.0
    flat = arena_scene(Arena(kind="cylinder", radius=5.0), 2)
    assert flat["b"][2] - flat["a"][2] == pytest.approx(0.1)            # a circle in 2-D: a thin disc
    open_world = SimpleNamespace(world=SimpleNamespace(obstacles=()), arena=Arena())
    assert scene_of(open_world) == ()


def test_predator_and_prey_of_the_observations_become_agents():
    obs = circling_run()
    agents = agents_of(obs)
    assert [a["kind"] for a in agents] == ["predator", "prey"]
    np.testing.assert_array_equal(agents[0]["pos"][:, 0], obs.predator)
    assert agents_of(Observations(**{**obs.__dict__, "predator": None, "prey": None})) == ()
    track = from_observations(obs, scene=scene_of(MODEL, obs.pos))
    assert len(track.agents) == 2 and len(track.scene) == 4
    thin = track.every(3)
    np.testing.assert_array_equal(thin.agents[1]["pos"][:, 0], obs.prey[::3])


def test_a_saved_trajectory_brings_its_predator_and_prey(tmp_path):
    obs = circling_run()
    path = tmp_path / "run.npz"
    np.savez(path, times=obs.times, pos=obs.pos, vel=obs.vel, predator=obs.predator, prey=obs.prey)
    track = from_npz(path)
    assert [a["kind"] for a in track.agents] == ["predator", "prey"]
    np.testing.assert_array_equal(track.agents[0]["pos"][:, 0], obs.predator)
    data = page_data(track, frame_observables(track))
    assert [(a["kind"], a["m"]) for a in data["agents"]] == [("predator", 1), ("prey", 1)]


@pytest.mark.slow
def test_the_page_draws_obstacles_agents_and_agent_trails(tmp_path):
    from browser import Browser

    obs = circling_run()
    track = from_observations(obs, scene=scene_of(MODEL, obs.pos))
    bare = from_observations(Observations(**{**obs.__dict__, "predator": None, "prey": None}))
    trail_s = 1.0
    k = min(len(obs.times) - 1, round(trail_s / obs.dt))
    step = math.ceil(k / 24)
    points = math.ceil(k / step)
    with Browser() as browser:
        counts = {}
        for name, source in (("with", track), ("bare", bare)):
            path = tmp_path / f"{name}.html"
            view(source, path, trail_s=trail_s, max_mb=None)
            page = browser.open(path)
            assert page.errors == []
            if name == "with":
                names = page.state("sceneNames()")
                for wanted in ("scene:sphere", "scene:plane", "scene:box", "scene:cylinder", "agent:predator",
                               "agent:prey"):
                    assert wanted in names
                legend = page.page.inner_text("#legend")
                assert "predator" in legend and "prey" in legend
            page.page.evaluate("window.flockViewer.pause()")
            page.page.evaluate("window.flockViewer.seek(50)")
            page.page.wait_for_timeout(300)
            counts[name] = page.state("trailVertices()")
            page.page.close()
    # every boid and agent has a full trail at frame 50 (no wraps in an open world)
    assert counts["bare"] == 12 * points * 2
    assert counts["with"] == (12 + 2) * points * 2


@pytest.mark.slow
def test_stills_and_animations_draw_the_agents_in_their_colours(tmp_path):
    from PIL import Image

    from flocksweep.analysis.viewer.animation import poster, write_animation

    obs = circling_run(frames=21)
    with_agents = from_observations(obs)
    bare = from_observations(Observations(**{**obs.__dict__, "predator": None, "prey": None}))

    def share(path, rgb) -> float:
        with Image.open(path) as image:
            pixels = np.asarray(image.convert("RGB"), dtype=int)
        return float((np.abs(pixels - rgb).max(axis=-1) < 30).mean())

    def rgb(hex_colour: str) -> tuple[int, int, int]:
        return tuple(int(hex_colour[i:i + 2], 16) for i in (1, 3, 5))

    predator, prey = rgb(AGENT_COLOURS["predator"]), rgb(AGENT_COLOURS["prey"])
    for name, track in (("with", with_agents), ("bare", bare)):
        poster(track, tmp_path / f"{name}.png", color_by="speed")
    with_png, bare_png = tmp_path / "with.png", tmp_path / "bare.png"
    assert share(with_png, predator) > 0.001 and share(bare_png, predator) == 0.0
    # the prey is black, as the text and axes are: it shows as black beyond the bare still's
    assert share(with_png, prey) - share(bare_png, prey) > 0.0005
    animation = write_animation(with_agents, tmp_path / "run.gif", fps=10, size=(320, 240))
    assert animation.frames == 11 and (tmp_path / "run.gif").stat().st_size > 10_000
