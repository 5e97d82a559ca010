"""Trace plots with obstacles, predator and prey (analysis.reports.traces, obstacle_artists)."""
from __future__ import annotations

import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")

from flocksweep.analysis.reports.obstacle_artists import box_faces, cylinder_parts, plane_patch, sphere_grid  # noqa: E402
from flocksweep.analysis.reports.traces import draw_traces, plot_traces  # noqa: E402
from flocksweep.simcore.obstacle_spec import Obstacle  # noqa: E402

OBSTACLES = (Obstacle(kind="sphere", centre=(0, 5, 0), radius=2.0),
             Obstacle(kind="plane", centre=(0, -1, 0), normal=(0, 1, 0)),
             Obstacle(kind="box", centre=(8, 5, 0), half_extents=(1, 2, 3)),
             Obstacle(kind="cylinder", centre=(-8, 5, 0), axis=(0, 1, 1), radius=1.0, length=4.0))


def flock(n: int = 6, records: int = 20) -> np.ndarray:
    t = np.linspace(0, 1, records)[:, None]
    pos = np.zeros((records, n, 3))
    pos[..., 0] = -15 + 30 * t
    pos[..., 1] = 5 + np.arange(n)[None, :]
    pos[..., 2] = 4.0
    return pos


def test_every_obstacle_kind_and_both_agents_are_drawn():
    import matplotlib.pyplot as plt

    fig = plt.figure()
    ax = fig.add_subplot(projection="3d")
    pos = flock()
    predator = pos[:, 0] + [0, 0, 3]
    prey = np.tile([20.0, 6.0, 4.0], (len(pos), 1))
    draw_traces(ax, pos, obstacles=OBSTACLES, predator=predator, prey=prey)
    gids = {artist.get_gid() for artist in ax.get_children()} - {None}
    assert {"obstacle:sphere:0", "obstacle:plane:1", "obstacle:box:2", "obstacle:cylinder:3",
            "obstacle:cylinder:3:caps", "predator", "prey"} <= gids
    line = next(a for a in ax.lines if a.get_gid() == "predator")
    xs, zs, ys = line.get_data_3d()
    np.testing.assert_array_equal(xs, predator[:, 0])   # world y is drawn as the plot's vertical axis
    np.testing.assert_array_equal(ys, predator[:, 1])
    np.testing.assert_array_equal(zs, predator[:, 2])
    labels = [text.get_text() for text in ax.get_legend().get_texts()]
    assert labels == ["predator", "prey"]
    plt.close(fig)


def test_without_obstacles_or_agents_nothing_extra_is_drawn():
    import matplotlib.pyplot as plt

    fig = plt.figure()
    ax = fig.add_subplot(projection="3d")
    draw_traces(ax, flock())
    assert {artist.get_gid() for artist in ax.get_children()} - {None} == set()
    assert ax.get_legend() is None
    plt.close(fig)


def test_obstacle_geometry_lies_on_the_obstacles_surfaces():
    grid = sphere_grid((1, 2, 3), 2.0)
    np.testing.assert_allclose(np.linalg.norm(grid - [1, 2, 3], axis=-1), 2.0)
    faces = box_faces((8, 5, 0), (1, 2, 3))
    assert len(faces) == 6
    corners = np.unique(np.concatenate(faces), axis=0)
    np.testing.assert_array_equal(np.abs(corners - [8, 5, 0]), np.tile([1, 2, 3], (8, 1)))
    axis = np.array([0, 1, 1]) / np.sqrt(2)
    side, caps = cylinder_parts((-8, 5, 0), axis, 1.0, 4.0)
    offsets = side - [-8, 5, 0]
    along = offsets @ axis
    np.testing.assert_allclose(np.abs(along), 2.0)
    np.testing.assert_allclose(np.linalg.norm(offsets - along[..., None] * axis, axis=-1), 1.0)
    assert len(caps) == 2
    points = flock().reshape(-1, 3)
    patch = plane_patch((0, -1, 0), (0, 1, 0), points)
    np.testing.assert_allclose(patch[:, 1], -1.0)                       # in the plane
    assert patch[:, 0].min() < points[:, 0].min() and patch[:, 0].max() > points[:, 0].max()
    assert patch[:, 2].min() < points[:, 2].min() and patch[:, 2].max() > points[:, 2].max()


@pytest.mark.parametrize("suffix", ["png", "svg"])
def test_plot_traces_writes_a_picture_with_obstacles_and_agents(tmp_path, suffix):
    pos = flock()
    out = plot_traces(pos, tmp_path / f"traces.{suffix}", title="obstacles", obstacles=OBSTACLES,
                      predator=pos[:, 0] + 1.0, prey=pos[:, -1] - 1.0)
    assert out.is_file() and out.stat().st_size > 10_000


def test_thumbnails_pass_obstacles_and_agents_to_each_panel(tmp_path, monkeypatch):
    from flocksweep.analysis.reports import figures

    drawn = []

    def recording(ax, pos, *args, **scene):
        drawn.append(scene)
        return draw_traces(ax, pos, *args, **scene)

    monkeypatch.setattr(figures, "draw_traces", recording)
    pos = flock()
    items = [("plain", pos, None), ("scene", pos, None, {"obstacles": OBSTACLES, "predator": pos[:, 0], "prey": None})]
    out = figures.thumbnails_figure(items, tmp_path / "thumbs.png", ncols=2)
    assert out.is_file()
    assert drawn[0] == {} and drawn[1]["obstacles"] == OBSTACLES
    np.testing.assert_array_equal(drawn[1]["predator"], pos[:, 0])
