"""From a tracks file to a verdict, end to end, through the documented commands only: simulated tracks of a
known flock written to a file (2-D, from above, position noise, missed detections, metres, a tracker's
column names and an extra channel: configs/tracks/make_flight_2d.py), then

    flocksweep init flight_2d.csv.gz --model configs/models/holland.toml --out fit.toml
    (the researcher's edits: the flock's start, init.radius = 8; the tracker's error, position_sd = 0.1;
     the range of vision left at the preset's; the truth, for the check)
    flocksweep calibrate fit.toml --set method.npe.simulations=N ...

and the verdict, the 90% intervals against the truth and the held-out coverage printed (figures for
bench/RESULTS.md). ``edited(path, truth)`` is the researcher's edit, shared with the end-to-end test
(tests/analysis/calibration/test_tracks_to_verdict.py).

    python bench/bench_tracks_to_verdict.py --out /tmp/e2e --simulations 1500 --heldout 200 --ensemble 3
"""
from __future__ import annotations

import argparse
import importlib.util
import json
import sys
import time
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
TRUTH = {"max_speed": 7.0, "separation_weight": 10.0}


def make_flight():
    spec = importlib.util.spec_from_file_location("make_flight_2d", ROOT / "configs" / "tracks" / "make_flight_2d.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def edited(path: Path, truth: dict = TRUTH) -> Path:
    """The researcher's edit of the file ``flocksweep init`` wrote: the flock's known start (a ball of radius
    8), the tracker's position error (0.1 BL), the range of vision fixed at the preset's, the truth."""
    import tomli_w

    data = tomllib.loads(path.read_text())
    data["model"].setdefault("set", {})["init.radius"] = 8.0
    data["observation"]["position_sd"] = 0.1
    data["parameters"].pop("range", None)
    data["targets"]["truth"] = dict(truth)
    path.write_text(tomli_w.dumps(data))
    return path


def main(argv=None) -> int:
    from flocksweep.cli import main as flocksweep

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--simulations", type=int, default=1500)
    p.add_argument("--heldout", type=int, default=200)
    p.add_argument("--ensemble", type=int, default=3)
    p.add_argument("--rounds", type=int, default=1)
    a = p.parse_args(argv)
    a.out.mkdir(parents=True, exist_ok=True)
    tracks = make_flight().write(a.out)
    started = time.time()
    assert flocksweep(["init", str(tracks), "--model", str(ROOT / "configs" / "models" / "holland.toml"),
                       "--out", str(a.out / "fit.toml"), "--force"]) == 0
    edited(a.out / "fit.toml")
    status = flocksweep(["calibrate", str(a.out / "fit.toml"), "--out", str(a.out / "fit"), "--no-progress",
                         "--set", f"method.simulations={a.simulations}", "--set", f"method.heldout={a.heldout}",
                         "--set", f"method.ensemble={a.ensemble}", "--set", f"method.rounds={a.rounds}"])
    report = json.loads((a.out / "fit" / "convergence.json").read_text())
    print(f"status {status}; {time.time() - started:.0f} s wall; {report['verdict']}")
    print(json.dumps({"coverage": report["npe"]["coverage"], "accounting": report["accounting"]}, indent=1))
    return status


if __name__ == "__main__":
    sys.exit(main())
