"""The front door: what a newcomer reads first says what they need, no more.

* README.md: at most 150 lines of at most 120 characters; no dated or comparative timing (those live in
  bench/RESULTS.md); every built-in dynamics named; the one-minute try, the main job with its
  expectation, the test command (exactly what CI runs), a Python snippet on ``import flocksweep as fs``,
  and a line for every documentation page.
* LICENSE is BSD-3-Clause and pyproject.toml says so; CONTRIBUTING.md covers the quick loop, CI, the
  architecture test and how to add each kind of piece; CHANGELOG.md keeps "Unreleased" first, then the
  history by feature.
* Every shipped config file opens with a header of at most 10 comment lines; those of sweeps,
  calibrations, comparisons and external sweeps say what the file does, what it costs and the command
  that runs it, with no dated figures.
"""
from __future__ import annotations

import re
import tomllib

import pytest

from flocksweep.simcore import params
from paths import ROOT

README = (ROOT / "README.md").read_text(encoding="utf-8")
DATE = re.compile(r"\b20\d\d-\d\d-\d\d\b")
# "17.8-18.8 s measured", "against 23.7-24.7 s", "63-66 s": a measured range of seconds is a bench figure
TIMING_RANGE = re.compile(r"\b\d+(?:\.\d+)?\s*-\s*\d+(?:\.\d+)?\s*(?:s|ms|min)\b")
DYNAMICS_WORDS = {"opensteer": "OpenSteer", "hartman_benes": "Hartman & Benes", "reynolds87": "Reynolds 1987",
                  "boidspp": "Boids++", "couzin2002": "Couzin et al. 2002", "vicsek": "Vicsek et al. 1995"}
QUICK_START = "python -m pip install -e . && flocksweep run configs/sweeps/holland648.toml"
TEST_COMMAND = "python -m pip install -e '.[test]' && python -m pytest -q -n 2 --dist loadfile"


def test_the_readme_is_short_and_its_lines_are_readable():
    lines = README.splitlines()
    assert len(lines) <= 150, f"README.md has {len(lines)} lines (at most 150)"
    long = [n for n, line in enumerate(lines, 1) if len(line) > 120]
    assert not long, f"README.md lines longer than 120 characters: {long}"


def test_the_readme_holds_no_dated_or_comparative_timing():
    assert not DATE.findall(README), DATE.findall(README)
    assert not TIMING_RANGE.findall(README), TIMING_RANGE.findall(README)
    assert "bench/RESULTS.md" in README


def test_the_readme_names_every_built_in_model_and_plugins_md_too():
    assert set(DYNAMICS_WORDS) == set(params.DYNAMICS)
    intro = "\n".join(README.splitlines()[:8])
    for words in DYNAMICS_WORDS.values():
        assert words in intro, words
    plugins = (ROOT / "docs" / "plugins.md").read_text(encoding="utf-8")
    for name in params.DYNAMICS:
        assert f"`{name}`" in plugins, name


def test_the_quick_start_commands_keep_their_roles_and_ci_runs_the_readmes_test_command():
    assert f"```bash\n{QUICK_START}\n```" in README
    assert f"```bash\n{TEST_COMMAND}\n```" in README
    assert (ROOT / ".ci" / "run").read_text().strip().splitlines()[-1] == TEST_COMMAND
    assert "a few minutes the first time, mostly a one-time compile" in README


def test_the_one_minute_try_is_the_smoke_sweep_its_report_and_the_viewer():
    for command in ("flocksweep run configs/sweeps/smoke.toml", "flocksweep report results/smoke",
                    "flocksweep view results/smoke --showcase wide"):
        assert command in README, command
    smoke = tomllib.loads((ROOT / "configs/sweeps/smoke.toml").read_text())
    assert "wide" in smoke["report"]["showcase"]


def test_the_python_snippet_uses_the_one_face():
    block = re.search(r"## Python API\n+```python\n(.*?)```", README, re.S).group(1)
    assert block.startswith("import flocksweep as fs\n")
    assert 'if __name__ == "__main__":' in block and "fs.run_sweep(" in block


def test_where_to_read_next_names_every_docs_page():
    """Every page of the documentation site's guides (docs/index.md's tables of contents), and the API."""
    section = README[README.index("## Where to read next"):]
    index = (ROOT / "docs" / "index.md").read_text()
    pages = [f"docs/{line.strip()}.md" for block in re.findall(r"```\{toctree\}(.*?)```", index, re.S)
             for line in block.splitlines() if line.strip() and not line.strip().startswith(":")]
    assert "docs/model.md" in pages and "docs/api/index.md" in pages and len(pages) >= 14
    for page in pages:
        assert f"]({page})" in section, page
    assert "docs/architecture.md" in section and "contributors" in section


def test_license_is_bsd_3_clause_and_pyproject_says_so():
    text = (ROOT / "LICENSE").read_text()
    assert text.startswith("BSD 3-Clause License")
    assert "Neither the name of the copyright holder nor the names of its" in text
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert project["license"] == {"text": "BSD-3-Clause"}
    assert "License :: OSI Approved :: BSD License" in project["classifiers"]


def test_contributing_covers_the_loop_ci_the_architecture_test_and_each_extension():
    text = (ROOT / "CONTRIBUTING.md").read_text()
    for needed in ('python -m pytest -q -m "not slow"', TEST_COMMAND, "tests/test_architecture.py",
                   "**A model**", "**A metric**", "**A calibration method**", "**A track format or check**",
                   "**A command**", "docs/architecture.md"):
        assert needed in text, needed


def test_the_changelog_keeps_unreleased_first_then_the_history():
    text = (ROOT / "CHANGELOG.md").read_text()
    headings = re.findall(r"^## (.+)$", text, re.M)
    assert headings[0] == "Unreleased" and any(h.startswith("History") for h in headings[1:])
    for feature in ("Simulator", "Sweeps", "Calibration", "Viewer", "Measured flocks", "More models"):
        assert re.search(rf"^### {feature}", text, re.M), feature


def config_files():
    return sorted(p for p in (ROOT / "configs").rglob("*.toml"))


def header(path) -> list[str]:
    lines = []
    for line in path.read_text(encoding="utf-8").splitlines():
        if not line.startswith("#"):
            break
        lines.append(line)
    return lines


@pytest.mark.parametrize("path", config_files(), ids=lambda p: p.relative_to(ROOT / "configs").as_posix())
def test_every_config_header_is_short_and_undated(path):
    lines = header(path)
    assert lines, f"{path.name} opens with no header saying what it is"
    assert len(lines) <= 10, f"{path.name}: a header of {len(lines)} lines (at most 10)"
    assert not DATE.search("\n".join(lines)), f"{path.name}: a dated figure in its header"


RUNNABLE = ("sweeps", "calibration", "compare", "external")
COST = re.compile(r"^# Cost: .*\b(s|min|minutes?|hours?|an hour|a minute|seconds)\b", re.M)


@pytest.mark.parametrize("path", [p for p in config_files() if p.parent.name in RUNNABLE],
                         ids=lambda p: p.relative_to(ROOT / "configs").as_posix())
def test_every_runnable_config_says_what_it_costs_and_how_to_run_it(path):
    text = "\n".join(header(path))
    relative = path.relative_to(ROOT).as_posix()
    assert re.search(rf"flocksweep (run|calibrate|compare|sbc) {re.escape(relative)}", text), \
        f"{relative}: its header names no command that runs it"
    assert COST.search(text), f"{relative}: its header says nothing of what it costs"


@pytest.mark.slow
def test_the_readmes_python_snippet_runs_as_a_script_and_writes_a_report(tmp_path):
    import os
    import subprocess
    import sys

    block = re.search(r"## Python API\n+```python\n(.*?)```", README, re.S).group(1)
    script = tmp_path / "example.py"
    script.write_text(block.replace('"configs/', f'"{ROOT}/configs/'))
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    done = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=env, capture_output=True, text=True,
                          timeout=900)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "perception.field_deg" in done.stdout and "240" in done.stdout          # the printed table
    assert (tmp_path / "results" / "fov" / "report" / "report.html").is_file()
