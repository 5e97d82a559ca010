#!/usr/bin/env python3
"""A noisy Vicsek-like flock in 3-D open space: the example external simulator of docs/sweeps.md.

Each step every agent takes the mean direction of the headings of the agents within ``--radius`` (itself
included), turns towards their centre with weight ``--cohesion``, adds Gaussian noise of sd ``--noise`` to
each component of that unit heading and moves at ``--speed`` for ``--dt`` seconds. The run is a pure function of its arguments and ``--seed``.
It writes long-format tracks (CSV, one row per agent and record: id, t, x, y, z, vx, vy, vz in body
lengths and seconds), the format ``flocksweep measure`` and a sweep's ``[model] command`` read.

    python vicsek_sim.py --seed 1 --out tracks.csv --n_agents 20 --noise 0.3
"""
import argparse
import csv

import numpy as np


def arguments(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seed", type=int, required=True)
    p.add_argument("--out", required=True, help="the CSV file to write")
    p.add_argument("--n_agents", type=int, default=20)
    p.add_argument("--noise", type=float, default=0.3, help="sd of the heading noise per step")
    p.add_argument("--speed", type=float, default=2.0, help="body lengths per second")
    p.add_argument("--radius", type=float, default=5.0, help="interaction radius, body lengths")
    p.add_argument("--cohesion", type=float, default=0.05, help="weight of the turn towards the neighbours")
    p.add_argument("--duration", type=float, default=10.0, help="seconds")
    p.add_argument("--dt", type=float, default=0.1, help="seconds per step (one record per step)")
    return p.parse_args(argv)


def unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def simulate(a):
    rng = np.random.default_rng(a.seed)
    pos = rng.uniform(-3.0, 3.0, (a.n_agents, 3))
    heading = unit(rng.normal(size=(a.n_agents, 3)) + [2.0, 0.0, 0.0])
    for step in range(int(round(a.duration / a.dt)) + 1):
        yield step * a.dt, pos.copy(), a.speed * heading
        near = np.linalg.norm(pos[:, None] - pos[None], axis=-1) < a.radius
        towards = near @ pos / near.sum(1, keepdims=True) - pos
        heading = unit(unit(near @ heading) + a.cohesion * towards + a.noise * rng.normal(size=heading.shape))
        pos = pos + a.speed * heading * a.dt


def main(argv=None):
    a = arguments(argv)
    with open(a.out, "w", newline="") as handle:
        out = csv.writer(handle)
        out.writerow(["id", "t", "x", "y", "z", "vx", "vy", "vz"])
        for t, pos, vel in simulate(a):
            for i in range(a.n_agents):
                out.writerow([i, repr(t), *map(repr, pos[i].tolist()), *map(repr, vel[i].tolist())])


if __name__ == "__main__":
    main()
