"""What a calibration cost: the simulations it ran, by phase, its likelihood evaluations and wall time.

Contract
--------
``Accounting()`` starts the clock. ``add(phase, simulations, evaluations=0)`` counts ``simulations``
(simulated runs: rows a simulator returned) and ``evaluations`` (synthetic-likelihood or objective
evaluations, each ``n_sim`` runs) under ``phase``, one of :data:`PHASES`:

* ``training``: the npe method's training simulations (prior draws run as a sweep), this invocation's;
* ``heldout``: the npe method's held-out simulations for the coverage check;
* ``observed``: SBC's synthetic observed datasets (one per dataset);
* ``initial``: the emcee walkers' starting points (and their redraws);
* ``search``: emcee's proposals, or the optimiser's evaluations (common seeds), or, for the emulator,
  none (the emulator's chain runs no simulation);
* ``reevaluation``: BSL's re-simulation of the walkers' current points (``reevaluate_every``);
* ``predictive``: one run per posterior draw for the posterior predictive check;
* ``recheck``: the optimiser's fresh-seed re-check at the optimum;
* ``confirmation``: the emulator's real runs at the posterior median (every refinement round's);
* ``refinement``: sweep runs the emulator's sequential design added to its sweep.

Only what this invocation ran is counted: a resumed chain's earlier steps are not (``resumed_from`` says
from which step it went on), and the runs made before that this invocation used are reported apart
(``training_runs_reused``: the sweep runs an emulator was trained on, or the npe training runs found stored).

``total_simulations(blocks) -> dict``: the phase-wise sum of several blocks' ``simulations`` (SBC's
datasets), ``total`` included.

``block(**extra) -> dict`` is the ``accounting`` entry of ``convergence.json`` / ``optimum.json``:
``simulations`` (per phase and ``total``), ``likelihood_evaluations`` (per phase and ``total``),
``wall_s``, ``cpu_s`` (this process's CPU time; worker processes' not included), ``simulations_per_s``,
and ``extra``. ``lines(block)`` are the plain sentences printed at the end and shown in the report.
"""
from __future__ import annotations

import time

PHASES = ("training", "heldout", "observed", "initial", "search", "reevaluation", "predictive", "recheck", "confirmation", "refinement")


class Accounting:
    """Counts of one calibration run (see the module docstring)."""

    def __init__(self):
        self.started = time.time()
        self.cpu_started = time.process_time()
        self.simulations = dict.fromkeys(PHASES, 0)
        self.evaluations = dict.fromkeys(PHASES, 0)

    def add(self, phase: str, simulations: int, evaluations: int = 0) -> None:
        if phase not in PHASES:
            raise ValueError(f"phase: unknown {phase!r}; allowed: {', '.join(PHASES)}")
        self.simulations[phase] += int(simulations)
        self.evaluations[phase] += int(evaluations)

    def block(self, **extra) -> dict:
        wall = time.time() - self.started
        sims = {p: n for p, n in self.simulations.items() if n}
        evals = {p: n for p, n in self.evaluations.items() if n}
        total = sum(sims.values())
        return {"simulations": {**sims, "total": total},
                "likelihood_evaluations": {**evals, "total": sum(evals.values())},
                "wall_s": wall, "cpu_s": time.process_time() - self.cpu_started,
                "simulations_per_s": total / wall if wall > 0 else None, **extra}


def total_simulations(blocks) -> dict:
    """Phase-wise sum of the ``simulations`` of several accounting blocks (see the module docstring)."""
    out = {}
    for block in blocks:
        for phase, count in block.items():
            out[phase] = out.get(phase, 0) + int(count)
    return out


def lines(block: dict | None) -> list[str]:
    """Plain sentences on a calibration's cost (empty without an accounting block)."""
    if not block:
        return []
    sims = block["simulations"]
    parts = ", ".join(f"{phase} {count:,}" for phase, count in sims.items() if phase != "total")
    evals = block["likelihood_evaluations"]["total"]
    out = [f"cost: {sims['total']:,} simulations ({parts or 'none'}), {evals:,} likelihood evaluations, "
           f"{block['wall_s'] / 60:.1f} min wall"]
    if block.get("resumed_from"):
        out.append(f"  (resumed from step {block['resumed_from']}: the simulations of earlier runs are not counted)")
    if block.get("training_runs_reused"):
        out.append(f"  (and {block['training_runs_reused']:,} runs made before were used: the emulator's sweep, or "
                   "the estimator's stored training runs, found and not run again)")
    return out
