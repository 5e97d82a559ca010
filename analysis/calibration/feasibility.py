"""What a calibration asks of the model and of the machine, checked before anything is written.

* ``check_support(where, key, support, preset, integer)``: both ends of the support the chain explores
  (the prior's, cut to ``bounds``) must be allowed values of the preset ``key``; integer keys are
  rounded as the simulator rounds them (Python's ``round``); an end that is itself excluded but whose
  inside is allowed (``field_deg`` at 0: the range is (0, 360]) is fine, since the chain never proposes
  it. ConfigError at ``where`` (``parameters.<name>.prior`` or ``.bounds``) naming the end and why.
* ``check_memory(preset, parameters, n_sim)``: one evaluation runs ``n_sim`` replicates at once; they
  must fit in memory for the largest ``init.n`` the parameters allow (:func:`sweeps.budget.check_runs`).
* ``check_chain_size(walkers, steps, n_sim, dim, yes=False, available=None)``: the chain (``walkers x
  steps`` rows of ``dim`` coordinates and a log-probability, read back whole for the diagnostics) must
  fit in memory, and a chain of more than :data:`MAX_SIMULATIONS` simulations (``walkers x (steps + 1)
  x n_sim``) needs ``yes`` (``--yes``), as a sweep of more than ``sweeps.budget.MAX_RUNS`` runs does.
* ``check_simulation_count(key, simulations, yes=False, given="", dim=1)``: the same gate for a known
  number of simulations (npe, ``flocksweep compare``), and a refusal whatever ``yes`` says when their
  parameter vectors alone would not fit in memory.
  :class:`~sweeps.budget.BudgetError` naming ``method.walkers`` with the figures and how to shrink it.
"""
from __future__ import annotations

import numpy as np

from flocksweep.simcore.params import Preset
from flocksweep.simcore.schema import ConfigError
from flocksweep.sweeps.budget import BudgetError, available_memory, check_runs, human

MAX_SIMULATIONS = 20_000_000   # a larger chain needs --yes (the shipped studies run up to a few million)


def check_chain_size(walkers: int, steps: int, n_sim: int, dim: int, yes: bool = False,
                     available: int | None = None) -> None:
    """Refuse a chain too large to hold, or gate one with too many simulations (see the module docstring)."""
    available = available_memory() if available is None else available
    rows = walkers * steps
    chain_bytes = 8 * rows * (dim + 1) * 3    # the file's rows, read back, and the diagnostics' copies
    shape = f"{walkers:,} walkers x {steps:,} steps"
    if available is not None and chain_bytes > available:
        raise BudgetError("method.walkers", f"a chain of {shape} would need about {human(chain_bytes)} of memory; "
                                            f"this machine has {human(available)} available: use fewer walkers "
                                            "or steps")
    simulations = walkers * (steps + 1) * n_sim
    if simulations > MAX_SIMULATIONS and not yes:
        raise BudgetError("method.walkers", f"a chain of {shape} x {n_sim:,} simulations per evaluation runs "
                                            f"{simulations:,} simulations (more than {MAX_SIMULATIONS:,}); that takes "
                                            "long: use fewer walkers, steps or n_sim, or pass --yes to go ahead")


def check_simulation_count(key: str, simulations: int, yes: bool = False, given: str = "", dim: int = 1) -> None:
    """Gate a method that runs a known number of simulations (npe's training and held-out sets, a model
    comparison's) as a chain is gated: more than ``MAX_SIMULATIONS`` needs ``yes``; a design whose
    parameter vectors alone (``simulations x dim`` numbers) would not fit in memory is refused even then.
    ``given``: how the count came about, said before it ("got 10 x ... = ")."""
    available = available_memory()
    if available is not None and 8 * simulations * dim > available:
        raise BudgetError(key, f"{given}{simulations:,} simulations: their parameter vectors alone would need about "
                               f"{human(8 * simulations * dim)} of memory; this machine has {human(available)} "
                               f"available; at most {MAX_SIMULATIONS:,} run without --yes: use fewer")
    if simulations > MAX_SIMULATIONS and not yes:
        raise BudgetError(key, f"{given}{simulations:,} simulations (more than {MAX_SIMULATIONS:,}); that takes long: "
                               "use fewer, or pass --yes to go ahead")


def check_support(where: str, key: str, support: tuple[float, float], preset: Preset, integer: bool) -> None:
    """Both ends of the support the chain explores must be allowed values of ``key`` (see the module
    docstring); the message names ``where`` and the offending end."""
    low, high = support
    for end, inward in ((low, high), (high, low)):
        candidates = [end, float(np.nextafter(end, inward))]
        if integer:
            candidates = [int(round(v)) for v in candidates]
        errors = []
        for value in candidates:
            try:
                preset.replace({key: value})
                break
            except ConfigError as err:
                errors.append(err)
        else:
            raise ConfigError(where, f"the prior's support [{low:g}, {high:g}] reaches {candidates[0]!r}, where "
                                     f"{errors[0]}; keep it inside the allowed range (e.g. with bounds = "
                                     "[low, high])") from None


def check_memory(preset: Preset, parameters, n_sim: int) -> None:
    """``n_sim`` runs at once (one batched evaluation) of the largest flock the parameters allow must fit."""
    n, key = preset.init.n, "run.n"
    for parameter in parameters:
        if parameter.key == "init.n" and parameter.bounds[1] > n:
            n, key = parameter.bounds[1], f"parameters.{parameter.name}.prior"
    check_runs(key, n, preset.run.n_steps, preset.run.record_every, copies=n_sim,
               what=f"a run of {n:,.0f} boids ({key})")
