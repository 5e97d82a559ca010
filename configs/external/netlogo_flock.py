#!/usr/bin/env python3
"""Run a NetLogo model headless through BehaviorSpace and write its turtles' tracks in long format: the
wrapper pattern of docs/sweeps.md ("A NetLogo model").

It writes a BehaviorSpace setup file (one experiment, one run: ``random-seed`` then ``setup``, ``go`` for
``--ticks`` ticks, one metric: every turtle's who, xcor and ycor at every tick, and one value for every
``--<variable> VALUE`` it is given, ``_`` in a name read as ``-``), runs

    netlogo-headless.sh --model MODEL --setup-file SETUP --experiment flocksweep --table TABLE --threads 1

(a list of arguments, no shell) and turns the table into CSV rows ``id, t, x, y`` (t = tick x
``--tick-seconds``), with the positions unwrapped across the edges of a wrapping world (each step taken
the short way round), so a flock that crosses an edge does not jump. NetLogo's seed is an integer in
[-2^31, 2^31): the run's seed is taken modulo 2^31.

    python netlogo_flock.py --netlogo /opt/NetLogo/netlogo-headless.sh --model Flocking.nlogo \\
        --seed 7 --out tracks.csv --scratch /tmp/run --ticks 300 --population 30 --vision 5.0
"""
import argparse
import csv
import re
import subprocess
import sys
from pathlib import Path
from xml.sax.saxutils import escape, quoteattr

METRIC = "[(list who xcor ycor)] of turtles"


def arguments(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    for name in ("--netlogo", "--model", "--out", "--scratch"):
        p.add_argument(name, required=True)
    p.add_argument("--seed", type=int, required=True)
    p.add_argument("--ticks", type=int, default=300)
    p.add_argument("--tick-seconds", type=float, default=1.0)
    known, rest = p.parse_known_args(argv)
    if len(rest) % 2 or not all(a.startswith("--") for a in rest[::2]):
        p.error(f"model variables come as --name value pairs, got {rest}")
    known.variables = {name[2:].replace("_", "-"): value for name, value in zip(rest[::2], rest[1::2])}
    return known


def setup_xml(seed: int, ticks: int, variables: dict) -> str:
    values = "".join(f"<enumeratedValueSet variable={quoteattr(name)}><value value={quoteattr(value)}/>"
                     "</enumeratedValueSet>" for name, value in variables.items())
    return ('<?xml version="1.0" encoding="us-ascii"?>\n<experiments><experiment name="flocksweep" repetitions="1" '
            f'runMetricsEveryStep="true"><setup>random-seed {seed % 2**31}\nsetup</setup><go>go</go>'
            f'<timeLimit steps="{ticks}"/><metric>{escape(METRIC)}</metric>{values}</experiment></experiments>\n')


def read_table(path: Path):
    """(world width, world height, [(step, [(who, x, y), ...]), ...]) of a BehaviorSpace table."""
    with open(path, newline="") as handle:
        lines = list(csv.reader(handle))
    world = dict(zip(lines[4], map(float, lines[5])))
    width = world["max-pxcor"] - world["min-pxcor"] + 1
    height = world["max-pycor"] - world["min-pycor"] + 1
    at = next(i for i, line in enumerate(lines) if line and line[0] == "[run number]")
    header = lines[at]
    step, metric = header.index("[step]"), header.index(METRIC)
    ticks = []
    for line in lines[at + 1:]:
        numbers = [float(v) for v in re.findall(r"-?[\d.]+(?:[eE][-+]?\d+)?", line[metric])]
        ticks.append((int(float(line[step])), [tuple(numbers[k:k + 3]) for k in range(0, len(numbers), 3)]))
    return width, height, sorted(ticks)


def unwrapped(width: float, height: float, ticks):
    """Rows (who, tick, x, y), each turtle's steps taken the short way round the wrapping world."""
    seen = {}   # who -> (unwrapped position, position as NetLogo reported it)
    for tick, turtles in ticks:
        for who, x, y in turtles:
            if who in seen:
                (ux, uy), (wx, wy) = seen[who]
                dx, dy = x - wx, y - wy
                ux, uy = ux + dx - width * round(dx / width), uy + dy - height * round(dy / height)
            else:
                ux, uy = x, y
            seen[who] = ((ux, uy), (x, y))
            yield int(who), tick, ux, uy


def main(argv=None):
    a = arguments(argv)
    scratch = Path(a.scratch)
    (scratch / "setup.xml").write_text(setup_xml(a.seed, a.ticks, a.variables))
    status = subprocess.run([a.netlogo, "--model", a.model, "--setup-file", str(scratch / "setup.xml"),
                             "--experiment", "flocksweep", "--table", str(scratch / "table.csv"),
                             "--threads", "1"], stdin=subprocess.DEVNULL).returncode
    if status:
        sys.exit(f"netlogo-headless failed with exit status {status}")
    with open(a.out, "w", newline="") as handle:
        out = csv.writer(handle)
        out.writerow(["id", "t", "x", "y"])
        for who, tick, x, y in unwrapped(*read_table(scratch / "table.csv")):
            out.writerow([who, repr(tick * a.tick_seconds), repr(x), repr(y)])


if __name__ == "__main__":
    main()
