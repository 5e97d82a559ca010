"""Plug-in dynamics (simcore.plugin, docs/plugins.md): a user's module named in a preset.

Fast: its parameters are checked by the schema engine (defaults, bounds with units, unknown keys, the
module's own cross-checks); a bad module or name is refused naming ``dynamics``; the module's source hash
is part of the resolved spec (so of the run id) and a stored spec whose module changed is refused; built-in
specs are unchanged; entry points name a module; only the named module is imported.
Slow: the compiled run agrees with a numpy twin (reference perception and physics, the module's ``steer``
called as plain Python); a plug-in with OpenSteer's rules reproduces the built-in ``opensteer`` bit for
bit; runs are bit-identical alone, batched and threaded; editing a module gives new results in a new
process (numba's cache never serves the old code).
"""
from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from collections import namedtuple

import numpy as np
import pytest

import reference
from conftest import flock_state
from paths import ROOT
from flocksweep.simcore import ConfigError, advance, load_preset, preset_from_dict, simulate, simulate_batch
from flocksweep.simcore import hooks
from flocksweep.simcore import plugin as plugins

COUZIN = ROOT / "examples" / "couzin_like.toml"
PROBE = '''
from dataclasses import dataclass
from flocksweep.simcore.plugin import PluginParams, parameter


@dataclass(frozen=True)
class Params(PluginParams):
    push: float = parameter(1.0, unit="N", low=0.0, high=10.0)
    turns: int = parameter(2, low=1)
    flag: bool = parameter(False)


def steer(i, step, m, nbrs, state, fp, ip, p, key):
    return FORCE * p[0], 0.0, 0.0
'''


@pytest.fixture
def module_dir(tmp_path, monkeypatch):
    """A folder on sys.path for plug-in modules written by a test."""
    monkeypatch.syspath_prepend(str(tmp_path))
    return tmp_path


def write_probe(folder, name, force=1.0):
    (folder / f"{name}.py").write_text(PROBE.replace("FORCE", repr(force)))
    return name


def couzin(**changes):
    preset = load_preset(COUZIN)
    return preset.replace(changes) if changes else preset


def test_parameters_take_defaults_and_preset_values():
    model = couzin().model
    assert model.plugin.zor == 1.0 and model.plugin.noise == 0.05   # from the preset's [plugin]
    assert couzin(**{"plugin": {}}).model.plugin.noise == 0.0          # the declared default
    assert couzin(**{"plugin.zoa": 12}).model.plugin.zoa == 12.0       # an int becomes a float


@pytest.mark.parametrize("changes, key, words", [
    ({"plugin.zor": 0.0}, "plugin.zor", ["0.0 world units", "(0.0, inf)"]),
    ({"plugin.noise": 2.5}, "plugin.noise", ["[0.0, 2.0]"]),
    ({"plugin.gain": float("nan")}, "plugin.gain", ["finite"]),
    ({"plugin.gain": "fast"}, "plugin.gain", ["expected a number"]),
    ({"plugin.zorr": 1.0}, "plugin.zorr", ["did you mean 'zor'"]),
    ({"plugin.zoo": 0.5}, "plugin.zoo", ["zones must nest"]),          # the module's own check
    ({"leadership.x": 0.5}, "leadership.x", ["no change of leadership"]),
])
def test_bad_parameters_are_refused_naming_the_key(changes, key, words):
    with pytest.raises(ConfigError) as caught:
        couzin(**changes)
    assert caught.value.key == key
    for word in words:
        assert word in str(caught.value)


def test_a_built_in_dynamics_has_no_plugin_table():
    preset = load_preset(ROOT / "configs" / "models" / "opensteer.toml")
    with pytest.raises(ConfigError, match="applies only to a plug-in dynamics") as caught:
        preset.replace({"plugin": {"zor": 1.0}})
    assert caught.value.key == "plugin"
    assert "plugin" not in preset.to_dict() and "plugin_sha256" not in preset.to_dict()


@pytest.mark.parametrize("name, words", [
    ("examples.no_such_module", ["no module 'examples.no_such_module'", "PYTHONPATH", "'opensteer'"]),
    ("opensteeer", ["did you mean 'opensteer'"]),
    ("json", ["not a plug-in dynamics", "Params, steer"]),
])
def test_a_name_that_is_no_plugin_is_refused(name, words):
    with pytest.raises(ConfigError) as caught:
        couzin(dynamics=name)
    assert caught.value.key == "dynamics"
    for word in words:
        assert word in str(caught.value)


def test_a_module_that_fails_to_import_is_refused_with_its_error(module_dir):
    (module_dir / "unimportable_plugin.py").write_text("raise RuntimeError('no licence file')\n")
    with pytest.raises(ConfigError, match="RuntimeError: no licence file"):
        couzin(dynamics="unimportable_plugin")


def test_parameter_types_are_checked_by_the_schema(module_dir):
    name = write_probe(module_dir, "probe_types")
    preset = couzin(dynamics=name, plugin={"push": 2, "turns": 3, "flag": True})
    assert preset.model.plugin.push == 2.0 and preset.model.plugin.turns == 3 and preset.model.plugin.flag is True
    with pytest.raises(ConfigError, match="expected an integer"):
        preset.replace({"plugin.turns": 1.5})
    with pytest.raises(ConfigError, match="expected true or false"):
        preset.replace({"plugin.flag": 1})
    with pytest.raises(ConfigError, match=r"got 0; allowed range \[1, inf\)"):
        preset.replace({"plugin.turns": 0})


def test_the_module_source_hash_is_part_of_the_spec(module_dir):
    first = couzin(dynamics=write_probe(module_dir, "probe_hash_a", force=1.0))
    second = couzin(dynamics=write_probe(module_dir, "probe_hash_b", force=2.0))
    spec_a, spec_b = first.to_dict(), second.to_dict()
    assert spec_a["plugin_sha256"] != spec_b["plugin_sha256"]
    assert len(spec_a["plugin_sha256"]) == 64
    assert preset_from_dict(spec_a) == first
    numbers = {plugins.load("probe_hash_a").number, plugins.load("probe_hash_b").number}
    assert len(numbers) == 2 and min(numbers) >= plugins.PLUGIN_BASE


def test_a_stored_spec_whose_module_changed_is_refused(module_dir):
    spec = couzin(dynamics=write_probe(module_dir, "probe_changed")).to_dict()
    spec["plugin_sha256"] = "0" * 64
    with pytest.raises(ConfigError, match="changed since this spec was made"):
        preset_from_dict(spec)


def test_the_run_id_follows_the_module_source():
    from flocksweep.sweeps.identity import run_id
    from flocksweep.observables.summary import MetricSettings
    from flocksweep.sweeps.config import Storage

    spec = couzin().to_dict()
    changed = {**spec, "plugin_sha256": "f" * 64}
    args = (MetricSettings(group_radius=9.0), Storage())
    assert run_id(spec, *args, 1) != run_id(changed, *args, 1)


def test_an_entry_point_names_the_module(monkeypatch):
    point = namedtuple("EntryPoint", "name value")("couzin", "examples.couzin_like")
    monkeypatch.setattr(plugins.importlib.metadata, "entry_points",
                        lambda group: [point] if group == plugins.ENTRY_POINT_GROUP else [])
    monkeypatch.delitem(plugins.LOADED, "couzin", raising=False)
    preset = couzin(dynamics="couzin")
    assert type(preset.model.plugin).__module__ == "examples.couzin_like"
    assert plugins.load("couzin").sha256 == couzin().model.plugin_sha256


def test_only_the_named_module_is_imported(module_dir):
    write_probe(module_dir, "probe_named")
    write_probe(module_dir, "probe_bystander")
    couzin(dynamics="probe_named")
    assert "probe_named" in sys.modules and "probe_bystander" not in sys.modules


# ---------------------------------------------------------------------------------------- compiled runs

def twin_step(preset, state, key):
    """One synchronous step in numpy: reference perception and physics, the module's steer as plain Python."""
    from examples import couzin_like

    model = preset.model
    nbrs_type = namedtuple("Nbrs", "idx off")
    p = np.array(plugins.load(model.dynamics).values(model.plugin))
    fp, ip, _ = hooks.pack(model, preset.run.dt)
    arrays = {name: getattr(state, name).copy() for name in ("pos", "vel", "fwd", "up", "side", "acc")}
    group = (arrays["pos"], arrays["vel"], arrays["fwd"], arrays["up"], arrays["side"], arrays["acc"],
             state.pattern)
    forces = []
    for i in range(state.n):
        seen = reference.perceive(i, state.pos, state.fwd, state.side, model)["visible"]
        off = np.array([reference.offset(state.pos[i], state.pos[j]) for j in seen]).reshape(-1, 3)
        forces.append(couzin_like.steer(i, 0, len(seen), nbrs_type(np.array(seen, np.int64), off), group, fp, ip, p,
                                        np.uint64(key)))
    for i, force in enumerate(forces):
        reference.move(i, force, arrays, model, preset.run.dt)
    return arrays


@pytest.mark.slow
def test_the_compiled_run_matches_its_numpy_twin():
    preset = couzin(**{"perception.radius": 3.5, "plugin.zor": 0.6, "plugin.zoo": 1.5, "plugin.zoa": 3.5,
                       "plugin.noise": 0.3})
    state = flock_state(5, n=24)
    key = 12345
    for step in range(6):
        got = advance(preset.model, state, 1, preset.run.dt, key=key)
        want = twin_step(preset, state, key)
        for name, array in want.items():
            np.testing.assert_allclose(getattr(got.final, name), array, rtol=1e-12, atol=1e-12,
                                       err_msg=f"step {step}: {name}")
        assert got.visible[0].sum() >= 3 * state.n   # a meaningful comparison: neighbours in every zone
        state = got.final


@pytest.mark.slow
@pytest.mark.parametrize("world", [{}, {"world.update_order": "sequential", "world.boundary": "periodic_box",
                                       "world.box_size": 30.0}], ids=["synchronous-open", "sequential-box"])
def test_a_plugin_with_opensteer_rules_is_the_built_in_bit_for_bit(world):
    preset = load_preset(ROOT / "configs" / "models" / "opensteer.toml", ["init.n=40", "run.duration=3"])
    preset = preset.replace(world) if world else preset
    twin = preset.replace({"dynamics": "examples.opensteer_rules"})
    built_in, plugged = simulate(preset.model, preset.init, 4, 3.0, preset.run.dt), \
        simulate(twin.model, twin.init, 4, 3.0, twin.run.dt)
    assert np.array_equal(built_in.pos, plugged.pos) and np.array_equal(built_in.vel, plugged.vel)
    assert np.array_equal(built_in.visible, plugged.visible)
    assert not np.array_equal(built_in.pos[0], built_in.pos[-1])


@pytest.mark.slow
def test_runs_are_bit_identical_alone_batched_and_threaded():
    preset = couzin(**{"init.n": 40})
    args = (preset.model, preset.init)
    alone = [simulate(*args, seed, 4.0, preset.run.dt, 5) for seed in (1, 2)]
    batched = simulate_batch(*args, [1, 2], 4.0, preset.run.dt, 5)
    threaded = simulate(*args, 1, 4.0, preset.run.dt, 5, threads=2)
    for a, b in zip(alone, batched):
        assert np.array_equal(a.pos, b.pos) and np.array_equal(a.vel, b.vel)
    assert np.array_equal(alone[0].pos, threaded.pos)
    assert not np.array_equal(alone[0].pos, alone[1].pos)


STALE_RUN = textwrap.dedent("""
    import sys
    import numpy as np
    from flocksweep.simcore import load_preset, simulate
    preset = load_preset(sys.argv[1]).replace({"dynamics": "plugin_stale_probe", "plugin": {},
                                               "init.n": 6, "perception.radius": 1.0})
    obs = simulate(preset.model, preset.init, 1, 2.0, preset.run.dt, 10)
    print(repr(float(obs.vel[-1, 0, 0])))
""")


def run_probe(folder):
    env = {**os.environ, "PYTHONPATH": f"{folder}{os.pathsep}{ROOT}"}
    done = subprocess.run([sys.executable, "-c", STALE_RUN, str(COUZIN)], capture_output=True, text=True,
                          env=env, timeout=900, cwd=folder)
    assert done.returncode == 0, done.stderr
    return float(done.stdout.strip().splitlines()[-1])


@pytest.mark.slow
def test_an_edited_module_is_compiled_again_not_served_from_the_cache(tmp_path):
    """Each version runs in its own process, the cache of the first present when the second runs: the
    second must give its own results, and the first version again its first results."""
    write_probe(tmp_path, "plugin_stale_probe", force=100.0)
    first = run_probe(tmp_path)
    write_probe(tmp_path, "plugin_stale_probe", force=-100.0)
    second = run_probe(tmp_path)
    assert first > 8.0 and second < -8.0    # pushed (at max_force) along +x to max_speed 9, then along -x
    write_probe(tmp_path, "plugin_stale_probe", force=100.0)
    assert run_probe(tmp_path) == first
