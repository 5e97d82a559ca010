"""The first compile, in fresh processes with an empty numba cache: a run compiles only the perception
kind and the dynamics it uses (a holland run never compiles the topological kNN nor another dynamics'
hooks, an opensteer run neither the binocular view phase nor occlusion), every simcore kernel is compiled
for one signature only (a second signature is a whole second compile; the run loop once per dynamics and
perception kind), a second process loads everything from the cache, and the notice that kernels are
compiling is printed once per process that compiles."""
from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from paths import ROOT

CODE = """
import collections, json, sys
from numba.core import event
runs = []
class Count(event.Listener):
    def on_start(self, ev):
        pass
    def on_end(self, ev):
        func = ev.data["dispatcher"].py_func
        runs[-1][f"{func.__module__}.{func.__qualname__}"] += 1
event.register("numba:compile", Count())
from flocksweep.simcore import load_preset, simulate_preset
for name in sys.argv[2:]:
    runs.append(collections.Counter())
    preset = load_preset(sys.argv[1] + "/configs/models/" + name, ["init.n=12", "run.duration=0.1"])
    simulate_preset(preset, 1)
print(json.dumps([{k: v for k, v in run.items() if k.startswith("flocksweep.simcore.")} for run in runs]))
"""

RUN_LOOP = "flocksweep.simcore.kernel.run_model"
PERCEIVERS = {kind: f"flocksweep.simcore.perception.perceive_{kind}" for kind in ("sphere", "opensteer", "binocular",
                                                                        "topological")}
NEAREST, OCCLUDE = "flocksweep.simcore.topological.nearest", "flocksweep.simcore.occlusion.occlude"
OTHER_DYNAMICS = tuple(f"flocksweep.simcore.{name}." for name in
                       ("hartman_benes", "reynolds87", "boidspp", "couzin2002", "vicsek", "headings"))


def compiles(cache, *models) -> tuple[list[dict], str]:
    """What each run compiled (qualified name -> count), in a fresh process, and its stderr."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache),
               PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    done = subprocess.run([sys.executable, "-c", CODE, str(ROOT), *models], cwd=cache.parent, env=env,
                          capture_output=True, text=True, timeout=1800)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1]), done.stderr


@pytest.mark.slow
def test_a_run_compiles_its_own_perception_kind_once_and_the_notice_is_printed_once(tmp_path):
    cache = tmp_path / "cache"
    (holland, opensteer), stderr = compiles(cache, "holland.toml", "opensteer.toml")
    assert {RUN_LOOP, PERCEIVERS["binocular"], OCCLUDE, "flocksweep.simcore.opensteer.sense",
            "flocksweep.simcore.opensteer.move"} <= set(holland)
    assert not [name for name in holland if name.startswith(OTHER_DYNAMICS)]
    assert set(holland).isdisjoint({PERCEIVERS["sphere"], PERCEIVERS["opensteer"], PERCEIVERS["topological"],
                                    NEAREST})
    # the second kind adds its run loop, its perceiver and the perceiver's own helper (an @llvm_inline,
    # compiled on its own), nothing else (the other leaves are shared)
    assert opensteer == {RUN_LOOP: 1, PERCEIVERS["opensteer"]: 1, "flocksweep.simcore.perception._opensteer": 1}
    assert {name: count for name, count in holland.items() if count != 1} == {}
    assert stderr.count("compiling the simulation kernels") == 1

    (holland, opensteer), stderr = compiles(cache, "holland.toml", "opensteer.toml")
    assert holland == opensteer == {}, "a second process compiled again instead of loading numba's cache"
    assert "compiling" not in stderr   # nothing compiled: no notice (each kind's own notice: above)
