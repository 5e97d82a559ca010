"""Cost of the obstacle, predator and prey metrics of one run, next to the per-record metrics.

    python bench/bench_encounter_metrics.py [--repeats 5] [--records 301]

For N = 100 and 1,000 boids at normal random positions (sd 20) over ``--records`` records, with 10
obstacles (7 spheres, a plane, a box, a cylinder) and a predator and prey at random positions: the
median over repeats of :func:`~observables.encounters.obstacle_metrics`,
``predator_metrics``, ``prey_metrics`` and, for scale, ``frame_metrics`` (one call at N = 1,000).
Prints a Markdown table (milliseconds per run).
"""
from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from flocksweep.observables.encounters import obstacle_metrics, predator_metrics, prey_metrics
from flocksweep.observables.metrics import frame_metrics
from flocksweep.simcore.obstacle_spec import Obstacle


def scene(rng) -> tuple:
    spheres = tuple(Obstacle(kind="sphere", centre=tuple(rng.uniform(-50, 50, 3)), radius=3.0) for _ in range(7))
    return spheres + (Obstacle(kind="plane", centre=(0, -60, 0), normal=(0, 1, 0)),
                      Obstacle(kind="box", centre=(10, 0, 0), half_extents=(2, 3, 4)),
                      Obstacle(kind="cylinder", centre=(-10, 0, 0), axis=(0, 1, 0), radius=2, length=10))


def median_ms(call, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        call()
        times.append(time.perf_counter() - start)
    return 1e3 * statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--records", type=int, default=301)
    args = parser.parse_args()
    rng = np.random.default_rng(1)
    obstacles = scene(rng)
    print("| N | obstacles (10) | predator | prey | frame_metrics |\n|---:|---:|---:|---:|---:|")
    for n in (100, 1000):
        r = args.records
        pos = rng.normal(0, 20, (r, n, 3))
        vel = rng.normal(0, 1, pos.shape)
        agent = rng.normal(0, 20, (r, 3))
        times = np.arange(r) * 0.1
        ones = np.ones(r)
        obstacle_metrics(pos[:2], times[:2], obstacles, 0.5, 3.0)   # compile or load the geometry
        cost = [median_ms(lambda: obstacle_metrics(pos, times, obstacles, 0.5, 3.0), args.repeats),
                median_ms(lambda: predator_metrics(pos, agent, times, ones, ones, 1.0, 10.0, 3.0), args.repeats),
                median_ms(lambda: prey_metrics(pos, agent, times, 5.0), args.repeats),
                median_ms(lambda: frame_metrics(pos, vel, None, None, None, 5.0, None, 0.1),
                          args.repeats if n <= 100 else 1)]
        print(f"| {n:,} | " + " | ".join(f"{c:.0f} ms" for c in cost) + " |")


if __name__ == "__main__":
    main()
