"""Cost of the compiled obstacle geometry per call, single thread, after compilation.

    python bench/bench_obstacles.py [--repeats 5] [--calls 200000]

Each figure is the median over repeats of one compiled loop making ``--calls`` calls with fixed-seed
random boids (positions in a ball of radius 12 around one obstacle, 25 around a scene; half the headings
aimed at the centre; body radius 0.5, lookahead 10, margin 1): a ray cast against one obstacle of each
kind, ``first_hit``, ``nearest_clearance`` and ``steer_to_avoid`` against a scene of 10 mixed obstacles,
and ``fan_avoid_direction`` with 32 rays against 10 spheres. Prints a Markdown table (ns per call, with
the share of rays that hit or of calls that steer).
"""
from __future__ import annotations

import argparse
import os
import statistics
import time

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numba as nb  # noqa: E402
import numpy as np  # noqa: E402

from flocksweep.simcore import obstacle_avoidance as avoid  # noqa: E402
from flocksweep.simcore import obstacles as geo  # noqa: E402
from flocksweep.simcore.obstacle_spec import Obstacle, pack_obstacles  # noqa: E402

SINGLE = {
    "sphere": Obstacle("sphere", centre=(0, 0, 0), radius=3.0),
    "plane": Obstacle("plane", centre=(0, -5, 0), normal=(0, 1, 0)),
    "box": Obstacle("box", centre=(0, 0, 0), half_extents=(3, 2, 1)),
    "cylinder": Obstacle("cylinder", centre=(0, 0, 0), axis=(0.3, 0.9, 0.3), radius=1.5, length=6.0),
}
SCENE = (
    Obstacle("plane", centre=(0, -20, 0), normal=(0, 1, 0)),
    *(Obstacle("sphere", centre=(x, 0, z), radius=2.0) for x, z in ((-10, -10), (10, -10), (0, 10))),
    *(Obstacle("box", centre=(x, 5, z), half_extents=(2, 5, 2)) for x, z in ((-12, 8), (12, 8), (0, -15))),
    *(Obstacle("cylinder", centre=(x, 0, z), axis=(0, 1, 0), radius=1.5, length=20.0)
      for x, z in ((-5, 0), (5, 0), (0, 20))),
)
SPHERES = tuple(Obstacle("sphere", centre=tuple(c), radius=2.0)
                for c in np.random.default_rng(1).uniform(-15, 15, (10, 3)))


@nb.njit(cache=False)
def ray_casts(table, kinds, pos, fwd):
    acc = 0.0
    for i in range(pos.shape[0]):
        acc += geo.ray_cast(table, kinds, 0, pos[i, 0], pos[i, 1], pos[i, 2], fwd[i, 0], fwd[i, 1], fwd[i, 2],
                            0.5, 10.0)[1] < 1e9
    return acc


@nb.njit(cache=False)
def first_hits(table, kinds, pos, fwd):
    acc = 0.0
    for i in range(pos.shape[0]):
        acc += geo.first_hit(table, kinds, pos[i, 0], pos[i, 1], pos[i, 2], fwd[i, 0], fwd[i, 1], fwd[i, 2],
                             0.5, 10.0)[0] >= 0
    return acc


@nb.njit(cache=False)
def clearances(table, kinds, pos):
    acc = 0.0
    for i in range(pos.shape[0]):
        acc += geo.nearest_clearance(table, kinds, pos[i, 0], pos[i, 1], pos[i, 2])[1]
    return acc


@nb.njit(cache=False)
def steers(table, kinds, pos, fwd, up):
    acc = 0.0
    for i in range(pos.shape[0]):
        acc += avoid.steer_to_avoid(table, kinds, pos[i, 0], pos[i, 1], pos[i, 2], fwd[i, 0], fwd[i, 1], fwd[i, 2],
                                    up[i, 0], up[i, 1], up[i, 2], 0.5, 10.0, 1.0)[0] >= 0
    return acc


@nb.njit(cache=False)
def fans(table, kinds, fan, pos, fwd, up, side):
    acc = 0.0
    for i in range(pos.shape[0]):
        acc += avoid.fan_avoid_direction(table, kinds, fan, pos[i, 0], pos[i, 1], pos[i, 2], fwd[i, 0], fwd[i, 1],
                                         fwd[i, 2], up[i, 0], up[i, 1], up[i, 2], side[i, 0], side[i, 1],
                                         side[i, 2], 0.5, 10.0)[0] != avoid.FAN_CLEAR
    return acc


def boids(calls: int, radius: float, seed: int = 0):
    """Positions uniform in a ball of ``radius``; half the headings random, half aimed at the origin
    (give or take 3 units), so that a fair share of the rays meet an obstacle."""
    rng = np.random.default_rng(seed)
    pos = rng.standard_normal((calls, 3))
    pos *= (radius * rng.random(calls) ** (1 / 3) / np.linalg.norm(pos, axis=1))[:, None]
    fwd = rng.standard_normal((calls, 3))
    aimed = rng.random(calls) < 0.5
    fwd[aimed] = rng.normal(0.0, 3.0, (aimed.sum(), 3)) - pos[aimed]
    fwd /= np.linalg.norm(fwd, axis=1, keepdims=True)
    side = np.cross(fwd, [0.0, 1.0, 0.0])
    side /= np.linalg.norm(side, axis=1, keepdims=True)
    up = np.cross(side, fwd)
    return pos, fwd, up, side


def timed(fn, *args, repeats: int) -> tuple[float, float]:
    """(median seconds, the loop's result) after one untimed call (compilation)."""
    result = fn(*args)
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn(*args)
        times.append(time.perf_counter() - start)
    return statistics.median(times), result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--calls", type=int, default=200_000)
    args = parser.parse_args()
    pos, fwd, up, side = boids(args.calls, 12.0)
    rows = []
    for kind, obstacle in SINGLE.items():
        table, kinds = pack_obstacles((obstacle,))
        seconds, hits = timed(ray_casts, table, kinds, pos, fwd, repeats=args.repeats)
        rows.append((f"ray_cast, one {kind}", seconds, f"{hits / args.calls:.0%} of the rays hit"))
    pos, fwd, up, side = boids(args.calls, 25.0)
    table, kinds = pack_obstacles(SCENE)
    seconds, found = timed(first_hits, table, kinds, pos, fwd, repeats=args.repeats)
    rows.append(("first_hit, 10 mixed obstacles", seconds, f"{found / args.calls:.0%} of the rays hit"))
    seconds, _ = timed(clearances, table, kinds, pos, repeats=args.repeats)
    rows.append(("nearest_clearance, 10 mixed obstacles", seconds, ""))
    seconds, active = timed(steers, table, kinds, pos, fwd, up, repeats=args.repeats)
    rows.append(("steer_to_avoid, 10 mixed obstacles", seconds, f"{active / args.calls:.0%} of the calls steer"))
    table, kinds = pack_obstacles(SPHERES)
    fan = avoid.golden_fan(32)
    seconds, active = timed(fans, table, kinds, fan, pos, fwd, up, side, repeats=args.repeats)
    rows.append(("fan_avoid_direction, 32 rays, 10 spheres", seconds, f"{active / args.calls:.0%} of the calls steer"))
    print(f"| call | ns per call (median of {args.repeats} x {args.calls:,} calls) | note |")
    print("|---|---:|---|")
    for name, seconds, note in rows:
        print(f"| {name} | {1e9 * seconds / args.calls:,.0f} | {note} |")


if __name__ == "__main__":
    main()
