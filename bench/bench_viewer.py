"""Viewer pages: size, build time, load time and frame rate in headless Chromium, for N = 100 and 1,000.

    python bench/bench_viewer.py [--n 100 1000] [--duration 30] [--repeats 3] [--model configs/models/holland.toml]

For each N: one run of the model (seed 1, recorded every step), then two pages: the default (capped at
5 MB, frames thinned to fit) and uncapped (every step kept). Each page is opened ``--repeats`` times in a
fresh tab of one headless Chromium (Debian's package, SwiftShader WebGL, no GPU; tests/browser.py):
load time = from navigation to the page reporting ready (scripts parsed, frames decoded, scene built,
first frame drawn); frame rate = frames rendered per second while playing, over 4 s. Medians (ranges).
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]   # the checkout's packages before tests/'s same-named folders


def _median_range(values) -> str:
    return f"{statistics.median(values):.2f} ({min(values):.2f}-{max(values):.2f})"


def main() -> None:
    from flocksweep.analysis.viewer.page import MB, build_page
    from flocksweep.analysis.viewer.resimulate import record_step_for
    from flocksweep.analysis.viewer.track import from_observations
    from browser import Browser, measure_fps
    from flocksweep.simcore import load_preset, simulate_preset

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, nargs="+", default=[100, 1000])
    parser.add_argument("--duration", type=float, default=30.0)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--model", default=str(ROOT / "configs/models/holland.toml"))
    parser.add_argument("--out", type=Path, default=Path("results/bench_viewer"))
    args = parser.parse_args()
    rows = []
    for n in args.n:
        preset = load_preset(args.model, [f"init.n={n}", f"run.duration={args.duration}"])
        start = time.perf_counter()
        obs = simulate_preset(preset, 1, record_step_for(preset.run.n_steps, n))
        sim_s = time.perf_counter() - start
        track = from_observations(obs, preset)
        for cap in (5.0, None):
            start = time.perf_counter()
            page = build_page(track, max_mb=cap)
            build_s = time.perf_counter() - start
            path = page.save(args.out / f"n{n}_{'cap5' if cap else 'full'}.html")
            rows.append({"n": n, "cap": cap, "path": path, "mb": page.size_bytes / MB, "frames": page.frames,
                         "stride": page.stride, "build_s": build_s, "sim_s": sim_s})
            print(f"N={n} cap={cap}: {page.size_bytes / MB:.2f} MB, {page.frames} frames (stride {page.stride}), "
                  f"built in {build_s:.1f} s (simulation {sim_s:.1f} s)", flush=True)
    with Browser() as browser:
        for row in rows:
            loads, rates = [], []
            for _ in range(args.repeats):
                opened = browser.open(row["path"], timeout_s=180)
                if opened.errors or opened.blocked:
                    raise SystemExit(f"{row['path']}: console errors {opened.errors}, requests {opened.blocked}")
                loads.append(opened.load_s)
                rates.append(measure_fps(opened, 4.0))
                opened.page.close()
            row["load"], row["fps"] = _median_range(loads), _median_range(rates)
            print(f"N={row['n']} cap={row['cap']}: load {row['load']} s, {row['fps']} frames/s", flush=True)
    print("\n| N | page | size (MB) | frames kept (stride) | build (s) | load in Chromium (s) | frames/s playing |")
    print("|---|---|---|---|---|---|---|")
    for row in rows:
        kind = "default (cap 5 MB)" if row["cap"] else "uncapped"
        print(f"| {row['n']:,} | {kind} | {row['mb']:.2f} | {row['frames']} ({row['stride']}) | {row['build_s']:.1f} | "
              f"{row['load']} | {row['fps']} |")


if __name__ == "__main__":
    main()
