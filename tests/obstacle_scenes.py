"""Builders for the obstacle tests: single obstacles by kind, random obstacles and rays (fixed seeds).

Only builders live here; every assertion is in the test modules.
"""
from __future__ import annotations

import numpy as np

from flocksweep.simcore.obstacle_spec import Obstacle, pack_obstacles

AXES = np.eye(3)


def sphere(centre, radius) -> Obstacle:
    return Obstacle("sphere", centre=tuple(centre), radius=radius)


def plane(centre, normal) -> Obstacle:
    return Obstacle("plane", centre=tuple(centre), normal=tuple(normal))


def box(centre, half_extents) -> Obstacle:
    return Obstacle("box", centre=tuple(centre), half_extents=tuple(half_extents))


def cylinder(centre, axis, radius, length) -> Obstacle:
    return Obstacle("cylinder", centre=tuple(centre), axis=tuple(axis), radius=radius, length=length)


def packed(*obstacles):
    return pack_obstacles(obstacles)


def unit(rng: np.random.Generator, n: int | None = None) -> np.ndarray:
    v = rng.standard_normal(3 if n is None else (n, 3))
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def random_obstacle(rng: np.random.Generator, kind: str) -> Obstacle:
    """An obstacle of ``kind`` near the origin; a third of boxes' rays and cylinders' axes are made
    axis-aligned elsewhere, so degenerate views come up."""
    centre = rng.uniform(-3.0, 3.0, 3)
    if kind == "sphere":
        return sphere(centre, rng.uniform(0.5, 4.0))
    if kind == "plane":
        return plane(centre, unit(rng))
    if kind == "box":
        return box(centre, rng.uniform(0.3, 4.0, 3))
    axis = AXES[rng.integers(3)] if rng.random() < 0.3 else unit(rng)
    return cylinder(centre, axis, rng.uniform(0.3, 3.0), rng.uniform(0.5, 8.0))


def random_direction(rng: np.random.Generator, obstacle: Obstacle, start: np.ndarray) -> np.ndarray:
    """Mostly toward the obstacle (about half the rays hit), sometimes exactly along a world axis or,
    for a cylinder, exactly along or across its axis."""
    roll = rng.random()
    if roll < 0.1:
        return AXES[rng.integers(3)] * rng.choice([-1.0, 1.0])
    if obstacle.kind == "cylinder" and roll < 0.2:
        axis = np.asarray(obstacle.axis)
        if roll < 0.15:
            return axis * rng.choice([-1.0, 1.0])
        across = np.cross(axis, unit(rng))
        return across / np.linalg.norm(across)
    aim = np.asarray(obstacle.centre) + rng.normal(0.0, 3.0, 3) - start
    return aim / np.linalg.norm(aim)


def random_rays(rng: np.random.Generator, obstacle: Obstacle, n: int):
    """(starts (n, 3), directions (n, 3), body radii (n,), lookaheads (n,)); one lookahead in 20 is 0."""
    starts = unit(rng, n) * (15.0 * rng.random(n) ** (1.0 / 3.0))[:, None]
    directions = np.array([random_direction(rng, obstacle, p) for p in starts])
    radii = rng.uniform(0.05, 1.0, n)
    lookaheads = np.where(rng.random(n) < 0.05, 0.0, rng.uniform(1.0, 30.0, n))
    return starts, directions, radii, lookaheads


def frame_from(forward, up_hint=(0.0, 1.0, 0.0)):
    """(f, u, s): forward, up made perpendicular to it, side = f x u."""
    f = np.asarray(forward, dtype=float)
    f = f / np.linalg.norm(f)
    u = np.asarray(up_hint, dtype=float)
    u = u - (u @ f) * f
    if np.linalg.norm(u) < 1e-9:
        u = np.array([1.0, 0.0, 0.0]) - f[0] * f
    u = u / np.linalg.norm(u)
    return f, u, np.cross(f, u)
