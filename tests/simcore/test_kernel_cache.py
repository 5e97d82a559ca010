"""simcore._cache: numba's on-disk cache kept in step with the sources and with the name the package is
imported under (numba records neither the sources a kernel inlines nor that name)."""
from __future__ import annotations

from flocksweep.simcore._cache import STAMP, refresh


def package_with_cache(tmp_path):
    folder = tmp_path / "pkg"
    (folder / "__pycache__").mkdir(parents=True)
    (folder / "kernels.py").write_text("x = 1\n")
    return folder


def cached(folder):
    for name in ("kernels.f-3.py311.nbi", "kernels.f-3.py311.1.nbc"):
        (folder / "__pycache__" / name).write_bytes(b"kernel")
    return sorted(p.name for p in (folder / "__pycache__").glob("*.nb*"))


def test_unchanged_sources_keep_the_cache_and_an_edit_drops_it(tmp_path):
    folder = package_with_cache(tmp_path)
    refresh(folder, "flocksweep.pkg")
    assert (folder / "__pycache__" / STAMP).exists()
    assert cached(folder) and not refresh(folder, "flocksweep.pkg")
    assert len(list((folder / "__pycache__").glob("*.nb*"))) == 2
    (folder / "kernels.py").write_text("x = 2\n")
    assert refresh(folder, "flocksweep.pkg")
    assert not list((folder / "__pycache__").glob("*.nb*"))


def test_kernels_cached_under_another_import_name_are_dropped(tmp_path):
    """A kernel cached when the layer was the top-level package ``pkg`` names its modules ``pkg.X``; under
    ``flocksweep.pkg`` it would fail to load, so the same sources under a new name drop the cache."""
    folder = package_with_cache(tmp_path)
    refresh(folder, "pkg")
    cached(folder)
    assert refresh(folder, "flocksweep.pkg")
    assert not list((folder / "__pycache__").glob("*.nb*"))


def test_both_layers_with_kernels_keep_their_cache_in_step():
    import flocksweep.observables as observables
    import flocksweep.simcore as simcore
    from pathlib import Path

    for package in (simcore, observables):
        stamp = Path(package.__file__).parent / "__pycache__" / STAMP
        assert stamp.read_text().strip().endswith(f" {package.__name__}")
