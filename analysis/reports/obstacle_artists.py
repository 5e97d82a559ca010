"""Obstacles drawn into a matplotlib 3-D axes, for trace plots (``flocksweep simulate --plot``).

``draw_obstacles(ax, obstacles, around)`` draws every :class:`simcore.obstacle_spec.Obstacle` as a
translucent grey solid and returns the artists (one per obstacle, their ``gid`` ``"obstacle:<kind>:<k>"``):

* sphere: its surface (a 24 x 12 mesh);
* plane: a square patch of the plane centred on the projection of the middle of ``around`` (the points
  drawn, (M, 3)) onto it, wide enough to lie under all of them (plus 10%), with its normal drawn as a
  short arrow-less segment toward the free side;
* box: its six faces;
* cylinder: its side (a 24-segment mesh) and its two caps.

Drawn as the trace plots draw the world: world y (up) is the plot's vertical axis, so a world point
(x, y, z) is plotted at (x, z, y).
"""
from __future__ import annotations

import numpy as np

FACE = "#8c8c8c"
EDGE = "#5a5a5a"
ALPHA = 0.25


def _plot_coords(points: np.ndarray) -> np.ndarray:
    """World (..., 3) points as plot coordinates (x, z, y)."""
    return np.asarray(points, dtype=np.float64)[..., [0, 2, 1]]


def _basis(direction) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors perpendicular to the unit ``direction`` and to each other."""
    d = np.asarray(direction, dtype=np.float64)
    helper = np.array([0.0, 1.0, 0.0]) if abs(d[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    u = np.cross(d, helper)
    u /= np.linalg.norm(u)
    return u, np.cross(d, u)


def _polygons(ax, faces, gid: str):
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    artist = Poly3DCollection([_plot_coords(face) for face in faces], facecolor=FACE, edgecolor=EDGE,
                              linewidths=0.3, alpha=ALPHA)
    artist.set_gid(gid)
    ax.add_collection3d(artist)
    return artist


def _surface(ax, grid: np.ndarray, gid: str):
    """A surface through the world points ``grid`` (a, b, 3)."""
    p = _plot_coords(grid)
    artist = ax.plot_surface(p[..., 0], p[..., 1], p[..., 2], color=FACE, alpha=ALPHA, linewidth=0,
                             shade=True)
    artist.set_gid(gid)
    return artist


def sphere_grid(centre, radius: float, n: int = 24) -> np.ndarray:
    theta = np.linspace(0.0, np.pi, n // 2 + 1)
    phi = np.linspace(0.0, 2.0 * np.pi, n + 1)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    unit = np.stack([np.sin(t) * np.cos(p), np.cos(t), np.sin(t) * np.sin(p)], axis=-1)
    return np.asarray(centre) + radius * unit


def box_faces(centre, half) -> list[np.ndarray]:
    """The six faces of an axis-aligned box, each (4, 3) corners in order."""
    c, h = np.asarray(centre, dtype=np.float64), np.asarray(half, dtype=np.float64)
    faces = []
    for axis in range(3):
        a, b = [k for k in range(3) if k != axis]
        for side in (-1.0, 1.0):
            corners = []
            for sa, sb in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                point = c.copy()
                point[axis] += side * h[axis]
                point[a] += sa * h[a]
                point[b] += sb * h[b]
                corners.append(point)
            faces.append(np.array(corners))
    return faces


def cylinder_parts(centre, axis, radius: float, length: float, n: int = 24):
    """(side grid (2, n + 1, 3), [two cap polygons (n, 3)]) of a capped cylinder."""
    a = np.asarray(axis, dtype=np.float64)
    u, v = _basis(a)
    angles = np.linspace(0.0, 2.0 * np.pi, n + 1)
    ring = radius * (np.cos(angles)[:, None] * u + np.sin(angles)[:, None] * v)
    ends = [np.asarray(centre) + s * (length / 2.0) * a for s in (-1.0, 1.0)]
    side = np.stack([end + ring for end in ends])
    return side, [end + ring[:-1] for end in ends]


def plane_patch(point, normal, around: np.ndarray) -> np.ndarray:
    """(4, 3) corners of the square patch of the plane under the points ``around`` (module docstring)."""
    n = np.asarray(normal, dtype=np.float64)
    u, v = _basis(n)
    points = np.asarray(around, dtype=np.float64).reshape(-1, 3)
    middle = points.mean(axis=0) if len(points) else np.asarray(point, dtype=np.float64)
    foot = middle - np.dot(middle - np.asarray(point), n) * n
    offsets = points - foot
    half = 1.1 * max(np.abs(offsets @ u).max(initial=0.0), np.abs(offsets @ v).max(initial=0.0), 1.0)
    return np.array([foot + su * half * u + sv * half * v for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1))])


def draw_obstacles(ax, obstacles, around: np.ndarray) -> list:
    """Draw every obstacle into the 3-D axes ``ax`` (module docstring); returns the artists."""
    artists = []
    for k, obstacle in enumerate(obstacles):
        gid = f"obstacle:{obstacle.kind}:{k}"
        if obstacle.kind == "sphere":
            artists.append(_surface(ax, sphere_grid(obstacle.centre, obstacle.radius), gid))
        elif obstacle.kind == "box":
            artists.append(_polygons(ax, box_faces(obstacle.centre, obstacle.half_extents), gid))
        elif obstacle.kind == "cylinder":
            side, caps = cylinder_parts(obstacle.centre, obstacle.axis, obstacle.radius, obstacle.length)
            artists.append(_surface(ax, side, gid))
            _polygons(ax, caps, gid + ":caps")
        else:
            corners = plane_patch(obstacle.centre, obstacle.normal, around)
            artists.append(_polygons(ax, [corners], gid))
            foot = corners.mean(axis=0)
            tip = foot + 0.15 * np.linalg.norm(corners[0] - corners[1]) * np.asarray(obstacle.normal)
            segment = _plot_coords(np.array([foot, tip]))
            ax.plot(segment[:, 0], segment[:, 1], segment[:, 2], color=EDGE, linewidth=1.0)
    return artists
