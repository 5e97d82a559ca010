"""Synthetic runs for the viewer tests: a milling flock with patterns and leaders, scene objects of every
kind and two extra agents (prey and predator). Builders only; assertions live in the test modules."""
from __future__ import annotations

import numpy as np

from flocksweep.analysis.viewer.track import from_arrays

MAGENTA = "#ff00ff"


def milling_arrays(n: int = 30, frames: int = 91, dt: float = 1 / 30, radius: float = 12.0, seed: int = 3) -> dict:
    """Boids circling the y axis at radius ~``radius`` (omega = 1 rad/s), split into two patterns; boid 0
    leads during the middle third of the run."""
    rng = np.random.default_rng(seed)
    times = np.arange(frames) * dt
    phase = rng.uniform(0, 2 * np.pi, n)
    r = radius + rng.normal(0, 1.0, n)
    height = rng.normal(0, 2.0, n)
    angle = phase[None, :] + times[:, None]
    pos = np.stack([r * np.cos(angle), np.broadcast_to(height, angle.shape), r * np.sin(angle)], axis=-1)
    vel = np.stack([-r * np.sin(angle), np.zeros_like(angle), r * np.cos(angle)], axis=-1)
    leader = np.zeros((frames, n), bool)
    leader[frames // 3: 2 * frames // 3, 0] = True
    pattern = np.where(np.arange(n) % 2, 0b00111010, 0b11000101).astype(np.uint32)
    return {"times": times, "pos": pos, "vel": vel, "pattern": pattern, "leader": leader}


def scene_objects() -> list[dict]:
    return [{"type": "sphere", "center": [0, 0, 0], "radius": 4.0, "color": MAGENTA, "opacity": 1.0, "label": "rock"},
            {"type": "plane", "point": [0, -8, 0], "normal": [0, 1, 0], "size": 60, "color": "#a0b4c8"},
            {"type": "box", "center": [20, 0, 0], "size": [3, 6, 3], "rotation": [0, 0.3827, 0, 0.9239]},
            {"type": "cylinder", "a": [-20, -5, 0], "b": [-20, 5, 0], "radius": 1.5, "caps": "flat"},
            {"type": "cylinder", "a": [0, -5, -20], "b": [0, 5, -20], "radius": 1.5, "caps": "round"}]


def agents(arrays: dict) -> list[dict]:
    times = arrays["times"]
    angle = -0.5 * times
    predator = np.stack([18 * np.cos(angle), np.full_like(angle, 3.0), 18 * np.sin(angle)], axis=-1)[:, None, :]
    prey = arrays["pos"][:, :2, :] + np.array([0.0, 4.0, 0.0])
    return [{"kind": "predator", "label": "hawk", "pos": predator},
            {"kind": "prey", "pos": prey, "color": "#00c8c8"}]


def milling_track(with_scene: bool = True, **kwargs):
    arrays = milling_arrays(**kwargs)
    extra = {"scene": tuple(scene_objects()), "agents": tuple(agents(arrays))} if with_scene else {}
    return from_arrays(**arrays, title="synthetic milling flock", group_radius=6.0,
                       params={"model": "synthetic", "omega": 1.0}, info={"seed": "none"}, **extra)
