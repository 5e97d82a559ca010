"""One simulation from a model preset, with its outputs: the engine of ``flocksweep simulate``.

``run_single(preset, seed, out_dir=None, record_every=None) -> (summary, written paths, observations)``
simulates and returns the run's summary: ``n``, ``time_s`` and ``wall_s``, then the summary row of
:func:`observables.summary.summarize_run` over the run's records (the columns a sweep's row has:
``polarization_final``, ``speed_mean_final``, ``visible_mean_final``, ``binocular_share_final``, ...,
and the obstacle, predator and prey columns when the run has them) with the model's metric settings and
no warm-up (:func:`summarize`), so window means and encounter scalars cover the whole run. When
``out_dir`` is given it writes there atomically:

* ``trajectory.npz``: every record, in the one trajectory format (:mod:`sweeps.trajectory`: times, pos,
  vel, visible, binocular, leader, pattern, seed, and for a Boids++ run with a predator or prey their
  positions ``predator``, ``prey``);
* ``params.json``: the resolved preset, seed, record interval, the summary and the provenance stamp;
* with ``tracks = "csv"`` or ``"parquet"``: ``tracks.csv`` / ``tracks.parquet``, the records as long-format
  tracks (:func:`observables.tracks.tracks_frame`: flock, id, t, x, y, z, vx, vy, vz, pattern, in
  body lengths and seconds), and the sidecar ``tracks.json`` saying so, for ``flocksweep measure``.

A run that ends in a non-finite state is :class:`~sweeps.failures.SimulationFailed` naming the step and
boid where it began (:func:`sweeps.worker.where_non_finite`), before anything is written. A plug-in
dynamics (:mod:`simcore.plugin`) is checked first (:func:`sweeps.plugin_check.check_plugin`: a compile
error is one message naming its line), its run loop compiled here with no step simulated, and the run
simulated in a child process (:class:`~sweeps.sandbox.Sandbox`), so that a crash of its code (SIGSEGV) is
:class:`SimulationFailed` too, never a dead command.

The trace figure of ``--plot`` is drawn by the CLI (:mod:`analysis.reports.traces`).
"""
from __future__ import annotations

import time
from pathlib import Path

from flocksweep.observables.summary import MetricSettings, NonFiniteState, summarize_run
from flocksweep.observables.tracks import TRACKS_SIDECAR, tracks_frame
from flocksweep.simcore import Observations, Preset, simulate, simulate_preset
from flocksweep.simcore.registry import is_builtin

from .failures import SimulationFailed
from .files import write_csv, write_json, write_parquet
from .non_finite import check_finite_run
from .provenance import stamp
from .trajectory import write_trajectory


def summarize(obs: Observations, settings: MetricSettings) -> dict:
    """``n``, ``time_s`` and the summary row of the run (``settings`` resolved for its model; see the
    module docstring)."""
    return {"n": int(obs.n), "time_s": float(obs.times[-1]), **summarize_run(obs, settings)}


def save_tracks(obs: Observations, out_dir: Path, fmt: str, flock: str, description: str) -> list[Path]:
    """``tracks.<fmt>`` and its sidecar ``tracks.json`` (units: body lengths, seconds)."""
    frame = tracks_frame(obs, flock)
    path = out_dir / f"tracks.{fmt}"
    if fmt == "csv":
        write_csv(path, frame, index=False)
    else:
        write_parquet(path, frame)
    write_json(out_dir / "tracks.json", {**TRACKS_SIDECAR, "description": description})
    return [path, out_dir / "tracks.json"]


def _simulate(preset: Preset, seed, record_every: int | None) -> Observations:
    """The run's observations; a plug-in's in a sandbox (module docstring); SimulationFailed when it
    crashed or ended in a non-finite state."""
    if is_builtin(preset.model.dynamics):
        obs = simulate_preset(preset, seed, record_every)
    else:   # imported here: the sandbox loads multiprocessing's connections, a built-in model needs none
        from .plugin_check import check_plugin
        from .sandbox import Sandbox, TaskCrashed

        check_plugin(preset.model)
        run = preset.run
        simulate(preset.model, preset.init, seed, 0.25 * run.dt, run.dt, 1)   # compiled here, no step simulated
        try:
            with Sandbox() as box:
                obs = box.call(simulate_preset, preset, seed, record_every)
        except TaskCrashed as err:
            raise SimulationFailed(f"it crashed: {err} in compiled code: for a plug-in, an index outside an array "
                                   "in its steer (docs/plugins.md)") from None
    try:
        check_finite_run(preset, seed, obs)
    except NonFiniteState as err:
        raise SimulationFailed(str(err)) from None
    return obs


def run_single(preset: Preset, seed, out_dir=None, record_every: int | None = None, tracks: str | None = None
               ) -> tuple[dict, list[Path], Observations]:
    """Simulate and write the trajectory and parameters; returns (summary, written paths, observations)."""
    from flocksweep.simcore.simulate import compile_seconds

    started, compiling = time.perf_counter(), compile_seconds()
    obs = _simulate(preset, seed, record_every)
    summary = summarize(obs, MetricSettings(warmup=0.0).resolve(preset.model))
    summary["compile_s"] = compile_seconds() - compiling   # run loops compiled for this run (0 when cached)
    summary["wall_s"] = time.perf_counter() - started - summary["compile_s"]
    written = []
    if out_dir is not None:
        out_dir = Path(out_dir)
        write_trajectory(out_dir / "trajectory.npz", obs, seed)
        write_json(out_dir / "params.json", {"preset": preset.to_dict(), "seed": seed,
                                             "record_every_steps": obs.record_every,
                                             "summary": summary, "provenance": stamp()})
        written += [out_dir / "trajectory.npz", out_dir / "params.json"]
        if tracks:
            flock = f"{preset.model.name}-seed{seed}"
            written += save_tracks(obs, out_dir, tracks, flock, f"simulated: {preset.model.name}, seed {seed}, "
                                   f"{obs.n} boids, records every {obs.dt * obs.record_every:g} s")
    return summary, written, obs
