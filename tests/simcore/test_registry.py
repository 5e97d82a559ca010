"""The registry of dynamics (simcore.registry): every built-in described by a numba-free descriptor and run
by its hooks module; plug-ins described through the same path.

Fast: every built-in's descriptor and hooks are complete; validating a preset imports no numba; random
streams are distinct; nothing above the descriptors branches on a dynamics' name; a plug-in's flags
reach validation. Slow: a throwaway built-in from a temporary package (two files and one registry entry,
no other file edited) validates, keeps its own table in the canonical form and runs; Vicsek's heading
rule written as a full-hook plug-in (examples/vicsek_heading.py) reproduces the built-in bit for bit.
"""
from __future__ import annotations

import os
import re
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from paths import ROOT
from flocksweep.simcore import ConfigError, load_preset, simulate
from flocksweep.simcore import registry, rng
from flocksweep.simcore.params import DYNAMICS, Cruise, ModelParams, Perception, World, model_dict

HOOKS = ("pack", "scratch", "sense", "move")


def test_every_built_in_is_described_with_complete_hooks():
    assert DYNAMICS == registry.builtin_names() and len(DYNAMICS) == 6
    for number, dynamics in enumerate(registry.builtins()):
        assert dynamics.number == number and dynamics.builtin
        assert registry.by_number(number) is dynamics is registry.describe(dynamics.name)
        hooks = dynamics.hooks()
        missing = [name for name in HOOKS if not callable(getattr(hooks, name, None))]
        assert not missing, f"{dynamics.name}: hooks module {hooks.__name__} lacks {missing}"
        assert dynamics.table in {f.name for f in ModelParams.__dataclass_fields__.values()}


def test_validating_a_preset_imports_no_numba():
    script = textwrap.dedent("""
        import sys
        from flocksweep.simcore.params import load_preset
        for name in ("holland", "reynolds87_obstacles", "boidspp_predator", "couzin2002_torus", "vicsek"):
            load_preset(f"configs/models/{name}.toml").to_dict()
        print("numba" in sys.modules)
    """)
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "False"


def test_random_streams_are_distinct():
    shared = {name: value for name, value in vars(rng).items() if name.startswith("STREAM_")}
    used = [(f"rng.{name}", value) for name, value in shared.items()]
    used += [(f"{d.name}.{name}", value) for d in registry.builtins() for name, value in d.streams.items()]
    numbers = [value for _, value in used]
    assert len(numbers) == len(set(numbers)), f"streams shared: {sorted(used, key=lambda u: u[1])}"


BRANCH = re.compile(r"dynamics (==|!=|in|not in) ")


def test_nothing_above_the_descriptors_branches_on_a_dynamics_name():
    descriptors = {ROOT / "simcore" / f"{module.lstrip('.')}.py" for module in registry.BUILTINS.values()}
    found = []
    for folder in ("simcore", "observables", "sweeps", "analysis", "flocksweep"):
        for path in (ROOT / folder).rglob("*.py"):
            if path in descriptors:
                continue
            for number, line in enumerate(path.read_text().splitlines(), 1):
                if BRANCH.search(line):
                    found.append(f"{path.relative_to(ROOT)}:{number}: {line.strip()}")
    assert not found, "\n".join(found)


def test_capabilities_come_from_the_descriptor():
    sphere = Perception(kind="sphere")
    with pytest.raises(ConfigError, match="world.dimensions"):   # plug-ins are 3-D unless they say PLANAR
        load_preset(ROOT / "examples" / "couzin_like.toml", ["world.dimensions=2"])
    with pytest.raises(ConfigError, match="perception.kind"):
        ModelParams(dynamics="vicsek", perception=Perception(kind="binocular"))
    with pytest.raises(ConfigError, match="cruise.speed"):
        ModelParams(dynamics="couzin2002", perception=sphere, cruise=Cruise(speed=2.0))
    with pytest.raises(ConfigError, match="world.obstacles"):
        load_preset(ROOT / "configs/models/reynolds87_obstacles.toml", ["dynamics='hartman_benes'"])
    planar = ModelParams(dynamics="vicsek", perception=sphere, world=World(dimensions=2))
    assert model_dict(planar)["perception"] == {"kind": "sphere"}   # the sphere is vicsek.radius
    assert planar.sphere_radius == planar.vicsek.radius


def test_a_plugin_may_declare_what_it_can_do():
    sys.path.insert(0, str(ROOT))
    try:
        preset = load_preset(ROOT / "examples" / "vicsek_heading.toml", ["init.n=20"])
        described = registry.describe(preset.model.dynamics)
    finally:
        sys.path.remove(str(ROOT))
    assert not described.builtin and described.planar and described.heading and described.hooks_module == \
        "examples.vicsek_heading"
    with pytest.raises(ConfigError, match="noise"):
        preset.replace({"noise.kappa": 10.0})                 # its own noise: SHARED_NOISE = False
    with pytest.raises(ConfigError, match="perception.kind"):
        preset.replace({"perception": {"kind": "topological"}})


TOY_DESCRIPTOR = '''
"""A throwaway dynamics: every boid flies straight on at its table's speed."""
from dataclasses import dataclass

from flocksweep.simcore.plugin import PluginParams, parameter

TABLE = "toy"
HOOKS = "toy_pkg.toy"
PERCEPTION = "sphere"


@dataclass(frozen=True)
class Params(PluginParams):
    TABLE = "toy"
    speed: float = parameter(2.0, unit="units/s", low=0.0, length=1)


def check(model):
    pass
'''

TOY_HOOKS = '''
"""The throwaway dynamics' hooks: straight on at ``toy.speed``."""
import numpy as np

from flocksweep.simcore.layout import F


def pack(model, dt):
    return (np.array([model.toy.speed]), np.zeros(0, np.int64), np.zeros((0, 1)), np.zeros(0, np.int64),
            np.zeros((0, 3)))


def scratch(dynamics, n):
    return np.zeros((n, 1)), np.zeros((0, 3))


def sense(dynamics, i, step, m, nbrs, state, params, key, scratch):
    scratch[0][i, 0] = m
    return False


def move(dynamics, i, state, params, scratch):
    pos, vel, fwd = state[0], state[1], state[2]
    fp, ip, dyn = params
    for c in range(3):
        vel[i, c] = dyn[0][0] * fwd[i, c]
        pos[i, c] += vel[i, c] * fp[F.DT]
'''

TOY_RUN = textwrap.dedent("""
    import json
    from flocksweep.simcore import registry
    registry.BUILTINS["toy"] = "toy_pkg.toy_params"       # the one registry line
    import numpy as np
    from flocksweep.simcore import ConfigError, preset_from_dict, simulate_preset
    preset = preset_from_dict({"dynamics": "toy", "toy": {"speed": 3.0}, "perception": {"kind": "sphere"},
                               "init": {"n": 5, "speed": 1.0}, "run": {"duration": 1.0, "dt": 0.1,
                                                                       "record_interval": 0.5}})
    obs = simulate_preset(preset, seed=4)
    step = obs.pos[-1] - obs.pos[0]
    try:
        preset.replace({"toy.speed": -1.0})
        refused = ""
    except ConfigError as err:
        refused = str(err)
    print(json.dumps({"tables": sorted(preset.to_dict()), "speeds": np.linalg.norm(obs.vel[-1], axis=1).tolist(),
                      "travelled": np.linalg.norm(step, axis=1).tolist(), "refused": refused,
                      "number": registry.describe("toy").number}))
""")


@pytest.mark.slow
def test_a_throwaway_built_in_from_a_temporary_package(tmp_path):
    """Its descriptor and hooks in a package of its own, its one registry entry set before the presets are
    read: nothing else is edited, and it validates, is identified and runs (in a fresh process with its own
    numba cache, so the shared cache never holds it)."""
    package = tmp_path / "toy_pkg"
    package.mkdir()
    (package / "__init__.py").write_text("")
    (package / "toy_params.py").write_text(TOY_DESCRIPTOR)
    (package / "toy.py").write_text(TOY_HOOKS)
    env = {**os.environ, "PYTHONPATH": f"{tmp_path}{os.pathsep}{ROOT}", "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    done = subprocess.run([sys.executable, "-c", TOY_RUN], capture_output=True, text=True, env=env, timeout=1500,
                          cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    import json

    out = json.loads(done.stdout.strip().splitlines()[-1])
    assert out["number"] == len(DYNAMICS)
    assert "toy" in out["tables"] and not {"steering", "vehicle", "vicsek", "plugin"} & set(out["tables"])
    assert out["speeds"] == pytest.approx([3.0] * 5, rel=1e-12)
    assert out["travelled"] == pytest.approx([3.0 * 1.0] * 5, rel=1e-9)   # straight on, first to last record
    assert "toy.speed" in out["refused"]


def _heading_pair(dimensions: int):
    sys.path.insert(0, str(ROOT))
    try:
        builtin = load_preset(ROOT / "configs" / "models" / "vicsek.toml",
                              ["init.n=60", "init.radius=1.5", f"world.dimensions={dimensions}", "vicsek.noise=1.0",
                               "world.box_size=3.0", "run.duration=40", "run.record_interval=5"])
        plugin = builtin.replace({"dynamics": "examples.vicsek_heading", "vicsek": {},
                                  "perception": {"kind": "sphere", "radius": builtin.model.vicsek.radius},
                                  "plugin": {"speed": builtin.model.vicsek.speed, "noise": builtin.model.vicsek.noise}})
    finally:
        sys.path.remove(str(ROOT))
    return builtin, plugin


@pytest.mark.slow
@pytest.mark.parametrize("dimensions", [2, 3])
def test_vicsek_written_as_a_plugin_is_the_built_in_bit_for_bit(dimensions):
    builtin, plugin = _heading_pair(dimensions)
    assert plugin.model.dynamics == "examples.vicsek_heading"
    run = lambda p, threads: simulate(p.model, p.init, 11, p.run.duration, p.run.dt, 5, threads=threads)  # noqa: E731
    a, b = run(builtin, 1), run(plugin, 1)
    assert np.array_equal(a.pos, b.pos) and np.array_equal(a.vel, b.vel)
    assert not np.array_equal(a.pos[0], a.pos[-1])                         # it moved
    if dimensions == 2:
        assert np.array_equal(b.pos, run(plugin, 2).pos)                   # THREADS = True: the same on two
