#!/usr/bin/env python3
"""A stand-in for NetLogo's netlogo-headless.sh (tests of configs/external/netlogo_flock.py): reads the
BehaviorSpace setup file it is given and writes the table NetLogo would, for turtles that march along +x one
patch per tick (turtle k at y = k, slowed by 0.1 x vision's fraction, starting at x = seed mod 7) in a
world of -8..8 patches that wraps. Its arguments are NetLogo's: --model, --setup-file, --experiment,
--table, --threads."""
import argparse
import csv
import re
import sys
import xml.etree.ElementTree as ET

p = argparse.ArgumentParser()
for name in ("--model", "--setup-file", "--experiment", "--table", "--threads"):
    p.add_argument(name, required=True)
a = p.parse_args()
experiment = ET.parse(a.setup_file).getroot().find("experiment")
assert experiment.get("name") == a.experiment
seed = int(re.match(r"random-seed (-?\d+)\nsetup", experiment.find("setup").text).group(1))
steps = int(experiment.find("timeLimit").get("steps"))
metric = experiment.find("metric").text
values = {e.get("variable"): float(e.find("value").get("value")) for e in experiment.iter("enumeratedValueSet")}
if values.get("population", 0) > 50:
    sys.exit("fake netlogo: population too large")
n, step_size = int(values["population"]), 1.0 - 0.1 * (values["vision"] % 1)

with open(a.table, "w", newline="") as handle:
    out = csv.writer(handle, quoting=csv.QUOTE_ALL)
    out.writerows([["BehaviorSpace results (NetLogo 6.4.0)"], [a.model], [a.experiment], ["01/01/2026 00:00:00"],
                   ["min-pxcor", "max-pxcor", "min-pycor", "max-pycor"], ["-8", "8", "-8", "8"],
                   ["[run number]", *values, "[step]", metric]])
    for tick in range(steps + 1):
        turtles = " ".join(f"[{k} {(seed % 7 + step_size * tick + 8.5) % 17 - 8.5!r} {float(k)!r}]" for k in range(n))
        out.writerow(["1", *map(repr, values.values()), str(tick), f"[{turtles}]"])
