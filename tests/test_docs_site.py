"""The documentation site builds with Sphinx (MyST pages + autodoc/napoleon API reference) with every
warning an error, as CI builds it: a broken cross reference, a heading or docstring Sphinx cannot read,
or a public name that fails to import breaks this test. The API pages document the public names."""
from __future__ import annotations

import subprocess
import sys

import pytest

from paths import ROOT


@pytest.mark.slow
def test_the_docs_site_builds_without_warnings(tmp_path):
    out = tmp_path / "html"
    done = subprocess.run([sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html",
                           str(ROOT / "docs"), str(out)], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-5000:]
    assert not done.stderr.strip(), done.stderr[-5000:]
    api = {page: (out / "api" / f"{page}.html").read_text(encoding="utf-8") for page in ("simcore", "sweeps", "analysis")}
    for page, names in {"simcore": ["flocksweep.simcore.load_preset", "flocksweep.simcore.simulate_preset", "flocksweep.simcore.Preset"],
                        "sweeps": ["flocksweep.sweeps.run_sweep", "flocksweep.sweeps.load_results", "flocksweep.sweeps.config.SweepConfig",
                                   "flocksweep.sweeps.config.SweepConfig.from_toml", "flocksweep.sweeps.config.SweepConfig.from_dict"],
                        "analysis": ["flocksweep.analysis.report", "flocksweep.analysis.calibrate", "flocksweep.analysis.summary_simulator",
                                     "flocksweep.analysis.calibration.config.CalibrationConfig",
                                     "flocksweep.analysis.calibration.config.CalibrationConfig.from_toml"]}.items():
        for name in names:
            assert f'id="{name}"' in api[page], name
    assert "NUMBA_NUM_THREADS" in api["analysis"]       # summary_simulator's thread use is documented
    for guide in ("model", "sweeps", "calibration", "architecture"):
        assert (out / f"{guide}.html").exists(), guide
