"""One simulation from a model preset, with its outputs: the engine of ``flocksweep simulate``.

``run_single(preset, seed, out_dir=None, plot=None, color_by="auto", record_every=None)`` simulates,
returns a summary dict (final polarization, mean speed, mean visible neighbours, binocular share) and,
when ``out_dir`` is given, writes there atomically:

* ``trajectory.npz``: times (R,), pos and vel (R, N, 3), visible and binocular (R, N), pattern (N,);
* ``params.json``: the resolved preset, seed, record interval and the provenance stamp;
* ``traces.png`` when ``plot`` is true (or the path given by ``plot``).
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from analysis.metrics import mean_speed, polarization
from analysis.traces import plot_traces
from simcore import Observations, Preset, simulate_preset

from .atomic import atomic_path, write_json
from .provenance import stamp


def summarize(obs: Observations) -> dict:
    visible = obs.visible[-1]
    seen = visible.sum()
    return {
        "n": int(obs.n),
        "time_s": float(obs.times[-1]),
        "final_polarization": float(polarization(obs.vel[-1])),
        "final_mean_speed": float(mean_speed(obs.vel[-1])),
        "final_mean_visible": float(visible.mean()),
        "final_binocular_share": float(obs.binocular[-1].sum() / seen) if seen else 0.0,
    }


def wrap_jump(preset: Preset) -> float | None:
    world = preset.model.world
    if world.boundary == "sphere_wrap":
        return world.sphere_radius
    if world.boundary == "periodic_box":
        return world.box_size / 2
    return None


def save_trajectory(obs: Observations, path: Path) -> None:
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as handle:
            np.savez_compressed(handle, times=obs.times, pos=obs.pos, vel=obs.vel, visible=obs.visible,
                                binocular=obs.binocular, pattern=obs.pattern)


def run_single(preset: Preset, seed, out_dir=None, plot=None, color_by: str = "auto",
               record_every: int | None = None) -> tuple[dict, list[Path]]:
    """Simulate and write the requested outputs; returns (summary, written paths)."""
    started = time.perf_counter()
    obs = simulate_preset(preset, seed, record_every)
    summary = summarize(obs)
    summary["wall_s"] = time.perf_counter() - started
    written = []
    if out_dir is not None:
        out_dir = Path(out_dir)
        save_trajectory(obs, out_dir / "trajectory.npz")
        write_json(out_dir / "params.json", {"preset": preset.to_dict(), "seed": seed,
                                             "record_every_steps": obs.record_every,
                                             "summary": summary, "provenance": stamp()})
        written += [out_dir / "trajectory.npz", out_dir / "params.json"]
    if plot:
        target = Path(plot) if isinstance(plot, (str, Path)) else Path(out_dir) / "traces.png"
        title = (f"{preset.model.name}: N={obs.n}, {obs.times[-1]:g} s, seed {seed}, "
                 f"final polarization {summary['final_polarization']:.2f}")
        with atomic_path(target) as tmp:
            plot_traces(obs.pos, tmp.with_suffix(target.suffix), obs.pattern, color_by, wrap_jump(preset), title)
            tmp.with_suffix(target.suffix).replace(tmp)
        written.append(target)
    return summary, written
