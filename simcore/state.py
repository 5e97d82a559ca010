"""Simulation state as arrays (docs/model.md section 1) and its initial conditions (section 0).

:class:`State` holds, for N boids: ``pos``, ``vel``, ``fwd``, ``up``, ``side``, ``acc`` (float64 (N, 3);
``side`` = normalize(fwd x up), kept with the frame), ``pattern`` (uint32 (N,)) and the leadership
``clock`` (float64 (N,), seconds since the last trigger, +inf at start) and ``escape`` (float64 (N, 3)),
and the Boids++ ``agents`` (float64 (6, 3): predator and prey, :mod:`simcore.boidspp_layout`; NaN
positions until the kernel places them, untouched by the other dynamics). No per-boid objects.

:func:`initial_state` draws it from the run's init generator (``numpy.random.Generator``): positions
uniform in a ball (radius ``InitParams.ball_radius``, centred at the origin), headings uniform on the
sphere, speed ``InitParams.speed``, up = world y made orthogonal to the heading (OpenSteer's reset),
zero smoothed acceleration (or uniform in a cube with ``init.region = "cube"``; in the plane z = 0 for
2-D models, :func:`planar_state`). Patterns: counts are fraction x N rounded by largest remainder (ties to the
earlier entry), and which boid gets which pattern is a random permutation from the same generator.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .boidspp_layout import new_agents
from .params import InitParams, Patterns


FIELDS = ("pos", "vel", "fwd", "up", "side", "acc", "pattern", "clock", "escape")  # the shared kernels' arguments


@dataclass(frozen=True)
class State:
    pos: np.ndarray
    vel: np.ndarray
    fwd: np.ndarray
    up: np.ndarray
    side: np.ndarray
    acc: np.ndarray
    pattern: np.ndarray
    clock: np.ndarray | None = None
    escape: np.ndarray | None = None
    agents: np.ndarray | None = None

    def __post_init__(self):
        n = self.pos.shape[0]
        if self.agents is None:
            object.__setattr__(self, "agents", new_agents())
        if self.clock is None:
            object.__setattr__(self, "clock", np.full(n, np.inf))
        if self.escape is None:
            object.__setattr__(self, "escape", np.zeros((n, 3)))

    @property
    def n(self) -> int:
        return self.pos.shape[0]

    def copy(self) -> "State":
        return State(*(np.array(getattr(self, f), copy=True) for f in FIELDS), agents=self.agents.copy())


def pattern_counts(patterns: Patterns, n: int) -> np.ndarray:
    """Boids per pattern: fraction x n rounded by largest remainder (ties go to the earlier entry)."""
    exact = np.array([p.fraction for p in patterns.set]) * n
    counts = np.floor(exact).astype(np.int64)
    short = n - int(counts.sum())
    order = sorted(range(len(counts)), key=lambda k: (-(exact[k] - counts[k]), k))
    for k in order[:short]:
        counts[k] += 1
    return counts


def frame_from_forward(fwd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(up, side) completing unit headings ``fwd`` (N, 3) to right-handed frames with up near world y."""
    world_up = np.array([0.0, 1.0, 0.0])
    side = np.cross(fwd, world_up)
    norm = np.linalg.norm(side, axis=1, keepdims=True)
    degenerate = norm[:, 0] < 1e-12
    side[degenerate] = np.cross(fwd[degenerate], [1.0, 0.0, 0.0])
    side /= np.linalg.norm(side, axis=1, keepdims=True)
    up = np.cross(side, fwd)
    return up, side


def _pattern_draw(patterns: Patterns, n: int, rng: np.random.Generator) -> np.ndarray:
    values = np.array([p.value for p in patterns.set], dtype=np.uint32)
    return np.repeat(values, pattern_counts(patterns, n))[rng.permutation(n)]


def state_from_file(init: InitParams, patterns: Patterns, rng: np.random.Generator, dimensions: int = 3) -> State:
    """The state in ``init.from_file`` (:mod:`simcore.initfile`); patterns from the file in pattern mode,
    else drawn from ``rng`` as for a random start. In 2-D the frame is the plane's (up = +z, side = f x
    up, :func:`planar_frame`) whatever the file's up (the run checks that the state lies in the plane)."""
    from .initfile import file_digest, read_state_file
    from .schema import ConfigError

    if file_digest(init.from_file) != init.from_file_sha256:
        raise ConfigError("init.from_file", f"{init.from_file!r} changed since this run's spec was made")
    data = read_state_file(init.from_file)
    n = len(data["pos"])
    fwd = data["fwd"]
    if dimensions == 2:
        up, side = planar_frame(fwd)
    elif data["up"] is None:
        up, side = frame_from_forward(fwd)
    else:
        up = data["up"]
        side = np.cross(fwd, up)
        side /= np.linalg.norm(side, axis=1, keepdims=True)
    pattern = np.zeros(n, dtype=np.uint32)
    if patterns.enabled:
        pattern = _pattern_draw(patterns, n, rng) if data["pattern"] is None else data["pattern"]
        if (pattern >> np.uint32(patterns.n_bits)).any() and patterns.n_bits < 32:
            raise ConfigError("init.from_file", f"{init.from_file!r}: patterns do not fit in {patterns.n_bits} bits")
    acc = np.zeros((n, 3)) if data["acc"] is None else data["acc"]
    return State(pos=data["pos"].copy(), vel=data["vel"].copy(), fwd=fwd.copy(), up=up.copy(),
                  side=side, acc=acc.copy(), pattern=np.ascontiguousarray(pattern, dtype=np.uint32))


def initial_state(init: InitParams, patterns: Patterns, rng: np.random.Generator, dimensions: int = 3) -> State:
    """Initial state of ``init.n`` boids drawn from ``rng`` (see module docstring), or read from
    ``init.from_file``. With ``dimensions = 2`` the draw is in the plane z = 0 (:func:`planar_state`)."""
    if init.from_file is not None:
        return state_from_file(init, patterns, rng, dimensions)
    if dimensions == 2:
        return planar_state(init, rng, patterns)
    n = init.n
    if init.region == "cube":
        pos = init.region_radius(3) * (2.0 * rng.random((n, 3)) - 1.0)
    else:
        direction = rng.standard_normal((n, 3))
        direction /= np.linalg.norm(direction, axis=1, keepdims=True)
        radius = init.ball_radius * rng.random(n) ** (1.0 / 3.0)
        pos = direction * radius[:, None]
    fwd = rng.standard_normal((n, 3))
    fwd /= np.linalg.norm(fwd, axis=1, keepdims=True)
    up, side = frame_from_forward(fwd)
    pattern = _pattern_draw(patterns, n, rng)
    if not patterns.enabled:
        pattern = np.zeros(n, dtype=np.uint32)
    return State(pos=pos, vel=fwd * init.speed, fwd=fwd, up=up, side=side, acc=np.zeros((n, 3)),
                 pattern=np.ascontiguousarray(pattern, dtype=np.uint32))


def planar_frame(fwd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(up, side) of headings ``fwd`` (N, 3) in the plane z = 0: up = +z, side = f x up = (f_y, -f_x, 0)
    (:func:`simcore.dynamics.planar_axes`)."""
    up = np.tile([0.0, 0.0, 1.0], (len(fwd), 1))
    side = np.stack([fwd[:, 1], -fwd[:, 0], np.zeros(len(fwd))], axis=1)
    return up, side


def planar_state(init: InitParams, rng: np.random.Generator, patterns: Patterns | None = None) -> State:
    """A start in the plane z = 0: positions uniform in the disc of radius ``init.region_radius(2)`` (or the
    square of that half side, ``region = "cube"``), headings uniform on the circle, up = +z, side = f x up
    (the frame of the 2-D models, :func:`planar_frame`); in pattern mode the patterns are drawn last, as in
    3-D (nothing is drawn for them otherwise)."""
    n = init.n
    half = init.region_radius(2)
    pos = np.zeros((n, 3))
    if init.region == "cube":
        pos[:, :2] = half * (2.0 * rng.random((n, 2)) - 1.0)
    else:
        angle, radius = 2.0 * np.pi * rng.random(n), half * np.sqrt(rng.random(n))
        pos[:, 0], pos[:, 1] = radius * np.cos(angle), radius * np.sin(angle)
    heading = 2.0 * np.pi * rng.random(n)
    fwd = np.stack([np.cos(heading), np.sin(heading), np.zeros(n)], axis=1)
    up, side = planar_frame(fwd)
    pattern = np.zeros(n, dtype=np.uint32)
    if patterns is not None and patterns.enabled:
        pattern = np.ascontiguousarray(_pattern_draw(patterns, n, rng), dtype=np.uint32)
    return State(pos=pos, vel=fwd * init.speed, fwd=fwd, up=up, side=side, acc=np.zeros((n, 3)),
                 pattern=pattern)
