"""Training CPU of one flow, ours against sbi's NPE, on the same simulations (issue 43's target "training
CPU per flow at most sbi's one flow on the same simulations", measured side by side).

    python bench/bench_npe.py --simulations 500 --rounds 2 --ensemble 5 --seeds 1 --out OUT   # writes OUT/.../flows/train-1000.npz
    python bench/bench_sbi_flow.py --data OUT/500-5-r2-s1/flows/train-1000.npz --sbi-python /tmp/sbivenv/bin/python --repeats 3

The data file holds ``theta`` (N, d) and ``x`` (N, k), exactly what the calibration's flow was trained on
(the statistics transformed, measurement noise added). Each repeat starts one process per side, ours
first then sbi's (interleaved, so both see the same machine load), and each process trains ``--flows``
flows one after the other (seeds 0, 1, ...): the first flow of a process pays JAX's or PyTorch's one-off
start (compilation, kernel selection), the later ones are what each further member of an ensemble or round
costs. A flow's CPU is the process's user + sys seconds around the training call alone (imports and data
loading excluded; every thread of JAX or PyTorch counted). Ours: ``npe_flow.train_flow`` with the
calibration's default settings. sbi: ``NPE(prior=BoxUniform(bounds)).append_simulations(theta,
x).train()`` with sbi's defaults (a masked autoregressive flow; batches of 200, learning rate 5e-4, 10 %
validation, stop after 20 epochs without improvement). sbi needs PyTorch, which flocksweep does not
depend on: install both in a throwaway virtual environment (``python -m venv /tmp/sbivenv &&
/tmp/sbivenv/bin/pip install sbi==0.27.*``; several GB of CUDA packages come with PyPI's Linux torch)
and name its python with ``--sbi-python``. ``--threads 1`` runs both sides with one OpenMP/MKL thread
(PyTorch's idle threads spin: on a busy 2-core machine sbi's flow took 167-181 CPU-s with its default 2
threads and 10 CPU-s with one). ``--which ours|sbi`` runs one side in this process (what the
driver calls). Prints one JSON line per process and a markdown table of the medians.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

BOUNDS = [[60.0, 300.0], [0.0, 90.0]]     # recover_holland's uniform priors (field, direction)


def _cpu() -> float:
    times = os.times()
    return times.user + times.system


def ours(theta, x, seed: int) -> dict:
    from flocksweep.analysis.calibration.npe_flow import FlowSettings, train_flow

    estimator = train_flow(theta, x, FlowSettings(), seed)
    return {"epochs": len(estimator.losses["train"])}


def train_sbi(theta, x, seed: int) -> dict:
    import torch
    from sbi.inference import NPE
    from sbi.utils import BoxUniform

    torch.manual_seed(seed)
    bounds = torch.tensor(BOUNDS, dtype=torch.float32)
    inference = NPE(prior=BoxUniform(low=bounds[:, 0], high=bounds[:, 1]), show_progress_bars=False)
    inference.append_simulations(torch.tensor(theta, dtype=torch.float32), torch.tensor(x, dtype=torch.float32))
    inference.train()
    return {"epochs": int(inference.epoch)}


def one_side(which: str, data: Path, flows: int) -> list[dict]:
    arrays = np.load(data)
    theta, x = np.asarray(arrays["theta"], dtype=float), np.asarray(arrays["x"], dtype=float)
    train = ours if which == "ours" else train_sbi
    if which == "ours":
        import flocksweep.analysis.calibration.npe_flow  # noqa: F401 - imports outside the timing
    else:
        import tempfile

        import sbi.inference  # noqa: F401

        os.chdir(tempfile.mkdtemp(prefix="sbi-logs-"))   # sbi writes its tensorboard logs to ./sbi-logs
    rows = []
    for seed in range(flows):
        cpu, wall = _cpu(), time.perf_counter()
        row = train(theta, x, seed)
        rows.append({"which": which, "flow": seed, "simulations": len(theta), "cpu_s": _cpu() - cpu,
                     "wall_s": time.perf_counter() - wall, **row})
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, required=True, help="an .npz with theta and x (bench_npe.py writes them)")
    parser.add_argument("--which", choices=["ours", "sbi"], help="run one side in this process")
    parser.add_argument("--flows", type=int, default=3, help="flows trained one after the other in each process")
    parser.add_argument("--sbi-flows", type=int, help="flows per sbi process (default --flows; sbi's take minutes)")
    parser.add_argument("--threads", type=int, help="OMP/MKL threads of each process (sbi's PyTorch spins its idle "
                        "threads: on a busy machine its default 2 threads cost many times the CPU of 1)")
    parser.add_argument("--repeats", type=int, default=3, help="interleaved pairs of processes")
    parser.add_argument("--sbi-python", default="/tmp/sbivenv/bin/python", help="a python with sbi and torch")
    args = parser.parse_args()
    if args.which:
        for row in one_side(args.which, args.data, args.flows):
            print(json.dumps(row), flush=True)
        return
    rows = []
    for repeat in range(args.repeats):
        for which, python, flows in (("ours", sys.executable, args.flows),
                                     ("sbi", args.sbi_python, args.sbi_flows or args.flows)):
            load = os.getloadavg()[0]
            env = dict(os.environ, **({"OMP_NUM_THREADS": str(args.threads), "MKL_NUM_THREADS": str(args.threads)}
                                      if args.threads else {}))
            out = subprocess.run([python, __file__, "--data", str(args.data), "--which", which, "--flows",
                                  str(flows)], capture_output=True, text=True, check=True, env=env).stdout
            for line in out.splitlines():
                if "{" in line:    # sbi prints "... converged after N epochs." with no newline before ours
                    row = {**json.loads(line[line.index("{"):]), "repeat": repeat, "load": load,
                           "threads": args.threads or "default"}
                    rows.append(row)
                    print(json.dumps(row), flush=True)
    import pandas as pd

    table = pd.DataFrame(rows)
    table["first"] = np.where(table["flow"] == 0, "first flow of the process", "later flows")
    print(table.groupby(["which", "first"])[["cpu_s", "wall_s", "epochs"]].median().round(2).to_string())


if __name__ == "__main__":
    main()
