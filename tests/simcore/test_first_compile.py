"""The first compile, in a fresh process with an empty numba cache: every simcore kernel is compiled for
one signature only (a second signature is a whole second compile), and the notice that kernels are
compiling is printed once, however many runs follow."""
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
counts = collections.Counter()
class Count(event.Listener):
    def on_start(self, ev):
        pass
    def on_end(self, ev):
        func = ev.data["dispatcher"].py_func
        counts[f"{func.__module__}.{func.__qualname__}"] += 1
event.register("numba:compile", Count())
from simcore import load_preset, simulate_preset
for name in ("holland.toml", "opensteer.toml"):
    preset = load_preset(sys.argv[1] + "/configs/models/" + name, ["init.n=12", "run.duration=0.1"])
    simulate_preset(preset, 1)
print(json.dumps({k: v for k, v in counts.items() if k.startswith("simcore.")}))
"""


@pytest.mark.slow
def test_each_kernel_compiles_once_and_the_notice_is_printed_once(tmp_path):
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"),
               PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    done = subprocess.run([sys.executable, "-c", CODE, str(ROOT)], cwd=tmp_path, env=env, capture_output=True,
                          text=True, timeout=1800)
    assert done.returncode == 0, done.stderr
    compiled = json.loads(done.stdout.strip().splitlines()[-1])
    assert {"simcore.kernel.run_model", "simcore.perception.perceive", "simcore.occlusion.occlude"} <= set(compiled)
    assert {name: count for name, count in compiled.items() if count != 1} == {}
    assert done.stderr.count("compiling the simulation kernels") == 1
