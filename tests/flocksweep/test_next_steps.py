"""Every command names what comes next, with its real paths: the last lines of its output are ``next:``
and the commands to run or files to open (sweeps.progress.next_steps). Run in-process on tiny inputs:
simulate, run (and a dry run), status, export, compile's helper, targets (TOML comments), and
calibrate's Ctrl-C hint, whose "stop here and still get a report" command is checked to do so. The
commands with long work (report, view, measure, calibrate, sbc, compare, posterior) are checked where
their end-to-end tests already run them (tests/flocksweep/test_progress.py, tests/analysis/calibration)."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from flocksweep.cli import main
from malformed import calibration_text
from paths import ROOT

HOLLAND = str(ROOT / "configs/models/holland.toml")
TINY = ["--set", "run.n=6", "--set", "run.duration=1.0", "--set", "run.record_interval=0.5",
        "--set", "run.warmup=0.25"]


def next_lines(out: str) -> list[str]:
    lines = out.splitlines()
    assert "next:" in lines, out
    start = len(lines) - lines[::-1].index("next:")
    assert start > 0 and all(line.startswith("  ") for line in lines[start:]), out   # the last lines
    return [line.strip() for line in lines[start:]]


@pytest.fixture(scope="module")
def tiny_sweep(tmp_path_factory):
    out = tmp_path_factory.mktemp("next") / "tiny"
    assert main(["run", "--model", HOLLAND, "--axis", "perception.field_deg=60,180", *TINY, "--executor", "serial",
                 "--out", str(out), "--no-progress"]) == 0
    return out


def test_run_names_its_report_and_a_run_to_view(tiny_sweep, tmp_path, capsys):
    assert main(["run", "--model", HOLLAND, "--axis", "perception.field_deg=60,180", *TINY, "--executor", "serial",
                 "--out", str(tiny_sweep), "--no-progress"]) == 0        # again: nothing to compute, same steps
    steps = next_lines(capsys.readouterr().out)
    assert steps[0] == (f"flocksweep report {tiny_sweep}   (statistics, figures and claims: "
                        f"{tiny_sweep / 'report' / 'report.html'})")
    run_id = steps[1].split("--run ")[1].split()[0]
    assert steps[1].startswith(f"flocksweep view {tiny_sweep} --run {run_id}")
    assert (tiny_sweep / "runs.parquet").is_file() and len(run_id) == 20


def test_a_dry_run_names_the_same_command_without_dry_run(tmp_path, capsys):
    assert main(["run", "--model", HOLLAND, "--axis", "perception.field_deg=60,180", *TINY, "--executor", "serial",
                 "--out", str(tmp_path / "d"), "--dry-run"]) == 0
    (step,) = next_lines(capsys.readouterr().out)
    assert step.startswith(f"flocksweep run --model {HOLLAND} --axis=perception.field_deg=60,180 --set=run.n=6")
    assert f"--out {tmp_path / 'd'}" in step and "--dry-run" not in step


def test_status_names_the_report_or_the_runs_still_to_compute(tiny_sweep, tmp_path, capsys):
    assert main(["status", str(tiny_sweep)]) == 0
    assert next_lines(capsys.readouterr().out) == [
        f"flocksweep report {tiny_sweep}   (statistics, figures and claims of the finished runs)"]
    from flocksweep.commands.status import after_status

    folder = Path("results/x")
    unfinished = after_status(folder, {"running": None, "missing": 3, "failed": 2, "ok": 5})
    assert unfinished == [
        "flocksweep run results/x/sweep.toml --out results/x   (computes the 3 missing runs only)",
        "flocksweep run results/x/sweep.toml --out results/x --retry-failed   (runs the failed ones again)",
        "flocksweep report results/x   (statistics, figures and claims of the finished runs)"]
    assert after_status(folder, {"running": "pid 7", "missing": 3, "failed": 0, "ok": 0})[0].startswith(
        "flocksweep status results/x   (again")


def test_the_stored_sweep_file_that_status_names_runs_the_sweep(tiny_sweep, capsys):
    assert main(["run", str(tiny_sweep / "sweep.toml"), "--out", str(tiny_sweep), "--executor", "serial",
                 "--no-progress"]) == 0
    assert "2 runs, 2 ok, 0 failed; computed 0 now, 2 already done" in capsys.readouterr().out


def test_export_names_how_to_read_what_it_wrote(tiny_sweep, tmp_path, capsys):
    assert main(["export", str(tiny_sweep), "--csv", "--out", str(tmp_path / "e")]) == 0
    steps = next_lines(capsys.readouterr().out)
    assert steps[0].startswith(f'pandas.read_csv("{tmp_path / "e" / "runs.csv"}") in Python, '
                               f'read.csv("{tmp_path / "e" / "runs.csv"}") in R')
    assert (tmp_path / "e" / "runs.csv").is_file() and steps[1].startswith(f"flocksweep report {tiny_sweep}")


def test_simulate_names_the_viewer_of_its_run_and_a_sweep(tmp_path, capsys):
    out = tmp_path / "one"
    assert main(["simulate", HOLLAND, "--n", "5", "--duration", "1", "--out", str(out)]) == 0
    steps = next_lines(capsys.readouterr().out)
    assert steps[0] == f"flocksweep view {out / 'trajectory.npz'}   (this run in 3-D)"
    assert steps[1].startswith(f"flocksweep run --model {HOLLAND} --axis perception.field_deg=60,120,180")
    assert main(["simulate", HOLLAND, "--n", "5", "--duration", "1", "--seed", "3"]) == 0      # nothing written
    assert next_lines(capsys.readouterr().out)[0] == (f"flocksweep view {HOLLAND} --seed=3 --n=5 --duration=1.0   "
                                                      "(this run in 3-D)")


def test_targets_name_the_next_step_as_toml_comments(tmp_path, capsys):
    config = tmp_path / "c.toml"
    config.write_text(calibration_text().replace("{holland}", HOLLAND))
    assert main(["targets", str(config), "--truth", "field=150", "--replicates", "1"]) == 0
    out = capsys.readouterr().out
    assert out.rstrip().splitlines()[-2:] == [f"# next: put this [targets] table in {config} (in place of its own), "
                                              "then run", f"#   flocksweep calibrate {config}"]
    import tomllib

    tomllib.loads(out)                                           # still TOML to paste


@pytest.mark.slow   # over half a second of CPU: out of the quick loop (CI runs it)
def test_calibrate_names_its_report_and_on_ctrl_c_how_to_stop_with_a_report(tmp_path, capsys):
    """After an interrupt the hint's "stop here" command makes the saved steps the whole chain: no step
    is added and the report is written."""
    from flocksweep.analysis.calibration.chainfile import stored_steps
    from flocksweep.analysis.calibration.run import resume_hint
    from flocksweep.commands.calibrate import stop_early_hint

    config = tmp_path / "c.toml"
    config.write_text(calibration_text(steps=3).replace("{holland}", HOLLAND))
    out = tmp_path / "out"
    assert main(["calibrate", str(config), "--out", str(out), "--no-progress"]) == 0
    assert next_lines(capsys.readouterr().out)[0] == (f"open {out / 'report.html'} in a browser (verdicts first, "
                                                      "then the posterior and its checks)")
    for name in ("report.html", "report.md", "convergence.json"):   # as if Ctrl-C had stopped it after 3 steps
        (out / name).unlink()
    hint = stop_early_hint(resume_hint, str(config), out)
    assert hint.splitlines()[1] == (f"  or stop here and still get a report from the 3 saved steps: flocksweep "
                                    f"calibrate {config} --out {out} --resume --set method.steps=3")
    command = hint.splitlines()[1].split(": flocksweep ")[1].split()
    assert main(command + ["--no-progress"]) == 0
    assert stored_steps(out / "chain.h5") == 3 and (out / "report.html").is_file()
    assert json.loads((out / "convergence.json").read_text())["steps"] == 3
