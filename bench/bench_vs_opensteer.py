"""flocksweep against the OpenSteer C++ Boids plugin: fidelity from the same state, then speed side by side.

    python bench/bench_vs_opensteer.py --opensteer DIR [--sizes 50 100 200 1000] [--steps 3600] [--repeats 5]
                                       [--init own|cxx] [--json FILE]

DIR is a checkout of OpenSteer's public source (https://github.com/meshula/OpenSteer, measured at commit
7104323: ``git clone https://github.com/meshula/OpenSteer DIR``). Without it the script says so and
exits. In a temporary directory it writes a headless driver of the plugin (the plugin's own
``plugins/Boids.cpp`` compiled in, its proximity database as the plugin builds it, and no-op stand-ins
for the OpenGL drawing and camera of OpenSteerDemo), builds it with ``g++ -O2`` and deletes it
afterwards; nothing of OpenSteer is copied into this repository.

1. Fidelity. The driver seeds ``rand()`` as given and prints its flock's state (position, forward, up,
   side, speed, smoothed acceleration) before and after each of 10 steps of ``BoidsPlugIn::update``. For
   every step k, flocksweep's ``configs/models/opensteer_plugin.toml`` (sequential order, as the plugin
   updates in place) advances the C++ state of step k by one step, and the largest difference from the
   C++ state of step k + 1 is reported; the C++ works in single precision, so the differences should be
   single-precision rounding (below 1e-4), and the script fails otherwise. It also runs the 10 steps
   freely from the C++ initial state (``init.from_file``) and reports the drift.
2. Speed. In one interleaved run (C++, flocksweep, C++, ... for each N and repeat), each side times its
   own update loop in-process over ``--steps`` steps from the same initial state (the C++'s): the C++
   with ``std::chrono`` around the loop, flocksweep with ``time.perf_counter`` around ``advance`` on one
   thread, kernels compiled beforehand, recording only the first and last state. Reported: median
   microseconds per boid-step on each side and the median of the per-repeat ratios C++ time / flocksweep
   time (above 1: flocksweep is faster).
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

from flocksweep.simcore import State, advance, load_preset  # noqa: E402

PRESET = ROOT / "configs" / "models" / "opensteer_plugin.toml"
DT = 1.0 / 60.0
FIDELITY_STEPS = 10
FIDELITY_TOLERANCE = 1e-4
SOURCES = ["src/SimpleVehicle.cpp", "src/Vec3.cpp", "src/Vec3Utilities.cpp", "src/Obstacle.cpp", "src/PlugIn.cpp",
           "src/Color.cpp", "src/Camera.cpp", "src/lq.c"]

DRIVER = r"""
// Headless driver of the OpenSteer Boids plugin (written by flocksweep's bench/bench_vs_opensteer.py).
// usage: driver N STEPS SEED dump|time
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>
#include "plugins/Boids.cpp"

namespace {
void dump(const std::vector<Boid*>& flock) {
    for (Boid* b : flock) {
        const Vec3 p = b->position(), f = b->forward(), u = b->up(), s = b->side(), a = b->smoothedAcceleration();
        std::printf("%.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g\n",
                    p.x, p.y, p.z, f.x, f.y, f.z, u.x, u.y, u.z, s.x, s.y, s.z, b->speed(), a.x, a.y, a.z);
    }
}
}  // namespace

int main(int argc, char** argv) {
    if (argc != 5) { std::fprintf(stderr, "usage: driver N STEPS SEED dump|time\n"); return 2; }
    const int n = std::atoi(argv[1]), steps = std::atoi(argv[2]);
    std::srand(static_cast<unsigned>(std::atoi(argv[3])));
    const bool timing = std::string(argv[4]) == "time";
    // the plugin's default proximity database (BoidsPlugIn::nextPD, case 0): a 10^3 lq bin lattice
    const float diameter = Boid::worldRadius * 1.1f * 2;
    ProximityDatabase* pd = new LQProximityDatabase<AbstractVehicle*>(
        Vec3(), Vec3(diameter, diameter, diameter), Vec3(10, 10, 10));
    std::vector<Boid*> flock;
    for (int i = 0; i < n; i++) flock.push_back(new Boid(*pd));
    const float dt = 1.0f / 60.0f;
    float t = 0.0f;
    if (!timing) dump(flock);
    const auto start = std::chrono::steady_clock::now();
    for (int k = 0; k < steps; k++) {
        for (Boid* b : flock) b->update(t, dt);  // BoidsPlugIn::update: in place, in flock order
        t += dt;
        if (!timing) dump(flock);
    }
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (timing) std::printf("%.9g\n", seconds);
    return 0;
}
"""

STUBS = r"""
// No-op stand-ins for OpenSteerDemo's OpenGL drawing and camera, so the Boids plugin runs headless.
#include <sstream>
#include "OpenSteer/OpenSteerDemo.h"
#include "OpenSteer/Draw.h"
namespace OpenSteer {
bool enableAnnotation = false;
bool drawPhaseActive = false;
AbstractVehicle* OpenSteerDemo::selectedVehicle = nullptr;
Camera OpenSteerDemo::camera;
const float OpenSteerDemo::cameraTargetDistance = 13;
AbstractVehicle* OpenSteerDemo::vehicleNearestToMouse(void) { return nullptr; }
void OpenSteerDemo::init3dCamera(AbstractVehicle&) {}
void OpenSteerDemo::position3dCamera(AbstractVehicle&) {}
void OpenSteerDemo::updateCamera(const float, const float, const AbstractVehicle*) {}
void OpenSteerDemo::drawCircleHighlightOnVehicle(const AbstractVehicle*, const float, const Color&) {}
void OpenSteerDemo::printMessage(const char*) {}
void OpenSteerDemo::printMessage(const std::ostringstream&) {}
float drawGetWindowHeight(void) { return 0; }
float drawGetWindowWidth(void) { return 0; }
void drawLine(const Vec3&, const Vec3&, const Color&) {}
void drawCameraLookAt(const Vec3&, const Vec3&, const Vec3&) {}
void deferredDrawLine(const Vec3&, const Vec3&, const Color&) {}
void drawBasic3dSphericalVehicle(const AbstractVehicle*, const Color&) {}
void draw2dTextAt2dLocation(const std::ostringstream&, const Vec3, const Color&, float, float) {}
void drawSphereObstacle(const SphereObstacle&, const float, const bool, const Color&, const Vec3&) {}
}  // namespace OpenSteer
"""


def build_driver(source: Path, workdir: Path) -> Path:
    """Compile the driver and the plugin's sources with g++ -O2; returns the executable."""
    (workdir / "driver.cpp").write_text(DRIVER)
    (workdir / "stubs.cpp").write_text(STUBS)
    flags = ["-O2", f"-I{source / 'include'}", f"-I{source}"]
    objects = []
    for path in [workdir / "driver.cpp", workdir / "stubs.cpp"] + [source / s for s in SOURCES]:
        obj = workdir / (path.stem + ".o")
        compiler = "gcc" if path.suffix == ".c" else "g++"
        subprocess.run([compiler, *flags, "-c", str(path), "-o", str(obj)], check=True)
        objects.append(str(obj))
    exe = workdir / "driver"
    subprocess.run(["g++", "-O2", *objects, "-o", str(exe)], check=True)
    return exe


def cxx_states(exe: Path, n: int, steps: int, seed: int) -> np.ndarray:
    """(steps + 1, n, 16) states printed by the driver: pos, fwd, up, side, speed, smoothed acceleration."""
    out = subprocess.run([str(exe), str(n), str(steps), str(seed), "dump"], capture_output=True, text=True,
                         check=True).stdout
    return np.array(out.split(), dtype=np.float64).reshape(steps + 1, n, 16)


def state_of(record: np.ndarray) -> State:
    fwd, speed = record[:, 3:6].copy(), record[:, 12]
    return State(pos=record[:, 0:3].copy(), vel=fwd * speed[:, None], fwd=fwd, up=record[:, 6:9].copy(),
                 side=record[:, 9:12].copy(), acc=record[:, 13:16].copy(), pattern=np.zeros(len(record), np.uint32))


def fidelity(exe: Path, n: int, seed: int, workdir: Path) -> dict:
    model = load_preset(PRESET).model
    states = cxx_states(exe, n, FIDELITY_STEPS, seed)
    per_step = []
    for k in range(FIDELITY_STEPS):
        ours = advance(model, state_of(states[k]), 1, DT).final
        cxx = states[k + 1]
        per_step.append(max(np.abs(ours.pos - cxx[:, 0:3]).max(), np.abs(ours.fwd - cxx[:, 3:6]).max(),
                            np.abs(ours.vel - cxx[:, 3:6] * cxx[:, 12:13]).max()))
    first = state_of(states[0])
    path = workdir / f"opensteer_state_{n}.npz"
    np.savez(path, pos=first.pos, fwd=first.fwd, speed=states[0, :, 12], up=first.up, acc=first.acc)
    preset = load_preset(PRESET, [f"init.from_file={json.dumps(str(path))}", f"init.n={n}",
                                  f"run.duration={FIDELITY_STEPS * DT!r}"])
    from flocksweep.simcore import simulate_preset

    free = simulate_preset(preset, seed=0, record_every=1)
    drift = [float(np.abs(free.pos[k] - states[k, :, 0:3]).max()) for k in range(FIDELITY_STEPS + 1)]
    return {"n": n, "one_step_max_diff": [float(x) for x in per_step], "free_run_max_pos_diff": drift}


def time_ours(model, state: State, steps: int) -> float:
    start = time.perf_counter()
    advance(model, state, steps, DT, record_every=steps, threads=1)
    return time.perf_counter() - start


def time_cxx(exe: Path, n: int, steps: int, seed: int) -> float:
    out = subprocess.run([str(exe), str(n), str(steps), str(seed), "time"], capture_output=True, text=True, check=True)
    return float(out.stdout)


def own_state(n: int, seed: int) -> State:
    """flocksweep's own initial state of the plugin preset with n boids, drawn from ``seed``."""
    from flocksweep.simcore.rng import run_streams
    from flocksweep.simcore.state import initial_state

    preset = load_preset(PRESET, [f"init.n={n}"])
    rng, _ = run_streams(seed)
    return initial_state(preset.init, preset.model.patterns, rng)


def speed(exe: Path, sizes, steps: int, repeats: int, seed: int, init: str = "own") -> list[dict]:
    model = load_preset(PRESET).model
    cxx_start = {n: state_of(cxx_states(exe, n, 0, seed)[0]) for n in sizes}
    for n in sizes:  # compile (or load) the kernels, warm both sides
        time_ours(model, cxx_start[n], 2)
        time_cxx(exe, n, 2, seed)
    samples = {n: {"cxx": [], "ours": [], "ratio": []} for n in sizes}
    for r in range(repeats):
        for n in sizes:
            start = cxx_start[n] if init == "cxx" else own_state(n, seed + r)
            cxx = time_cxx(exe, n, steps, seed + (r if init == "own" else 0))
            ours = time_ours(model, start, steps)
            samples[n]["cxx"].append(cxx)
            samples[n]["ours"].append(ours)
            samples[n]["ratio"].append(cxx / ours)
    rows = []
    for n in sizes:
        s = samples[n]
        rows.append({"n": n, "steps": steps, "repeats": repeats, "init": init,
                     "cxx_us_per_boid_step": statistics.median(s["cxx"]) * 1e6 / (n * steps),
                     "ours_us_per_boid_step": statistics.median(s["ours"]) * 1e6 / (n * steps),
                     "ratio_median": statistics.median(s["ratio"]), "ratio_min": min(s["ratio"]),
                     "ratio_max": max(s["ratio"])})
    return rows


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--opensteer", type=Path, help="OpenSteer source checkout (github.com/meshula/OpenSteer)")
    parser.add_argument("--sizes", type=int, nargs="+", default=[50, 100, 200, 1000])
    parser.add_argument("--steps", type=int, default=3600, help="steps per timed run (3600: a whole 60 s run)")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--init", choices=["own", "cxx"], default="own",
                        help="each side from its own initial state (default), or both from the C++'s")
    parser.add_argument("--seed", type=int, default=1, help="the C++ rand() seed of the initial flock")
    parser.add_argument("--json", type=Path, help="also write the results here")
    args = parser.parse_args()
    source = args.opensteer
    if source is None or not (source / "plugins" / "Boids.cpp").is_file():
        print("bench_vs_opensteer: skipped: needs --opensteer DIR, a checkout of OpenSteer's source:\n"
              "    git clone https://github.com/meshula/OpenSteer DIR   (measured at commit 7104323)")
        return 0
    if shutil.which("g++") is None:
        print("bench_vs_opensteer: skipped: g++ not found")
        return 0
    with tempfile.TemporaryDirectory(prefix="opensteer-driver-") as tmp:
        workdir = Path(tmp)
        exe = build_driver(source.resolve(), workdir)
        checks = [fidelity(exe, n, args.seed, workdir) for n in (100, 200)]
        for check in checks:
            print(f"fidelity N={check['n']}: one step from the C++ state, max |difference| per step: "
                  + " ".join(f"{x:.1e}" for x in check["one_step_max_diff"]))
            print(f"  free run from the C++ initial state (init.from_file), max |position difference| after "
                  f"1, 5, 10 steps: {check['free_run_max_pos_diff'][1]:.1e}, {check['free_run_max_pos_diff'][5]:.1e}, "
                  f"{check['free_run_max_pos_diff'][10]:.1e}")
        worst = max(max(c["one_step_max_diff"]) for c in checks)
        rows = speed(exe, args.sizes, args.steps, args.repeats, args.seed, args.init)
    load = os.getloadavg()
    print(f"\nspeed: {args.steps} steps, sequential order, one thread, {args.init} initial states, median of "
          f"{args.repeats} interleaved repeats (load average {load[0]:.1f} {load[1]:.1f} {load[2]:.1f})")
    print("| N | C++ plugin (us/boid-step) | flocksweep (us/boid-step) | C++ time / flocksweep time (min-max) |")
    print("|---:|---:|---:|---:|")
    for r in rows:
        print(f"| {r['n']} | {r['cxx_us_per_boid_step']:.3f} | {r['ours_us_per_boid_step']:.3f} | "
              f"**{r['ratio_median']:.2f}x** ({r['ratio_min']:.2f}-{r['ratio_max']:.2f}) |")
    if args.json:
        args.json.write_text(json.dumps({"fidelity": checks, "speed": rows, "machine": platform.platform(),
                                         "python": platform.python_version()}, indent=2))
    if worst > FIDELITY_TOLERANCE:
        print(f"FIDELITY FAILED: a one-step difference of {worst:.2e} exceeds {FIDELITY_TOLERANCE}")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
