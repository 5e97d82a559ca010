"""simcore.placeholder_observations: a run's arrays, types and shapes without running (the warm-up of the
metric kernels in a process that does not compile the run loop, sweeps/warmup.py)."""
from __future__ import annotations

import dataclasses
import os
import subprocess
import sys

import numpy as np
import pytest

from paths import ROOT
from flocksweep.simcore import load_preset, placeholder_observations, simulate

MODELS = sorted((ROOT / "configs" / "models").glob("*.toml"))
ARRAYS = ("times", "pos", "vel", "visible", "binocular", "leader", "triggers", "pattern", "predator", "prey",
          "captures")


def _tiny(path, **changes):
    preset = load_preset(path)
    init = dataclasses.replace(preset.init, n=5)
    model = dataclasses.replace(preset.model, **changes) if changes else preset.model
    return model, init, preset.run.dt


@pytest.mark.parametrize("path", MODELS, ids=lambda p: p.stem)
def test_every_array_has_the_type_shape_and_layout_of_a_run(path):
    model, init, dt = _tiny(path)
    run = simulate(model, init, 3, 4 * dt, dt, 2)
    placeholder = placeholder_observations(model, init, 3, 4 * dt, dt, 2)
    for name in ARRAYS:
        real, fake = getattr(run, name), getattr(placeholder, name)
        assert (real is None) == (fake is None), name
        if real is not None:
            real, fake = np.asarray(real), np.asarray(fake)
            assert (fake.dtype, fake.ndim, fake.flags.c_contiguous) == (real.dtype, real.ndim,
                                                                       real.flags.c_contiguous), name
            if name not in ("triggers", "captures"):   # event lists: none in a placeholder
                assert fake.shape == real.shape, name
    assert (placeholder.dt, placeholder.record_every) == (run.dt, run.record_every)
    for name in ("pos", "vel", "fwd", "up", "side", "acc", "pattern"):
        assert getattr(placeholder.final, name).dtype == getattr(run.final, name).dtype


def test_every_record_is_the_initial_state_of_the_seed_and_nothing_is_perceived():
    model, init, dt = _tiny(MODELS[0])
    run = simulate(model, init, 11, dt, dt, 1)   # record 0 of a run is its initial state
    placeholder = placeholder_observations(model, init, 11, 6 * dt, dt, 2)
    assert placeholder.pos.shape == (4, 5, 3)
    assert np.array_equal(placeholder.times, np.arange(4) * 2 * dt)
    for r in range(4):
        assert np.array_equal(placeholder.pos[r], run.pos[0]) and np.array_equal(placeholder.vel[r], run.vel[0])
    assert not placeholder.visible.any() and not placeholder.binocular.any() and not placeholder.leader.any()
    assert placeholder.triggers.shape == (0, 2)


@pytest.mark.slow   # over half a second of CPU: out of the quick loop (CI runs it)
def test_it_compiles_nothing_even_with_an_empty_cache(tmp_path):
    """In a fresh process whose numba cache is empty, placeholders of a leadership model (whose trigger
    bound is a compiled function) start no compile at all."""
    code = """
import sys
from numba.core import event
starts = []
class Count(event.Listener):
    def on_start(self, ev):
        starts.append(ev.data["dispatcher"].py_func.__qualname__)
    def on_end(self, ev):
        pass
event.register("numba:compile", Count())
from flocksweep.simcore import load_preset, placeholder_observations
preset = load_preset(sys.argv[1] + "/configs/models/hartman_benes.toml", ["leadership.x=4.0"])
obs = placeholder_observations(preset.model, preset.init, 1, 1.0, preset.run.dt, 6)
print(len(starts), obs.pos.shape[0])
"""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"),
               PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    done = subprocess.run([sys.executable, "-c", code, str(ROOT)], env=env, capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr
    starts, records = done.stdout.split()
    assert starts == "0" and int(records) > 1
