"""The adversarial battery of docs/errors.md, with the counts it asks for.

    python bench/fault_battery.py [--sweep-seeds 4] [--calibration-seeds 2] [--no-kills] [--json OUT]

1. Malformed inputs: every case of ``tests/malformed.py`` (config files, command-line values, damaged
   input folders) is run through ``flocksweep`` in an empty folder; a case counts as refused cleanly when
   it gets its documented exit status and message, no traceback, and no file is written.
2. Kill trials: the small sweep and the short calibration of ``tests/faults.py`` are stopped at random
   (seeded) moments by SIGINT to the process group, SIGTERM or SIGKILL to the runner, and SIGKILL to one
   worker or to multiprocessing's resource tracker (each seed draws its own moment), then the same command
   is run again with no cleanup; a trial is a lossless resume when the stop gave its documented exit
   status without a traceback, left no process behind, and the rerun's results equal an uninterrupted run's bit for bit.

3. Contained faults (issue 42: runs, stores and commands; ``tests/faults.py`` ``CONTAINED``): plug-ins whose
   steer returns NaN, writes out of bounds (SIGSEGV) or never returns, under serial, ``--workers 1`` and 2
   workers and through ``simulate``; one that does not compile; a built-in run over ``run.timeout_s``; a
   command that writes 200 MiB to stderr or leaves a background child; a value edited and ``manifest.json``
   deleted. A case is contained when every command gives its exit status and words, no traceback, and
   nothing is left running; the figures are each command's seconds and peak memory (its largest process).

Prints one line per failure and the totals; exit status 1 when anything failed.
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]   # the checkout's packages before tests/'s same-named folders

import faults  # noqa: E402  (tests/ holds the battery's cases and harness)
from malformed import CASES, attempt  # noqa: E402


def malformed_inputs(base: Path) -> dict:
    refused, failures = 0, []
    for number, case in enumerate(CASES):
        folder = base / f"case{number}"
        folder.mkdir()
        result = attempt(case, folder)
        if result.clean(case):
            refused += 1
        else:
            failures.append(f"{case.name}: status {result.code}, wrote {sorted(result.written)[:3]}: "
                            f"{(result.crash or result.stderr).strip()[-200:]}")
    return {"tried": len(CASES), "refused_cleanly": refused, "failures": failures}


def contained_faults(base: Path) -> dict:
    rows = []
    for number, case in enumerate(faults.CONTAINED):
        folder = base / f"contained{number}"
        folder.mkdir()
        result = faults.contained_trial(case, folder)
        rows.append({"case": case.name, "problems": result.problems, "seconds": [round(x, 1) for x in result.seconds],
                     "peak_mb": [round(x) for x in result.peak_mb]})
        print(f"  {case.name}: {'contained' if not result.problems else 'NOT CONTAINED'}; seconds "
              f"{', '.join(f'{x:.1f}' for x in result.seconds)}; peak memory "
              f"{', '.join(f'{x:.0f}' for x in result.peak_mb)} MB", flush=True)
        for line in result.problems:
            print(f"    {line}")
    return {"tried": len(rows), "contained": sum(not r["problems"] for r in rows), "cases": rows}


def lossless(trial, rerun, difference) -> str:
    """'' for a lossless trial, else why not."""
    if not trial.hit:
        return f"the command had finished before the signal ({trial.delay:.1f} s)"
    if trial.exit_code != faults.EXPECTED_EXIT[trial.how]:
        return f"exit status {trial.exit_code}, expected {faults.EXPECTED_EXIT[trial.how]}"
    if trial.traceback or "Traceback" in rerun.stderr:
        return "a traceback"
    if trial.orphans:
        return f"processes left behind: {trial.orphans}"
    if rerun.returncode != 0:
        return f"the rerun exited {rerun.returncode}"
    return difference


def kill_trials(base: Path, kind: str, seeds: int) -> dict:
    argv_of = faults.sweep_argv if kind == "sweep" else faults.calibration_argv
    ready_of = faults.sweep_ready if kind == "sweep" else faults.calibration_ready
    trial_of = faults.sweep_trial if kind == "sweep" else faults.calibration_trial
    reference = base / f"{kind}-reference"
    reference.mkdir()
    _, span = faults.timed_run(argv_of(reference), reference, ready_of(reference))
    rows = []
    for how in faults.HOW:
        for seed in range(1, seeds + 1):
            folder = base / f"{kind}-{how}-{seed}"
            folder.mkdir()
            trial, rerun, difference = trial_of(folder, reference / "out", how, seed, window=(0.1, 0.8 * span))
            rows.append({"kind": kind, "how": how, "seed": seed, "delay_s": round(trial.delay, 2),
                         "exit": trial.exit_code, "stopped_in_s": round(trial.elapsed_after_signal, 2),
                         "problem": lossless(trial, rerun, difference)})
            print(f"  {kind} {how} seed {seed}: signal after {trial.delay:.1f} s, exit {trial.exit_code}, "
                  f"{rows[-1]['problem'] or 'lossless resume'}", flush=True)
    return {"span_s": span, "trials": rows}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sweep-seeds", type=int, default=4, help="seeds per kind of kill for the sweep")
    parser.add_argument("--calibration-seeds", type=int, default=2, help="seeds per kind of kill for the calibration")
    parser.add_argument("--no-malformed", action="store_true", help="no malformed inputs")
    parser.add_argument("--no-kills", action="store_true", help="no kill trials")
    parser.add_argument("--no-contained", action="store_true", help="no contained-fault cases")
    parser.add_argument("--json", type=Path, help="also write the counts and every trial here")
    args = parser.parse_args(argv)
    started = time.time()
    report = {}
    with tempfile.TemporaryDirectory(prefix="fault-battery-") as tmp:
        base = Path(tmp)
        (base / "inputs").mkdir()
        m = report["malformed"] = ({"tried": 0, "refused_cleanly": 0, "failures": []} if args.no_malformed
                                   else malformed_inputs(base / "inputs"))
        print(f"malformed inputs: {m['tried']} tried, {m['refused_cleanly']} refused cleanly before any write",
              flush=True)
        for line in m["failures"]:
            print(f"  NOT CLEAN {line}")
        if not args.no_contained:
            report["contained"] = contained_faults(base)
            c = report["contained"]
            print(f"contained faults: {c['tried']} tried, {c['contained']} contained", flush=True)
        trials = []
        if not args.no_kills:
            for kind, seeds in (("sweep", args.sweep_seeds), ("calibration", args.calibration_seeds)):
                report[kind] = kill_trials(base, kind, seeds)
                trials += report[kind]["trials"]
    good = sum(not t["problem"] for t in trials)
    report["kills"] = {"trials": len(trials), "lossless_resumes": good}
    report["wall_s"] = time.time() - started
    if trials:
        print(f"kill trials: {len(trials)} ({sum(t['kind'] == 'sweep' for t in trials)} sweep, "
              f"{sum(t['kind'] == 'calibration' for t in trials)} calibration), {good} lossless resumes")
    print(f"{report['wall_s']:.0f} s")
    if args.json:
        args.json.write_text(json.dumps(report, indent=2))
    contained_ok = args.no_contained or report["contained"]["contained"] == report["contained"]["tried"]
    return 0 if not m["failures"] and good == len(trials) and contained_ok else 1


if __name__ == "__main__":
    sys.exit(main())
