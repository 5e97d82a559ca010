"""JAX's persistent compilation cache for flocksweep's JAX work (analysis.calibration.jax_cache): which
folder, decided from the environment without importing JAX; the off switch and a user's own
JAX_COMPILATION_CACHE_DIR honoured; a folder others may write refused; old versions' folders removed; and,
end to end, a fresh process writing its compiled programs there, and none with the switch off. The test
suite itself never writes into the real user cache (conftest points both caches at folders of the run)."""
from __future__ import annotations

import os
import subprocess
import sys
import time
from importlib.metadata import version
from pathlib import Path

import pytest

from flocksweep.analysis.calibration import jax_cache
from flocksweep.analysis.calibration.jax_cache import CacheSetting, cache_setting, enable_cache, remove_stale

VERSIONS = f"jax-{version('jax')}-jaxlib-{version('jaxlib')}"   # the installed packages


def test_the_folder_is_the_users_cache_with_a_subfolder_per_jax_version(tmp_path):
    home = Path.home()
    assert cache_setting({}) == CacheSetting(home / ".cache/flocksweep/jax" / jax_cache.version_folder(), "flocksweep")
    assert cache_setting({"XDG_CACHE_HOME": str(tmp_path)}).folder == tmp_path / "flocksweep/jax" / VERSIONS
    both = {"XDG_CACHE_HOME": str(tmp_path / "xdg"), "FLOCKSWEEP_CACHE_DIR": str(tmp_path / "own")}
    assert cache_setting(both).folder == tmp_path / "own/jax" / VERSIONS
    assert jax_cache.version_folder() == VERSIONS


@pytest.mark.parametrize("value", ["0", "off", "OFF", "false", "no", " 0 "])
def test_the_switch_turns_it_off_even_with_a_jax_folder_set(value, tmp_path):
    setting = cache_setting({"FLOCKSWEEP_JAX_CACHE": value, "JAX_COMPILATION_CACHE_DIR": str(tmp_path)})
    assert setting == CacheSetting(None, "FLOCKSWEEP_JAX_CACHE") and setting.describe().startswith("off")
    assert cache_setting({"FLOCKSWEEP_JAX_CACHE": "1"}).source == "flocksweep"


def test_a_users_own_jax_cache_folder_is_respected(tmp_path):
    setting = cache_setting({"JAX_COMPILATION_CACHE_DIR": str(tmp_path), "FLOCKSWEEP_CACHE_DIR": "/elsewhere"})
    assert setting == CacheSetting(tmp_path, "JAX_COMPILATION_CACHE_DIR")


def test_the_decision_imports_no_jax(tmp_path):
    code = ("import sys; from flocksweep.analysis.calibration.jax_cache import cache_setting; "
            "print(cache_setting().folder); assert 'jax' not in sys.modules and 'jaxlib' not in sys.modules")
    env = {k: v for k, v in os.environ.items() if k != "JAX_COMPILATION_CACHE_DIR"}
    out = subprocess.run([sys.executable, "-c", code], env={**env, "FLOCKSWEEP_CACHE_DIR": str(tmp_path)},
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == str(tmp_path / "jax" / VERSIONS)


def test_the_test_suite_never_uses_the_real_user_cache():
    folder = cache_setting().folder      # conftest's folder of this run, or the caller's JAX_COMPILATION_CACHE_DIR
    assert folder is not None and Path.home() / ".cache/flocksweep" not in folder.parents
    assert cache_setting({k: v for k, v in os.environ.items() if k != "JAX_COMPILATION_CACHE_DIR"}).folder.parents[1] \
        == Path(os.environ["FLOCKSWEEP_CACHE_DIR"])


class FakeJax:
    """The part of the jax module enable_cache uses: its config (values set are recorded)."""

    def __init__(self, cache_dir=None):
        self.config = self
        self.jax_compilation_cache_dir = cache_dir
        self.updates = {}

    def update(self, name, value):
        self.updates[name] = value


@pytest.fixture
def fresh(monkeypatch):
    """enable_cache as in a new process (it applies its setting once per process)."""
    monkeypatch.setattr(jax_cache, "_ENABLED", [])
    monkeypatch.delenv("JAX_COMPILATION_CACHE_DIR", raising=False)
    monkeypatch.delenv("FLOCKSWEEP_JAX_CACHE", raising=False)
    return monkeypatch


def test_enable_sets_the_folder_private_and_keeps_every_program(fresh, tmp_path):
    fresh.setenv("FLOCKSWEEP_CACHE_DIR", str(tmp_path))
    jax = FakeJax()
    setting = enable_cache(jax)
    folder = tmp_path / "jax" / VERSIONS
    assert setting.folder == folder and folder.is_dir() and folder.stat().st_mode & 0o777 == 0o700
    assert jax.updates == {"jax_compilation_cache_dir": str(folder), "jax_persistent_cache_min_compile_time_secs": 0.0,
                           "jax_persistent_cache_min_entry_size_bytes": -1}
    assert enable_cache(FakeJax()) is setting                       # once per process


def test_enable_changes_nothing_when_off_or_when_the_user_set_jax_cache(fresh, tmp_path):
    fresh.setenv("FLOCKSWEEP_CACHE_DIR", str(tmp_path))
    fresh.setenv("FLOCKSWEEP_JAX_CACHE", "0")
    jax = FakeJax()
    assert enable_cache(jax).folder is None and jax.updates == {} and not (tmp_path / "jax").exists()
    fresh.setattr(jax_cache, "_ENABLED", [])
    fresh.delenv("FLOCKSWEEP_JAX_CACHE")
    fresh.setenv("JAX_COMPILATION_CACHE_DIR", str(tmp_path / "mine"))
    jax = FakeJax()
    assert enable_cache(jax).source == "JAX_COMPILATION_CACHE_DIR" and jax.updates == {}
    fresh.setattr(jax_cache, "_ENABLED", [])
    fresh.delenv("JAX_COMPILATION_CACHE_DIR")
    jax = FakeJax(cache_dir=str(tmp_path / "set in code"))            # jax.config.update(...) by the caller
    assert enable_cache(jax) == CacheSetting(tmp_path / "set in code", "JAX_COMPILATION_CACHE_DIR")
    assert jax.updates == {} and not (tmp_path / "jax").exists()


@pytest.mark.skipif(not hasattr(os, "getuid"), reason="POSIX permissions")
def test_a_folder_others_may_write_is_not_used(fresh, tmp_path, capsys):
    fresh.setenv("FLOCKSWEEP_CACHE_DIR", str(tmp_path))
    folder = tmp_path / "jax" / VERSIONS
    folder.mkdir(parents=True)
    folder.chmod(0o777)
    jax = FakeJax()
    assert enable_cache(jax).folder is None and jax.updates == {}
    assert "not a private folder" in capsys.readouterr().err


def test_old_versions_folders_are_removed_recent_ones_kept(tmp_path):
    current, old, recent, other = (tmp_path / name for name in ("jax-9-jaxlib-9", "jax-1-jaxlib-1", "jax-2-jaxlib-2",
                                                                   "notes"))
    for folder in (current, old, recent, other):
        folder.mkdir()
        (folder / "entry").write_text("x")
    long_ago = time.time() - 40 * 86400
    os.utime(old, (long_ago, long_ago))
    os.utime(other, (long_ago, long_ago))
    assert remove_stale(current) == [old]
    assert current.exists() and recent.exists() and other.exists() and not old.exists()


@pytest.mark.slow
def test_a_fresh_process_keeps_its_compiled_programs_there_and_none_when_off(tmp_path):
    pytest.importorskip("jax")
    code = ("from flocksweep.analysis.calibration.npe_flow import require_jax\n"
            "jax, _ = require_jax()\n"
            "print(float(jax.jit(lambda x: (x * 3.0).sum())(jax.numpy.arange(4.0))))\n")
    env = {k: v for k, v in os.environ.items() if not k.startswith(("JAX_COMPILATION", "JAX_PERSISTENT"))}
    for switch, cache in (("1", tmp_path / "on"), ("0", tmp_path / "off")):
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300,
                             env={**env, "FLOCKSWEEP_CACHE_DIR": str(cache), "FLOCKSWEEP_JAX_CACHE": switch})
        assert out.returncode == 0 and out.stdout.strip() == "18.0", out.stderr
    entries = list((tmp_path / "on/jax" / VERSIONS).iterdir())
    assert any(entry.name.startswith("jit_") for entry in entries)
    assert not (tmp_path / "off").exists()
